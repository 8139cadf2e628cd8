"""A scene pays only for the effects it declares: the passes of its plan, and the kernels one substep
launches, counted."""

import dataclasses
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
from conftest import with_simulation
from warp_cloth import neighbour_lists
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from warp_cloth.kernels import particle_collision
from warp_cloth.neighbour_lists import LIST_THREADS_BY_SIZE
from warp_cloth.passes import ContactStart
from warp_cloth.plan import threads_per_particle
from warp_cloth.substep_rounds import LOOPED_FROM, ROUND

OFF = wc.SpringKind(enabled=False)


def fixed(scene: wc.Scene) -> wc.Scene:
    return with_simulation(scene, limit_solve="fixed")


@pytest.fixture
def launches(monkeypatch):
    """Counts kernel launches by kernel name."""
    counted: Counter = Counter()
    real_launch = wp.launch

    def counting_launch(kernel, *args, **kwargs):
        counted[kernel.key] += 1
        return real_launch(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "launch", counting_launch)
    return counted


LIMIT_ITERATIONS = 4
# With limit_solve = "fixed" (the counts below; the converged solve's passes, the default, depend on the
# state, see test_the_converged_solve_repeats_its_pair_of_passes_and_check_until_within_tolerance).
# Fixed pins cost nothing (a pinned particle has inverse mass 0 and nothing moves it); the colliders run
# inside the strain limit's last pass.
EXPECTED = {
    "hanging": {"explicit_step": 1, "limit_pass": LIMIT_ITERATIONS},
    "ground": {"explicit_step": 1, "limit_pass": LIMIT_ITERATIONS},
    "drape": {"explicit_step": 1, "limit_pass": LIMIT_ITERATIONS},
    "sphere_push": {"explicit_step": 1, "limit_pass": LIMIT_ITERATIONS, "move_spheres": 1, "advance_clock": 1},
}
EXPECTED_PLANS = {
    "hanging": ["integrate:explicit", *["limits"] * LIMIT_ITERATIONS],
    "ground": ["integrate:symplectic", *["limits"] * (LIMIT_ITERATIONS - 1), "limits+colliders"],
    "sphere_push": ["spheres:move", "integrate:explicit", *["limits"] * (LIMIT_ITERATIONS - 1), "limits+colliders",
                    "clock"],
}
# With particle collision, limits, separation and colliders are projected together in 8 passes (the
# larger of the collision's 8 and the limit's 4 iterations): colliders once before the passes (in the
# integration step, which begins the contacts) and at the end of every pass; the last 4 passes limit and
# separate in one kernel. The neighbour lists' kernels (spatial hash, gather) launch every substep but
# remake the lists only when a particle has moved far enough.
PASSES = 8  # the collision's fixed passes these counts take (the scene files leave the default)


def fixed_collision(name: str) -> wc.Scene:
    """A built-in collision scene with fixed passes: the limit's 4 and the collision's ``PASSES``."""
    scene = fixed(wc.load_scene(name))
    return dataclasses.replace(scene, collision=dataclasses.replace(scene.collision, iterations=PASSES))


