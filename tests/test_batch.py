"""Worlds: scenes packed into one batch step as they do alone (the same frames, to rounding), never touch
each other, and a batch refuses scenes that cannot share a step."""

import dataclasses

import numpy as np
from pxr import Usd, UsdGeom
import pytest

import warp_cloth as wc

SOFT = dict(structural=wc.SpringKind(15.0, 0.02), shear=wc.SpringKind(15.0, 0.02),
            bend=wc.SpringKind(5.0, 0.01, "compression", "compression"), limit=wc.Limit(0.1, 0.1), density=0.2)
COLLISION = wc.Collision(self_collision=True)


def simulation(**changes) -> wc.Simulation:
    settings = dict(fps=24, frames=24, substeps=40, integrator="symplectic", limit_solve="fixed")
    return wc.Simulation(**(settings | changes))


def three_worlds() -> list[wc.Scene]:
    """Different cloths, sizes, colliders, grounds and gravity, all in the same place: world 1's hanging
    cloth passes through where world 0's sphere and cloth are."""
    return [
        wc.Scene(name="drape", cloths=(wc.Cloth(resolution=(12, 12), size=(1.2, 1.2), orientation="horizontal",
                                                origin=(-0.6, 0.6, 0.6), **SOFT),),
                 spheres=(wc.Sphere(radius=0.4, friction=0.3),), ground=wc.Ground(height=-0.5, friction=0.4),
                 collision=COLLISION, simulation=simulation()),
        wc.Scene(name="hang", cloths=(wc.Cloth(resolution=(8, 6), size=(1.0, 0.8), orientation="vertical",
                                               origin=(-0.5, 0.0, 0.0),
                                               pins=(wc.Pin(corners=("top-left", "top-right")),), **SOFT),),
                 collision=COLLISION, simulation=simulation(gravity=(0.0, -5.0, 0.0))),
        wc.Scene(name="fall", cloths=(wc.Cloth(resolution=(10, 10), size=(1.0, 1.0), orientation="horizontal",
                                               origin=(-0.5, 0.3, 0.5), rotation=(20.0, 0.0, 0.0), **SOFT),
                                      wc.Cloth(name="second", resolution=(6, 6), size=(0.6, 0.6),
                                               orientation="horizontal", origin=(-0.3, 0.8, 0.3), **SOFT)),
                 ground=wc.Ground(height=0.0, friction=0.8), collision=COLLISION, simulation=simulation()),
    ]


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_each_world_of_a_batch_moves_as_its_scene_alone(device):
    scenes = three_worlds()
    batch = wc.Batch(scenes, device=device)
    alone = [wc.Simulator(scene, device=device) for scene in scenes]
    for _ in range(24):
        batch.step()
        for sim in alone:
            sim.step()
    for w, sim in enumerate(alone):
        np.testing.assert_allclose(batch.positions(w), sim.positions(), atol=1e-6, err_msg=f"world {w}")
        np.testing.assert_allclose(batch.velocities(w), sim.velocities(), atol=1e-5, err_msg=f"world {w}")
    # Each world meets its own colliders only: the hanging cloth of world 1 passes through world 0's sphere
    # (radius 0.4 at the origin), and world 2's cloths rest on their own ground.
    assert np.linalg.norm(batch.positions(1), axis=1).min() < 0.3
    assert batch.positions(2)[:, 1].min() >= -1e-6


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_worlds_of_another_step_are_packed_apart_and_each_moves_as_alone(device, tmp_path):
    scenes = three_worlds()
    scenes[1] = dataclasses.replace(scenes[1], simulation=simulation(substeps=60, gravity=(0.0, -5.0, 0.0)))
    batch = wc.Batch(scenes, device=device)
    assert [group.members for group in batch.groups] == [(0, 2), (1,)]
    assert [group.simulator.substeps_per_frame for group in batch.groups] == [40, 60]
    alone = [wc.Simulator(scene, device=device) for scene in scenes]
    writers = {w: [wc.UsdWriter(tmp_path / f"world{w}.usdc")] for w in range(3)}
    summary = batch.run(12, writers=writers)
    for sim in alone:
        sim.run(12)
    for w, sim in enumerate(alone):
        np.testing.assert_allclose(batch.positions(w), sim.positions(), atol=1e-6, err_msg=f"world {w}")
        stage = Usd.Stage.Open(str(tmp_path / f"world{w}.usdc"))
        assert stage.GetEndTimeCode() == 12
    assert summary.frames == 12 and not summary.interrupted and batch.frame == 12
    assert summary.particles == sum(sim.model.particle_count for sim in alone)
    with pytest.raises(ValueError, match="a simulator for each"):
        batch.simulator
    with pytest.raises(ValueError, match="must share one step"):
        batch.run(1, monitors=[wc.StrainMonitor()])


