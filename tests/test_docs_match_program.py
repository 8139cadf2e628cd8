"""The README, the docs and the help say what the program does: every link resolves inside the repository,
the lists of scenes and integrators are the program's, every scene key is in the scene reference, and each
option and suite is explained."""

import dataclasses
import re
import tomllib
import typing
from pathlib import Path

import pytest

import warp_cloth as wc
from conftest import REPO, run_cli
from warp_cloth.checks import toml_key
from warp_cloth.lab.bench import SUITES
from warp_cloth.scene import INTEGRATORS

DOCS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md")), *sorted((REPO / "tools").glob("*.md"))]
SCENE_REFERENCE = REPO / "docs" / "guide" / "scene-reference.md"
# Options being retired (issue 32): the user guide must not offer them, though the code may still take them.
RETIRED = {"simulation.limit_multilevel", "implicit.cg_loop", "collision.lists", "collision.broad_phase",
           "collision.search_scale", "cloth.limit.long_range"}
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)[^)]*\)")
CODE_SPAN_UP = re.compile(r"`(\.\./[^`\s]+)`")  # a path written relative to the file, leaving its folder


def _paragraph(doc: Path, starting: str) -> str:
    text = doc.read_text()
    start = text.index(starting)
    return text[start:text.index("\n\n", start)]


@pytest.mark.parametrize("doc", DOCS, ids=lambda path: str(path.relative_to(REPO)))
def test_every_relative_link_resolves_to_a_file_in_the_repository(doc: Path):
    text = doc.read_text()
    targets = [t for t in MARKDOWN_LINK.findall(text) if not re.match(r"[a-z]+:|#", t)] + CODE_SPAN_UP.findall(text)
    for target in targets:
        path = (doc.parent / target.split("#")[0]).resolve()
        assert path.is_relative_to(REPO) and path.exists(), f"{doc.name}: {target}"


def test_scene_reference_lists_every_builtin_scene():
    named = re.findall(r"`(\w+)`\s+\(", _paragraph(SCENE_REFERENCE, "Built-in scenes:"))
    assert sorted(named) == wc.builtin_scene_names()


def test_integrator_lists_are_the_programs():
    for doc in (REPO / "README.md", REPO / "docs" / "guide" / "command-line.md"):
        options = re.findall(r"--integrator ([a-z|]+)`", doc.read_text())
        assert options and all(option.split("|") == list(INTEGRATORS) for option in options), doc.name
    comment = re.search(r'^integrator = "\w+" +# (.*)$', SCENE_REFERENCE.read_text(), re.M).group(1)
    assert [part.split("(")[0].strip() for part in comment.split("|")] == list(INTEGRATORS)


def test_readme_says_what_the_seed_is_where_it_first_names_it():
    text = (REPO / "README.md").read_text()
    first = re.search(r"\bseed\b", text, re.I).start()
    paragraph = text[text.rindex("\n\n", 0, first):text.index("\n\n", first)]
    assert "C++ course project" in paragraph and "(https://github.com/loshjawrence/ClothSim)" in paragraph


def test_no_graph_help_says_what_it_does_on_the_cpu_and_a_gpu(tmp_path):
    result = run_cli("run", "--help", cwd=tmp_path)
    help_text = " ".join(result.stdout.split("--no-graph", 2)[2].split("--quiet")[0].split())
    assert "on a GPU" in help_text and "on the CPU" in help_text


def test_bench_help_explains_every_suite(tmp_path):
    result = run_cli("bench", "--help", cwd=tmp_path)
    assert result.returncode == 0
    for name, suite in SUITES.items():
        explained = re.search(rf"^  {name} +(.*(?:\n {{15}}.*)*)", result.stdout, re.M)
        assert explained and " ".join(explained.group(1).split()) == suite.measures


def test_every_public_name_is_exported_unstable_simulation_among_them():
    from warp_cloth.errors import UnstableSimulation

    assert wc.UnstableSimulation is UnstableSimulation and "UnstableSimulation" in wc.__all__
    assert all(getattr(wc, name) is not None for name in wc.__all__)


def _reference_sections() -> dict[str, str]:
    """The scene reference's annotated scene, by table: "" for the top level, "cloth.pins" for
    ``[[cloth.pins]]``; a table's header counts in its own text, commented out or not."""
    block = re.search(r"## Every key\n\n```toml\n(.*?)```", SCENE_REFERENCE.read_text(), re.S).group(1)
    sections, name = {"": ""}, ""
    for line in block.splitlines():
        header = re.match(r"#? ?\[\[?([\w.]+)\]\]?", line)
        if header:
            name = header.group(1)
            sections.setdefault(name, "")
        sections[name] += line + "\n"
    return sections


def _keys(cls: type, table: str, sections: dict[str, str], prefix: str = ""):
    """(the key's path, the text of the table it must be documented in) for every key a scene file takes;
    a nested dataclass is a table of its own where the reference has one, else inline in its parent's."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        path = f"{prefix}.{toml_key(f)}" if prefix else toml_key(f)
        yield path, sections[table] + sections.get(path, "")
        hint = hints[f.name]
        args = [a for a in typing.get_args(hint) if a is not type(None) and a is not Ellipsis] or [hint]
        nested = next((a for a in args if dataclasses.is_dataclass(a)), None)
        if nested is not None:
            yield from _keys(nested, path if path in sections else table, sections, path)


def test_scene_reference_has_every_key_of_every_table_and_none_retired():
    sections = _reference_sections()
    missing, retired = [], []
    for path, text in _keys(wc.Scene, "", sections):
        key = path.rsplit(".", 1)[-1]
        documented = re.search(rf"(^|[\s{{,#])({re.escape(key)} = |\[\[?{re.escape(path)}\]\]?)", text, re.M)
        if path in RETIRED and documented:
            retired.append(path)
        elif path not in RETIRED and not documented:
            missing.append(path)
    assert (missing, retired) == ([], [])
    assert "multilevel" not in " ".join(p.read_text() for p in (REPO / "docs" / "guide").glob("*.md"))


def test_readme_scene_loads_and_is_short():
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    scene = wc.scene_from_dict({"name": "mine", **tomllib.loads(re.search(r"```toml\n(.*?)```", readme, re.S).group(1))})
    assert scene.collision is not None and len(scene.cloths) == 1 and scene.spheres[0].name == "ball"


def test_scene_reference_names_the_builtin_scenes_whose_solves_reach_their_cap_as_measured():
    """The scene reference's claim of which built-in scenes end every limit solve within tolerance is what each
    scene's full run measured (tools/builtin_solves.py), on every device recorded."""
    import json

    limited = {name for name in wc.builtin_scene_names() if any(c.limit is not None for c in wc.load_scene(name).cloths)}
    capped = set()
    records = sorted((REPO / "docs" / "results").glob("builtin-solves-*.jsonl"))
    assert records
    for path in records:
        rows = [json.loads(line) for line in path.read_text().splitlines()]
        assert {row["scene"] for row in rows} == limited, path
        capped |= {row["scene"] for row in rows if row["limit_residual"] is not None and row["limit_residual"] > 1.0}
    text = " ".join(SCENE_REFERENCE.read_text().split())
    claim = re.search(r"every solve ends within its tolerance(?: but some of (.*?)'s)?:", text)
    assert claim is not None, "the scene reference says which scenes' solves reach their cap"
    assert set(re.findall(r"`(\w+)`", claim.group(1) or "")) == capped
