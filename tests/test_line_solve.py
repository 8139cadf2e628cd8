"""The lab's held line solve of the strain limits (warp_cloth/line_solve.py): the grid's lines cover every
limited spring once, rounds of it inside the converged solve hold the limit, and lines solved in segments
(kernels/line_solve_segments.py) move the particles as whole lines do."""

import dataclasses

import numpy as np

import warp_cloth as wc
from warp_cloth.limit_solve import lab_hooks
from warp_cloth.line_solve import FAMILIES, LineSolves, grid_lines, line_segments
from warp_cloth.model import build_model
from warp_cloth.strain import StrainMonitor


def test_the_lines_hold_every_limited_spring_once_split_at_the_pins():
    scene = wc.load_scene("hanging")
    model = build_model(scene)
    lines = grid_lines(model, scene)
    n = model.particle_count
    found = []
    for family in FAMILIES:
        starts, particles, lo, hi = lines[family]
        for first, end in zip(starts[:-1], starts[1:]):
            line = particles[first:end]
            assert (model.inv_mass[line[1:-1]] > 0).all()  # pins only at a line's ends
            a, b = np.minimum(line[:-1], line[1:]), np.maximum(line[:-1], line[1:])
            found += list(a.astype(np.int64) * n + b)
            assert (lo[first:end - 1] > 0).all() and (hi[first:end - 1] > lo[first:end - 1]).all()
    pairs = np.sort(model.springs.pairs[np.isfinite(model.springs.limit_max)], axis=1).astype(np.int64)
    free = (model.inv_mass[pairs] > 0).any(axis=1)  # a spring between two pins is in no line
    assert sorted(found) == sorted(pairs[free, 0] * n + pairs[free, 1])


def test_rounds_of_line_solves_hold_the_hanging_cloth_within_the_tolerance():
    scene = wc.load_scene("hanging")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_tolerance=0.005))
    with lab_hooks(chebyshev_rho=0.0, line_solve=True):
        sim = wc.Simulator(scene, device="cpu")
    assert "line solves" in str(sim.plan)
    monitor = StrainMonitor()
    sim.run(12, writers=[monitor])
    stats = sim.solver_stats(since_start=True)
    assert stats.limit_residual <= 1.0
    assert monitor.report().stretch <= 1.1 * 1.005 - 1.0 + 1e-5


def test_line_segments_cut_each_line_at_every_size_th_spring_but_its_last():
    starts = np.array([0, 2, 7, 17])  # lines of 1, 4 and 9 springs
    segments = line_segments(starts, 3)
    assert segments["separator"].tolist() == [4, 9, 12]
    assert segments["separator_start"].tolist() == [0, 0, 1, 3]
    assert segments["first"].tolist() == [0, 2, 5, 7, 10, 13]
    assert segments["end"].tolist() == [1, 4, 6, 9, 12, 16]
    assert segments["left"].tolist() == [-1, -1, 4, -1, 9, 12]
    assert segments["right"].tolist() == [-1, 4, -1, 9, 12, -1]


def test_lines_solved_in_segments_move_the_particles_as_whole_lines_do():
    scene = wc.load_scene("hanging")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, limit_solve="converged"))
    rng = np.random.default_rng(3)
    moved = {}
    for segment in (0, 2, 3, 32):
        with lab_hooks(chebyshev_rho=0.0, line_solve=True, line_hold_margin=1.0, line_newton_steps=2,
                       line_segment=segment):
            sim = wc.Simulator(scene, device="cpu", graph=False)
        if segment == 0:
            start = sim.positions() + rng.normal(0.0, 0.2, sim.positions().shape) * sim.model.edge_rest.mean()
            start[sim.model.inv_mass == 0] = sim.positions()[sim.model.inv_mass == 0]
        sim.state.x.assign(start.astype(np.float32))
        line_solves = sim.plan.projection.body[0]
        assert isinstance(line_solves, LineSolves) and (line_solves.segments is None) == (segment == 0)
        line_solves.run(sim.state)
        moved[segment] = sim.positions() - start
    scale = np.abs(moved[0]).max()
    assert scale > 0.1 * sim.model.edge_rest.mean()  # the lines moved
    for segment in (2, 3, 32):
        assert np.abs(moved[segment] - moved[0]).max() <= 1e-6 * scale
