"""Scene files: built-ins load; bad input is one clear message (file, key path, expectation), exit
code 2, no traceback and nothing written."""

import dataclasses
import math
import os
import tomllib
import typing

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import warp_cloth as wc
from conftest import run_cli_in_process
from warp_cloth import scene as scene_module, simulator
from warp_cloth.lab import bench
from warp_cloth.writers.shot_layer import prim_name
from warp_cloth.model import build_model
from warp_cloth.stability import choose_step, scene_with_step

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


def test_substeps_auto_is_said_or_left_out_and_a_number_fixes_the_step():
    auto = wc.scene_from_dict(tomllib.loads(VALID.replace("substeps = 2", 'substeps = "auto"')))
    left_out = wc.scene_from_dict(tomllib.loads(VALID.replace("substeps = 2\n", "")))
    assert auto.simulation.auto_substeps and left_out.simulation.auto_substeps
    assert auto.simulation.substeps_per_frame is None and auto.simulation.time_step is None
    assert scene_with_step(auto) == scene_with_step(left_out)  # one scene to a checkpoint's fingerprint
    assert not wc.scene_from_dict(tomllib.loads(VALID)).simulation.auto_substeps


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
    (VALID.replace("substeps = 2", 'substeps = "fast"'), "simulation.substeps", "a whole number or 'auto', got 'fast'"),
    (VALID.replace("substeps = 2", "substeps = 2.5"), "simulation.substeps", "a whole number or 'auto', got 2.5"),
    (VALID.replace("substeps = 2", "substeps = 0"), "simulation.substeps", 'a whole number in [1, 10000] or "auto"'),
    (VALID.replace("substeps = 2", 'substeps = "auto"\ndt = 0.01'), "simulation.dt", "either substeps or dt"),
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
    (VALID.replace("substeps = 2", 'integrator = "implicit"\ncompensated = true'), "simulation.compensated",
     "false with the implicit integrator"),
    (VALID + "\n[collision]\nthickness = 0.004\n", "collision.thickness", "a strain limit on every cloth"),
    (VALID + "\n[collision]\nthickness = 0.0\n", "collision.thickness", "a number > 0, got 0.0"),
    (VALID + "\n[collision]\nthickness = -0.004\n", "collision.thickness", "a number > 0"),
    (VALID + '\n[collision]\nthickness = "4 mm"\n', "collision.thickness", "a number"),
    (VALID + "\n[collision]\nthickness = 1e9\n", "collision.thickness", "metres of magnitude at most"),
    (VALID + "\n[collision]\nthickness = 0.004\n", "collision.thickness",
     "no thickness, or a strain limit on every cloth"),
    (VALID.replace("substeps = 2", 'substeps = 2\nlimit_solve = "fixed"').replace(
        "size = [1.0, 1.0]", "size = [1.0, 1.0]\nlimit = { stretch = 0.1 }") + "\n[collision]\nthickness = 0.004\n",
     "collision.thickness", 'simulation.limit_solve = "converged"'),
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
    # In this process: tests/test_scene_fuzz.py shows the real entry point answers the same way.
    code, out, err = run_cli_in_process("run", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert code == 2 and out == ""
    assert "Traceback" not in err
    assert err.strip() == f"warp-cloth: error: {message}"
    assert not (tmp_path / "out").exists()


RETIRED = [
    # (change to VALID, key path, what the message tells the user to do instead)
    (VALID.replace("substeps = 2", "substeps = 2\nlimit_multilevel = true"), "simulation.limit_multilevel",
     "the converged solve is the default"),
    (VALID + "\n[implicit]\ncg_loop = \"unrolled\"\n", "implicit.cg_loop", "a conditional loop"),
    (VALID + "\n[collision]\nbroad_phase = \"brute_force\"\n", "collision.broad_phase", "the hash grid"),
    (VALID + "\n[collision]\nlists = \"every_substep\"\n", "collision.lists", "moved far enough"),
    (VALID + "\n[collision]\nsearch_scale = 2.0\n", "collision.search_scale", "1.5 contact distances"),
    (VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nlimit = { long_range = true }"),
     "cloth[0].limit.long_range", "Chebyshev acceleration"),
    (VALID.replace("substeps = 2", "substeps = 2\nlimit_chebyshev_rho = 0.95"), "simulation.limit_chebyshev_rho",
     "estimates its Chebyshev radius itself"),
    (VALID + "\n[collision]\nprojection = \"sequential\"\n", "collision.projection", "jointly for a substep's first 200"),
    (VALID + "\n[collision]\nedges = true\n", "collision.edges", "set [collision] thickness"),
]


@pytest.mark.parametrize("text, key, instead", RETIRED, ids=[r[1] for r in RETIRED])
def test_a_retired_key_is_refused_saying_it_was_retired_and_what_to_do(tmp_path, text, key, instead):
    path = tmp_path / "old.toml"
    path.write_text(text)
    code, out, err = run_cli_in_process("run", str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert code == 2 and out == "" and "Traceback" not in err
    message = err.strip()
    assert message.startswith(f"warp-cloth: error: {path}: {key}: expected ") and "\n" not in message
    assert "retired" in message and "remove it" in message and instead in message
    assert not (tmp_path / "out").exists()


def test_no_retired_key_names_a_key_the_scene_still_has():
    from warp_cloth.checks import toml_key
    from warp_cloth.scene_file import RETIRED_KEYS
    for table, key in RETIRED_KEYS:
        assert key not in {toml_key(f) for f in dataclasses.fields(getattr(scene_module, table))}


def test_missing_file_names_the_file_and_the_builtins(tmp_path):
    code, _, err = run_cli_in_process("run", "nowhere.toml", cwd=tmp_path)
    assert code == 2 and "Traceback" not in err
    assert "nowhere.toml" in err and "no such file" in err and "hanging" in err


def test_bad_command_line_value_is_named(tmp_path):
    code, _, err = run_cli_in_process("run", "hanging", "--dt", "-1", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert code == 2 and "Traceback" not in err
    assert "--dt" in err and "> 0" in err
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


def refused_in_one_line(tmp_path, text: str | bytes, name: str = "bad.toml") -> str:
    """Run a scene file through ``warp-cloth run`` (in this process): exit code 2, one line on stderr naming
    the file, nothing written. Returns the message after the file's name."""
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    before = set(os.listdir(tmp_path))
    code, out, err = run_cli_in_process("run", str(path), "--device", "cpu", "--frames", "1", "--quiet", cwd=tmp_path)
    assert code == 2 and out == "" and "Traceback" not in err, err
    assert len(err.splitlines()) == 1 and err.startswith(f"warp-cloth: error: {path}: "), err
    assert set(os.listdir(tmp_path)) == before
    return err.strip()[len(f"warp-cloth: error: {path}: "):]


CLOTH = '[[cloth]]\nname = "{}"\nresolution = [3, 3]\nsize = [1.0, 1.0]\norigin = [{}, 0.0, 0.0]\n'
SPHERE = '[[sphere]]\nname = "{}"\ncenter = [0.0, 10.0, 0.0]\n'
COLLIDING_NAMES = [
    # (file, the key named, words of the expectation)
    (CLOTH.format("a-b", 0) + CLOTH.format("a_b", 5), "cloth[0].name", "ASCII letters, digits and '_'"),
    (CLOTH.format("\u00e9", 0) + CLOTH.format("\u00fc", 5), "cloth[0].name", "ASCII letters, digits and '_'"),
    ("[ground]\nheight = -1.0\n" + CLOTH.format("ground", 0), "cloth[0].name", "nor the ground"),
    (CLOTH.format("ball", 0) + SPHERE.format("ball"), "sphere[0].name", "cloth[0] has it"),
    (CLOTH.format("Cloth", 0) + CLOTH.format("cloth", 5), "cloth[1].name", "ignoring case"),
    (CLOTH.format("x" * 101, 0), "cloth[0].name", "at most 100"),
    (f'name = "{"x" * 101}"\n' + CLOTH.format("c", 0), "name", "at most 100"),
    (CLOTH.format("nul", 0), "cloth[0].name", "nor a Windows device name"),
    ('name = "CON"\n' + CLOTH.format("c", 0), "name", "nor a Windows device name"),
]


@pytest.mark.parametrize("text, key, expected", COLLIDING_NAMES, ids=[c[1] + str(k) for k, c in enumerate(COLLIDING_NAMES)])
def test_names_that_would_collide_as_usd_prims_or_files_are_refused(tmp_path, text, key, expected):
    message = refused_in_one_line(tmp_path, text)
    assert message.startswith(f"{key}: expected ") and expected in message


def test_names_collide_the_same_way_in_python():
    with pytest.raises(wc.SceneError, match=r"sphere\[0\]\.name: .*cloth\[0\] has it"):
        wc.Scene(cloths=(wc.Cloth(name="ball"),), spheres=(wc.Sphere(name="ball"),))
    with pytest.raises(wc.SceneError, match="name: .*ASCII"):
        wc.Cloth(name="a-b")


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.text(max_size=8))
def test_an_accepted_cloth_or_sphere_name_is_its_usd_prim_name(name):
    try:
        wc.Sphere(name=name)
    except wc.SceneError:
        return
    assert prim_name(name) == name


def test_a_file_without_a_name_is_named_after_its_stem_made_valid(tmp_path):
    path = tmp_path / "my.shot.v2.toml"
    path.write_text(VALID)
    assert wc.load_scene(path).name == "my_shot_v2"
    (tmp_path / f"{'x' * 150}.toml").write_text(VALID)
    assert wc.load_scene(tmp_path / f"{'x' * 150}.toml").name == "x" * 100
    (tmp_path / "aux.toml").write_text(VALID)
    assert wc.load_scene(tmp_path / "aux.toml").name == "aux_"


VALID_BODY = VALID.replace("[[cloth]]", "[[cloth]]\nmass = 0.025")
NOT_FINITE_IN_FLOAT32 = [
    # (change to VALID, key, words of the expectation, the same scene built in Python)
    (("size = [1.0, 1.0]", "size = [1.0, 1.0]\norigin = [1e39, 0.0, 0.0]"), "cloth[0].origin[0]", "float32",
     lambda: wc.Cloth(origin=(1e39, 0.0, 0.0))),
    (("size = [1.0, 1.0]", "size = [1.0, 1.0]\norigin = [nan, 0.0, 0.0]"), "cloth[0].origin[0]", "finite",
     lambda: wc.Cloth(origin=(math.nan, 0.0, 0.0))),
    (("mass = 0.025", "mass = 1e46"), "cloth[0].mass", "float32", lambda: wc.Cloth(mass=1e46)),
    (("mass = 0.025", "mass = 1e-39"), "cloth[0].mass", "the lightest particle's mass a finite, normal float32",
     lambda: wc.Cloth(mass=1e-39)),
    (("mass = 0.025", "density = 1e-38"), "cloth[0].density", "the lightest particle's mass a finite, normal",
     lambda: wc.Cloth(resolution=(3, 3), size=(1.0, 1.0), density=1e-38)),
    (("size = [1.0, 1.0]", "size = [1.0, 1.0]\nstructural = { stiffness = 1e38 }"), "cloth[0].structural.stiffness",
     "/ the lightest particle's mass", lambda: wc.Cloth(mass=0.025, structural=wc.SpringKind(stiffness=1e38))),
    (("size = [1.0, 1.0]", "size = [1.0, 1.0]\nseed = -1"), "cloth[0].seed", ">= 0", lambda: wc.Cloth(seed=-1)),
    (("resolution = [3, 3]", "resolution = [2147483648, 3]"), "cloth[0].resolution[0]", "int32",
     lambda: wc.Cloth(resolution=(2**31, 3))),
    (("resolution = [3, 3]", "resolution = [3.5, 3]"), "cloth[0].resolution[0]", "a whole number",
     lambda: wc.Cloth(resolution=(3.5, 3))),
    (("size = [1.0, 1.0]", 'size = [1.0, 1.0]\norientation = "diagonal"'), "cloth[0].orientation", "one of",
     lambda: wc.Cloth(orientation="diagonal")),
    (("size = [1.0, 1.0]", "size = [1.0, 1.0]\norigin = [0.0, 1e6, 0.0]"), "cloth[0].origin",
     "of the world origin", lambda: wc.Cloth(size=(1.0, 1.0), resolution=(3, 3), origin=(0.0, 1e6, 0.0))),
    (('corners = ["top-left"]', "indices = [4294967296]"), "cloth[0].pins[0].indices[0]", "int32",
     lambda: wc.Pin(indices=(2**32,))),
]


@pytest.mark.parametrize("change, key, expected, in_python", NOT_FINITE_IN_FLOAT32,
                         ids=[f"{c[1]}-{k}" for k, c in enumerate(NOT_FINITE_IN_FLOAT32)])
def test_values_the_device_cannot_hold_are_refused_alike_from_a_file_and_from_python(tmp_path, change, key,
                                                                                     expected, in_python):
    message = refused_in_one_line(tmp_path, VALID_BODY.replace(*change))
    assert message.startswith(f"{key}: expected ") and expected in message
    with pytest.raises(wc.SceneError) as info:
        in_python()
    # The same check, the same words: only the key's path differs (a file names the table it is in).
    assert message.endswith(str(info.value)) and key.endswith(info.value.key)


def test_weight_past_float32_is_refused():
    heavy = wc.Cloth(mass=3e37)
    with pytest.raises(wc.SceneError, match=r"cloth\[0\]\.mass: expected a mass whose weight"):
        wc.Scene(cloths=(heavy,), simulation=wc.Simulation(gravity=(0.0, -20.0, 0.0)))


def _valid_instances() -> dict[type, object]:
    pin = wc.Pin(indices=(0,), corners=("top-left",), motion=wc.Oscillation())
    cloth = wc.Cloth(pins=(pin,), limit=wc.Limit())
    return {wc.Oscillation: wc.Oscillation(), wc.SpringKind: wc.SpringKind(), wc.Limit: wc.Limit(),
            wc.Box: wc.Box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)), wc.Pin: pin, wc.Cloth: cloth, wc.Ground: wc.Ground(),
            wc.Sphere: wc.Sphere(), wc.Collision: wc.Collision(radius=0.1), wc.ImplicitSolver: wc.ImplicitSolver(),
            wc.Simulation: wc.Simulation(dt=0.001), wc.Output: wc.Output(),
            wc.Scene: wc.Scene(cloths=(cloth,), ground=wc.Ground(height=-1.0))}


