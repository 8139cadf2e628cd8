"""Time per frame and worst edge strain of the speed matrix's cloths, in ours and in Newton's solvers.

    python tools/compare_quality.py OUT.jsonl ITEM...      ITEM = variant:n:engine[:substeps[:worlds]]

variant is hanging, sphere or self; engine is ours (the matrix's fixed 2 limit passes), ours_sequential
(the self rows' collision passes with ``projection = "sequential"``), ours_METHOD for a method of
tools/strain_solve_probe.py (``ours_chebyshev``: the limit solved, Chebyshev 0.95, at most 400 passes a
substep; ``ours_chebyshev+long_range``), semi_implicit, xpbd or vbd; substeps (default 10) sets the step,
the springs stiffening with 1/dt^2 in both engines (``matrix_scene``, newton_compare), and worlds (Newton
only, default 1) runs that many copies as Newton's worlds of one model. Each row is 2 warm-up
frames, then the median of 3 x 48 timed frames (8 for VBD from 1024^2 on), then the strain over every frame
of a second run of as many frames from the start (2 + 3 x 48), on the structural and shear edges, stretch
and compression, for both engines. Writes one JSON line per row after a line with the environment. Used for
docs/benchmarks.md's strain and equal-quality tables.
"""

import dataclasses
import json
import statistics
import sys
import time

import warp as wp

from warp_cloth.bench import environment, matrix_scene, seconds_of_runs
from warp_cloth.newton_compare import time_newton
from warp_cloth.simulator import Simulator
from warp_cloth.strain import StrainMonitor
from strain_solve_probe import configured

REPEATS = 3
MAX_PASSES = 400
RHO = 0.95


def time_ours(variant: str, n: int, device: str, frames: int, engine: str, substeps: int) -> dict:
    scene = matrix_scene(variant, n, "symplectic", substeps)
    method = engine.partition("_")[2] or "fixed"
    if method == "sequential":
        scene = dataclasses.replace(scene, collision=dataclasses.replace(scene.collision, projection="sequential"))
    else:
        scene = configured(scene, method, MAX_PASSES, RHO)
    sim = Simulator(scene, device=device)
    sim.run(2)
    sim.solver_stats()
    median = statistics.median(seconds_of_runs(sim, frames, REPEATS))
    stats = sim.solver_stats()
    strained = Simulator(scene, device=device)
    monitor = StrainMonitor()
    strained.run(2 + REPEATS * frames, writers=[monitor])
    report = monitor.report()
    solved = stats is not None and stats.limit_passes is not None
    return {"solver": engine, "variant": variant, "n": n, "substeps": sim.substeps_per_frame, "frames": frames,
            "ms_per_frame": 1e3 * median / frames,
            "particle_substeps_per_second": n * n * sim.substeps_per_frame * frames / median,
            "max_strain": report.worst, "stretch": report.stretch, "compression": report.compression,
            "strain_frames": 2 + REPEATS * frames,
            "mean_passes": stats.limit_mean_passes if solved else None,
            "most_passes": stats.limit_passes if solved else None,
            "residual": stats.limit_residual if solved else None}


def main(out_path: str, items: list[str]) -> None:
    wp.config.log_level = wp.LOG_ERROR
    device = "cuda" if wp.is_cuda_available() else "cpu"
    with open(out_path, "a") as out:
        print(json.dumps({"environment": environment(device)}), file=out, flush=True)
        for item in items:
            variant, n, engine, *rest = item.split(":")
            n, substeps, worlds = int(n), int(rest[0]) if rest else 10, int(rest[1]) if len(rest) > 1 else 1
            frames = 8 if engine == "vbd" and n >= 1024 else 48
            started = time.perf_counter()
            try:
                row = (time_ours(variant, n, device, frames, engine, substeps)
                       if engine.startswith("ours") else
                       time_newton(variant, n, engine, device, frames=frames, substeps=substeps, repeats=REPEATS,
                                   worlds=worlds))
            except Exception as error:  # one failing solver must not lose the other rows
                row = {"solver": engine, "variant": variant, "n": n, "substeps": substeps,
                       "error": f"{type(error).__name__}: {error}"}
            row["wall_including_build_s"] = time.perf_counter() - started
            print(json.dumps(row), file=out, flush=True)
            print(f"{item}: {row.get('ms_per_frame', float('nan')):.3f} ms/frame, worst edge over the run "
                  f"+{row.get('stretch', float('nan')):.3f} / -{row.get('compression', float('nan')):.3f} "
                  f"{row.get('error', '')}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
