"""The lab's held line solve of the strain limits (warp_cloth/line_solve.py): the lines (warp_cloth/
cloth_lines.py) of a grid and of a mesh cloth cover every limited spring once, split at the pins, in families
whose lines share no free particle; rounds of it inside the converged solve hold the limit, with particle
collision too; and lines solved in segments (kernels/line_solve.py), their arrays stored contiguous or
interleaved (warp_cloth/line_solve.py), move the particles as whole lines do."""

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

import warp_cloth as wc
from warp_cloth.cloth_lines import cloth_lines, mesh_chains
from warp_cloth.diagnostics import ContactGaps, TriangleIntersections
from warp_cloth.lab.bench_meshes import as_mesh_cloth
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from warp_cloth.scene_file import scene_from_dict
from warp_cloth.line_solve import (CHAIN, LineSolves, line_segments, longest_line, reduction_strides,
                                   segment_for_device, slot_layout)
from warp_cloth.model import build_model
from warp_cloth.strain import StrainMonitor

sys.path.insert(0, str(Path(__file__).parent))
import hard_cases  # noqa: E402


def hanging(mesh: str) -> wc.Scene:
    """The hanging scene's grid cloth, or the same read from an OBJ of its quads or of triangles."""
    scene = wc.load_scene("hanging")
    return scene if mesh == "grid" else as_mesh_cloth(scene, triangles=mesh == "triangles")


@pytest.mark.parametrize("mesh, families", [("grid", 4), ("quads", 4), ("triangles", 3)])
def test_the_lines_hold_every_limited_spring_once_split_at_the_pins(mesh, families):
    scene = hanging(mesh)
    model = build_model(scene)
    lines = cloth_lines(model, scene)
    assert len(lines) == families  # on a mesh from a grid, its rows, columns and diagonals again
    n = model.particle_count
    found = []
    for starts, particles, lo, hi in lines:
        free_in = []
        for first, end in zip(starts[:-1], starts[1:]):
            line = particles[first:end]
            assert (model.inv_mass[line[1:-1]] > 0).all()  # pins only at a line's ends
            a, b = np.minimum(line[:-1], line[1:]), np.maximum(line[:-1], line[1:])
            found += list(a.astype(np.int64) * n + b)
            assert (lo[first:end - 1] > 0).all() and (hi[first:end - 1] > lo[first:end - 1]).all()
            free_in += list(np.unique(line[model.inv_mass[line] > 0]))
        assert len(free_in) == len(set(free_in))  # no free particle in two lines of one family
    pairs = np.sort(model.springs.pairs[np.isfinite(model.springs.limit_max)], axis=1).astype(np.int64)
    free = (model.inv_mass[pairs] > 0).any(axis=1)  # a spring between two pins is in no line
    assert sorted(found) == sorted(pairs[free, 0] * n + pairs[free, 1])


def test_mesh_chains_pair_the_springs_that_continue_each_other_and_open_a_closed_chain():
    # a square with one diagonal: at each corner the springs meet at 90 or 45 degrees, none continues another
    points = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]])
    assert sorted(len(c) - 1 for c in mesh_chains(pairs, points)) == [1, 1, 1, 1, 1]
    # a straight line of three springs given out of order, and a spring meeting its middle at 90 degrees
    points = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [1, 1, 0]])
    pairs = np.array([[2, 3], [1, 4], [0, 1], [1, 2]])
    chains = sorted(mesh_chains(pairs, points), key=len)
    assert sorted(chains[0].tolist()) == [1, 4] and chains[1].tolist() in ([0, 1, 2, 3], [3, 2, 1, 0])
    # a regular octagon's sides meet at 135 degrees and continue each other: one closed chain, opened
    angle = np.pi / 4 * np.arange(8)
    points = np.stack([np.cos(angle), np.sin(angle), 0 * angle], axis=1)
    pairs = np.stack([np.arange(8), (np.arange(8) + 1) % 8], axis=1)
    (chain,) = mesh_chains(pairs, points)
    assert len(chain) == 9 and chain[0] == chain[-1] and sorted(chain[:-1]) == list(range(8))


@pytest.mark.parametrize("mesh", ["grid", "triangles"])
def test_rounds_of_line_solves_hold_the_hanging_cloth_within_the_tolerance(mesh):
    scene = hanging(mesh)
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_tolerance=0.005))
    with lab_hooks(SolveChoices(chebyshev_rho=0.0, line_solve=True)):
        sim = wc.Simulator(scene, device="cpu")
    assert "line solves" in str(sim.plan)
    monitor = StrainMonitor()
    sim.run(12, writers=[monitor])
    stats = sim.solver_stats(since_start=True)
    assert stats.limit_residual <= 1.0
    assert monitor.report().stretch <= 1.1 * 1.005 - 1.0 + 1e-5


def test_a_scene_without_strain_limits_runs_under_the_line_solves_hooks_as_without_them():
    scene = wc.load_scene("swing")  # springs only: no limit, so no lines and no limit solve
    runs = []
    for choices in (SolveChoices(), SolveChoices(line_solve=True)):
        with lab_hooks(choices):
            sim = wc.Simulator(scene, device="cpu")
        sim.run(2)
        runs.append(sim.positions())
    assert np.array_equal(*runs)


