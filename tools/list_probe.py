"""Probe: the time to remake the neighbour lists (hash insert, gather, sort) of the speed matrix's
self-collision cloth after 48 frames, by threads per particle. A graph of 20 remakes, microseconds per
remake. Not used by the package.

    python tools/list_probe.py OUT.json [SIZE ...]

docs/results/list-probe-h200.json is its output on the H200.
"""

import json
import statistics
import sys
import time

import warp as wp

from warp_cloth.bench import matrix_scene
from warp_cloth.simulator import Simulator
from warp_cloth.stages import ParticleCollision

wp.config.log_level = wp.LOG_ERROR


def us_per_remake(stage: ParticleCollision, x: wp.array) -> float:
    stage.make_lists(x)
    with wp.ScopedCapture() as capture:
        for _ in range(20):
            stage.make_lists(x)
    times = []
    for _ in range(5):
        wp.synchronize()
        started = time.perf_counter()
        for _ in range(10):
            wp.capture_launch(capture.graph)
        wp.synchronize()
        times.append((time.perf_counter() - started) / 200 * 1e6)
    return statistics.median(times)


def main() -> None:
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    results = {}
    for n in sizes:
        scene = matrix_scene("self", n, "symplectic")
        settled = Simulator(scene, device="cuda", threads_per_particle=1)
        settled.run(48)
        row = {}
        for lanes in (1, 2, 4, 8, 16, 32):
            sim = Simulator(scene, device="cuda", threads_per_particle=lanes)
            stage = next(s for s in sim.stages if isinstance(s, ParticleCollision))
            row[lanes] = us_per_remake(stage, settled.state.x)
        results[n] = row
        print(n, {k: round(v, 1) for k, v in row.items()}, flush=True)
    json.dump({"device": wp.get_device("cuda").name, "warp": wp.config.version, "us_per_remake": results},
              open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