def _number_fields(instance) -> list[tuple[str, type, int | None]]:
    """(field, float or int, component index or None) for every number an instance holds."""
    found = []
    for f in dataclasses.fields(instance):
        hint = typing.get_type_hints(type(instance))[f.name]
        args = [a for a in typing.get_args(hint) if a is not type(None)] if typing.get_origin(hint) is not tuple \
            else [hint]
        hint = args[0] if args else hint
        if hint in (int, float):
            found.append((f.name, hint, None))
        elif typing.get_origin(hint) is tuple:
            value = getattr(instance, f.name)
            found += [(f.name, type(v), k) for k, v in enumerate(value) if type(v) in (int, float)]
    return found


@pytest.mark.parametrize("cls", list(_valid_instances()), ids=lambda c: c.__name__)
def test_every_number_of_every_settings_class_is_checked_for_float32_and_int32(cls):
    instance = _valid_instances()[cls]
    fields = _number_fields(instance)
    assert fields or cls in (wc.Output, wc.Scene)  # these hold only names and settings classes
    for name, kind, index in fields:
        for bad in ((math.nan, math.inf, 1e39, "1") if kind is float else (2**31, -(2**31) - 1, 2.5, True)):
            value = getattr(instance, name)
            if index is not None:
                value = value[:index] + (bad,) + value[index + 1:]
            key = f"{name}[{index}]" if index is not None else name
            with pytest.raises(wc.SceneError) as info:
                dataclasses.replace(instance, **{name: value if index is not None else bad})
            assert info.value.key == key, (cls.__name__, key, bad, str(info.value))


