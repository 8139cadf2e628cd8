"""The command line, the README's and the Python guide's examples, and the built wheel's contents."""

import re
import shutil
import subprocess
import sys
import zipfile

import pytest
from pxr import Usd

import warp_cloth as wc
from conftest import REPO, run_cli, run_cli_in_process


def test_scenes_lists_every_builtin_with_its_description(tmp_path):
    result = run_cli("scenes", cwd=tmp_path)
    assert result.returncode == 0
    lines = result.stdout.strip().splitlines()
    assert [line.split()[0] for line in lines] == wc.builtin_scene_names()
    assert all(len(line.split(maxsplit=1)) == 2 for line in lines)


@pytest.mark.parametrize("args", [["--help"], ["run", "--help"], ["scenes", "--help"]])
def test_help_everywhere(tmp_path, args):
    result = run_cli(*args, cwd=tmp_path)
    assert result.returncode == 0 and "usage:" in result.stdout


def test_run_writes_usd_and_poly_and_prints_one_summary_line(tmp_path):
    code, out, err = run_cli_in_process("run", "sphere_push", "--frames", "5", "--substeps", "6", "--integrator",
                                        "symplectic", "--device", "cpu", cwd=tmp_path)
    assert code == 0, err
    lines = out.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith("sphere_push: step 6.94 ms (6 substeps/frame), as set;")
    assert re.match(r"sphere_push: 5 frames \(30 substeps of 6.94 ms, symplectic\) of 121 particles on cpu", lines[1])
    stage = Usd.Stage.Open(str(tmp_path / "out" / "sphere_push.usdc"))
    assert stage.GetEndTimeCode() == 5
    assert len(list((tmp_path / "out" / "sphere_push" / "poly").glob("cloth.*.poly"))) == 6


def test_run_output_options(tmp_path):
    result = run_cli("run", "hanging", "--frames", "2", "--usd", "shots/h.usdc", "--no-poly", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "shots" / "h.usdc").is_file()
    assert not (tmp_path / "out").exists()
    result = run_cli("run", "hanging", "--frames", "2", "--no-usd", "--poly", "p", "--out", "o", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert len(list((tmp_path / "p").iterdir())) == 3 and not (tmp_path / "o").exists()


def test_readme_and_python_guide_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    readme = re.search(r"\nFrom Python:\n\n```python\n(.*?)```", (REPO / "README.md").read_text(), re.S).group(1)
    exec(compile(readme, "README.md", "exec"), {})
    assert (tmp_path / "out" / "hanging_1s.usdc").is_file()
    (tmp_path / "out" / "hanging_1s.usdc").unlink()
    text = (REPO / "docs" / "guide" / "python-api.md").read_text()
    example = re.search(r"## From Python\n\n```python\n(.*?)```", text, re.S).group(1)
    batch = re.search(r"## Many scenes at once: a batch of worlds\n\n```python\n(.*?)```", text, re.S).group(1)
    names: dict = {}
    exec(compile(example, "python-api.md", "exec"), names)
    assert (tmp_path / "out" / "hanging_1s.usdc").is_file()
    exec(compile(batch, "python-api.md", "exec"), names)  # goes on from the first example's scene
    assert names["batch"].frame == 24 and names["batch"].world_count == 3


def test_readme_starts_with_the_install_and_test_commands():
    text = (REPO / "README.md").read_text()
    blocks = re.findall(r"```\n(.*?)\n```", text, re.S)
    assert "pip install -e . " in blocks[0] and "warp-cloth run hanging" in blocks[0]  # the light install
    assert blocks[1] == "pip install -e '.[test]' && python -m pytest -q -n auto --dist loadfile"
    ci = (REPO / ".ci" / "run").read_text()
    assert blocks[1] in ci


# Where each source folder goes in the wheel (the package-dir mapping of pyproject.toml).
WHEEL_FOLDERS = {"warp_cloth": "warp_cloth", "kernels": "warp_cloth/kernels", "scenes": "warp_cloth/scenes"}


def test_wheel_contains_every_module_and_scene(tmp_path):
    # Built from a copy, so that setuptools' build/ and egg-info land there and not in the checkout.
    had_build_folder = (REPO / "build").exists()
    source = tmp_path / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    for folder in WHEEL_FOLDERS:
        shutil.copytree(REPO / folder, source / folder, ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(source)], check=True, capture_output=True)
    wheel = next(tmp_path.glob("warp_cloth-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {f"{WHEEL_FOLDERS[folder]}/{path.relative_to(REPO / folder).as_posix()}"
                for folder in ("warp_cloth", "kernels") for path in (REPO / folder).rglob("*.py")}
    expected |= {f"warp_cloth/scenes/{scene}.toml" for scene in wc.builtin_scene_names()}
    assert "warp_cloth/writers/usd.py" in expected and "warp_cloth/kernels/springs.py" in expected
    assert expected - names == set()
    assert (REPO / "build").exists() == had_build_folder


def test_version_is_the_packages_one_from_the_command_and_from_python(tmp_path):
    import tomllib

    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    result = run_cli("--version", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"warp-cloth {version} ") and "warp-lang" in result.stdout
    assert wc.__version__ == version
