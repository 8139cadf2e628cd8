"""Probe: the product's spring kernel with K threads ("lanes") per particle and P = B / K particles per
block of B threads (``integration.euler_step_lanes``), against its one-thread kernel, all compiled without
fast math, and the one-thread kernel with it. A graph of 100 launches of each on the hanging matrix cloth;
microseconds per launch and the largest position difference from the one-thread kernel. Not used by the
package. docs/results/lanes-probe-h200.json is its output on the H200 (its first version, with its own
copies of these kernels, measured the same to within 0.3 us at 64^2).

    python tools/lanes_probe.py OUT.json [cuda|cpu]
"""

import json
import statistics
import sys
import time

import warp as wp

from gather_threads import set_fast_math
from warp_cloth.bench import matrix_scene
from warp_cloth.kernels import integration
from warp_cloth.simulator import Simulator
from warp_cloth.stages import no_contact_start, upload_springs

wp.config.log_level = wp.LOG_ERROR


def per_launch_us(launch, device) -> float:
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


def main() -> None:
    device = sys.argv[2] if len(sys.argv) > 2 else "cuda"
    sizes = (64, 128, 256, 1024) if device == "cuda" else (8,)
    shapes = [(K, B) for B in (64, 128, 256) for K in (1, 2, 4, 8, 16)] if device == "cuda" else [(1, 1)]
    results = {}
    for n in sizes:
        sim = Simulator(matrix_scene("hanging", n, "symplectic"), device=device)
        sim.run(2)
        inv_mass = wp.array(sim.model.inv_mass, dtype=float, device=device)
        start_inputs, start_outputs = no_contact_start(device)
        args = [sim.state.x, sim.state.v, inv_mass, wp.vec3(0.0, -9.81, 0.0), 0.0, 1.0 / 240, 1,
                *upload_springs(sim.model, device), *start_inputs]
        x_out, v_out = wp.empty_like(sim.state.x), wp.empty_like(sim.state.v)
        outputs = [x_out, v_out, *start_outputs]
        particles = sim.model.particle_count
        row = {}

        def one_thread() -> None:
            wp.launch(integration.euler_step, particles, inputs=args, outputs=outputs, device=device)

        set_fast_math(False)
        row["loop"] = per_launch_us(one_thread, device)
        reference = x_out.numpy().copy()
        for K, B in shapes:
            kernel, blocks = integration.euler_step_lanes(K, B), (particles + B // K - 1) // (B // K)
            row[f"K{K}_B{B}"] = per_launch_us(
                lambda: wp.launch_tiled(kernel, dim=[blocks], inputs=args, outputs=outputs, block_dim=B,
                                        device=device), device)
            row[f"K{K}_B{B}_max_diff"] = float(abs(x_out.numpy() - reference).max())
        set_fast_math(True)
        row["loop_fast_math"] = per_launch_us(one_thread, device)
        row["loop_fast_math_max_diff"] = float(abs(x_out.numpy() - reference).max())
        results[n] = row
        print(n, {k: round(v, 2) for k, v in row.items() if not k.endswith("diff")},
              "max diff", max(v for k, v in row.items() if k.endswith("diff")), flush=True)
    json.dump({"device": str(wp.get_device(device).name), "warp": wp.config.version, "per_launch_us": results},
              open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