TOO_MUCH_WORK = [
    (("substeps = 2", "substeps = 100000000"), "simulation.substeps", "in [1, 10000]"),
    (("substeps = 2", "dt = 1e-9"), "simulation.dt", "at most 10000 substeps a frame"),
    (("substeps = 2", "limit_iterations = 1e9"), "simulation.limit_iterations", "a whole number"),
    (("substeps = 2", "limit_iterations = 1000000000"), "simulation.limit_iterations", "in [1, 1000]"),
    (("frames = 2", "frames = 100000000"), "simulation.frames", "in [1, 1000000]"),
    (("[simulation]", "[collision]\niterations = 100000000\n[simulation]"), "collision.iterations", "in [1, 1000]"),
    (("[simulation]", "[implicit]\ncg_max_iterations = 1000000\n[simulation]"), "implicit.cg_max_iterations",
     "in [1, 100000]"),
    # Each within its own bound, together past what a frame may take (checked at start-up).
    (("substeps = 2", 'substeps = 10000\nlimit_solve = "fixed"\nlimit_iterations = 1000'), "simulation.substeps",
     "at most 50,000 passes a frame"),
    (("substeps = 2", 'substeps = 100\nlimit_solve = "fixed"\nlimit_iterations = 999'),
     "simulation.limit_iterations", "at most 50,000 passes a frame"),
    (("substeps = 2", 'substeps = 100\nlimit_solve = "converged"\nlimit_max_passes = 999'),
     "simulation.limit_max_passes", "at most 50,000 passes a frame"),
    (("substeps = 2", 'substeps = 20\nintegrator = "implicit"\n[implicit]\nnewton_iterations = 100\n'
                      'cg_max_iterations = 100000'), "implicit.cg_max_iterations", "at most 50,000 passes a frame"),
]


