"""Time per frame and worst edge strain of the speed matrix's cloths, in ours and in Newton's solvers.

    python tools/compare_quality.py OUT.jsonl ITEM...      ITEM = variant:n:engine[:substeps[:worlds]]
    python tools/compare_quality.py OUT.jsonl --equal-quality sphere:256 self:32:1024 [--engines ours
        semi_implicit vbd] [--target 0.11]   each engine from 10 substeps, doubling until it holds the target

variant is hanging, sphere or self; engine is ours (the matrix's fixed 2 limit passes), ours_sequential
(the self rows' collision passes projected sequentially, ``SolveChoices(joint_passes=0)``), ours_METHOD for a method
of tools/strain_solve_probe.py (``ours_chebyshev``: the limit solved, Chebyshev 0.95, at most 400 passes a
substep), semi_implicit, xpbd or vbd; substeps (default 10) sets the step,
the springs stiffening with 1/dt^2 in both engines (``matrix_scene``, newton_compare), and worlds (default
1) runs that many copies, as the worlds of one batch (ours) or of one model (Newton's). Each row is 2 warm-up
frames, then the median of 3 x 48 timed frames (8 for VBD from 1024^2 on), then the strain over every frame
of a second run of as many frames from the start (2 + 3 x 48), on the structural and shear edges, stretch
and compression, for both engines (ours: ``bench.time_case``). Writes one JSON line per row after a line with the environment. Used for
docs/benchmarks.md's strain and equal-quality tables.
"""

import argparse
import json
import time

import warp as wp

from warp_cloth.lab.bench import Case, environment, matrix_scene, time_case
from warp_cloth.lab.newton_compare import time_newton
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from strain_solve_probe import configured

REPEATS = 3
MAX_PASSES = 400
RHO = 0.95


def time_ours(variant: str, n: int, device: str, frames: int, engine: str, substeps: int, worlds: int) -> dict:
    """``bench.time_case`` of the matrix scene so configured (as ``worlds`` copies in one batch)."""
    scene = matrix_scene(variant, n, "symplectic", substeps)
    method = engine.partition("_")[2] or "fixed"
    choices = SolveChoices(joint_passes=0)  # the fixed passes, sequential
    if method != "sequential":
        scene, rho = configured(scene, method, MAX_PASSES, RHO)
        choices = SolveChoices(chebyshev_rho=rho)
    with lab_hooks(choices):
        result = time_case(Case(engine, scene, frames, fresh=False, worlds=worlds), device, REPEATS)
    if not result.stable:
        return {"solver": engine, "variant": variant, "n": n, "worlds": worlds, "substeps": substeps,
                "error": "blew up"}
    return {"solver": engine, "variant": variant, "n": n, "worlds": worlds, "substeps": result.substeps_per_frame,
            "frames": frames, "ms_per_frame": result.ms_per_frame,
            "particle_substeps_per_second": result.particle_substeps_per_second, "max_strain": result.max_strain,
            "stretch": result.strain["stretch"], "compression": result.strain["compression"],
            "strain_frames": result.strain["frames"]}


def measured_row(variant: str, n: int, engine: str, substeps: int, worlds: int, device: str) -> dict:
    """One item's row (an ``error`` key where its engine failed: one failing solver must not lose the others)."""
    frames = 8 if engine == "vbd" and n >= 1024 else 48
    started = time.perf_counter()
    try:
        row = (time_ours(variant, n, device, frames, engine, substeps, worlds) if engine.startswith("ours") else
               time_newton(variant, n, engine, device, frames=frames, substeps=substeps, repeats=REPEATS,
                           worlds=worlds))
    except Exception as error:
        row = {"solver": engine, "variant": variant, "n": n, "substeps": substeps,
               "error": f"{type(error).__name__}: {error}"}
    row["wall_including_build_s"] = time.perf_counter() - started
    return row


def held(row: dict, target: float) -> bool:
    return "error" not in row and row["max_strain"] <= target


def cloth_of(row: dict) -> tuple[str, int, int]:
    return row["variant"], row["n"], row.get("worlds", 1)


def equal_quality(rows: list[dict], target: float) -> list[str]:
    """Each cloth's cheapest row of each engine that holds ``target``, and ours' speed over each."""
    lines = []
    for cloth in dict.fromkeys(map(cloth_of, rows)):
        mine = [r for r in rows if cloth_of(r) == cloth]
        best = {}
        for r in filter(lambda r: held(r, target), mine):
            if r["solver"] not in best or r["ms_per_frame"] < best[r["solver"]]["ms_per_frame"]:
                best[r["solver"]] = r
        ours = min((r for e, r in best.items() if e.startswith("ours")), key=lambda r: r["ms_per_frame"], default=None)
        name = f"{cloth[0]} {cloth[1]}^2 x{cloth[2]}"
        for engine in dict.fromkeys(r["solver"] for r in mine):
            r = best.get(engine)
            if r is None:
                lines.append(f"{name}: {engine} does not hold {target:.1%} at the substeps tried")
                continue
            ratio = f", ours {r['ms_per_frame'] / ours['ms_per_frame']:.1f}x its speed" \
                if ours is not None and not engine.startswith("ours") else ""
            lines.append(f"{name}: {engine} holds {target:.1%} at {r['substeps']} substeps, "
                         f"{r['ms_per_frame']:.3f} ms a frame, +{r['stretch']:.1%} / -{r['compression']:.1%}{ratio}")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", help="JSON lines file, appended to")
    parser.add_argument("items", nargs="*", help="variant:n:engine[:substeps[:worlds]]")
    parser.add_argument("--equal-quality", nargs="+", metavar="VARIANT:N[:WORLDS]",
                        help="for each, every --engines from 10 substeps, doubling until its worst edge holds "
                             "--target (at most --most-substeps); then each engine's cheapest such row")
    parser.add_argument("--engines", nargs="+", default=["ours", "semi_implicit", "vbd"])
    parser.add_argument("--target", type=float, default=0.11)
    parser.add_argument("--most-substeps", type=int, default=640)
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    device = "cuda" if wp.is_cuda_available() else "cpu"
    searches = []
    for item in args.equal_quality or []:
        variant, n, *worlds = item.split(":")
        searches += [(variant, int(n), engine, int(worlds[0]) if worlds else 1) for engine in args.engines]
    rows = []
    with open(args.out, "a") as out:
        print(json.dumps({"environment": environment(device)}), file=out, flush=True)

        def record(row: dict) -> None:
            rows.append(row)
            print(json.dumps(row), file=out, flush=True)
            print(f"{row['variant']}:{row['n']}:{row['solver']}:{row['substeps']}:{row.get('worlds', 1)}: "
                  f"{row.get('ms_per_frame', float('nan')):.3f} ms/frame, worst edge over the run "
                  f"+{row.get('stretch', float('nan')):.3f} / -{row.get('compression', float('nan')):.3f} "
                  f"{row.get('error', '')}", flush=True)

        for item in args.items:
            variant, n, engine, *rest = item.split(":")
            record(measured_row(variant, int(n), engine, int(rest[0]) if rest else 10,
                                int(rest[1]) if len(rest) > 1 else 1, device))
        for variant, n, engine, worlds in searches:
            substeps = 10
            while substeps <= args.most_substeps:
                record(measured_row(variant, n, engine, substeps, worlds, device))
                if held(rows[-1], args.target) or "error" in rows[-1]:
                    break
                substeps *= 2
    if searches:
        print("\n".join(equal_quality(rows, args.target)))


if __name__ == "__main__":
    main()
