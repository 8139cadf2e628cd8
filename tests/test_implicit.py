"""Backward Euler: against the analytic recurrence of a spring, on stiff cloth, where explicit explodes,
with pinned particles held exactly, and with the solver's residuals reported and met."""

import dataclasses
import math

import numpy as np
import pytest

import warp_cloth as wc
from conftest import spring_strains, with_simulation

OFF = wc.SpringKind(enabled=False)


def spring_pair_scene(stiffness: float, damping: float, substeps: int, **implicit) -> wc.Scene:
    """One quad whose left edge is pinned, pushed along x: each free particle is a 1D oscillator on its
    horizontal spring (the vertical spring between the free pair stays at rest length and moves rigidly)."""
    spring = wc.SpringKind(stiffness=stiffness, damping=damping, acts="both", damping_acts="both")
    cloth = wc.Cloth(resolution=(1, 1), size=(1.0, 1.0), mass=0.5, velocity=(1.0, 0.0, 0.0), structural=spring,
                     shear=OFF, bend=OFF, pins=(wc.Pin(edges=("left",)),))
    return wc.Scene(cloths=(cloth,), implicit=wc.ImplicitSolver(cg_tolerance=1e-7, **implicit),
                    simulation=wc.Simulation(fps=24, substeps=substeps, integrator="implicit", gravity=(0.0, 0.0, 0.0)))


@pytest.mark.parametrize("damping", [0.0, 2.0])
@pytest.mark.parametrize("substeps", [1, 4])
def test_single_spring_follows_the_backward_euler_recurrence(damping, substeps):
    stiffness, mass, rest = 40.0, 0.5, 1.0
    sim = wc.Simulator(spring_pair_scene(stiffness, damping, substeps), device="cpu")
    h = sim.dt
    omega_sq = stiffness / rest / mass
    x, v = 1.0, 1.0  # particle 1: x along the spring from the pin at 0, rest at 1
    expected = []
    for _ in range(24 * substeps):
        # m (v' - v) = h (-k' (x' - L) - b v'),  x' = x + h v'
        v = (v - h * omega_sq * (x - rest)) / (1.0 + h * damping / mass + h * h * omega_sq)
        x = x + h * v
        expected.append((x, v))
    simulated = []
    for _ in range(24):
        for _ in range(substeps):
            sim.substep()
            simulated.append((sim.positions()[1, 0], sim.velocities()[1, 0]))
    np.testing.assert_allclose(np.array(simulated), np.array(expected), atol=2e-5)
    if damping == 0.0:
        # The recurrence's numerical damping: the energy falls by 1 / (1 + h^2 w^2) per step.
        energy = lambda x, v: 0.5 * mass * v * v + 0.5 * stiffness / rest * (x - rest) ** 2  # noqa: E731
        steps = len(expected)
        ratio = energy(*simulated[-1]) / energy(1.0, 1.0)
        assert ratio == pytest.approx((1.0 + h * h * omega_sq) ** -steps, rel=1e-3)


def test_stiff_cloth_at_one_step_per_frame_settles_where_small_steps_do():
    seed = wc.load_scene("hanging")
    stiff = wc.SpringKind(10000.0, 10.0, "tension", "both")
    cloth = dataclasses.replace(seed.cloths[0], structural=stiff, shear=stiff,
                                bend=wc.SpringKind(10000.0, 10.0, "compression", "compression"))
    base = dataclasses.replace(seed, cloths=(cloth,))
    implicit = with_simulation(base, integrator="implicit", substeps=1, dt=None, drag=2.0, frames=240)
    reference = with_simulation(base, integrator="symplectic", substeps=96, dt=None, drag=2.0, frames=240)
    results = {}
    for name, scene in (("implicit", implicit), ("reference", reference)):
        sim = wc.Simulator(scene, device="cpu")
        sim.run(240)
        assert np.isfinite(sim.positions()).all()
        assert np.linalg.norm(sim.velocities(), axis=1).max() < 0.05, f"{name} should have settled"
        results[name] = sim.positions()
        assert np.abs(spring_strains(sim)).max() < 0.02  # 1000x stiffer: the springs barely stretch
    # Same rest shape within 2 cm on the 10 m cloth (one step per frame with 1000x springs: h w = 75).
    assert np.abs(results["implicit"] - results["reference"]).max() < 0.02


@pytest.mark.parametrize("dt", [0.0208, 0.04165])
def test_seed_cloth_implicit_is_stable_where_explicit_explodes(dt):
    from test_seed_stability import first_unstable_frame

    seed = wc.load_scene("hanging")
    assert first_unstable_frame(with_simulation(seed, dt=dt), 240) is not None
    implicit = with_simulation(seed, dt=dt, integrator="implicit")
    sim = wc.Simulator(implicit, device="cpu")
    for _ in range(240):
        sim.step()
        x, v = sim.positions(), sim.velocities()
        assert np.isfinite(x).all() and np.abs(x).max() < 30 and np.abs(v).max() < 50


