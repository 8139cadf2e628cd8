"""Where the stacked drape's frames spend their time, kernel by kernel (docs/notebook/layers.md).

The stacked drape of tools/stacked_drape.py (its scene, a 4 mm contact radius), with the
surface thickness and the lab's displacement bounds as asked, stepped without graphs (``use_graph`` off: a
CPU graph replays launches that ``wp.launch`` does not see), after ``--skip`` frames stepped with them. On
the CPU ``wp.launch`` is wrapped in a wall clock: a CPU launch returns when its kernel has run, so each
launch's wall time is its kernel's. On CUDA Warp's
activity timing (``wp.timing_begin``) gives each kernel's, copy's and fill's device time, after one frame
that loads the kernels. Prints the frames' wall time and each kernel's launches, time, time a launch and
share of the frames, costliest first, and writes them as JSON.

    python tools/stacked_drape_kernels.py --sheets 3 --n 24 --frames 30 --thickness 0.004 \\
        --json docs/results/stacked-drape-3x24-kernels-cpu.json
    python tools/stacked_drape_kernels.py --sheets 5 --n 128 --frames 3 --thickness 0.004 --device cuda
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


def device_seconds(sim: wc.Simulator, frames: int) -> tuple[float, dict[str, list]]:
    """As ``kernel_seconds``, on CUDA: each activity's device time, by name."""
    sim.step()
    totals: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
    started = time.perf_counter()
    for _ in range(frames):
        sim.step()
    wp.synchronize()
    wall = time.perf_counter() - started
    for activity in wp.timing_end():
        entry = totals[activity.name]
        entry[0] += 1
        entry[1] += activity.elapsed * 1e-3
    return wall, dict(sorted(totals.items(), key=lambda item: -item[1][1]))


def frames_by_kernel(sim: wc.Simulator, frames: int, skip: int = 0) -> tuple[float, dict[str, list]]:
    """``skip`` frames stepped with graphs, unmeasured, then ``frames`` frames launched pass by pass (no
    graphs), timed by kernel as the device allows."""
    for _ in range(skip):
        sim.step()
    sim.use_graph = False
    sim.prepare()
    timing = device_seconds if sim.device.is_cuda else kernel_seconds
    return timing(sim, frames)


def report_kernels(args: argparse.Namespace, wall: float, kernels: dict[str, list]) -> None:
    """Each kernel's launches, milliseconds, microseconds a launch and share of the frames' wall time, costliest
    first; and, where ``args.json`` names a file, the run's arguments, its frames' seconds and each kernel's
    launches and seconds there as JSON."""
    for name, (launches, seconds) in kernels.items():
        print(f"{name:<48} {launches:>7} {seconds * 1e3:>10.2f} ms {seconds / launches * 1e6:>9.1f} us "
              f"{100 * seconds / wall:>5.1f}%")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"args": vars(args), "frames_seconds": wall,
                       "kernels": {name: {"launches": c, "seconds": s} for name, (c, s) in kernels.items()},
                       "environment": environment(args.device)}, out, indent=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sheets", type=int, default=3)
    parser.add_argument("--n", type=int, default=24)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--skip", type=int, default=0,
                        help="frames stepped first, with graphs and unmeasured (a later stage of the drape)")
    parser.add_argument("--size", type=float, default=2.0, help="metres, a sheet's side")
    parser.add_argument("--sphere-radius", type=float, default=0.5)
    parser.add_argument("--radius", type=float, default=0.004)
    parser.add_argument("--thickness", type=float, default=None, help="[collision] thickness, metres (default none)")
    parser.add_argument("--bounds", default="off",
                        help="off (the scene's own), on or radius=R,... (BoundSettings.parse)")
    parser.add_argument("--integrator", default="symplectic", choices=("symplectic", "implicit", "explicit"))
    parser.add_argument("--substeps", type=int, default=None, help="fixed substeps a frame (default: the simulator's)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    scene = stacked_drape_scene(sheets=args.sheets, n=args.n, frames=args.skip + args.frames, size=args.size,
                                sphere_radius=args.sphere_radius, radius=args.radius,
                                thickness=args.thickness, substeps=args.substeps, integrator=args.integrator)
    with lab_hooks(BoundSettings.parse(args.bounds)):
        sim = wc.Simulator(scene, device=args.device)
    wall, kernels = frames_by_kernel(sim, args.frames, args.skip)
    print(f"{args.frames} frames after {args.skip} in {wall:.1f} s")
    report_kernels(args, wall, kernels)


if __name__ == "__main__":
    main()
