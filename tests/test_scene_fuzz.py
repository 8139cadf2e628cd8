"""Generated malformed scene files, thrown at ``warp-cloth run``: each must end with exit code 2 and one
line on stderr naming the file and the key, no traceback, nothing written.

Every case is a built-in scene with exactly one change that is invalid by construction: a value of the
wrong type, not finite in float32 or out of its key's range, an unknown key, a missing table, a bad
encoding, a truncation that is no longer TOML, deep nesting. Truncations that still parse are skipped
(tomllib, not warp-cloth, says so). Most run in-process through ``cli.main`` (a subprocess costs seconds
of imports); a few run the real entry point to show it behaves the same."""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import operator
import os
import re
import tempfile
import tomllib
import types
import typing
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import warp_cloth as wc
from conftest import run_cli, run_cli_in_process

BASES = {name: tomllib.loads(resources.files("warp_cloth.scenes").joinpath(f"{name}.toml").read_text())
         for name in wc.builtin_scene_names()}
for _name, _doc in BASES.items():
    _doc["name"] = _name
    _doc["simulation"]["frames"] = 1  # should a case be wrongly accepted, it costs one frame
    for _table in _doc.get("cloth", []) + _doc.get("collider", []):  # the cases are written elsewhere; as a
        _mesh = _table.get("mesh")                                    # table, as the fields' hints have it
        if _mesh is not None:
            _mesh = {"file": _mesh} if isinstance(_mesh, str) else _mesh
            _mesh["file"] = str(resources.files("warp_cloth.scenes").joinpath(_mesh["file"]))
            _table["mesh"] = _mesh

NAN, INF = float("nan"), float("inf")
BAD_NAMES = ["a-b", "\u00e9", "x" * 101, "", "ground", "1st", "a b"]
# Values out of range for one key of one settings class (components, for a key that is a list).
OUT_OF_RANGE: dict[tuple[str, str], list[Any]] = {
    ("Scene", "name"): ["", "a b", "x" * 101, "-x", "a/b"],
    ("Simulation", "fps"): [0.0, -24.0, 1e5],
    ("Simulation", "frames"): [0, -1, 10**6 + 1],
    ("Simulation", "substeps"): [0, 10**8],
    ("Simulation", "dt"): [0.0, -0.01, 1e-9, 1.0],
    ("Simulation", "limit_iterations"): [0, 10**9],
    ("Simulation", "limit_tolerance"): [0.0, -0.01, 0.5],
    ("Simulation", "limit_max_passes"): [1, 10**6],
    ("Simulation", "max_speed"): [0.0, -1.0],
    ("Simulation", "drag"): [-1.0],
    ("Cloth", "name"): BAD_NAMES,
    ("Cloth", "resolution"): [0, -3, 70000],
    ("Cloth", "size"): [0.0, -1.0, 1e7],
    ("Cloth", "origin"): [1e6, -1e6],
    ("Cloth", "velocity"): [1e4],
    ("Cloth", "mass"): [0.0, -1.0, 1e-39],
    ("Cloth", "density"): [0.0, -0.2, 1e-39],
    ("Cloth", "jitter"): [-0.1, 0.6],
    ("Cloth", "seed"): [-1],
    ("Cloth", "color"): [-0.1, 1.5],
    ("SpringKind", "stiffness"): [0.0, -1.0, 1e38],
    ("SpringKind", "damping"): [-1.0],
    ("Limit", "stretch"): [0.0, 11.0],
    ("Limit", "compression"): [0.0, 1.0],
    ("Pin", "indices"): [-1, 10**7],
    ("Oscillation", "amplitude"): [-1.0, 1e7],
    ("Oscillation", "frequency"): [-1.0],
    ("Ground", "height"): [1e7, -1e7],
    ("Ground", "friction"): [-0.5],
    ("Ground", "size"): [-1.0],
    ("Sphere", "name"): BAD_NAMES,
    ("Sphere", "center"): [1e7],
    ("Sphere", "radius"): [0.0, -1.0, 1e7],
    ("Sphere", "friction"): [-1.0],
    ("Collision", "iterations"): [0, 10**8],
    ("Collision", "separation"): [0.5, 5.0],
    ("Collision", "friction"): [-1.0],
    ("Collision", "max_neighbors"): [3, 300],
    ("Collision", "radius"): [0.0, -1.0],
    ("Collision", "tolerance"): [0.0, 0.6],
}
WRONG_FLOAT = [NAN, INF, -INF, 1e39, -1e39, "1.0", True, [1.0], {"x": 1.0}]
WRONG_INT = [2.5, "3", True, 2**31, -(2**31) - 1, [1]]
WRONG_STR = [1, 2.5, True, ["a"]]
WRONG_BOOL = [1, "true", 0.5]
WRONG_TABLE = [5, "x", [1, 2], True]
WRONG_ARRAY_OF_TABLES = [5, "x", [1], {"a": 1}]