@pytest.mark.parametrize("change, key, expected", TOO_MUCH_WORK, ids=[f"{c[1]}-{k}" for k, c in enumerate(TOO_MUCH_WORK)])
def test_absurd_amounts_of_work_are_refused_before_running(tmp_path, change, key, expected):
    limited = VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nlimit = {}")
    message = refused_in_one_line(tmp_path, limited.replace(*change))
    assert message.startswith(f"{key}: expected ") and expected in message


def test_an_unset_limit_cap_is_chosen_within_the_frame_bound():
    # 1000 substeps a frame: the default 1000 passes a substep would be 1,001,000 passes a frame; unset, the
    # cap becomes what fits (49), where a cap the scene sets is refused (above).
    limited = VALID.replace("size = [1.0, 1.0]", "size = [1.0, 1.0]\nlimit = {}")
    for substeps, cap in ((1000, 49), (2, 1000)):
        scene = wc.scene_from_dict(tomllib.loads(limited.replace("substeps = 2", f"substeps = {substeps}")))
        assert scene.simulation.limit_max_passes is None
        assert wc.Simulator(scene, device="cpu").scene.simulation.limit_max_passes == cap


def test_no_built_in_scene_sets_a_solver_constant():
    # What a scene needs, the solver finds itself (issue 32): the cap (the Chebyshev radius and the projection
    # order are no scene keys any more).
    for name in wc.builtin_scene_names():
        assert wc.load_scene(name).simulation.limit_max_passes is None, name


