"""Probe: the time to remake the neighbour lists (the remake request's memset, hash insert, gather and
sort, the end of the remake: ``NeighbourLists.remake_now``) of the speed matrix's self-collision cloth
after 48 frames, by threads per particle (``Simulator(scene, threads_per_particle=K)``, which sets the
remake's threads with the other gathering passes'). A graph of 20 remakes, microseconds per remake. Not
used by the package.

    [DEVICE=cpu] python tools/list_probe.py OUT.json [SIZE ...]

(DEVICE=cpu: a check that it runs, one thread per particle only.) docs/results/list-probe-h200.json is
its output on the H200 (from before the restructure): behind ``LIST_THREADS_BY_SIZE`` in
warp_cloth/neighbour_lists.py.
"""

import json
import os
import statistics
import sys
import time

import warp as wp

from warp_cloth.lab.bench import matrix_scene
from warp_cloth.neighbour_lists import NeighbourLists
from warp_cloth.simulator import Simulator

wp.config.log_level = wp.LOG_ERROR


def us_per_remake(lists: NeighbourLists, x: wp.array) -> float:
    lists.remake_now(x)
    with wp.ScopedCapture(device=x.device) as capture:
        for _ in range(20):
            lists.remake_now(x)
    times = []
    for _ in range(5):
        wp.synchronize_device(x.device)
        started = time.perf_counter()
        for _ in range(10):
            wp.capture_launch(capture.graph)
        wp.synchronize_device(x.device)
        times.append((time.perf_counter() - started) / 200 * 1e6)
    return statistics.median(times)


def main() -> None:
    device = os.environ.get("DEVICE", "cuda")
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    results = {}
    for n in sizes:
        scene = matrix_scene("self", n, "symplectic")
        settled = Simulator(scene, device=device, threads_per_particle=1)
        settled.run(48)
        row = {}
        for threads in (1, 2, 4, 8, 16, 32) if device.startswith("cuda") else (1,):
            sim = Simulator(scene, device=device, threads_per_particle=threads)
            row[threads] = us_per_remake(sim.plan.lists, settled.state.x)
        results[n] = row
        print(n, {k: round(v, 1) for k, v in row.items()}, flush=True)
    json.dump({"device": wp.get_device(device).name, "warp": wp.config.version, "us_per_remake": results},
              open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
