"""The step a run takes when the scene sets none: chosen from the scene's own stiffness, masses and cells
(warp_cloth/stability.py), stable where the old fixed default blew up; a set step past the bound warns
before the first frame."""

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings, strategies as st

import warp_cloth as wc
from warp_cloth.errors import UnstableSimulation
from warp_cloth.model import FLAG_DAMPING_COMPRESSION, FLAG_DAMPING_TENSION, FLAG_ELASTIC_COMPRESSION, \
    FLAG_ELASTIC_TENSION, build_model
from warp_cloth.scene import INTEGRATORS
from warp_cloth.stability import SAFETY, SAFETY_DAMPING, automatic_substeps, model_bound, safety, stable_step
from conftest import REPO, run_cli_in_process, spring_strains, with_simulation

LINEAR = FLAG_ELASTIC_TENSION | FLAG_ELASTIC_COMPRESSION | FLAG_DAMPING_TENSION | FLAG_DAMPING_COMPRESSION
TWO_CORNERS = (wc.Pin(corners=("top-left", "top-right")),)
MAX_TEST_SUBSTEPS = 200


def chain(count: int, k: float, rest: float, mass: float, damping: float = 0.0):
    """A straight chain of ``count`` free particles along x, as the arrays ``stable_step`` takes."""
    positions = np.stack([np.arange(count) * rest, np.zeros(count), np.zeros(count)], axis=1)
    pairs = np.stack([np.arange(count - 1), np.arange(1, count)], axis=1)
    springs = len(pairs)
    return (positions, np.full(count, 1.0 / mass), pairs, np.full(springs, rest), np.full(springs, k),
            np.full(springs, damping), np.full(springs, LINEAR))


def test_chain_bound_is_the_analytic_one_and_the_true_spectrum_is_below_it():
    k, rest, mass, count = 10.0, 0.5, 0.02, 200
    bound = stable_step(*chain(count, k, rest, mass), "symplectic")
    assert bound.omega_max ** 2 == pytest.approx(4.0 * k / (rest * mass), rel=1e-9)
    assert bound.step == pytest.approx(2.0 / math.sqrt(4.0 * k / (rest * mass)), rel=1e-9)
    # the chain's own largest eigenvalue of M^-1 K: below the bound, and close to it on a long chain
    stiffness = np.diag(np.full(count, 2.0)) - np.diag(np.ones(count - 1), 1) - np.diag(np.ones(count - 1), -1)
    stiffness[0, 0] = stiffness[-1, -1] = 1.0
    largest = np.linalg.eigvalsh(stiffness * k / (rest * mass))[-1]
    assert 0.999 * bound.omega_max ** 2 <= largest <= bound.omega_max ** 2


def test_explicit_euler_with_undamped_springs_is_bounded_by_growth_over_the_run():
    k, rest, mass, duration = 10.0, 0.5, 0.02, 4.0
    bound = stable_step(*chain(50, k, rest, mass), "explicit", duration=duration)
    assert "undamped" in bound.limited_by
    assert bound.step == pytest.approx(2.0 * math.log(2.0) / (duration * 4.0 * k / (rest * mass)), rel=1e-9)


def test_damped_single_mode_bounds_are_the_amplification_matrix_limits():
    # One free particle on one spring to a held one: a single mode, w^2 = k/(L0 m), c = b/m.
    k, rest, mass, b = 100.0, 1.0, 0.01, 0.5
    positions, inv_mass, pairs, rests, ks, bs, flags = chain(2, k, rest, mass, b)
    inv_mass[0] = 0.0
    w2, c = k / (rest * mass), b / mass
    symplectic = stable_step(positions, inv_mass, pairs, rests, ks, bs, flags, "symplectic").step
    explicit = stable_step(positions, inv_mass, pairs, rests, ks, bs, flags, "explicit").step
    assert symplectic == pytest.approx(4.0 / (c + math.sqrt(c * c + 4.0 * w2)))
    assert explicit == pytest.approx(c / w2)  # underdamped: |1 + h s|^2 = 1 - h c + h^2 w^2
    for integrator, h in (("symplectic", symplectic), ("explicit", explicit)):
        radius = lambda step: max(abs(np.linalg.eigvals(amplification(integrator, step, w2, c))))  # noqa: E731
        assert radius(0.99 * h) < 1.0 < radius(1.01 * h)