def check_work_bounds(scene: wc.Scene) -> None:
    scene = scene_with_step(scene)
    substeps = scene.simulation.substeps_per_frame
    if substeps is None:  # substeps auto: from the stable floor
        substeps = choose_step(build_model(scene), scene.simulation).substeps
    simulator.check_work(scene, substeps)


def test_work_bounds_leave_the_built_in_scenes_and_benchmarks_valid():
    for name in wc.builtin_scene_names():
        check_work_bounds(wc.load_scene(name))
    for device in ("cpu", "cuda"):
        for name, suite in bench.SUITES.items():
            if (name, device) == ("meshes", "cuda"):
                continue  # the slow test below: the matrix's sphere cases, with the settings checked here
            for case in suite.cases(device):
                check_work_bounds(case.scene)
    assert bench.MATRIX_SUBSTEPS <= scene_module.MAX_SUBSTEPS


@pytest.mark.slow
def test_work_bounds_leave_the_gpu_mesh_benchmarks_valid():
    """Listing these cases writes OBJ files of 1024^2 cloths: half a minute on two cores."""
    for case in bench.SUITES["meshes"].cases("cuda"):
        check_work_bounds(case.scene)


BAD_FILES = [
    ("utf8", "cloth = 1\n".encode() + b"name = \"caf\xe9\"\n", "a UTF-8 text file (line 2, byte 21 is not UTF-8)"),
    ("utf16", VALID.encode("utf-16"), "a UTF-8 text file (line 1, byte 0 is not UTF-8)"),
    ("nested", ("a = " + "[" * 3000 + "]" * 3000 + "\n").encode(), "TOML that is not nested hundreds of levels deep"),
]