def drop_densities(densities: tuple[float, ...]) -> list[wc.Scene]:
    """The README's drop (a cloth falling on a sphere, its step chosen for stability), small, in densities
    whose stable steps differ."""
    cloth = wc.Cloth(resolution=(6, 6), size=(2.0, 2.0), orientation="horizontal", origin=(-1.0, 2.0, 1.0),
                     density=0.2, limit=wc.Limit(stretch=0.1, compression=0.1))
    drop = wc.Scene(name="drop", cloths=(cloth,), spheres=(wc.Sphere(center=(0.0, 1.0, 0.0), radius=0.5),),
                    simulation=wc.Simulation(fps=24, frames=12, integrator="symplectic"))
    return [dataclasses.replace(drop, cloths=(dataclasses.replace(cloth, density=d),)) for d in densities]


def test_worlds_whose_chosen_steps_differ_each_take_their_own_and_move_as_alone():
    """Where the scenes set no step, each world takes the one chosen for its scene alone, not the finest of
    the batch's (which moved the densest world 1.4 cm from its scene alone in these 12 frames)."""
    scenes = drop_densities((0.1, 0.2, 0.4, 0.2))
    batch = wc.Batch(scenes, device="cpu")
    alone = [wc.Simulator(scene, device="cpu") for scene in scenes]
    assert len({sim.substeps_per_frame for sim in alone}) == 3
    assert [group.members for group in batch.groups] == [(0,), (1, 3), (2,)]
    for w, sim in enumerate(alone):
        assert batch.place(w)[0].simulator.substeps_per_frame == sim.substeps_per_frame, f"world {w}"
    batch.run(12)
    for sim in alone:
        sim.run(12)
    for w, sim in enumerate(alone):
        np.testing.assert_allclose(batch.positions(w), sim.positions(), atol=1e-6, err_msg=f"world {w}")
        np.testing.assert_allclose(batch.velocities(w), sim.velocities(), atol=1e-5, err_msg=f"world {w}")


def test_a_batch_refuses_no_scenes_and_worlds_it_does_not_have():
    with pytest.raises(wc.SceneError, match="scenes: expected at least one scene"):
        wc.Batch([], device="cpu")
    with pytest.raises(IndexError):
        wc.Batch(three_worlds()[:1], device="cpu").positions(1)


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
@pytest.mark.parametrize("own_step", [False, True], ids=["shared-step", "own-step"])
def test_a_world_that_blows_up_is_stopped_and_the_others_go_on(device, own_step):
    """Also where it is alone in a group of its own step: the group is left, the others' go on."""
    scenes = three_worlds()
    stiff = wc.SpringKind(1e6, 0.02)  # far past what the shared step holds: it blows up within frames
    scenes[1] = dataclasses.replace(scenes[1], cloths=(dataclasses.replace(scenes[1].cloths[0], structural=stiff),),
                                    simulation=simulation(substeps=41 if own_step else 40, gravity=(0.0, -5.0, 0.0)))
    with pytest.warns(wc.UnstableStepWarning):
        batch = wc.Batch(scenes, device=device)
    alone = [wc.Simulator(scenes[w], device=device) for w in (0, 2)]
    start = batch.positions(1).copy()
    for _ in range(24):
        batch.step()
        for sim in alone:
            sim.step()
    assert list(batch.stopped_worlds) == [1]
    assert batch.stopped_worlds[1].frame <= 3  # found within frames, as a scene alone would be
    np.testing.assert_array_equal(batch.positions(1), start)  # put back and held where it started
    for w, sim in zip((0, 2), alone):
        np.testing.assert_allclose(batch.positions(w), sim.positions(), atol=1e-6, err_msg=f"world {w}")


