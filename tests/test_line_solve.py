"""The lab's held line solve of the strain limits (warp_cloth/line_solve.py): the grid's lines cover every
limited spring once, and rounds of it inside the converged solve hold the limit."""

import dataclasses

import numpy as np

import warp_cloth as wc
from warp_cloth.limit_solve import lab_hooks
from warp_cloth.line_solve import FAMILIES, grid_lines
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
