"""Probe: the explicit step's kernel (spring forces, gravity and drag, one symplectic Euler step: the
``explicit_step_kernel`` of kernels/explicit_step.py) by threads per particle. Each form is a gathering kernel
(kernels/gathering.py) of K threads per particle, ``BLOCK / K`` particles to a block of ``BLOCK`` = 128
threads, launched with ``launch_gathering`` on the arguments the simulator's own explicit step takes
(``warp_cloth.integrators.ExplicitIntegrator.step_args``) on the hanging matrix cloth after 2 frames:

* ``loop``: one thread per particle, built without fast math from the same gather and finish functions;
* ``K{K}_B128``: K = 2 .. 16 threads per particle, without fast math;
* ``loop_fast_math``, ``K{K}_B128_fast_math``: the product's kernels (fast math), one and K threads.

A graph of 100 launches of each: microseconds per launch, and the largest position difference from
``loop``. The measurement behind ``THREADS_BY_SIZE`` in warp_cloth/plan.py; not used by the package. On
the CPU (a check that it runs) one 8^2 cloth, one thread per particle.

docs/results/lanes-probe-h200.json is the H200 output of this probe's earlier version, from before the
restructure: the same spring kernel taking its arrays one by one, its one-thread form launched one thread a
particle, and blocks of 64, 128 and 256 threads (the B of its keys); blocks are now ``BLOCK`` alone, and
the fast-math rows with several threads are new.

    python tools/lanes_probe.py OUT.json [cuda|cpu]
"""

import functools
import json
import statistics
import sys
import time

import warp as wp

from warp_cloth.lab.bench import matrix_scene
from warp_cloth.kernels import explicit_step
from warp_cloth.kernels.gathering import BLOCK, gathering_kernel, launch_gathering, load_gathering
from warp_cloth.simulator import Simulator

wp.config.log_level = wp.LOG_ERROR
THREADS = (2, 4, 8, 16)


def per_launch_us(launch, device) -> float:
    """Median over 5 repeats of 10 replays of a graph of 100 ``launch()``es, per launch."""
    launch()
    wp.synchronize_device(device)
    with wp.ScopedCapture(device=device) as capture:
        for _ in range(100):
            launch()
    times = []
    for _ in range(5):
        wp.synchronize_device(device)
        started = time.perf_counter()
        for _ in range(10):
            wp.capture_launch(capture.graph)
        wp.synchronize_device(device)
        times.append((time.perf_counter() - started) / 1000 * 1e6)
    return statistics.median(times)


@functools.cache
def precise_explicit_step(threads: int) -> wp.Kernel:
    """The product's explicit step kernel for ``threads`` threads per particle, without fast math."""
    return gathering_kernel("explicit_step_precise", explicit_step.ExplicitStepArgs,
                            explicit_step.gather_spring_forces, explicit_step.finish_explicit_step, threads,
                            options={"fast_math": False})


def main() -> None:
    device = sys.argv[2] if len(sys.argv) > 2 else "cuda"
    sizes = (64, 128, 256, 1024) if device == "cuda" else (8,)
    threads_tried = THREADS if device == "cuda" else ()
    results = {}
    for n in sizes:
        sim = Simulator(matrix_scene("hanging", n, "symplectic"), device=device)
        sim.run(2)
        args = sim.integrator.step_args(sim.device_model, sim.state)
        x, v = sim.state.x, sim.state.v
        x_out, v_out = wp.empty_like(x), wp.empty_like(v)
        particles = sim.device_model.particle_count

        def time_kernel(kernel: wp.Kernel, threads: int) -> float:
            load_gathering(kernel, threads, sim.device)
            return per_launch_us(lambda: launch_gathering(kernel, threads, particles, x, v, x_out, v_out, args),
                                 sim.device)

        row = {"loop": time_kernel(precise_explicit_step(1), 1)}
        reference = x_out.numpy().copy()
        forms = [("loop_fast_math", explicit_step.explicit_step_kernel(1), 1)]
        for K in threads_tried:
            forms += [(f"K{K}_B{BLOCK}", precise_explicit_step(K), K),
                      (f"K{K}_B{BLOCK}_fast_math", explicit_step.explicit_step_kernel(K), K)]
        for name, kernel, threads in forms:
            row[name] = time_kernel(kernel, threads)
            row[f"{name}_max_diff"] = float(abs(x_out.numpy() - reference).max())
        results[n] = row
        print(n, {k: round(v, 2) for k, v in row.items() if not k.endswith("diff")},
              "max diff", max(v for k, v in row.items() if k.endswith("diff")), flush=True)
    json.dump({"device": str(wp.get_device(device).name), "warp": wp.config.version, "block": BLOCK,
               "per_launch_us": results}, open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