@dataclasses.dataclass(frozen=True)
class Deep:
    """A list nested ``depth`` levels deep (written as text: no recursion in the writer)."""

    depth: int


# --- TOML writing (inline tables: any document the generator makes) ----------------------------------

def _string(text: str) -> str:
    # JSON's escapes are TOML's; TOML also wants DEL escaped.
    import json

    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _value(value: Any) -> str:
    if isinstance(value, Deep):
        return "[" * value.depth + "]" * value.depth
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value) if isinstance(value, int) or math.isfinite(value) else \
            ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return "{" + ", ".join(f"{_string(k)} = {_value(v)}" for k, v in value.items()) + "}"


def to_toml(doc: dict[str, Any]) -> str:
    return "".join(f"{_string(k)} = {_value(v)}\n" for k, v in doc.items())


# --- Where each value sits in the schema -------------------------------------------------------------

def _field_hints(cls: type) -> dict[str, tuple[str, Any]]:
    hints = typing.get_type_hints(cls)
    return {f.metadata.get("toml", f.name): (f.name, hints[f.name]) for f in dataclasses.fields(cls)}


def _plain(hint: Any) -> Any:
    if get_origin(hint) in (typing.Union, types.UnionType):
        return next(a for a in get_args(hint) if a is not type(None))
    return hint


def key_path(path: tuple) -> str:
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text


def slots(value: Any, hint: Any, owner: str, field: str, path: tuple) -> list[tuple[tuple, Any, str, str]]:
    """Every place a value can change: (path, hint, owning class, field name), tables and arrays too."""
    hint = _plain(hint)
    found = [(path, hint, owner, field)] if path else []
    if dataclasses.is_dataclass(hint) and isinstance(value, dict):
        for key, (name, sub) in _field_hints(hint).items():
            if key in value:
                found += slots(value[key], sub, hint.__name__, name, path + (key,))
    elif get_origin(hint) is tuple:
        args = get_args(hint)
        for k, item in enumerate(value):
            element = args[0] if args[1:] == (Ellipsis,) else args[k]
            found += slots(item, element, owner, field, path + (k,))
    return found


def wrong_values(hint: Any, owner: str, field: str) -> list[Any]:
    """Values that no scene accepts where ``hint`` is expected."""
    if dataclasses.is_dataclass(hint):
        return WRONG_TABLE
    if get_origin(hint) is tuple:
        args = get_args(hint)
        if args[1:] == (Ellipsis,):
            return WRONG_ARRAY_OF_TABLES if dataclasses.is_dataclass(args[0]) else [5, "x", {"a": 1}]
        return [5, "1, 2", True, [], [0.5] * (len(args) + 1), Deep(3), Deep(2000)]
    if get_origin(hint) is Literal:
        return ["nonsense", 1, True]
    ranged = OUT_OF_RANGE.get((owner, field), [])  # for a list's component, the component's range
    return ranged + {float: WRONG_FLOAT, int: WRONG_INT, str: WRONG_STR, bool: WRONG_BOOL}[hint] + [Deep(2)]


def _set(doc: Any, path: tuple, value: Any) -> None:
    for part in path[:-1]:
        doc = doc[part]
    doc[path[-1]] = value


# --- The generator -----------------------------------------------------------------------------------

@dataclasses.dataclass
class Case:
    content: bytes
    key: str | None  # the key the message names, or a key it must be related to; "" for no key
    exact: bool = False  # the message's key must be exactly ``key``


def _related(found: str, key: str) -> bool:
    return any(a == b or a.startswith(b + ".") or a.startswith(b + "[") for a, b in ((found, key), (key, found)))


@st.composite
def malformed_scenes(draw) -> Case:
    doc = copy.deepcopy(BASES[draw(st.sampled_from(sorted(BASES)))])
    kind = draw(st.sampled_from(["value", "value", "value", "unknown key", "structure", "bytes"]))
    if kind == "value":
        places = slots(doc, wc.Scene, "Scene", "", ())
        path, hint, owner, field = draw(st.sampled_from(places))
        value = draw(st.sampled_from(wrong_values(hint, owner, field)))
        _set(doc, path, value)
        key = "" if isinstance(value, Deep) and value.depth > 500 else key_path(path)
        return Case(to_toml(doc).encode(), key)
    if kind == "unknown key":
        # a table given by its shorthand (``material = "denim"``, ``mesh = "a.obj"``) is a string, not a table
        tables = [p for p, hint, _, _ in slots(doc, wc.Scene, "Scene", "", ())
                  if dataclasses.is_dataclass(hint) and isinstance(functools.reduce(operator.getitem, p, doc), dict)]
        path = draw(st.sampled_from([()] + tables))
        table = doc
        for part in path:
            table = table[part]
        known = _known_keys(path)
        name = draw(st.text(st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=12)
                    .filter(lambda k: k not in known))
        table[name] = draw(st.sampled_from([1, 1.5, "x", True, [1], {"a": 1}]))
        printed = name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else repr(name)
        return Case(to_toml(doc).encode(), f"{key_path(path)}.{printed}" if path else printed, exact=True)
    if kind == "structure":
        return draw(st.sampled_from(_structural_cases(doc)))
    text = to_toml(doc).encode()
    change = draw(st.sampled_from(["utf-16", "bad byte", "nul", "truncate"]))
    at = draw(st.integers(0, len(text) - 1))
    if change == "utf-16":
        return Case(to_toml(doc).encode("utf-16"), "")
    if change == "bad byte":
        return Case(text[:at] + draw(st.sampled_from([b"\xff", b"\xc3", b"\xfe\xff"])) + text[at:], "")
    if change == "nul":
        return Case(text[:at] + b"\x00" + text[at:], "")
    cut = text[:at]
    assume(not _parses(cut))
    return Case(cut, "")


