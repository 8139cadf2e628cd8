"""Scene files: built-ins load; bad input is one clear message (file, key path, expectation), exit
code 2, no traceback and nothing written."""

import pytest

import warp_cloth as wc
from conftest import run_cli
from warp_cloth import simulator

VALID = """
[simulation]
frames = 2
substeps = 2

[[cloth]]
resolution = [3, 3]
size = [1.0, 1.0]

[[cloth.pins]]
corners = ["top-left"]
"""


def test_every_builtin_scene_loads_and_describes_itself():
    names = wc.builtin_scene_names()
    assert {"hanging", "ground", "drape", "sphere_push", "oscillating_pins"} <= set(names)
    for name in names:
        scene = wc.load_scene(name)
        assert scene.name == name and scene.description


def test_scene_file_maps_onto_dataclasses(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(VALID)
    scene = wc.load_scene(path)
    assert scene.name == "mine"
    assert scene.cloths[0].resolution == (3, 3)
    assert scene.cloths[0].pins[0].corners == ("top-left",)
    assert scene.simulation.substeps_per_frame == 2


@pytest.mark.parametrize("dt, substeps", [(0.0025, 17), (0.0052, 8), (0.0104, 4), (0.0208, 2), (0.04165, 1)])
def test_seed_time_steps_land_on_whole_substeps(dt, substeps):
    assert wc.Simulation(fps=24, dt=dt).substeps_per_frame == substeps


BAD = [
    # (change to VALID, key path in the message, words of the expectation)
    ("colour = 1\n" + VALID, "colour", "a known key"),
    (VALID.replace("frames = 2", "frames = 2\nfrmes = 3"), "simulation.frmes", "a known key"),
    (VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nstructural = { stifness = 3 }"),
     "cloth[0].structural.stifness", "a known key"),
    (VALID.replace("resolution = [3, 3]", 'resolution = "3x3"'), "cloth[0].resolution", "a list of 2 whole numbers"),
    (VALID.replace("resolution = [3, 3]", "resolution = [3, 0]"), "cloth[0].resolution", "each >= 1"),
    (VALID.replace("size = [1.0, 1.0]", "size = [1.0, -1.0]"), "cloth[0].size", "each > 0"),
    (VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nmass = 0.0"), "cloth[0].mass", "> 0"),
    (VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nshear = { stiffness = -5.0 }"),
     "cloth[0].shear.stiffness", "> 0"),
    (VALID.replace("substeps = 2", "dt = 0.0"), "simulation.dt", "> 0"),
    (VALID.replace("substeps = 2", "dt = -0.01"), "simulation.dt", "> 0"),
    (VALID.replace("substeps = 2", "dt = nan"), "simulation.dt", "a finite number"),
    (VALID.replace("resolution = [3, 3]", "resolution = [100000, 100000]"), "cloth[0].resolution",
     "at most"),
    (VALID.replace('corners = ["top-left"]', 'corners = ["top-middle"]'), "cloth[0].pins[0].corners[0]",
     "one of 'bottom-left'"),
    (VALID.replace('corners = ["top-left"]', "indices = [16]"), "cloth[0].pins[0].indices[0]",
     "a particle index < 16"),
    (VALID.replace('corners = ["top-left"]', "region = { min = [5, 5, 5], max = [6, 6, 6] }"),
     "cloth[0].pins[0].region", "at least one particle"),
    (VALID.replace('substeps = 2', 'integrator = "rk4"'), "simulation.integrator", "one of 'explicit'"),
    (VALID + "\n[[sphere]]\nradius = 0\n", "sphere[0].radius", "> 0"),
    (VALID.replace("frames = 2", "frames = 2.5"), "simulation.frames", "a whole number"),
    (VALID.replace("[simulation]", "[simulation\n"), "", "valid TOML"),
]


@pytest.mark.parametrize("text, key, expected", BAD, ids=[b[1] or "syntax" for b in BAD])
def test_bad_scene_is_one_clear_error_with_exit_code_2_and_no_output(tmp_path, text, key, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(wc.SceneError) as info:
        wc.load_scene(path)
    message = str(info.value)
    assert message.startswith(str(path))
    assert f": {key}: " in message if key else True
    assert expected in message
    result = run_cli("run", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert result.stderr.strip() == f"warp-cloth: error: {message}"
    assert not (tmp_path / "out").exists()


def test_missing_file_names_the_file_and_the_builtins(tmp_path):
    result = run_cli("run", "nowhere.toml", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "nowhere.toml" in result.stderr and "no such file" in result.stderr and "hanging" in result.stderr


def test_bad_command_line_value_is_named(tmp_path):
    result = run_cli("run", "hanging", "--dt", "-1", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "--dt" in result.stderr and "> 0" in result.stderr
    assert not (tmp_path / "out").exists()


def test_scene_too_large_for_memory_is_refused_before_allocating(monkeypatch, tmp_path):
    monkeypatch.setattr(simulator, "HOST_BYTES_PER_PARTICLE", 1 << 40)
    with pytest.raises(wc.SceneError, match="fits in memory"):
        wc.Simulator(wc.load_scene("hanging"), device="cpu")


def test_scene_built_in_python_is_checked_by_the_same_rules():
    with pytest.raises(wc.SceneError, match="stiffness: expected a number > 0"):
        wc.SpringKind(stiffness=0.0)
    with pytest.raises(wc.SceneError, match="cloth: expected at least one"):
        wc.Scene(cloths=())