def test_a_bound_set_by_damping_is_taken_at_half_where_damped_velocities_keep_their_sign():
    # An overdamped single mode (c^2 > 4 w^2): explicit Euler's bound is the damping's 2/c. At 0.8 of it a
    # step flips the velocity's sign (a negative eigenvalue); at half of it both eigenvalues stay positive.
    k, rest, mass, b = 1.0, 1.0, 0.01, 0.5
    positions, inv_mass, pairs, rests, ks, bs, flags = chain(2, k, rest, mass, b)
    inv_mass[0] = 0.0
    w2, c = k / (rest * mass), b / mass
    bound = stable_step(positions, inv_mass, pairs, rests, ks, bs, flags, "explicit")
    assert bound.limited_by == "damping" and bound.step == pytest.approx(2.0 / c)
    assert safety(bound) == SAFETY_DAMPING == 0.5
    assert min(np.linalg.eigvals(amplification("explicit", 0.8 * bound.step, w2, c)).real) < 0.0
    assert np.all(np.linalg.eigvals(amplification("explicit", SAFETY_DAMPING * bound.step, w2, c)).real > 0.0)
    # seed_default's explicit step is bounded by its damping: left to the simulator, it starts at half of it
    scene = wc.load_scene("seed_default")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, dt=None, substeps=None))
    sim = wc.Simulator(scene, device="cpu")
    assert sim.step_choice.bound.limited_by == "damping"
    assert sim.step_choice.substeps == math.ceil(1.0 / (scene.simulation.fps * 0.5 * sim.step_choice.bound.step))


def amplification(integrator: str, h: float, w2: float, c: float) -> np.ndarray:
    """One step's matrix on (v, x) of x'' = -w^2 x - c x'."""
    if integrator == "symplectic":
        return np.array([[1 - h * c, -h * w2], [h * (1 - h * c), 1 - h * h * w2]])
    return np.array([[1 - h * c, -h * w2], [h, 1.0]])


def single_spring_scene(integrator: str, step_over_bound: float) -> wc.Scene:
    """A 1x1 cloth held at three corners, its free corner on two orthogonal linear springs (two decoupled
    copies of the single mode above), stepped at ``step_over_bound`` times its bound."""
    spring = wc.SpringKind(stiffness=100.0, damping=0.5, acts="both")
    cloth = wc.Cloth(resolution=(1, 1), size=(1.0, 1.0), mass=0.01, structural=spring,
                     shear=wc.SpringKind(enabled=False), bend=wc.SpringKind(enabled=False),
                     pins=(wc.Pin(corners=("bottom-left", "bottom-right", "top-left")),))
    w2, c = 100.0 / 0.01, 0.5 / 0.01
    bound = 4.0 / (c + math.sqrt(c * c + 4.0 * w2)) if integrator == "symplectic" else c / w2
    substeps = 10
    fps = 1.0 / (step_over_bound * bound * substeps)
    return wc.Scene(name="spring", cloths=(cloth,),
                    simulation=wc.Simulation(fps=fps, frames=60, substeps=substeps, integrator=integrator))


@pytest.mark.parametrize("integrator", ["symplectic", "explicit"])
def test_single_spring_holds_just_under_its_bound_and_grows_just_over(integrator):
    speeds = {}
    for ratio in (0.95, 1.05):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", wc.UnstableStepWarning)
            sim = wc.Simulator(single_spring_scene(integrator, ratio), device="cpu")
        assert sim.step_choice.bound.step * ratio == pytest.approx(sim.dt, rel=1e-5)
        per_frame = []
        try:
            for _ in range(60):
                sim.step()
                per_frame.append(np.abs(sim.velocities()).max())
            speeds[ratio] = max(per_frame[-10:]) / max(per_frame[:10])
        except UnstableSimulation:
            speeds[ratio] = math.inf
    assert speeds[0.95] < 1.0 < speeds[1.05]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(resolution=st.integers(2, 12), size=st.floats(0.3, 10.0), density=st.floats(0.01, 2.0),
       stiffness=st.floats(0.1, 1000.0), damping=st.floats(0.0, 10.0), integrator=st.sampled_from(INTEGRATORS),
       pinned=st.booleans())
