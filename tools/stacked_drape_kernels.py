"""Where the stacked drape's frames spend their time on the CPU, kernel by kernel (docs/notebook/layers.md).

The stacked drape of tools/stacked_drape.py (its scene, a 4 mm contact radius, edge contacts), with the
surface thickness and the lab's displacement bounds as asked, stepped without graphs (``graph=False``: a CPU
graph replays launches that ``wp.launch`` does not see) with ``wp.launch`` wrapped in a wall clock: a CPU
launch returns when its kernel has run, so each launch's wall time is its kernel's. Prints the frames' wall time and each
kernel's launches and seconds, costliest first, and writes them as JSON.

    python tools/stacked_drape_kernels.py --sheets 3 --n 24 --frames 30 --thickness 0.004 \\
        --json docs/results/stacked-drape-3x24-kernels-cpu.json
"""

from __future__ import annotations

import argparse
import collections
import json
import time

import warp as wp

import warp_cloth as wc
from stacked_drape import stacked_drape_scene
from warp_cloth.displacement_bounds import BoundSettings, lab_hooks
from warp_cloth.lab.bench import environment


def kernel_seconds(sim: wc.Simulator, frames: int) -> tuple[float, dict[str, list]]:
    """The wall time of ``frames`` frames and, by kernel, [launches, seconds]."""
    totals: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
    launch = wp.launch

    def timed(kernel, *args, **kwargs):
        started = time.perf_counter()
        result = launch(kernel, *args, **kwargs)
        entry = totals[kernel.key]
        entry[0] += 1
        entry[1] += time.perf_counter() - started
        return result

    wp.launch = timed
    try:
        started = time.perf_counter()
        for _ in range(frames):
            sim.step()
        wall = time.perf_counter() - started
    finally:
        wp.launch = launch
    return wall, dict(sorted(totals.items(), key=lambda item: -item[1][1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sheets", type=int, default=3)
    parser.add_argument("--n", type=int, default=24)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--radius", type=float, default=0.004)
    parser.add_argument("--thickness", type=float, default=None, help="[collision] thickness, metres (default none)")
    parser.add_argument("--bounds", default="off",
                        help="off (the scene's own), on or radius=R,... (BoundSettings.parse)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    scene = stacked_drape_scene(sheets=args.sheets, n=args.n, frames=args.frames, radius=args.radius, edges=True,
                                thickness=args.thickness)
    with lab_hooks(BoundSettings.parse(args.bounds)):
        sim = wc.Simulator(scene, device="cpu", graph=False)
    sim.prepare()
    wall, kernels = kernel_seconds(sim, args.frames)
    print(f"{args.frames} frames in {wall:.1f} s")
    for name, (launches, seconds) in kernels.items():
        print(f"{name:<40} {launches:>7} {seconds:>8.2f} s {100 * seconds / wall:>5.1f}%")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"args": vars(args), "frames_seconds": wall,
                       "kernels": {name: {"launches": c, "seconds": s} for name, (c, s) in kernels.items()},
                       "environment": environment("cpu")}, out, indent=1)


if __name__ == "__main__":
    main()