def smooth_implicit_worlds(stiffness: float) -> list[wc.Scene]:
    """The three worlds with the implicit step, world 1's structural springs of ``stiffness``, and without
    what switches on where a spring or a pair crosses a bound (strain limits, particle collision, bend
    springs that act in compression only), which turns a difference of rounding into one of whether it
    acts."""
    implicit = wc.ImplicitSolver(newton_iterations=3, newton_tolerance=1e-4, cg_tolerance=1e-6)
    smooth = lambda cloth, **changes: dataclasses.replace(  # noqa: E731
        cloth, limit=None, bend=wc.SpringKind(5.0, 0.01), **changes)
    scenes = [dataclasses.replace(s, cloths=tuple(smooth(c) for c in s.cloths), collision=None, implicit=implicit,
                                  simulation=simulation(integrator="implicit", substeps=8)) for s in three_worlds()]
    stiff = smooth(scenes[1].cloths[0], structural=wc.SpringKind(stiffness, 0.05))
    scenes[1] = dataclasses.replace(scenes[1], cloths=(stiff,))
    return scenes


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_implicit_worlds_each_solve_on_their_own(device):
    """Each world runs its own Newton loop and conjugate gradient: what another world does (here a stiffer
    cloth, whose solves take more iterations) changes nothing of it, to the bit; and its frames are those
    of its scene alone, but for the order its sums add up in (a float32 solve's result moves with that
    order, as between the CPU and CUDA: the same bound as theirs, tests/test_cuda.py)."""
    soft, stiff = smooth_implicit_worlds(15.0), smooth_implicit_worlds(1000.0)
    batches = [wc.Batch(scenes, device=device) for scenes in (soft, stiff)]
    alone = [wc.Simulator(scene, device=device) for scene in stiff]
    for _ in range(12):
        for run in [*batches, *alone]:
            run.step()
    for w in (0, 2):
        np.testing.assert_array_equal(batches[0].positions(w), batches[1].positions(w), err_msg=f"world {w}")
    for w, sim in enumerate(alone):
        np.testing.assert_allclose(batches[1].positions(w), sim.positions(), atol=1e-3, err_msg=f"world {w}")
    iterations = [sim.solver_stats().cg_iterations for sim in alone]
    assert iterations[1] > 2 * min(iterations[0], iterations[2])


def test_each_world_writes_its_own_outputs_and_a_stopped_world_keeps_its_frames_as_failed(tmp_path):
    scenes = three_worlds()
    stiff = wc.SpringKind(1e6, 0.02)
    scenes[1] = dataclasses.replace(scenes[1], cloths=(dataclasses.replace(scenes[1].cloths[0], structural=stiff),))
    with pytest.warns(wc.UnstableStepWarning):
        batch = wc.Batch(scenes, device="cpu")
    writers = {w: [wc.UsdWriter(tmp_path / f"world{w}.usdc"), wc.PolyWriter(tmp_path / f"world{w}")] for w in range(3)}
    summary = batch.run(6, writers=writers)
    assert summary.frames == 6 and list(batch.stopped_worlds) == [1]
    alone = wc.Simulator(scenes[2], device="cpu")
    alone.run(6, writers=[wc.UsdWriter(tmp_path / "alone2.usdc")])
    for name, expected_frames in (("world0", 6), ("world2", 6)):
        stage = Usd.Stage.Open(str(tmp_path / f"{name}.usdc"))
        points = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth")).GetPointsAttr()  # the scene's own names
        assert points.GetTimeSamples() == [float(f) for f in range(expected_frames + 1)]
    stages = [Usd.Stage.Open(str(tmp_path / name)) for name in ("world2.usdc", "alone2.usdc")]
    ours, theirs = (UsdGeom.Mesh(stage.GetPrimAtPath("/World/second")).GetPointsAttr().Get(6) for stage in stages)
    np.testing.assert_allclose(np.asarray(ours), np.asarray(theirs), atol=1e-6)
    assert len(list((tmp_path / "world2").glob("*.poly"))) == 2 * 7  # two cloths, frames 0 to 6
    # World 1 blew up in frame 1: its frame 0 is kept under the failed name, nothing in place.
    assert not (tmp_path / "world1.usdc").exists()
    failed = Usd.Stage.Open(str(tmp_path / "world1.failed.usdc"))
    assert UsdGeom.Mesh(failed.GetPrimAtPath("/World/cloth")).GetPointsAttr().GetTimeSamples() == [0.0]
