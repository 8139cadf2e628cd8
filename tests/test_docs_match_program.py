"""The README, the docs and the help say what the program does: every link resolves inside the repository,
the lists of scenes and integrators are the program's, and each option and suite is explained."""

import dataclasses
import re
from pathlib import Path

import pytest

import warp_cloth as wc
from conftest import REPO, run_cli
from warp_cloth.lab.bench import SUITES
from warp_cloth.scene import INTEGRATORS

DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), *sorted((REPO / "tools").glob("*.md"))]
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)[^)]*\)")
CODE_SPAN_UP = re.compile(r"`(\.\./[^`\s]+)`")  # a path written relative to the file, leaving its folder


def _readme_paragraph(starting: str) -> str:
    text = (REPO / "README.md").read_text()
    start = text.index(starting)
    return text[start:text.index("\n\n", start)]


@pytest.mark.parametrize("doc", DOCS, ids=lambda path: str(path.relative_to(REPO)))
def test_every_relative_link_resolves_to_a_file_in_the_repository(doc: Path):
    text = doc.read_text()
    targets = [t for t in MARKDOWN_LINK.findall(text) if not re.match(r"[a-z]+:|#", t)] + CODE_SPAN_UP.findall(text)
    for target in targets:
        path = (doc.parent / target.split("#")[0]).resolve()
        assert path.is_relative_to(REPO) and path.exists(), f"{doc.name}: {target}"


def test_readme_lists_every_builtin_scene():
    named = re.findall(r"`(\w+)`\s+\(", _readme_paragraph("Built-in scenes:"))
    assert sorted(named) == wc.builtin_scene_names()


def test_readme_integrator_lists_are_the_programs():
    readme = (REPO / "README.md").read_text()
    options = re.findall(r"--integrator ([a-z|]+)`", readme)
    assert options and all(option.split("|") == list(INTEGRATORS) for option in options)
    comment = re.search(r'^integrator = "\w+" +# (.*)$', readme, re.M).group(1)
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


def test_readme_scene_reference_has_every_simulation_key():
    reference = _readme_paragraph("[simulation]\n")
    documented = set(re.findall(r"(\w+) = ", reference))  # as a line's key, or in a comment ("or substeps = 17")
    assert {f.name for f in dataclasses.fields(wc.Simulation)} <= documented


def test_readme_names_the_builtin_scenes_whose_solves_reach_their_cap_as_measured():
    """The README's claim of which built-in scenes end every limit solve within tolerance is what each
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
    text = " ".join((REPO / "README.md").read_text().split())
    claim = re.search(r"every solve ends within its tolerance but some of (.*?)'s:", text)
    assert claim is not None, "the README says which scenes' solves reach their cap"
    assert set(re.findall(r"`(\w+)`", claim.group(1))) == capped
