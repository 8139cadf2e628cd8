"""Where the speed matrix's sphere cloth spends a frame, kernel by kernel, after ``--skip`` frames stepped
with graphs: one frame launched pass by pass, each kernel's device time on CUDA (Warp's activity timing) or
wall time on the CPU (tools/stacked_drape_kernels.py's timers), with its lines cut into ``--segment``
springs where asked (the lab's ``line_segment``; by default the device's). docs/notebook/strain-solve.md
("Segments as long as the square root of a line") quotes its output.

    python tools/line_solve_kernels.py --n 1024 --skip 30 --device cuda [--segment 16] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses

import warp_cloth as wc
from stacked_drape_kernels import frames_by_kernel, report_kernels
from warp_cloth.lab.bench import MATRIX_SUBSTEPS, matrix_scene
from warp_cloth.limit_solve import SolveChoices, lab_hooks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=256)
    parser.add_argument("--substeps", type=int, default=MATRIX_SUBSTEPS)
    parser.add_argument("--skip", type=int, default=30, help="frames stepped first, with graphs, unmeasured")
    parser.add_argument("--frames", type=int, default=1)
    parser.add_argument("--segment", type=int, default=None, help="springs a segment (default: the device's)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    scene = matrix_scene("sphere", args.n, "symplectic", args.substeps)
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", frames=args.skip + args.frames + 1))
    with lab_hooks(SolveChoices(line_segment=args.segment)):
        sim = wc.Simulator(scene, device=args.device)
    wall, kernels = frames_by_kernel(sim, args.frames, args.skip)
    stats = sim.solver_stats()
    print(f"{args.n}^2, {args.frames} frames after {args.skip}: {wall:.3f} s, rounds a substep "
          f"{stats.limit_mean_passes:.2f} mean, {stats.limit_passes} most")
    report_kernels(args, wall, kernels)


if __name__ == "__main__":
    main()
