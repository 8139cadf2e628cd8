"""What several threads per particle and fast math each give on the speed matrix's cloths (symplectic):
ms per frame and worst edge strain, timed as ``warp-cloth bench --suite matrix`` times them, for

* ``by_size``: threads per particle chosen by size, fast math (the product's default);
* ``one_thread``: one thread per particle, fast math;
* ``precise``: threads chosen by size, without fast math;
* ``threads_K``: K threads per particle in every kernel, fast math.

One JSON line per row, written as it goes.

    [CONFIGS=by_size,precise] python tools/gather_threads.py OUT.jsonl [SIZE ...]

docs/results/gather-threads-h200.jsonl is its output on the H200.
"""

import dataclasses
import json
import os
import sys

import warp as wp

from warp_cloth.bench import MATRIX_VARIANTS, SPRINGS_ONLY, Case, environment, matrix_frames, matrix_scene, time_case
from warp_cloth.kernels import colliders, integration, lanes, limits, particle_collision

wp.config.log_level = wp.LOG_ERROR
FAST_MATH_MODULES = (colliders, integration, limits, particle_collision)


def set_fast_math(on: bool) -> None:
    """Fast math for the kernels compiled from now on (a module's options are part of its cache key)."""
    lanes.FAST_MATH["fast_math"] = on
    for module in FAST_MATH_MODULES:
        loaded = wp.get_module(module.__name__)
        loaded.options["fast_math"] = on
        loaded.mark_modified()  # else the module compiled with the other option stays loaded
    for factory in (integration.euler_step_lanes, limits.project_strain_limits_lanes,
                    particle_collision.separate_particles_lanes, particle_collision.resolve_contact_velocities_lanes,
                    particle_collision.gather_neighbors_lanes):
        factory.cache_clear()


def main() -> None:
    out = open(sys.argv[1], "a")
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    print(json.dumps({"environment": environment("cuda")}), file=out, flush=True)
    named = {"by_size": (None, True), "one_thread": (1, True), "precise": (None, False)}
    configs = [(name, *named[name]) if name in named else (name, int(name.removeprefix("threads_")), True)
               for name in os.environ.get("CONFIGS", "by_size,one_thread,precise").split(",")]
    for config, threads, fast in configs:
        set_fast_math(fast)
        for n in sizes:
            for variant in (*MATRIX_VARIANTS, SPRINGS_ONLY):
                case = Case(f"{variant} {n}^2 symplectic", matrix_scene(variant, n, "symplectic"),
                            matrix_frames(n, "cuda"), fresh=False, grid=n, threads_per_particle=threads)
                result = time_case(case, "cuda", 3)
                row = dict(dataclasses.asdict(result), config=config, variant=variant, n=n,
                           ms_per_frame=result.ms_per_frame)
                print(json.dumps(row), file=out, flush=True)
                print(f"{config:10s} {variant:12s} {n:5d}^2 {result.ms_per_frame:8.3f} ms/frame  "
                      f"strain {result.max_strain}", flush=True)


if __name__ == "__main__":
    main()