def test_random_cloths_at_their_chosen_step_stay_finite_and_bounded(resolution, size, density, stiffness, damping,
                                                                    integrator, pinned):
    spring = wc.SpringKind(stiffness, damping)
    cloth = wc.Cloth(resolution=(resolution, resolution), size=(size, size), origin=(0.0, 1.0, 0.0), density=density,
                     structural=spring, shear=spring, bend=wc.SpringKind(stiffness, damping, "compression",
                                                                         "compression"),
                     limit=wc.Limit(), pins=TWO_CORNERS if pinned else ())
    scene = wc.Scene(cloths=(cloth,), ground=wc.Ground(), simulation=wc.Simulation(frames=24, integrator=integrator))
    assume(automatic_substeps(24, model_bound(build_model(scene), scene.simulation)) <= MAX_TEST_SUBSTEPS)  # a fast test
    with warnings.catch_warnings():
        warnings.simplefilter("error", wc.UnstableStepWarning)
        sim = wc.Simulator(scene, device="cpu")
    sim.run()  # the guard raises if anything went non-finite or past 1000 m/s
    fall = math.sqrt(2 * 9.81 * (1.0 + size))  # speed after falling the whole scene's height
    assert np.linalg.norm(sim.velocities(), axis=1).max() <= 3.0 * fall
    assert sim.positions()[:, 1].min() >= -1e-6


@pytest.fixture
def guide_example(tmp_path, monkeypatch) -> dict:
    """The names the Python guide's first example leaves, after running it in an empty folder."""
    text = (REPO / "docs" / "guide" / "python-api.md").read_text()
    example = re.search(r"## From Python\n\n```python\n(.*?)```", text, re.S).group(1)
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    exec(compile(example, "python-api.md", "exec"), names)
    return names


def test_python_guide_drop_scene_stays_stable_for_48_frames(guide_example):
    sim = guide_example["sim"]
    assert sim.scene.name == "drop" and sim.step_choice.automatic
    for _ in range(47):
        sim.step()  # raises UnstableSimulation on a blow-up
    assert np.abs(sim.velocities()).max() < 9.81 * sim.time + 1.0  # no faster than falling


@pytest.mark.parametrize("cloth", [wc.Cloth(pins=TWO_CORNERS), wc.Cloth(mass=0.005, pins=TWO_CORNERS),
                                   wc.Cloth(resolution=(40, 40), size=(1.0, 1.0), pins=TWO_CORNERS)],
                         ids=["defaults", "lighter", "finer"])
def test_cloth_from_api_defaults_with_its_own_changes_runs(cloth):
    sim = wc.Simulator(wc.Scene(cloths=(cloth,), simulation=wc.Simulation(frames=24)), device="cpu")
    assert sim.step_choice.automatic and sim.dt <= SAFETY * sim.step_choice.bound.step
    sim.run()  # the old fixed 10 substeps a frame: unstable at frame 1 (lighter) or 6 (finer)
    assert np.abs(sim.velocities()).max() < 9.81 * sim.time + 1.0


def drape_at(resolution: int) -> wc.Scene:
    scene = wc.load_scene("drape")
    return dataclasses.replace(scene, cloths=(dataclasses.replace(scene.cloths[0], resolution=(resolution,) * 2),))


def check_drape_stays_physical(resolution: int, frames: int = 12) -> None:
    """After half a second (the cloth has reached the sphere), the chosen step's run moves as one at half
    that step does, and the 10% strain limit holds. The scene's old fixed step boiled here instead: an RMS
    speed of 36 m/s against 4, 110% strain (64x64), or the guard stopping it at frame 8 (128x128)."""
    runs = []
    for halved in (False, True):
        scene = drape_at(resolution)
        if halved:
            scene = with_simulation(scene, substeps=2 * runs[0].substeps_per_frame)
        sim = wc.Simulator(scene, device="cpu")
        for _ in range(frames):
            sim.step()
        runs.append(sim)
    chosen, finer = runs
    assert chosen.step_choice.automatic
    rms = [np.sqrt(np.mean(np.sum(sim.velocities() ** 2, axis=1))) for sim in runs]
    assert rms[0] == pytest.approx(rms[1], rel=0.1)
    limited = np.isfinite(chosen.model.springs.limit_max)
    assert np.abs(spring_strains(chosen)[limited]).max() < 0.15


def test_drape_at_64x64_chooses_a_stable_step():
    check_drape_stays_physical(64)


@pytest.mark.slow
def test_drape_at_128x128_chooses_a_stable_step():
    check_drape_stays_physical(128)  # about a minute on a 2-core CPU


