"""Where a small frame's time goes on a GPU: per frame with run() (no writers), with step(), and as bare
replay of the frame's captured graph (``Simulator.frame_graph()``, guard flags unread); per kernel, the
device time of one frame launched pass by pass (``Simulator.substep()``, CUDA events); the substep's
passes (``sim.plan.pass_names``) and threads per particle; and what an empty graph node costs. For
docs/benchmarks.md's section on 64^2 frames.

    python tools/frame_profile.py OUT.json
    python tools/frame_profile.py OUT.json --worlds 1024   # the self cloth at 32^2 as 1024 worlds of a batch
    python tools/frame_profile.py OUT.json --worlds 1024 --solved   # the same, the limit solved (its Chebyshev radius estimated)
    python tools/frame_profile.py OUT.json --preset cotton --case hang --resolution 128 --run symplectic:auto --frames 4
        # one of tools/material_step.py's preset cloths, timed over --frames frames after as many
"""

import argparse
import collections
import dataclasses
import json
import statistics
import sys
import time

import warp as wp

from warp_cloth.batch import Batch
from warp_cloth.lab.bench import matrix_scene
from warp_cloth.simulator import Simulator

from material_step import preset_scene

FRAMES, REPEATS = 200, 5


def ms_per_frame(advance, frames: int = FRAMES) -> float:
    """Median over repeats of the wall time per frame of ``advance(frames)``."""
    times = []
    for _ in range(REPEATS):
        wp.synchronize()
        started = time.perf_counter()
        advance(frames)
        wp.synchronize()
        times.append((time.perf_counter() - started) / frames * 1e3)
    return statistics.median(times)


def replay(sim: Simulator, frames: int) -> None:
    """The next frame's graph replayed again and again (guard flags unread, the simulator's frame count
    unchanged), for the bare GPU time of a frame."""
    graph = sim.frame_graph()
    for _ in range(frames):
        wp.capture_launch(graph)


def kernel_times(sim: Simulator) -> dict:
    """Launches, and device milliseconds in all, of each kernel in one frame's substeps launched pass by
    pass (without the blow-up guard's check)."""
    wp.timing_begin(cuda_filter=wp.TIMING_ALL)
    for _ in range(sim.substeps_per_frame):
        sim.substep()
    totals = collections.defaultdict(lambda: [0, 0.0])
    for result in wp.timing_end():
        totals[result.name][0] += 1
        totals[result.name][1] += result.elapsed
    return {name: {"count": c, "total_ms": t} for name, (c, t) in sorted(totals.items(), key=lambda kv: -kv[1][1])}


@wp.kernel
def add_one(a: wp.array(dtype=float)):
    i = wp.tid()
    a[i] = a[i] + 1.0


@wp.kernel
def add_twelve(a: wp.array(dtype=float), b: wp.array(dtype=float), c: wp.array(dtype=float),
               d: wp.array(dtype=float), e: wp.array(dtype=float), f: wp.array(dtype=float),
               g: wp.array(dtype=float), h: wp.array(dtype=float), k: wp.array(dtype=float),
               m: wp.array(dtype=float), o: wp.array(dtype=float), p: wp.array(dtype=float)):
    i = wp.tid()
    a[i] = a[i] + b[i] + c[i] + d[i] + e[i] + f[i] + g[i] + h[i] + k[i] + m[i] + o[i] + p[i]


@wp.kernel
def add_one_of_twelve(a: wp.array(dtype=float), b: wp.array(dtype=float), c: wp.array(dtype=float),
                      d: wp.array(dtype=float), e: wp.array(dtype=float), f: wp.array(dtype=float),
                      g: wp.array(dtype=float), h: wp.array(dtype=float), k: wp.array(dtype=float),
                      m: wp.array(dtype=float), o: wp.array(dtype=float), p: wp.array(dtype=float)):
    """Twelve array arguments, one read: what the arguments alone cost a node."""
    i = wp.tid()
    a[i] = a[i] + 1.0