def test_cg_meets_its_tolerance_and_pins_move_exactly_as_prescribed():
    scene = with_simulation(wc.load_scene("oscillating_pins"), integrator="implicit", substeps=2, dt=None)
    scene = dataclasses.replace(scene, implicit=wc.ImplicitSolver(cg_tolerance=1e-5, cg_max_iterations=500))
    sim = wc.Simulator(scene, device="cpu")
    pins = sim.model.pins
    motions = [p.motion for p in scene.cloths[0].pins]
    for frame in range(1, 25):
        sim.step()
        stats = sim.solver_stats()
        assert 0 < stats.cg_iterations < 500 and stats.cg_relative_residual <= 1e-5
        t = frame / scene.simulation.fps
        for k, motion in enumerate(motions):
            i = pins.index[k]
            np.testing.assert_allclose(sim.positions()[i], pins.anchor[k] + np.array(motion.offset(t)), atol=2e-5)
            np.testing.assert_allclose(sim.velocities()[i], motion.velocity(t), atol=2e-4)


# Newton's residual is RMS |M (v - v0) - h f| / m in m/s; float32 sums put its floor near 2e-5 m/s on the
# seed's cloth at one step per frame (h g = 0.4 m/s), so 1e-4 is the tightest tolerance worth asking.
NEWTON_TOLERANCE = 1e-4


def test_newton_iterations_reduce_the_residual_below_their_tolerance():
    # Springs that act both ways have a smooth force, which Newton needs; the seed's one-sided springs
    # switch on and off at their rest length, where Newton can stall (as it does in its first frames).
    seed = with_simulation(wc.load_scene("hanging"), integrator="implicit", dt=0.04165)
    both = wc.SpringKind(10.0, 1.0, "both", "both")
    cloth = dataclasses.replace(seed.cloths[0], structural=both, shear=both, bend=OFF, limit=None)
    scene = dataclasses.replace(seed, cloths=(cloth,))
    residuals = {}
    for steps in (2, 8):
        solver = wc.ImplicitSolver(newton_iterations=steps, newton_tolerance=NEWTON_TOLERANCE, cg_tolerance=1e-7,
                                   cg_max_iterations=2000)
        sim = wc.Simulator(dataclasses.replace(scene, implicit=solver), device="cpu")
        worst, most_steps = 0.0, 0
        for _ in range(24):
            sim.step()
            stats = sim.solver_stats()
            worst, most_steps = max(worst, stats.newton_residual), max(most_steps, stats.newton_iterations)
        residuals[steps] = worst
        assert most_steps <= steps
    assert residuals[8] <= NEWTON_TOLERANCE < residuals[2]


def test_implicit_runs_the_same_pipeline_as_the_explicit_integrators():
    for name in ("drape", "fold"):
        scene = with_simulation(wc.load_scene(name), integrator="implicit")
        explicit_passes = wc.Simulator(wc.load_scene(name), device="cpu").plan.pass_names
        sim = wc.Simulator(scene, device="cpu")
        # the implicit step cannot begin the contacts as the explicit one does: a pass of its own does
        begins_contacts = ["contact_start"] if scene.collision is not None else []
        assert sim.plan.pass_names == ["integrate:implicit", *begins_contacts, *explicit_passes[1:]]
        sim.run(12)
        assert np.isfinite(sim.positions()).all()
        if scene.ground is not None:
            assert sim.positions()[:, 1].min() >= -1e-6


def test_explicit_integrators_with_a_fixed_limit_solve_report_no_solver_stats():
    scene = with_simulation(wc.load_scene("hanging"), limit_solve="fixed")
    assert wc.Simulator(scene, device="cpu").solver_stats() is None
    assert math.isfinite(wc.ImplicitSolver().cg_tolerance)



def test_a_step_started_from_the_last_solution_meets_the_same_tolerance_in_fewer_iterations():
    """The implicit step's solve starts from the last substep's dv (carried with the state), and its
    tolerance is relative to the right-hand side, so it stops where a solve from zero would: on a hanging
    cotton square the same substep, from the same state, taken from the last dv and from zero, both meet
    the tolerance, land within a micrometre of each other, and the first takes fewer iterations."""
    cloth = wc.Cloth(resolution=(23, 23), size=(2.0, 2.0), orientation="vertical", origin=(-1.0, 0.0, 0.0),
                     material=wc.Material(preset="cotton"), limit=wc.Limit(stretch=0.1, compression=0.1),
                     pins=(wc.Pin(corners=("top-left", "top-right")),))
    scene = wc.Scene(cloths=(cloth,), simulation=wc.Simulation(fps=24, substeps=10, integrator="implicit"))
    sim = wc.Simulator(scene, device="cpu")
    for _ in range(6):
        sim.step()
    assert "implicit.dv" in sim.carried()
    before = {name: array.numpy().copy() for name, array in sim.carried().items()}
    sim.solver_stats()
    runs = {}
    for start in ("last", "zero"):
        carried = sim.carried()  # the buffers of the current parity
        for name, array in carried.items():
            array.assign(before[name])
        if start == "zero":
            carried["implicit.dv"].zero_()
        sim.substep()
        runs[start] = (sim.solver_stats(), sim.positions())
    (warm, warm_x), (cold, cold_x) = runs["last"], runs["zero"]
    tolerance = scene.implicit.cg_tolerance
    assert warm.cg_relative_residual <= tolerance and cold.cg_relative_residual <= tolerance
    assert warm.cg_iterations < cold.cg_iterations
    assert np.abs(warm_x - cold_x).max() < 1e-6