def test_set_step_past_the_bound_warns_before_the_first_frame():
    scene = wc.Scene(cloths=(wc.Cloth(mass=0.005, pins=TWO_CORNERS),), simulation=wc.Simulation(substeps=10))
    with pytest.warns(wc.UnstableStepWarning, match=r"substeps = 10 gives a step of 4.17 ms, past the stable bound"):
        sim = wc.Simulator(scene, device="cpu")
    assert sim.frame == 0 and not sim.step_choice.automatic
    with warnings.catch_warnings():
        warnings.simplefilter("error", wc.UnstableStepWarning)
        wc.Simulator(wc.load_scene("hanging"), device="cpu")  # the seed's step is within the bound


def test_a_scene_whose_stable_step_needs_too_many_substeps_is_refused_before_running():
    scene = wc.Scene(cloths=(wc.Cloth(mass=1e-7, pins=TWO_CORNERS),))
    with pytest.raises(wc.SceneError, match=r"simulation.substeps: expected a scene whose stable step needs at most "
                                            r"10000 substeps a frame: this one needs \d+"):
        wc.Simulator(scene, device="cpu")


def test_cli_says_the_chosen_step_first_and_warns_of_a_set_one_before_running(tmp_path):
    code, out, err = run_cli_in_process("run", "drape", "--frames", "1", "--no-usd", "--no-poly", "--device", "cpu",
                                        cwd=tmp_path)
    assert code == 0, err
    choice = wc.Simulator(wc.load_scene("drape"), device="cpu").step_choice
    assert out.splitlines()[0] == f"drape: {choice.describe()}"
    assert re.match(r"step [\d.]+ ms \(\d+ substeps/frame\) to start, substeps auto \(the stable floor; more where "
                    r"a frame's solves miss\), chosen for stability", choice.describe())
    assert "warp-cloth: warning" not in err
    code, out, err = run_cli_in_process("run", "drape", "--frames", "1", "--substeps", "4", "--no-usd", "--no-poly",
                                        "--device", "cpu", cwd=tmp_path)
    warning = [line for line in err.splitlines() if line.startswith("warp-cloth: warning")]
    assert len(warning) == 1 and warning[0].startswith("warp-cloth: warning: command line: substeps = 4 gives a "
                                                       "step of 10.4 ms, past the stable bound")
    assert out.splitlines()[0].startswith("drape: step 10.4 ms (4 substeps/frame), as set;")
    (tmp_path / "light.toml").write_text("[simulation]\nframes = 1\nsubsteps = 2\n\n[[cloth]]\nmass = 0.005\n")
    code, out, err = run_cli_in_process("run", "light.toml", "--no-usd", "--no-poly", "--device", "cpu", cwd=tmp_path)
    warning = [line for line in err.splitlines() if line.startswith("warp-cloth: warning")]
    assert len(warning) == 1 and warning[0].startswith("warp-cloth: warning: light.toml: substeps = 2 gives a step")


def test_one_substep_a_frame_is_said_in_the_singular(tmp_path):
    scene = with_simulation(wc.load_scene("hanging"), integrator="implicit", substeps=1, dt=None)
    assert wc.Simulator(scene, device="cpu").step_choice.describe().startswith("step 41.7 ms (1 substep/frame), as set")
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "1", "--substeps", "1", "--integrator",
                                        "implicit", "--no-usd", "--no-poly", "--device", "cpu", cwd=tmp_path)
    assert code == 0, err
    first, summary = out.splitlines()
    assert first.startswith("hanging: step 41.7 ms (1 substep/frame), as set")
    assert summary.startswith("hanging: 1 frame (1 substep of 41.7 ms, implicit)"), summary
    planned = run_cli_in_process("plan", "hanging", "--substeps", "1", "--integrator", "implicit", "--device", "cpu",
                                 cwd=tmp_path)[1]
    assert planned.startswith("hanging on cpu, 1 substep a frame;"), planned


def test_a_simulator_prints_as_one_line_with_its_step_and_why():
    sim = wc.Simulator(wc.load_scene("drape"), device="cpu")
    text = str(sim)
    assert "\n" not in text and text == repr(sim)
    assert text.startswith(f"<Simulator drape on cpu: {sim.model.particle_count} particles, frame 0; step ")
    assert sim.step_choice.describe() in text and "chosen for stability" in text


def test_counts_are_said_in_the_singular_for_one_and_the_plural_otherwise():
    from warp_cloth.wording import counted

    assert [counted(n, "substep") for n in (0, 1, 2)] == ["0 substeps", "1 substep", "2 substeps"]
    assert counted(1, "batch", "batches") == "1 batch" and counted(3, "batch", "batches") == "3 batches"