def _known_keys(path: tuple) -> set[str]:
    hint: Any = wc.Scene
    for part in path:
        hint = _plain(hint)
        if isinstance(part, int):
            hint = get_args(hint)[0]
        else:
            hint = _field_hints(hint)[part][1]
    return set(_field_hints(_plain(hint)))


def _parses(content: bytes) -> bool:
    try:
        tomllib.loads(content.decode())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False
    return True


def _structural_cases(doc: dict[str, Any]) -> list[Case]:
    cases = []
    without_cloth = {k: v for k, v in doc.items() if k != "cloth"}
    cases.append(Case(to_toml(without_cloth).encode(), "cloth"))
    for c, cloth in enumerate(doc["cloth"]):
        pinned = copy.deepcopy(doc)
        pinned["cloth"][c]["pins"] = [{}]
        cases.append(Case(to_toml(pinned).encode(), f"cloth[{c}].pins[0]", exact=True))
        boxed = copy.deepcopy(doc)
        boxed["cloth"][c]["pins"] = [{"region": {"min": [0.0, 0.0, 0.0]}}]
        cases.append(Case(to_toml(boxed).encode(), f"cloth[{c}].pins[0].region.max", exact=True))
    named = [("cloth", k) for k in range(len(doc["cloth"]))] + [("sphere", k) for k in range(len(doc.get("sphere", [])))]
    for (kind_a, a), (kind_b, b) in zip(named, named[1:]):
        twin = copy.deepcopy(doc)
        twin[kind_b][b]["name"] = twin[kind_a][a].get("name", "cloth" if kind_a == "cloth" else "sphere").upper()
        cases.append(Case(to_toml(twin).encode(), f"{kind_b}[{b}].name", exact=True))
    return cases


# --- The tests ----------------------------------------------------------------------------------------

def check_refused(case: Case, path: Path, returncode: int, stderr: str) -> None:
    assert returncode == 2, (case, stderr)
    assert "Traceback" not in stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, lines
    prefix = f"warp-cloth: error: {path}: "
    assert lines[0].startswith(prefix), (lines[0], case.key)
    rest = lines[0][len(prefix):]
    found = "" if rest.startswith("expected ") else rest.partition(": expected ")[0]
    if case.exact or case.key == "":
        assert found == case.key, (found, case.key, rest)
    else:
        assert _related(found, case.key), (found, case.key, rest)


@settings(max_examples=400, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(malformed_scenes())
def test_malformed_scene_files_are_refused_in_one_line(case):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "scene.toml"
        path.write_bytes(case.content)
        returncode, stdout, stderr = run_cli_in_process("run", str(path), "--device", "cpu", "--frames", "1",
                                                        "--quiet", cwd=Path(folder))
        check_refused(case, path, returncode, stderr)
        assert stdout == ""
        assert os.listdir(folder) == ["scene.toml"]


def _changed(base: str, path: tuple, value: Any) -> bytes:
    doc = copy.deepcopy(BASES[base])
    _set(doc, path, value)
    return to_toml(doc).encode()


SUBPROCESS_CASES = [
    ("utf16", to_toml(BASES["hanging"]).encode("utf-16"), ""),
    ("float32", _changed("hanging", ("cloth", 0, "origin", 0), 1e39), "cloth[0].origin[0]"),
    ("unknown", (to_toml(BASES["drape"]) + '"\u00e9\\n" = 1\n').encode(), repr("\u00e9\n")),
    ("truncated", to_toml(BASES["pile"]).encode()[:-7], ""),
]


@pytest.mark.parametrize("name, content, key", SUBPROCESS_CASES, ids=[c[0] for c in SUBPROCESS_CASES])
def test_the_real_entry_point_refuses_them_the_same_way(tmp_path, name, content, key):
    path = tmp_path / "scene.toml"
    path.write_bytes(content)
    result = run_cli("run", str(path), "--device", "cpu", "--frames", "1", cwd=tmp_path)
    check_refused(Case(content, key, exact=True), path, result.returncode, result.stderr)
    assert os.listdir(tmp_path) == ["scene.toml"]
