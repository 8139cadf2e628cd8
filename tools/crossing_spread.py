"""How much of seed_default's crossing-triangle count and worst edge is one run's rounding: the scene run
with gravity scaled by 1 + k 1e-6 (k = 0 .. runs-1), each run's worst count of crossing pairs, closest
contact, worst edge strain over every frame and how its capped limit solves ended.

    python tools/crossing_spread.py OUT.jsonl DEVICE FRAMES RUNS

Used for the bound in tests/test_collision.py (docs/results/seed-default-crossings-*.jsonl).
"""

import dataclasses
import json
import sys

import warp as wp

import warp_cloth as wc
from warp_cloth.diagnostics import ContactGaps, TriangleIntersections


def main(out_path: str, device: str, frames: int, runs: int) -> None:
    wp.config.log_level = wp.LOG_ERROR
    base = wc.load_scene("seed_default")
    with open(out_path, "a") as out:
        for k in range(runs):
            eps = 1e-6 * k
            gravity = tuple(g * (1.0 + eps) for g in base.simulation.gravity)
            scene = dataclasses.replace(base, simulation=dataclasses.replace(base.simulation, gravity=gravity,
                                                                             frames=frames))
            sim = wc.Simulator(scene, device=device)
            crossings, gaps, strain = TriangleIntersections(sim), ContactGaps(sim), wc.StrainMonitor()
            strain.begin(sim)  # once: each Simulator.run begins its writers anew
            strain.write_frame(sim, 0)
            worst, closest, frames_with = 0, float("inf"), 0
            for frame in range(1, frames + 1):
                sim.step()
                strain.write_frame(sim, frame)
                count = crossings(sim)
                worst, frames_with, closest = max(worst, count), frames_with + (count > 0), min(closest, gaps(sim))
            report, stats = strain.report(), sim.solver_stats(since_start=True)
            row = {"device": device, "frames": frames, "eps": eps, "worst_crossings": worst,
                   "frames_with_crossings": frames_with, "closest_contact": closest,
                   "stretch": report.stretch, "stretch_frame": report.stretch_frame,
                   "compression": report.compression, "limit_passes_most": stats.limit_passes,
                   "limit_residual": stats.limit_residual}
            print(json.dumps(row), file=out, flush=True)
            print(row, flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
