"""Hard cases stay numerically stable, and the blow-up guard reports the ones that do not.

Each hard case (tests/hard_cases.py) asserts numbers after every frame: finite, speed and kinetic energy
bounded, strain within the stated bound, no collider penetration, particles kept apart, no crossing
triangles. Bounds are what this CPU measured plus about 25% (the strain bounds, where the limit is
solved, plus about 40%: a solve that stops at its cap leaves more). fast_sphere runs the fixed passes (see
hard_cases.fast_sphere), whose strain bound is well above the 10% limit: Jacobi projection moves a
correction one cell per pass, so a cloth struck hard stays stretched for a while; that is stated, not
hidden. (Measured before the limit was solved by default, with the fixed passes: fast_pins 18.7 m/s and
37% strain, twisted 11.5 m/s and 17%.)
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import warp as wp
from pxr import Usd, UsdGeom

import hard_cases
import warp_cloth as wc
from conftest import run_cli_in_process, spring_strains, with_simulation
from warp_cloth.diagnostics import ContactGaps, TriangleIntersections
from warp_cloth.errors import UnstableSimulation
from warp_cloth.kernels import guard
from warp_cloth.kernels.springs import ELASTIC_COMPRESSION, ELASTIC_TENSION

OFF = wc.SpringKind(enabled=False)

# case: (max speed m/s, max strain after the first 12 frames, min closest contact); measured values beside.
# fast_pins' speed is its hem's whip, whose peak a trajectory meets or misses: eight 0.1 mm jitters of the
# cloth peaked at 18.4 to 24.3 m/s before the Chebyshev extrapolation was bounded and 19.8 to 25.3 after
# (medians 21.9 and 22.0), and this unjittered run at 18.3 before and 26.0 after, a corner's snap at frame 41
# (docs/notebook/layers.md, "The extrapolation bounded"): the bound is the largest peak measured plus 25%.
BOUNDS = {
    "stiff_implicit": (15.0, 0.105, None),    # measured 11.1 m/s (free fall from 11 m: 14.7), strain 0.009
    "fast_sphere": (40.0, 0.30, 0.9),         # fixed passes: measured 23.4 m/s (the sphere: 20), strain 0.24
    "fast_pins": (32.0, 0.15, 0.9),           # measured 26.0 m/s (the pins: 3.8, the hem whips), strain 0.114
    "twisted": (22.0, 0.15, 0.9),             # measured 12.7 m/s, strain 0.105, contact 0.999
    "heavy_and_light": (10.0, 0.105, 0.9),    # measured 4.1 m/s, strain 0.100, contact 1.000
    "pile": (25.0, 0.15, 0.9),                # measured 19.6 m/s, strain 0.105, contact 0.974
}
CASES = {name: getattr(hard_cases, name) for name in BOUNDS}
# Cases with no energy input (no moving pin or collider, no wind): their total energy, kinetic + gravity's
# potential + the springs' elastic energy, may never exceed what they start with (twisted starts past its
# strain limit: from its start projected onto it, warp_cloth/start_projection.py). No slack: every spring
# has damping, the contacts and colliders are inelastic, and the drift of symplectic Euler's energy
# (O(h) wobble around a conserved modified energy) is below what the damping takes in a frame.
PASSIVE = {"stiff_implicit", "twisted", "heavy_and_light", "pile"}


def total_energy(sim: wc.Simulator, x: np.ndarray, v: np.ndarray) -> float:
    """Kinetic + gravitational potential energy of the free particles + the springs' elastic energy, the
    potential of kernels/springs.spring_force's -k (l/L - 1) n: k (l - L)^2 / (2 L), where the spring's
    elastic part acts (tension above its rest length, compression at or below it, as its flags say)."""
    model = sim.model
    free = model.inv_mass != 0
    mass, x, v = model.masses[free].astype(np.float64), x.astype(np.float64), v.astype(np.float64)
    gravity = np.asarray(sim.scene.simulation.gravity, dtype=np.float64)
    energy = 0.5 * float((mass * (v[free] ** 2).sum(axis=1)).sum()) - float((mass * (x[free] @ gravity)).sum())
    springs = model.springs
    if springs is None:
        return energy
    length = np.linalg.norm(x[springs.pairs[:, 0]] - x[springs.pairs[:, 1]], axis=1)
    rest = springs.rest.astype(np.float64)
    acts = np.where(length > rest, springs.flags & int(ELASTIC_TENSION), springs.flags & int(ELASTIC_COMPRESSION))
    return energy + float((0.5 * springs.stiffness / rest * (length - rest) ** 2)[acts != 0].sum())


def check_hard_case(scene: wc.Scene, device: str) -> None:
    max_speed, max_strain, min_contact = BOUNDS[scene.name]
    sim = wc.Simulator(scene, device=device)
    crossings = TriangleIntersections(sim)
    gaps = ContactGaps(sim) if scene.collision is not None else None
    limited = np.isfinite(sim.model.springs.limit_max)
    mass = sim.model.masses
    worst = {"speed": 0.0, "strain": 0.0, "contact": np.inf, "crossings": 0, "inside": np.inf,
             "energy_gain": -np.inf}
    passive = scene.name in PASSIVE
    still = all(s.motion is None and not s.keys and not any(s.spin) for s in scene.spheres) and not scene.colliders
    assert not passive or (scene.wind is None and still and (sim.model.pins is None or not sim.model.pins.moving))
    initial_energy = total_energy(sim, sim.positions(), sim.velocities())
    for frame in range(1, scene.simulation.frames + 1):
        sim.step()
        x, v = sim.positions(), sim.velocities()
        assert np.isfinite(x).all() and np.isfinite(v).all()
        worst["energy_gain"] = max(worst["energy_gain"], total_energy(sim, x, v) - initial_energy)
        worst["speed"] = max(worst["speed"], float(np.linalg.norm(v, axis=1).max()))
        if frame > 12:
            worst["strain"] = max(worst["strain"], float(np.abs(spring_strains(sim, x)[limited]).max()))
        for center, sphere in zip(sim.sphere_centers(), scene.spheres):
            worst["inside"] = min(worst["inside"], float(np.linalg.norm(x - center, axis=1).min() / sphere.radius))
        if gaps is not None:
            worst["contact"] = min(worst["contact"], gaps(sim))
            worst["crossings"] = max(worst["crossings"], crossings(sim))
    kinetic = 0.5 * float((mass * (v * v).sum(axis=1)).sum())
    print(f"{scene.name} on {device}: {worst}, final kinetic energy {kinetic:.3g} J")
    assert worst["speed"] <= max_speed
    assert 0.5 * float(mass.sum()) * max_speed ** 2 >= kinetic
    assert worst["strain"] <= max_strain
    assert worst["inside"] >= 1.0 - 1e-5
    if gaps is not None:
        assert worst["contact"] >= min_contact
        assert worst["crossings"] == 0
    if passive:
        assert worst["energy_gain"] <= 0.0, f"gained {worst['energy_gain']:.3g} J of {initial_energy:.3g} J"


@pytest.mark.parametrize("name", sorted(CASES))
def test_hard_case_stays_stable(name):
    check_hard_case(CASES[name](), "cpu")


@pytest.mark.cuda
@pytest.mark.parametrize("name", sorted(CASES))
def test_hard_case_stays_stable_on_cuda(name):
    check_hard_case(CASES[name](), "cuda")


def test_fast_sphere_with_the_limit_solved_stays_finite_and_reports_the_solves_it_could_not_finish():
    # The limit and the sphere cannot both hold here (see hard_cases.fast_sphere): the solve must neither
    # blow up nor hide that it stopped at its cap.
    scene = with_simulation(hard_cases.fast_sphere(), limit_solve="converged")
    sim = wc.Simulator(scene, device="cpu")
    deepest = np.inf
    for _ in range(scene.simulation.frames):
        sim.step()
        assert np.isfinite(sim.positions()).all() and np.isfinite(sim.velocities()).all()
        center = sim.sphere_centers()[0]
        deepest = min(deepest, float(np.linalg.norm(sim.positions() - center, axis=1).min()) / 0.5)
    stats = sim.solver_stats(since_start=True)
    assert deepest >= 1.0 - 1e-5
    assert stats.limit_passes == sim.scene.simulation.limit_max_passes and stats.limit_residual > 1.0


def test_two_thousand_frames_stay_bounded_and_come_to_rest():
    scene = hard_cases.long_run()
    sim = wc.Simulator(scene, device="cpu")
    limited = np.isfinite(sim.model.springs.limit_max)
    fastest = 0.0
    for frame in range(scene.simulation.frames):
        sim.step()
        if frame % 50 == 49:
            v = sim.velocities()
            fastest = max(fastest, float(np.linalg.norm(v, axis=1).max()))
            assert np.abs(spring_strains(sim)[limited]).max() <= 0.105
    assert fastest <= 25.0  # measured 22.4 m/s in the first swing
    assert np.linalg.norm(sim.velocities(), axis=1).max() < 0.01  # measured 0.002 m/s after 83 s
    assert sim.positions()[:, 1].min() > -2.0  # hangs about 11 m below the 10 m pins, no further


def test_guard_names_frame_and_substep_and_suggests_a_fix():
    scene = with_simulation(wc.load_scene("hanging"), dt=0.0104)
    sim = wc.Simulator(scene, device="cpu")
    with pytest.raises(UnstableSimulation) as info:
        for _ in range(240):
            sim.step()
    error = info.value
    assert 1 <= error.frame <= 24 and 1 <= error.substep <= sim.substeps_per_frame
    assert f"frame {error.frame}, substep {error.substep}" in str(error)
    assert "--integrator implicit" in str(error) and "smaller step" in str(error)


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_guard_flags_the_last_substep_of_a_long_frame_in_its_own_slot(device):
    # A free particle falls from rest: after k substeps of explicit Euler its speed is g k h. With
    # max_speed between g 9 h and g 10 h, the guard must first flag substep 10 of the first frame, the last
    # of its 10 flags.
    substeps, g = 10, 9.81
    h = 1.0 / (24 * substeps)
    cloth = wc.Cloth(resolution=(1, 1), limit=None, structural=OFF, shear=OFF, bend=OFF)
    scene = wc.Scene(cloths=(cloth,), simulation=wc.Simulation(fps=24, substeps=substeps, integrator="explicit",
                                                                max_speed=g * 9.5 * h))
    sim = wc.Simulator(scene, device=device)
    with pytest.raises(UnstableSimulation) as info:
        sim.step()
    assert (info.value.frame, info.value.substep) == (1, substeps)
    with pytest.raises(AttributeError):
        sim.substeps_per_frame = 2 * substeps  # the guard's flags are sized for the scene's substeps


def test_guard_never_writes_past_its_flags():
    flags = wp.zeros((4, 1), dtype=int, device="cpu")
    status = flags[:3]  # a frame of three substeps, with a row after it that must stay untouched
    x = wp.array([[0.0, 0.0, 0.0]], dtype=wp.vec3, device="cpu")
    v = wp.array([[float("nan"), 0.0, 0.0]], dtype=wp.vec3, device="cpu")
    world = wp.zeros(1, dtype=int, device="cpu")
    done = wp.array([1], dtype=int, device="cpu")  # the substeps before a round, to which its place is added
    for offset in (1, 2, 6):  # the last, and two past the end
        wp.launch(guard.check_state, dim=1, inputs=[x, v, world, 1.0, done, offset], outputs=[status], device="cpu")
    assert flags.numpy().ravel().tolist() == [0, 0, guard.NOT_FINITE, 0]


@pytest.mark.parametrize("device, graph", [("cpu", True), ("cpu", False),
                                           pytest.param("cuda", True, marks=pytest.mark.cuda)])
def test_run_without_writers_names_the_same_frame_as_step(device, graph):
    # run() without writers checks a frame while the next one runs (on a GPU through pinned memory and an
    # event): the error must still name the frame and substep that step() by step finds, and a stable run
    # must not raise at its end.
    scene = with_simulation(wc.load_scene("hanging"), dt=0.0104)
    stepped = wc.Simulator(scene, device=device, graph=graph)
    with pytest.raises(UnstableSimulation) as by_step:
        for _ in range(240):
            stepped.step()
    ran = wc.Simulator(scene, device=device, graph=graph)
    with pytest.raises(UnstableSimulation) as by_run:
        ran.run(240)
    assert (by_run.value.frame, by_run.value.substep) == (by_step.value.frame, by_step.value.substep)
    assert ran.frame == by_run.value.frame + 1  # the one frame queued behind the failing one
    summary = wc.Simulator(wc.load_scene("hanging"), device=device, graph=graph).run(by_step.value.frame + 3)
    assert summary.frames == by_step.value.frame + 3


def test_unstable_run_keeps_every_written_frame_valid_and_writes_no_nan(tmp_path):
    code, _, err = run_cli_in_process("run", "hanging", "--dt", "0.0104", "--out", str(tmp_path), "--quiet",
                                      cwd=tmp_path)
    assert code == 3, err
    assert "Traceback" not in err and "unstable at frame" in err
    # a failed run keeps its frames beside the output, under names that say so (issue 13)
    stage = Usd.Stage.Open(str(tmp_path / "hanging.failed.usdc"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    samples = mesh.GetPointsAttr().GetTimeSamples()
    assert samples == list(range(int(stage.GetEndTimeCode()) + 1)) and len(samples) >= 2
    for t in samples:
        assert np.isfinite(np.array(mesh.GetPointsAttr().Get(t))).all()
    polys = sorted((tmp_path / "hanging" / "poly.failed").iterdir())
    assert len(polys) == len(samples)
    assert all("nan" not in p.read_text().lower() for p in polys)


def test_coincident_particles_are_refused_with_a_clear_error():
    with pytest.raises(wc.SceneError, match="cloths that start apart: .* start 0 m apart, 0.00 of their contact distance of "):
        wc.Simulator(hard_cases.coincident(), device="cpu")


def stacked_sheets(gap: float, radius: float) -> wc.Scene:
    """Two horizontal 8 x 8 sheets of 0.5 m, ``gap`` apart, colliding with particles of ``radius``."""
    cloths = tuple(wc.Cloth(name=f"sheet{k}", resolution=(7, 7), size=(0.5, 0.5), orientation="horizontal",
                            origin=(0.0, 1.0 + k * gap, 0.0), pins=(wc.Pin(corners=("top-left", "top-right")),))
                   for k in range(2))
    return wc.Scene(name="stacked", cloths=cloths, collision=wc.Collision(radius=radius))


def test_layers_that_start_inside_their_contact_distance_are_refused():
    # 1 cm apart at a contact distance of 2.1 x 6 mm: 0.79 of it, which the first substep would turn into
    # tens of m/s (the stacked drape of docs/notebook/layers.md); 1.3 cm apart they start outside it
    with pytest.raises(wc.SceneError, match=r"cloths that start apart: particle \d+ of 'sheet\d' and particle \d+ of "
                                            r"'sheet\d' start 0.01 m apart, 0.79 of their contact distance of "
                                            r"0.0126 m \(at least 1 needed"):
        wc.Simulator(stacked_sheets(0.01, 0.006), device="cpu")
    wc.Simulator(stacked_sheets(0.013, 0.006), device="cpu")


def test_zero_and_vanishing_spring_lengths_are_refused():
    with pytest.raises(wc.SceneError, match="size: expected .* each > 0"):
        wc.Cloth(resolution=(4, 4), size=(0.0, 1.0))
    with pytest.raises(wc.SceneError, match="cells of at least 0.0001 m"):
        wc.Cloth(resolution=(1000, 1000), size=(0.01, 0.01))


def stiffness_scale(mass: float, rest: float, h: float) -> float:
    """A stiffness whose fastest mode is about 1/h at step h (w^2 = 8 k / (L0 m), a particle held by its
    eight stretch springs): the scale the random scenes' stiffness is drawn against."""
    return (1.0 / h) ** 2 * mass * rest / 8.0


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(resolution=st.integers(2, 10), size=st.floats(0.5, 4.0), density=st.floats(0.05, 1.0),
       stiffness_fraction=st.floats(0.05, 1.0), damping_fraction=st.floats(0.0, 1.0),
       integrator=st.sampled_from(["symplectic", "implicit"]), pinned=st.booleans())