EXPECTED_WITH_COLLISION = {
    name: {"explicit_step_and_contact_start": 1, "insert_points": 1, "gather_neighbors": 1,
           "separation_pass": PASSES - LIMIT_ITERATIONS, "limit_and_separation_pass": LIMIT_ITERATIONS,
           "contact_velocities_and_end_remake": 1}
    for name in ("fold", "pile")
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_substep_launches_only_declared_effects(name, launches):
    scene = fixed(wc.load_scene(name))
    assert scene.simulation.limit_iterations == LIMIT_ITERATIONS and scene.collision is None
    sim = wc.Simulator(scene, device="cpu")
    assert sim.plan.lists is None and sim.state.contacts is None, "no collision, no lists nor spatial hash"
    if name in EXPECTED_PLANS:
        assert sim.plan.pass_names == EXPECTED_PLANS[name]
    launches.clear()
    sim.substep()
    assert dict(launches) == EXPECTED[name]
    launches.clear()
    sim.step()  # a frame captured: its substeps, each followed by the blow-up guard's check, looped in rounds
    substeps = sim.substeps_per_frame
    looped = substeps >= LOOPED_FROM
    captured = ROUND + substeps % ROUND if looped else substeps
    frame = {kernel: count * captured for kernel, count in EXPECTED[name].items()}
    loop = {"start_rounds": 1, "next_round": 1} if looped else {}
    assert dict(launches) == {**frame, "check_state": captured, **loop}


def test_driven_pins_move_before_the_contacts_start():
    """oscillating_pins: its pins move after the step, so the contacts start in a pass of their own after
    them (in the other collision scenes the integration step starts them); 4 limit passes, the last 2
    with the collision's 2 separations."""
    sim = wc.Simulator(fixed(wc.load_scene("oscillating_pins")), device="cpu")
    assert sim.plan.pass_names == ["integrate:symplectic", "pins:oscillating", "contact_start",
                                   "lists:remake-if-moved", "limits", "limits", "limits+separation",
                                   "limits+separation", "contact_velocities+end_remake", "clock"]


@pytest.mark.parametrize("name", sorted(EXPECTED_WITH_COLLISION))
def test_collision_stage_exists_only_when_declared(name, launches):
    scene = fixed_collision(name)
    assert scene.simulation.limit_iterations == LIMIT_ITERATIONS
    sim = wc.Simulator(scene, device="cpu", graph=False)  # (it makes the lists to check the start)
    contacts = sim.state.contacts
    lists_made = lambda: (int(contacts.epoch.numpy()[0]), contacts.x_built.numpy().copy())  # noqa: E731
    epoch, built = lists_made()
    assert epoch == 1
    np.testing.assert_array_equal(built, sim.model.positions)
    launches.clear()
    sim.substep()
    assert dict(launches) == EXPECTED_WITH_COLLISION[name]
    epoch, built_after = lists_made()
    assert epoch == 1 and contacts.rebuild.numpy()[0] == 0, "nothing moved far: no remake"
    np.testing.assert_array_equal(built_after, built)
    contacts.x_built.fill_(wp.vec3(1.0e30))  # as if every particle had moved far since
    launches.clear()
    sim.substep()
    assert dict(launches) == EXPECTED_WITH_COLLISION[name]
    epoch, built_after = lists_made()
    assert epoch == 2 and contacts.rebuild.numpy()[0] == 0
    assert np.abs(built_after).max() < 100.0, "lists remade from this substep's positions"
    without = wc.Simulator(dataclasses.replace(scene, collision=None), device="cpu")
    assert without.model.contacts is None
    assert not any("separation" in name or "lists" in name for name in without.plan.pass_names)


def test_lists_remade_every_substep_where_a_test_asks(launches, monkeypatch):
    monkeypatch.setattr(neighbour_lists, "REMAKE_EVERY_SUBSTEP", True)  # the bench's and tests' reference
    sim = wc.Simulator(wc.load_scene("pile"), device="cpu", graph=False)
    epochs = [int(sim.state.contacts.epoch.numpy()[0])]
    for _ in range(3):
        sim.substep()
        epochs.append(int(sim.state.contacts.epoch.numpy()[0]))
    assert epochs == [1, 2, 3, 4]
    assert "lists:remake" in sim.plan.pass_names


def test_sequential_projection_runs_the_limit_and_then_the_separation_in_each_pass_that_has_both(launches):
    with lab_hooks(SolveChoices(joint_passes=0)):  # the fixed passes sequential from the first
        sim = wc.Simulator(fixed_collision("pile"), device="cpu", graph=False)
    launches.clear()
    sim.substep()
    assert dict(launches) == {"explicit_step_and_contact_start": 1, "insert_points": 1, "gather_neighbors": 1,
                              "limit_pass": LIMIT_ITERATIONS, "separation_pass": PASSES,
                              "contact_velocities_and_end_remake": 1}


def test_a_converged_solve_with_contacts_projects_jointly_then_sequentially(launches):
    # Cloths stretched 20% past their rest and a tolerance nothing meets run the solve to its cap of 10
    # passes: 2 joint pairs (the switch moved to 4 passes from 200), then sequential pairs, each counting its
    # limit and separation passes; joint throughout where the switch is past the cap, sequential where it is 0.
    scene = with_simulation(wc.load_scene("pile"), limit_tolerance=1e-9, limit_max_passes=10)
    for joint_passes, expected in ((4, {"limit_and_separation_pass": 4, "limit_pass": 4, "separation_pass": 4}),
                                   (10, {"limit_and_separation_pass": 10}),
                                   (0, {"limit_pass": 6, "separation_pass": 6})):
        with lab_hooks(SolveChoices(joint_passes=joint_passes)):
            sim = wc.Simulator(scene, device="cpu", graph=False)
        sim.state.x.assign(sim.state.x.numpy() * 1.2)
        launches.clear()
        sim.substep()
        names = ("limit_and_separation_pass", "limit_pass", "separation_pass")
        assert {k: launches[k] for k in names if launches[k]} == expected, joint_passes


def test_the_converged_solve_repeats_its_pair_of_passes_and_check_until_within_tolerance(launches):
    # The step, then pairs of limit passes (colliders in each), each pair followed by the check of the
    # residual and the loop's bookkeeping, as many pairs as the substep needs.
    with lab_hooks(SolveChoices(chebyshev_rho=0.0)):  # plain passes
        sim = wc.Simulator(wc.load_scene("sphere_push"), device="cpu")
    assert sim.plan.pass_names == ["spheres:move", "integrate:explicit", "converged solve", "clock"]
    for _ in range(20):
        launches.clear()
        sim.substep()
        pairs = launches["continue_solve"]
        assert dict(launches) == {"move_spheres": 1, "explicit_step": 1, "start_solve": 1, "limit_pass": 2 * pairs,
                                  "projection_residual": pairs, "continue_solve": pairs, "advance_clock": 1}
    stats = sim.solver_stats()
    assert 2 <= stats.limit_passes <= sim.scene.simulation.limit_max_passes and stats.limit_residual <= 1.0


def test_an_accelerated_solve_adds_its_extrapolation_and_no_other_launch_a_pair(launches):
    # Chebyshev's weight, its restart test and the loop's bookkeeping are one kernel: a small cloth's
    # iteration costs its launches.
    with lab_hooks(SolveChoices(chebyshev_rho=0.95)):
        sim = wc.Simulator(wc.load_scene("sphere_push"), device="cpu")
    for _ in range(20):
        launches.clear()
        sim.substep()
        pairs = launches["continue_chebyshev_solve"]
        assert dict(launches) == {"move_spheres": 1, "explicit_step": 1, "start_solve": 1, "start_chebyshev": 1,
                                  "limit_pass": 2 * pairs, "chebyshev_step_and_colliders": pairs,
                                  "projection_residual": pairs, "continue_chebyshev_solve": pairs, "advance_clock": 1}
    assert sim.solver_stats().limit_residual <= 1.0


def test_the_printed_plan_names_every_launch_of_the_solve_and_says_the_simulator_runs_the_guard(launches):
    # Each kernel of the solve's loop that a substep launches is printed under the loop, by the kernel's
    # name; its passes by theirs (limit_pass: "limits+colliders", hold_and_collide: "pins+colliders").
    sim = wc.Simulator(wc.load_scene("sphere_push"), device="cpu")
    launches.clear()
    sim.substep()
    printed = str(sim.plan)
    assert printed.splitlines()[1:] == [
        "   1. spheres:move",
        "   2. integrate:explicit",
        "   3. converged solve, until within tolerance or at 1000 passes:",
        "          start_solve",
        "        each iteration:",
        "          limits+colliders",
        "          limits+colliders",
        "          projection_residual",
        "          continue_solve (the loop's bookkeeping)",
        "        after 2 passes, each iteration instead:",
        "          line solves (4 families, each 2 times: eliminate_segments, reduce_separators, "
        "solve_separator_chains, finish_segments; forwards and backwards in turn: turn_order)",
        "          pins+colliders",
        "          limits+colliders",
        "          limits+colliders",
        "          projection_residual",
        "          continue_solve (the loop's bookkeeping)",
        "   4. clock",
        "not in the plan: after each substep of a frame (Simulator.step and run, not Simulator.substep)",
        "the simulator checks the state for a blow-up (check_state)",
        "before the first substep of a run that starts fresh (not restored from a checkpoint), the",
        "simulator projects the cloths that start past their strain limits onto them (limit_violations,",
        "then a converged solve of the limits+colliders pass), keeping the velocities the scene gives"]
    passes = {"move_spheres", "explicit_step", "limit_pass", "hold_and_collide", "advance_clock"}
    assert all(kernel in printed for kernel in set(launches) - passes)
    pile = str(wc.Simulator(wc.load_scene("pile"), device="cpu").plan)
    assert "        after 200 passes, each iteration instead:\n          limits\n          separation+colliders\n" in pile


@pytest.mark.parametrize("name", ["flag", "seed_default"])
def test_the_printed_plan_names_each_launch_of_the_wind_and_the_lists(name, launches):
    # The wind's pass and the lists' remake launch several kernels a substep (each list kernel returning at
    # once where nothing is remade), as do the bounds read off the surface lists: the plan prints them under
    # the pass, from the list the pass launches.
    sim = wc.Simulator(wc.load_scene(name), device="cpu", graph=False)
    launches.clear()
    sim.substep()
    printed = str(sim.plan).splitlines()
    several = [p for p in sim.plan.passes if hasattr(p, "kernels")]
    assert {p.name for p in several} == ({"wind", "lists:remake-if-moved"} if name == "flag"
                                         else {"lists:remake-if-moved+edges+faces", "bounds:from-lists"})
    for step in several:
        at = next(k for k, line in enumerate(printed) if line.endswith(f". {step.name}:"))
        keys = [kernel.key for kernel in step.kernels]
        assert [line.strip() for line in printed[at + 1:at + 1 + len(keys)]] == keys
        assert all(launches[key] == keys.count(key) for key in keys), dict(launches)  # two hashes: each fill twice


def test_bare_cloth_launches_one_kernel_and_holds_no_effect_arrays(launches):
    cloth = wc.Cloth(resolution=(3, 3), structural=OFF, shear=OFF, bend=OFF)
    sim = wc.Simulator(wc.Scene(cloths=(cloth,)), device="cpu")
    model = sim.model
    assert (model.springs, model.limits, model.pins, model.spheres) == (None, None, None, None)
    launches.clear()
    sim.substep()
    assert dict(launches) == {"explicit_step": 1}


def test_limit_iterations_and_integrator_change_the_launches(launches):
    scene = with_simulation(wc.load_scene("hanging"), limit_solve="fixed", limit_iterations=7, integrator="symplectic")
    sim = wc.Simulator(scene, device="cpu")
    assert sim.plan.pass_names == ["integrate:symplectic", *["limits"] * 7]
    launches.clear()
    sim.substep()
    assert launches["limit_pass"] == 7


def test_colliders_without_limit_launch_once_for_ground_and_spheres(launches):
    cloth = wc.Cloth(resolution=(3, 3), limit=None, structural=OFF, shear=OFF, bend=OFF)
    spheres = (wc.Sphere(name="a", center=(0.0, -5.0, 0.0), radius=1.0),
               wc.Sphere(name="b", center=(3.0, -5.0, 0.0), radius=1.0))
    sim = wc.Simulator(wc.Scene(cloths=(cloth,), ground=wc.Ground(), spheres=spheres), device="cpu")
    assert sim.plan.pass_names == ["integrate:symplectic", "colliders"]
    launches.clear()
    sim.substep()
    assert dict(launches) == {"explicit_step": 1, "collide": 1}


def test_threads_per_particle_follow_the_cloth_size_on_a_gpu_only():
    gpu, cpu = SimpleNamespace(is_cuda=True), SimpleNamespace(is_cuda=False)
    assert [threads_per_particle(n * n, gpu) for n in (16, 64, 128, 256, 1024)] == [16, 16, 4, 2, 1]
    assert [threads_per_particle(n * n, gpu, LIST_THREADS_BY_SIZE) for n in (64, 128, 256, 1024)] == [16, 4, 4, 1]
    assert threads_per_particle(64 * 64, cpu) == 1


@pytest.mark.parametrize("threads", [0, 3, 16, 128])
def test_threads_per_particle_other_than_one_is_refused_on_the_cpu(threads):
    with pytest.raises(ValueError, match="threads_per_particle must be None or a power of two up to 64"):
        wc.Simulator(wc.load_scene("hanging"), device="cpu", threads_per_particle=threads)


def unfused(sim: wc.Simulator) -> wc.Simulator:
    """``sim``'s substep as it was before the integration step began the contacts: the spheres moved
    after the step, and a pass of its own beginning the contacts."""
    fused_step = next(p for p in sim.plan.passes if p.name.endswith("+contact_start"))
    step = sim.integrator.step(sim.device_model, sim.state, sim.plan.threads, None)
    movers = [p for p in sim.plan.passes if p.name == "spheres:move"]
    rest = [p for p in sim.plan.passes if p is not fused_step and p not in movers]
    sim.plan = dataclasses.replace(sim.plan, passes=(step, *movers, ContactStart(fused_step.args.start), *rest))
    return sim


@pytest.mark.parametrize("name, frames", [("pile", 20), ("seed_default", 6)])
def test_contacts_begun_in_the_step_give_the_separate_kernels_results_exactly(name, frames, launches):
    scene = wc.load_scene(name)
    fused = wc.Simulator(scene, device="cpu")
    assert any(name.endswith("+contact_start") for name in fused.plan.pass_names)
    reference = unfused(wc.Simulator(scene, device="cpu"))
    fused.run(frames)
    launches.clear()
    reference.run(frames)
    assert launches["contact_start"] > 0
    np.testing.assert_array_equal(fused.positions(), reference.positions())
    np.testing.assert_array_equal(fused.velocities(), reference.velocities())


def test_driven_pins_keep_the_collision_stage_beginning_its_contacts(launches):
    scene = wc.load_scene("oscillating_pins")
    scene = dataclasses.replace(scene, collision=wc.Collision())
    sim = wc.Simulator(scene, device="cpu", graph=False)
    assert sim.plan.pass_names[:3] == ["integrate:symplectic", "pins:oscillating", "contact_start"]
    launches.clear()
    sim.substep()
    assert launches["contact_start"] == 1


def test_search_scale_sets_how_far_candidates_reach(monkeypatch):
    scene = wc.load_scene("pile")
    lengths = []
    for scale in (1.5, 3.0):
        monkeypatch.setattr(particle_collision, "SEARCH_SCALE", scale)  # as tools/skin_probe.py sets it
        sim = wc.Simulator(scene, device="cpu", graph=False)
        sim.run(24)  # the layers have landed on each other
        sim.plan.lists.remake_now(sim.state.x)
        lengths.append(sum(len(c) for c in sim.plan.lists.candidates()))
        x, radius, separation = sim.positions(), sim.model.contacts.radius, scene.collision.separation
        for i, candidates in enumerate(sim.plan.lists.candidates()[:200]):
            reach = scale * separation * 0.5 * (radius[i] + radius[candidates])
            assert (np.linalg.norm(x[candidates] - x[i], axis=1) < reach).all()
    assert lengths[1] > 2 * lengths[0]
