"""Scene files: TOML in, a checked ``Scene`` out, or a ``SceneError`` naming file, key and expectation.

The file's tables and keys are the dataclass fields of ``warp_cloth.scene`` (a field may name its TOML
key in its metadata, as ``Scene.cloths`` does with ``[[cloth]]``), so the schema lives in one place.
"""

from __future__ import annotations

import dataclasses
import re
import tomllib
import types
import typing
from importlib import resources
from pathlib import Path
from typing import Any, get_args, get_origin

from .checks import describe, file_name_from, toml_key
from .errors import SceneError
from .geometry_checks import validate
from .scene import Scene

_BUILTIN_PACKAGE = "warp_cloth.scenes"
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")  # a key printed as it is; any other is quoted

# Keys that older scene files may still set, by table, with what the program does instead: their options
# lost their experiments (docs/notebook/strain-solve.md, docs/notebook/benchmarks.md).
RETIRED_KEYS = {
    ("Simulation", "limit_multilevel"): "the converged solve is the default, and Chebyshev's method "
                                        "accelerates it",
    ("Simulation", "limit_chebyshev_rho"): "the converged solve estimates its Chebyshev radius itself, solve "
                                           "by solve",
    ("ImplicitSolver", "cg_loop"): "the CG iterations always run in a conditional loop on the device",
    ("Collision", "broad_phase"): "the hash grid finds the pairs (checking all of them up to 512 particles)",
    ("Collision", "lists"): "the lists are remade once a particle has moved far enough",
    ("Collision", "search_scale"): "candidates are listed within 1.5 contact distances",
    ("Collision", "projection"): "the limits and contacts are projected jointly for a substep's first 200 "
                                 "passes, then sequentially",
    ("Collision", "edges"): "set [collision] thickness (metres): every triangle edge and vertex-triangle pair "
                            "held that far apart, under bounds that let no step make a crossing",
    ("Limit", "long_range"): "the converged solve's Chebyshev acceleration or more substeps hold a fine "
                             "cloth's limit",
}


def builtin_scene_names() -> list[str]:
    """The built-in scenes, by name (the file stem)."""
    folder = resources.files(_BUILTIN_PACKAGE)
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def resolve_scene_path(name_or_path: str | Path) -> Path:
    """A path to an existing scene file, or a built-in's file when given a built-in's name."""
    text = str(name_or_path)
    if not text:
        raise SceneError("scene", "a built-in scene name or a path to a .toml file", text)
    if text in builtin_scene_names():
        return Path(str(resources.files(_BUILTIN_PACKAGE).joinpath(f"{text}.toml")))
    path = Path(text)
    if path.is_dir():
        raise SceneError("", "a scene file (this is a directory)", has_got=False, source=text)
    if path.exists() and not path.is_file():
        raise SceneError("", "a scene file (this is not a regular file)", has_got=False, source=text)
    if not path.is_file():
        known = ", ".join(builtin_scene_names())
        raise SceneError("", f"an existing scene file (no such file) or a built-in scene name ({known})",
                         has_got=False, source=text)
    return path


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a built-in scene by name, or a scene file by path. Without a ``name`` key the scene is named
    after the file, its characters other than ASCII letters, digits, '_' and '-' made '_'."""
    data, path = load_scene_data(name_or_path)
    try:
        return scene_from_dict(data)
    except SceneError as exc:
        raise exc.in_file(str(path)) from None


def load_scene_data(name_or_path: str | Path) -> tuple[dict[str, Any], Path]:
    """A scene file's plain data as ``scene_from_dict`` takes it (named, its mesh paths made absolute), and
    the file it came from."""
    path = resolve_scene_path(name_or_path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("", f"valid TOML ({exc})", has_got=False, source=str(path)) from None
    except UnicodeDecodeError as exc:
        line = exc.object[:exc.start].count(b"\n") + 1
        raise SceneError("", f"a UTF-8 text file (line {line}, byte {exc.start} is not UTF-8)", has_got=False,
                         source=str(path)) from None
    except RecursionError:
        raise SceneError("", "TOML that is not nested hundreds of levels deep", has_got=False,
                         source=str(path)) from None
    except OSError as exc:
        raise SceneError("", f"a readable file ({exc.strerror})", has_got=False, source=str(path)) from None
    if "name" not in data:
        data["name"] = file_name_from(path.stem)
    _mesh_paths_from(path.parent.absolute(), data)
    return data, path


def _mesh_paths_from(folder: Path, data: dict[str, Any]) -> None:
    """A cloth's or collider's relative mesh path is taken from the scene file's folder, not the working
    directory."""
    for table in ("cloth", "collider"):
        items = data.get(table)
        for item in items if isinstance(items, list) else ():
            mesh = item.get("mesh") if isinstance(item, dict) else None
            if isinstance(mesh, str) and mesh:
                item["mesh"] = str(folder / mesh)
            elif isinstance(mesh, dict) and isinstance(mesh.get("file"), str) and mesh["file"]:
                mesh["file"] = str(folder / mesh["file"])


def scene_from_dict(data: dict[str, Any]) -> Scene:
    """A ``Scene`` from plain data as TOML gives it, checked; errors name the key path. Tables become the
    dataclasses they stand for and arrays of tables tuples of them; the dataclasses check every value
    themselves, as they do for a scene built in Python, and ``geometry_checks.validate`` the rest."""
    scene = _convert(data, Scene, "")
    validate(scene)
    return scene


def table_as(data: dict[str, Any], cls: type) -> Any:
    """A table of plain data as the dataclass ``cls`` (a ``Material``, say), checked as a scene's table of
    it is; errors name its keys from the top."""
    return _convert(data, cls, "")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _convert(value: Any, hint: Any, path: str) -> Any:
    """Tables to dataclasses where ``hint`` asks for them; every other value as it is."""
    if get_origin(hint) in (typing.Union, types.UnionType):
        options = [a for a in get_args(hint) if a is not type(None)]
        return _convert(value, options[0], path)
    if dataclasses.is_dataclass(hint) and isinstance(value, dict):
        return _to_dataclass(value, hint, path)
    if dataclasses.is_dataclass(hint) and isinstance(value, str) and hasattr(hint, "from_string"):
        try:
            return hint.from_string(value)
        except SceneError as exc:
            raise exc.within(path) from None
    if get_origin(hint) is tuple and isinstance(value, list):
        args = get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis and dataclasses.is_dataclass(args[0]):
            return tuple(_convert(item, args[0], f"{path}[{k}]") for k, item in enumerate(value))
    return value


def _printable_key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else repr(key)


def _to_dataclass(value: dict[str, Any], cls: type, path: str) -> Any:
    hints = typing.get_type_hints(cls)
    fields = {toml_key(f): f for f in dataclasses.fields(cls)}
    for key in value:
        if (cls.__name__, key) in RETIRED_KEYS:
            raise SceneError(_join(path, key), f"no {key}: it was retired, remove it "
                                               f"({RETIRED_KEYS[cls.__name__, key]})", has_got=False)
        if key not in fields:
            raise SceneError(_join(path, _printable_key(key)),
                             "a known key (one of " + ", ".join(sorted(fields)) + ")", has_got=False)
    for key, f in fields.items():
        if key not in value and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise SceneError(_join(path, key), f"{describe(hints[f.name])} (required)", has_got=False)
    kwargs = {f.name: _convert(value[key], hints[f.name], _join(path, key))
              for key, f in fields.items() if key in value}
    try:
        return cls(**kwargs)
    except SceneError as exc:
        raise (exc.within(path) if path else exc) from None