def node_costs() -> dict:
    """Microseconds per node of a graph of 100 launches of 4096 threads."""
    a = wp.zeros(4096, dtype=float)
    more = [wp.zeros(4096, dtype=float) for _ in range(11)]
    never = wp.zeros(1, dtype=int)
    launches = {"one array": lambda: wp.launch(add_one, 4096, inputs=[a]),
                "twelve arrays": lambda: wp.launch(add_twelve, 4096, inputs=[a, *more]),
                "twelve arrays, one read": lambda: wp.launch(add_one_of_twelve, 4096, inputs=[a, *more]),
                "memset": lambda: a.zero_(),
                "conditional, false": lambda: wp.capture_if(
                    never, on_true=lambda: wp.launch(add_one, 4096, inputs=[a]))}
    costs = {}
    for name, launch in launches.items():
        launch()
        with wp.ScopedCapture() as capture:
            for _ in range(100):
                launch()
        costs[name] = 1e3 / 100 * ms_per_frame(lambda frames: [wp.capture_launch(capture.graph) for _ in range(frames)])
    return costs


def profile(sim: Simulator, frames: int = FRAMES) -> dict:
    sim.run(max(20, frames))  # past the start: the swing has begun and the neighbour lists are in use
    return {"step_ms": ms_per_frame(lambda count: [sim.step() for _ in range(count)], frames),
            "run_ms": ms_per_frame(sim.run, frames),
            "replay_ms": ms_per_frame(lambda count: replay(sim, count), frames),
            "kernels": kernel_times(sim),
            "threads_per_particle": sim.plan.threads, "passes": sim.plan.pass_names}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="JSON")
    parser.add_argument("--worlds", type=int, help="the self cloth at 32^2 as this many worlds of a batch")
    parser.add_argument("--solved", action="store_true", help="with --worlds: the limit solved")
    parser.add_argument("--preset", help="a preset cloth of tools/material_step.py instead of the matrix's")
    parser.add_argument("--case", choices=["hang", "sphere"], default="hang")
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--run", default="symplectic:auto", help="INTEGRATOR:SUBSTEPS")
    parser.add_argument("--frames", type=int, default=FRAMES, help="frames a timing")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    results = {"device": wp.get_device("cuda").name}
    world = matrix_scene("self", 32, "symplectic")
    if args.solved:
        world = dataclasses.replace(world, simulation=dataclasses.replace(
            world.simulation, limit_solve="converged"))
    if args.worlds:
        cases = {f"self 32 x {args.worlds} worlds{', limit solved' if args.solved else ''}": lambda: Batch(
            [world] * args.worlds, device="cuda").simulator}
    elif args.preset:
        integrator, substeps = args.run.split(":")
        scene = preset_scene(args.preset, args.case, args.resolution, 10_000, integrator, substeps)
        cases = {f"{scene.name} {args.run}": lambda: Simulator(scene, device="cuda")}
    else:
        cases = {f"{variant} {n}": lambda variant=variant, n=n: Simulator(matrix_scene(variant, n, "symplectic"),
                                                                          device="cuda")
                 for n in (64, 256) for variant in ("springs", "hanging", "sphere", "self")}
    for name, make in cases.items():
        results[name] = row = profile(make(), args.frames)
        print(name, {k: round(v, 3) for k, v in row.items() if k.endswith("_ms")}, flush=True)
    if args.worlds or args.preset:
        top = sorted(row["kernels"].items(), key=lambda kv: -kv[1]["total_ms"])[:15]
        print("\n".join(f"  {v['total_ms']:8.3f} ms {v['count']:6d}x {k}" for k, v in top), flush=True)
    else:
        results["node_us"] = node_costs()
        print("us per graph node", results["node_us"], flush=True)
    with open(args.out, "w") as out:
        json.dump(results, out, indent=1)


if __name__ == "__main__":
    main()