def test_random_valid_scenes_stay_finite_and_bounded(resolution, size, density, stiffness_fraction,
                                                      damping_fraction, integrator, pinned):
    substeps = 10
    h = 1.0 / (24 * substeps)
    cell = size / resolution
    mass = density * cell * cell  # an interior particle's share
    k_max = stiffness_scale(mass, cell, h)
    if integrator == "implicit":
        k_max *= 1000.0  # backward Euler has no step limit; 1000x past the explicit one
    stiffness = max(1e-3, stiffness_fraction * k_max)
    damping = damping_fraction * mass / (8.0 * h)
    spring = wc.SpringKind(stiffness, damping)
    bend = wc.SpringKind(stiffness, damping, "compression", "compression")
    cloth = wc.Cloth(resolution=(resolution, resolution), size=(size, size), origin=(0.0, 1.0, 0.0), density=density,
                     structural=spring, shear=spring, bend=bend, limit=wc.Limit(),
                     pins=(wc.Pin(corners=("top-left", "top-right")),) if pinned else ())
    scene = wc.Scene(cloths=(cloth,), ground=wc.Ground(),
                     # symplectic: the step the simulator chooses (docs/stability.md); implicit: 10 a frame
                     simulation=wc.Simulation(fps=24, frames=24, integrator=integrator,
                                              substeps=substeps if integrator == "implicit" else None))
    sim = wc.Simulator(scene, device="cpu")
    for _ in range(24):
        sim.step()  # the guard raises if anything went non-finite or past 1000 m/s
    fall = math.sqrt(2 * 9.81 * (1.0 + size))  # speed after falling the whole scene's height
    assert np.linalg.norm(sim.velocities(), axis=1).max() <= 3.0 * fall
    assert sim.positions()[:, 1].min() >= -1e-6