def test_rounds_of_line_solves_with_self_collision_hold_the_limit_and_keep_the_cloth_from_crossing_itself():
    scene = hard_cases.twisted()  # released from a twist onto the ground, folding onto itself
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_tolerance=0.005))
    lines = SolveChoices(chebyshev_rho=0.0, line_solve=True, line_contacts=True)
    with pytest.warns(wc.UnstableStepWarning), lab_hooks(lines):
        sim = wc.Simulator(scene, device="cpu")
    assert "line solves" in str(sim.plan) and "separation" in str(sim.plan)
    monitor = StrainMonitor()
    crossings, gaps = TriangleIntersections(sim), ContactGaps(sim)
    monitor.begin(sim)
    for _ in range(12):
        sim.step()
        monitor.write_frame(sim, sim.frame)
        assert crossings(sim) == 0
        assert gaps(sim) >= 1.0 - scene.collision.tolerance
    stats = sim.solver_stats(since_start=True)
    assert stats.limit_residual <= 1.0
    report = monitor.report()
    assert report.stretch <= 1.1 * 1.005 - 1.0 + 1e-5
    assert report.compression <= 1.0 - 0.9 * 0.995 + 1e-5


def test_line_segments_cut_each_line_at_every_size_th_spring_but_its_last():
    starts = np.array([0, 2, 7, 17])  # lines of 1, 4 and 9 springs
    segments = line_segments(starts, 3)
    assert segments["separator"].tolist() == [4, 9, 12]
    assert segments["separator_start"].tolist() == [0, 0, 1, 3]
    assert segments["first"].tolist() == [0, 2, 5, 7, 10, 13]
    assert segments["end"].tolist() == [1, 4, 6, 9, 12, 16]
    assert segments["left"].tolist() == [-1, -1, 4, -1, 9, 12]
    assert segments["right"].tolist() == [-1, 4, -1, 9, 12, -1]


def test_the_interleaved_layout_stores_each_segments_j_th_slot_at_its_segment_plus_j_times_the_segments():
    segments = line_segments(np.array([0, 2, 7, 17]), 3)  # lines of 1, 4 and 9 springs; segments of 2 to 4 slots
    contiguous = slot_layout(segments, interleaved=False)
    assert contiguous.storage.tolist() == list(range(17)) and contiguous.step == 1 and contiguous.size == 17
    interleaved = slot_layout(segments, interleaved=True)
    assert interleaved.base.tolist() == list(range(6)) and interleaved.step == 6 and interleaved.size == 6 * 4
    assert interleaved.storage.tolist() == [0, 6, 1, 7, 13, 2, 8, 3, 9, 15, 4, 10, 16, 5, 11, 17, 23]


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_the_device_chooses_whole_contiguous_lines_on_the_cpu_and_on_cuda_interleaved_segments_of_the_root_of_a_line(
        device):
    with lab_hooks(SolveChoices(line_solve=True)):
        sim = wc.Simulator(wc.load_scene("hanging"), device=device, graph=False)
    line_solves = sim.plan.projection.later_body[0]
    assert isinstance(line_solves, LineSolves)
    longest = longest_line(cloth_lines(sim.model, sim.scene))
    assert longest == 10  # the hanging cloth's longest lines
    assert (line_solves.segment, line_solves.interleaved) == ((4, True) if device == "cuda" else (longest, False))
    cut = [family.segment_count > family.line_count for family in line_solves.families]
    assert cut == ([True] * 4 if device == "cuda" else [False] * 4)
    assert [segment_for_device(n) for n in (1, 3, 255, 511, 1023, 2047, 4095)] == [4, 4, 4, 8, 16, 16, 16]


def test_cyclic_reduction_halves_the_separators_chains_until_none_is_longer_than_a_thread_walks():
    lines = lambda separators: line_segments(np.array([0, 2 * separators + 3]), 2)  # noqa: E731
    assert [reduction_strides(lines(n)) for n in (0, 1, CHAIN, CHAIN + 1, 19, 31, 45)] == [
        [1], [1], [1], [1, 2], [1, 2, 4], [1, 2, 4], [1, 2, 4, 8]]


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_lines_solved_in_segments_move_the_particles_as_whole_lines_do(device):
    # on a GPU the segments' threads run at once: a race between them would show here, not on the CPU
    scene = wc.load_scene("hanging")  # its cloth at 40 x 36 cells: rows of 40 springs cut by segments of 32
    scene = dataclasses.replace(scene, cloths=(dataclasses.replace(scene.cloths[0], resolution=(40, 36)),),
                                simulation=dataclasses.replace(scene.simulation, limit_solve="converged"))
    whole = longest_line(cloth_lines(build_model(scene), scene))
    rng = np.random.default_rng(3)
    moved = {}
    for segment, interleaved in [(whole, False), (whole, True)] + [(s, i) for s in (2, 3, 32) for i in (False, True)]:
        with lab_hooks(SolveChoices(chebyshev_rho=0.0, line_solve=True, line_hold_margin=1.0, line_newton_steps=2,
                                    line_segment=segment, line_interleaved=interleaved)):
            sim = wc.Simulator(scene, device=device, graph=False)
        if not moved:
            start = sim.positions() + rng.normal(0.0, 0.2, sim.positions().shape) * sim.model.edge_rest.mean()
            start[sim.model.inv_mass == 0] = sim.positions()[sim.model.inv_mass == 0]
        sim.state.x.assign(start.astype(np.float32))
        line_solves = sim.plan.projection.later_body[0]
        assert isinstance(line_solves, LineSolves)
        assert (line_solves.segment, line_solves.interleaved) == (segment, interleaved)
        line_solves.run(sim.state)
        moved[segment, interleaved] = sim.positions() - start
    scale = np.abs(moved[whole, False]).max()
    assert scale > 0.1 * sim.model.edge_rest.mean()  # the lines moved
    assert whole > 32 and all(family.segment_count > family.line_count for family in line_solves.families)
    for key, positions in moved.items():
        assert np.abs(positions - moved[whole, False]).max() <= 1e-6 * scale, key


