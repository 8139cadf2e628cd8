"""How each built-in scene's strain-limit solve ends over its full run: the worst edge strain over every
frame, the converged solve's passes a substep (mean, most) and where its worst solve ended, in tolerances
(at most 1: every solve within tolerance; more: some reached the cap). The README's claim about the
built-in scenes' solves is read from these records (tests/test_docs_match_program.py). ``--frames N`` measures the first N frames only, ``--check`` adds
the most crossing triangle pairs in a frame and the closest contact (of the contact distance).

    python tools/builtin_solves.py --device cpu --out docs/results/builtin-solves-cpu.jsonl [SCENE ...]
"""

from __future__ import annotations

import argparse
import io
import json
import platform
import sys
import time
from pathlib import Path

import warp as wp

import warp_cloth as wc
from warp_cloth.diagnostics import CheckReport
from warp_cloth.lab.bench import environment


def measure(name: str, device: str, frames: int | None = None, check: bool = False) -> dict:
    scene = wc.load_scene(name)
    sim = wc.Simulator(scene, device=device)
    strain = wc.StrainMonitor()
    checks = CheckReport(io.StringIO()) if check else None
    started = time.perf_counter()
    sim.run(frames, writers=[strain] + ([checks] if checks else []))
    seconds = time.perf_counter() - started
    report, stats = strain.report(), sim.solver_stats(since_start=True)
    crossings = {"crossings": checks.worst_intersections[0], "closest_contact":
                 checks.closest_contact[0] if checks.closest_contact else None} if checks else {}
    solved = stats is not None and stats.limit_solves
    return {"scene": name, "device": wp.get_device(device).name, "frames": report.frames,
            "substeps_per_frame": sim.substeps_per_frame, "stretch": report.stretch,
            "compression": report.compression, "limit_solve": scene.simulation.limit_solve,
            "limit_passes_mean": stats.limit_mean_passes if solved else None,
            "limit_passes_most": stats.limit_passes if solved else None,
            "limit_residual": stats.limit_residual if solved else None, **crossings, "seconds": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", help="built-in scenes (default: every one with a strain limit)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--frames", type=int, help="the first FRAMES frames only (default: the scene's run)")
    parser.add_argument("--check", action="store_true",
                        help="also count crossing triangle pairs and the closest contact every frame (slower)")
    parser.add_argument("--out", type=Path, required=True, help="JSON lines, one a scene (appended)")
    parser.add_argument("--commit", help="the commit measured (default: git's HEAD, or WARP_CLOTH_COMMIT)")
    args = parser.parse_args()
    names = args.scenes or [n for n in wc.builtin_scene_names()
                            if any(c.limit is not None for c in wc.load_scene(n).cloths)]
    commit = args.commit or environment(args.device)["commit"]  # git's, or WARP_CLOTH_COMMIT where no .git travels
    versions = {"warp": wp.config.version, "python": platform.python_version(), "commit": commit}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    print(f"{'scene':<18} {'frames':>6} {'stretch':>8} {'compress':>8} {'passes':>8} {'most':>6} {'ended':>7} {'s':>7}" + ("  crossings closest" if args.check else ""))
    for name in names:
        row = {**measure(name, args.device, args.frames, args.check), **versions}
        with open(args.out, "a") as handle:
            handle.write(json.dumps(row) + "\n")
        ended = "" if row["limit_residual"] is None else f"{row['limit_residual']:.2f}"
        passes = "" if row["limit_passes_mean"] is None else f"{row['limit_passes_mean']:.1f}"
        print(f"{name:<18} {row['frames']:>6} {100 * row['stretch']:>7.1f}% {100 * row['compression']:>7.1f}% "
              f"{passes:>8} {row['limit_passes_most'] or '':>6} {ended:>7} {row['seconds']:>7.1f}" + (f"  {row['crossings']:>9} {row['closest_contact'] or '':>7}"
              if args.check else ""), flush=True)
    print(f"builtin_solves: {len(names)} scenes on {args.device}; wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