@pytest.mark.parametrize("name, content, expected", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_unreadable_scene_files_are_one_line(tmp_path, name, content, expected):
    assert refused_in_one_line(tmp_path, content) == f"expected {expected}"


def test_a_directory_or_a_device_given_as_a_scene_is_called_what_it_is(tmp_path):
    (tmp_path / "shots").mkdir()
    code, _, err = run_cli_in_process("run", "shots", "--device", "cpu", cwd=tmp_path)
    assert code == 2 and err == "warp-cloth: error: shots: expected a scene file (this is a directory)\n"
    code, _, err = run_cli_in_process("run", "/dev/null", "--device", "cpu", cwd=tmp_path)
    assert code == 2 and err == "warp-cloth: error: /dev/null: expected a scene file (this is not a regular file)\n"


TWO_CLOTHS = VALID.replace("[[cloth.pins]]\ncorners = [\"top-left\"]\n", "") + \
    '\n[collision]\n\n[[cloth]]\nname = "other"\nresolution = [3, 3]\nsize = [1.0, 1.0]\n'
START_INSIDE = [
    (TWO_CLOTHS, "cloth: expected cloths that start apart"),
    # 0.6 - |(1/3, 1/3) - (1/2, 1/2)| deep, past half of a 1/3 m cell
    (VALID + '\n[[sphere]]\nname = "ball"\ncenter = [0.5, 0.5, 0.0]\nradius = 0.6\n',
     "cloth[0]: expected a cloth that starts outside the static colliders: particle 5 of 'cloth' starts 0.364 m inside "
     "sphere[0] 'ball' (at most 0.167 m, half a cell)"),
    (VALID + "\n[ground]\nheight = 0.5\n",
     "cloth[0]: expected a cloth that starts outside the static colliders: particle 0 of 'cloth' starts 0.5 m inside "
     "the ground (at most 0.167 m, half a cell)"),
]


@pytest.mark.parametrize("text, expected", START_INSIDE, ids=["overlap", "sphere", "ground"])
def test_scenes_refused_at_start_up_name_the_file_and_the_colliders(tmp_path, text, expected):
    assert refused_in_one_line(tmp_path, text).startswith(expected)


def test_a_cloth_touching_a_collider_less_than_half_a_cell_deep_starts():
    scene = wc.scene_from_dict({"cloth": [{"resolution": [3, 3], "size": [1.0, 1.0]}], "ground": {"height": 0.15},
                                "sphere": [{"center": [0.5, 0.5, 0.6], "radius": 0.75}]})
    wc.Simulator(scene, device="cpu")  # 0.15 m below the ground, 0.105 m inside the sphere: contacts


def test_values_from_python_are_stored_as_a_file_gives_them():
    cloth = wc.Cloth(resolution=[4, 4], origin=[0, 1, 0], mass=1)
    assert cloth.resolution == (4, 4) and cloth.origin == (0.0, 1.0, 0.0) and isinstance(cloth.mass, float)
    assert hash(cloth) == hash(wc.Cloth(resolution=(4, 4), origin=(0.0, 1.0, 0.0), mass=1.0))
