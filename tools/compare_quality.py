"""Time per frame and worst edge strain of the speed matrix's cloths, in ours and in Newton's solvers.

    python tools/compare_quality.py OUT.jsonl ITEM...      ITEM = variant:n:engine[:substeps]

variant is hanging, sphere or self; engine is ours, ours_sequential (the self rows' collision passes with
``projection = "sequential"``), semi_implicit, xpbd or vbd; substeps (Newton only,
default 10) sets Newton's step, its springs stiffening with 1/dt^2 as newton_compare sets them. Each row is
2 warm-up frames, then the median of 3 x 48 timed frames (8 for VBD from 1024^2 on), then the strain.
Writes one JSON line per row after a line with the environment. Used for docs/benchmarks.md's strain and
equal-quality tables (docs/results/strain-ours-h200.jsonl, newton-strain-h200.jsonl,
newton-substeps-h200.jsonl).
"""

import dataclasses
import json
import statistics
import sys
import time

import warp as wp

from warp_cloth.bench import environment, matrix_scene, seconds_of_runs
from warp_cloth.newton_compare import max_edge_strain, time_newton
from warp_cloth.simulator import Simulator

REPEATS = 3


def time_ours(variant: str, n: int, device: str, frames: int, projection: str = "joint") -> dict:
    scene = matrix_scene(variant, n, "symplectic")
    if scene.collision is not None:
        scene = dataclasses.replace(scene, collision=dataclasses.replace(scene.collision, projection=projection))
    sim = Simulator(scene, device=device)
    sim.run(2)
    median = statistics.median(seconds_of_runs(sim, frames, REPEATS))
    return {"solver": "ours" if projection == "joint" else f"ours_{projection}", "variant": variant, "n": n,
            "substeps": sim.substeps_per_frame, "frames": frames,
            "ms_per_frame": 1e3 * median / frames,
            "particle_substeps_per_second": n * n * sim.substeps_per_frame * frames / median,
            "max_strain": max_edge_strain(sim.positions(), n)}


def main(out_path: str, items: list[str]) -> None:
    wp.config.log_level = wp.LOG_ERROR
    device = "cuda" if wp.is_cuda_available() else "cpu"
    with open(out_path, "a") as out:
        print(json.dumps({"environment": environment(device)}), file=out, flush=True)
        for item in items:
            variant, n, engine, *rest = item.split(":")
            n, substeps = int(n), int(rest[0]) if rest else 10
            frames = 8 if engine == "vbd" and n >= 1024 else 48
            started = time.perf_counter()
            try:
                row = (time_ours(variant, n, device, frames, engine.partition("_")[2] or "joint")
                       if engine.startswith("ours") else
                       time_newton(variant, n, engine, device, frames=frames, substeps=substeps, repeats=REPEATS))
            except Exception as error:  # one failing solver must not lose the other rows
                row = {"solver": engine, "variant": variant, "n": n, "substeps": substeps,
                       "error": f"{type(error).__name__}: {error}"}
            row["wall_including_build_s"] = time.perf_counter() - started
            print(json.dumps(row), file=out, flush=True)
            print(f"{item}: {row.get('ms_per_frame', float('nan')):.3f} ms/frame, worst edge strain "
                  f"{row.get('max_strain', float('nan')):.3f} {row.get('error', '')}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