def tube_obj(path: Path, around: int, rows: int) -> str:
    """An OBJ of a tube of quads, ``around`` cells round and ``rows`` high: its rings are closed lines."""
    angle = 2.0 * np.pi * np.arange(around) / around
    lines = [f"v {0.5 * np.cos(a):.6f} {0.1 * y:.6f} {0.5 * np.sin(a):.6f}" for y in range(rows + 1) for a in angle]
    at = lambda i, y: 1 + i % around + around * y  # noqa: E731
    lines += [f"f {at(i, y)} {at(i + 1, y)} {at(i + 1, y + 1)} {at(i, y + 1)}"
              for y in range(rows) for i in range(around)]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_a_tubes_rings_cut_into_segments_move_their_particles_as_whole_rings_do(device, tmp_path):
    # a ring's first particle is its last: cut, its first segment moves it for both ends (on a GPU two
    # threads moving it at once would lose a move)
    cloth = wc.Cloth.from_mesh(tube_obj(tmp_path / "tube.obj", 24, 3), density=0.3, limit=wc.Limit(0.1, 0.1))
    scene = wc.Scene(name="tube", cloths=(cloth,), simulation=wc.Simulation(limit_solve="converged"))
    rng = np.random.default_rng(5)
    moved = {}
    for segment in (1 << 30, 2, 3, 5):
        with lab_hooks(SolveChoices(chebyshev_rho=0.0, line_solve=True, line_hold_margin=1.0, line_newton_steps=2,
                                    line_segment=segment)):
            sim = wc.Simulator(scene, device=device, graph=False)
        if not moved:
            start = sim.positions() + rng.normal(0.0, 0.2, sim.positions().shape) * sim.model.edge_rest.mean()
            starts, particles = cloth_lines(sim.model, scene)[0][:2]
            rings = particles[starts[:-1]] == particles[starts[1:] - 1]
            assert rings.sum() >= 4 and np.diff(starts)[rings].min() > 24  # the tube's rings: closed lines
        sim.state.x.assign(start.astype(np.float32))
        line_solves = sim.plan.projection.later_body[0]
        line_solves.run(sim.state)
        moved[segment] = sim.positions() - start
    scale = np.abs(moved[1 << 30]).max()
    assert scale > 0.1 * sim.model.edge_rest.mean()
    for segment, positions in moved.items():
        assert np.abs(positions - moved[1 << 30]).max() <= 1e-6 * scale, segment


def test_the_hanging_cloth_comes_to_rest_under_the_line_solve_as_under_the_default():
    # Line rounds alone kept this cloth moving at 0.1 m/s for good; the Jacobi pair before them settles it
    # (docs/notebook/strain-solve.md, "A Jacobi pair before the lines").
    scene = wc.load_scene("hanging")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, drag=1.0,
                                                                      integrator="symplectic"))
    with lab_hooks(SolveChoices(line_solve=True)):
        sim = wc.Simulator(scene, device="cpu")
    assert sim.plan.projection.later_body is not None
    for _ in range(480):
        sim.step()
    assert np.linalg.norm(sim.velocities(), axis=1).max() < 0.01


def test_a_scene_whose_only_limited_springs_are_a_seams_has_no_lines_and_keeps_the_jacobi_solve():
    data = {"name": "sewn", "cloth": [{"name": "a", "resolution": [4, 4], "size": [0.4, 0.4]},
                                       {"name": "b", "resolution": [4, 4], "size": [0.4, 0.4],
                                        "origin": [0.9, 0.4, 0.0], "rotation": [0.0, 0.0, 180.0]}],
            "seam": [{"a": {"cloth": "a", "edge": "right"}, "b": {"cloth": "b", "edge": "right"}}]}
    scene = scene_from_dict(data)
    with lab_hooks(SolveChoices(line_solve=True)):
        sim = wc.Simulator(scene, device="cpu")
    assert cloth_lines(sim.model, scene) == [] and sim.model.limits is not None
    assert sim.plan.projection.later_body is None  # the default's Jacobi pairs
