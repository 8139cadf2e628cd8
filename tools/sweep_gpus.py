"""A sweep's throughput by the GPUs it runs on: the same sweep of the speed matrix's sphere cloth (n x n
particles swinging onto a sphere, 10 substeps a frame, 10% limit, the default converged limit solve) run by ``warp-cloth sweep`` on one GPU
without Ray, then with ``--cluster local`` on the first 1, 2, ... GPUs of this host (each run a fresh
process seeing only those GPUs through ``CUDA_VISIBLE_DEVICES``, its time the whole command's: Ray's start
and each worker's kernel loads counted, after an untimed one-frame sweep has compiled them). Throughput is variant-frames a second; each row carries the worst
edge strain over every frame and variant that the sweep's table reports, so that speed is read with the
quality it was bought at.

    python tools/sweep_gpus.py OUT.json [--gpus 1 2] [--n 512] [--variants 16] [--worlds 2] [--frames 48]

docs/benchmarks.md ("A sweep over several GPUs") quotes it.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import warp as wp

from warp_cloth.lab.bench import environment, matrix_scene

def sphere_cloth_toml(n: int) -> tuple[str, float]:
    """The speed matrix's sphere cloth (``matrix_scene("sphere", n, "symplectic")``) as a scene file, and its
    bend stiffness, which the sweep varies."""
    scene = matrix_scene("sphere", n, "symplectic")
    cloth, sphere, simulation = scene.cloths[0], scene.spheres[0], scene.simulation
    spring = cloth.structural
    springs = f"{{ stiffness = {spring.stiffness!r}, damping = {spring.damping!r} }}"
    return f"""description = "The speed matrix's sphere cloth at {n}x{n}"
[simulation]
fps = {simulation.fps}
frames = {simulation.frames}
substeps = {simulation.substeps}
integrator = "{simulation.integrator}"

[[sphere]]
name = "{sphere.name}"
center = {list(sphere.center)!r}
radius = {sphere.radius!r}

[[cloth]]
name = "cloth"
resolution = {list(cloth.resolution)!r}
size = {list(cloth.size)!r}
orientation = "{cloth.orientation}"
origin = {list(cloth.origin)!r}
rotation = {list(cloth.rotation)!r}
mass = {cloth.mass!r}
limit = {{ stretch = {cloth.limit.stretch!r}, compression = {cloth.limit.compression!r}, attachments = true }}
structural = {springs}
shear = {springs}
bend = {{ stiffness = {cloth.bend.stiffness!r}, damping = {cloth.bend.damping!r}, acts = "compression", \
damping_acts = "compression" }}

[[cloth.pins]]
edges = ["top"]
""", cloth.bend.stiffness


def run_sweep(scene: Path, base: float, out: Path, gpus: int, cluster: bool, args: argparse.Namespace) -> dict:
    values = ",".join(repr(base * (1.0 + 0.1 * k)) for k in range(args.variants))
    command = [sys.executable, "-m", "warp_cloth", "sweep", str(scene), "--set", f"cloth.bend.stiffness={values}",
               "--frames", str(args.frames), "--worlds", str(args.worlds), "--no-usd", "--out", str(out)]
    if cluster:
        command += ["--cluster", "local"]
    env = {**os.environ, "CUDA_VISIBLE_DEVICES": ",".join(str(g) for g in range(gpus))}
    started = time.perf_counter()
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if result.returncode != 0:
        raise SystemExit(f"sweep failed ({result.returncode}): {result.stderr.strip()[-2000:]}")
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    frames = args.variants * args.frames
    return {"how": "--cluster local" if cluster else "local", "gpus": gpus, "n": args.n, "variants": len(rows),
            "frames": args.frames, "worlds_a_batch": args.worlds, "batches": round(sum(1 / r["batch_worlds"] for r in rows)),
            "seconds": round(seconds, 2), "variant_frames_per_s": round(frames / seconds, 2),
            "median_batch_s": round(statistics.median(r["batch_seconds"] for r in rows), 3),
            "stretch": round(max(r["stretch"] for r in rows), 4),
            "compression": round(max(r["compression"] for r in rows), 4),
            "blew_up": sum(r["unstable_frame"] is not None for r in rows),
            "summary": result.stdout.strip().splitlines()[-1]}


def format_table(rows: list[dict]) -> str:
    base = rows[0]["variant_frames_per_s"]
    header = f"{'how':<16} {'gpus':>4} {'batches':>7} {'seconds':>8} {'variant-frames/s':>16} {'vs first':>8} " \
             f"{'stretch':>8} {'compression':>11}"
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(f"{r['how']:<16} {r['gpus']:>4} {r['batches']:>7} {r['seconds']:>8.1f} "
                     f"{r['variant_frames_per_s']:>16.2f} {r['variant_frames_per_s'] / base:>7.2f}x "
                     f"{r['stretch']:>+8.2%} {r['compression']:>11.2%}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--gpus", type=int, nargs="+", default=[1, 2], help="GPU counts to run --cluster local on")
    parser.add_argument("--n", type=int, default=512, help="particles a side")
    parser.add_argument("--variants", type=int, default=16)
    parser.add_argument("--worlds", type=int, default=2, help="most variants a batch")
    parser.add_argument("--frames", type=int, default=48)
    args = parser.parse_args()
    wp.config.quiet = True
    env = environment("cuda" if wp.is_cuda_available() else "cpu")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        scene = Path(folder) / f"sphere_{args.n}.toml"
        text, bend = sphere_cloth_toml(args.n)
        scene.write_text(text)
        warm_up = argparse.Namespace(**{**vars(args), "variants": 1, "frames": 1})
        run_sweep(scene, bend, Path(folder) / "warm-up", 1, False, warm_up)  # compiles: the runs timed load
        runs = [(1, False)] + [(g, True) for g in args.gpus]
        for k, (gpus, cluster) in enumerate(runs):
            rows.append(run_sweep(scene, bend, Path(folder) / f"sweep-{k}", gpus, cluster, args))
            print(f"[{k + 1}/{len(runs)}] {rows[-1]['how']} on {gpus} GPU(s): {rows[-1]['seconds']} s", flush=True)
            args.out.write_text(json.dumps({"environment": env, "rows": rows}, indent=1))  # each run's, as it ends
    print(format_table(rows))
    print(f"sweep_gpus: {len(rows)} sweeps; wrote {args.out}")


if __name__ == "__main__":
    main()
