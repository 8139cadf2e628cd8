"""What a preset cloth's step costs under each integrator (issue 35: a realistic fabric at tens of substeps a
frame, its limit held): a 2 m square of a fabric preset, hung by its two top corners (``hang``) or dropped
flat from 0.6 m onto a 0.5 m sphere (``sphere``), strain limit 10% / 10%, 24 fps, run under each
``INTEGRATOR:SUBSTEPS`` asked for (``auto``: the simulator chooses). Prints a table and writes JSON lines:
substeps a frame, the worst edge strain over every frame (stretch, compression), the limit solve's passes
and CG iterations a substep, milliseconds a frame (the run's clock, kernels loaded before it) and the device,
versions and commit.

    python tools/material_step.py --device cuda --resolution 128 --frames 12 --out OUT.jsonl \
        --presets cotton denim --cases hang sphere --runs symplectic:auto implicit:auto implicit:20
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import warp_cloth as wc
from warp_cloth.lab.bench import environment


def preset_scene(preset: str, case: str, resolution: int, frames: int, integrator: str, substeps: str) -> wc.Scene:
    limit = wc.Limit(stretch=0.1, compression=0.1)
    material = wc.Material(preset=preset)
    if case == "hang":
        cloth = wc.Cloth(resolution=(resolution, resolution), size=(2.0, 2.0), orientation="vertical",
                         origin=(-1.0, 0.0, 0.0), material=material, limit=limit,
                         pins=(wc.Pin(corners=("top-left", "top-right")),))
        spheres = ()
    else:
        cloth = wc.Cloth(resolution=(resolution, resolution), size=(2.0, 2.0), orientation="horizontal",
                         origin=(-1.0, 1.6, 1.0), material=material, limit=limit)
        spheres = (wc.Sphere(center=(0.0, 1.0, 0.0), radius=0.5),)
    simulation = wc.Simulation(fps=24, frames=frames, integrator=integrator,
                               substeps="auto" if substeps == "auto" else int(substeps))
    return wc.Scene(name=f"{preset}_{case}_{resolution}", cloths=(cloth,), spheres=spheres, simulation=simulation)


def measure(scene: wc.Scene, device: str) -> dict:
    sim = wc.Simulator(scene, device=device)
    strain = wc.StrainMonitor()
    summary = sim.run(scene.simulation.frames, writers=[strain])
    report, stats = strain.report(), sim.solver_stats(since_start=True)
    per_frame = list(summary.frame_substeps) or [sim.substeps_per_frame] * summary.frames
    return {"scene": scene.name, "integrator": scene.simulation.integrator, "substeps_asked": scene.simulation.substeps,
            "frame_substeps": per_frame, "frames": summary.frames, "stretch": report.stretch,
            "compression": report.compression,
            "limit_passes_mean": stats.limit_mean_passes if stats and stats.limit_solves else None,
            "limit_passes_most": stats.limit_passes if stats and stats.limit_solves else None,
            "limit_residual": stats.limit_residual if stats and stats.limit_solves else None,
            "cg_most": stats.cg_iterations if stats else None,
            "ms_per_frame": 1000.0 * summary.wall_seconds / max(summary.frames, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--presets", nargs="+", default=["cotton", "denim", "polyester", "jersey"])
    parser.add_argument("--cases", nargs="+", choices=["hang", "sphere"], default=["hang", "sphere"])
    parser.add_argument("--runs", nargs="+", default=["symplectic:auto", "implicit:auto"],
                        help="INTEGRATOR:SUBSTEPS, SUBSTEPS a count a frame or auto")
    parser.add_argument("--resolution", type=int, default=40)
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, required=True, help="JSON lines, one a run (appended)")
    args = parser.parse_args()
    versions = environment(args.device)  # the commit from git, or WARP_CLOTH_COMMIT where the tree has no .git
    args.out.parent.mkdir(parents=True, exist_ok=True)
    print(f"{'scene':<20} {'integrator':<10} {'substeps (min/med/max)':>22} {'stretch':>8} {'compress':>8} "
          f"{'passes':>7} {'most':>5} {'CG':>4} {'ms/frame':>9}", flush=True)
    count = 0
    for preset in args.presets:
        for case in args.cases:
            for run in args.runs:
                integrator, substeps = run.split(":")
                row = {**measure(preset_scene(preset, case, args.resolution, args.frames, integrator, substeps),
                                 args.device), "preset": preset, "case": case, "resolution": args.resolution,
                       **versions}
                with open(args.out, "a") as handle:
                    handle.write(json.dumps(row) + "\n")
                count += 1
                counts = sorted(row["frame_substeps"])
                spread = f"{counts[0]}/{counts[len(counts) // 2]}/{counts[-1]}"
                passes = "" if row["limit_passes_mean"] is None else f"{row['limit_passes_mean']:.1f}"
                print(f"{row['scene']:<20} {integrator:<10} {spread:>22} {100 * row['stretch']:>7.2f}% "
                      f"{100 * row['compression']:>7.2f}% {passes:>7} {row['limit_passes_most'] or '':>5} "
                      f"{row['cg_most'] or '':>4} {row['ms_per_frame']:>9.1f}", flush=True)
    print(f"material_step: {count} runs on {versions['device']}; wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
