"""What the converged limit solve takes: the passes a substep (mean and most) and the worst edge strain
over every frame, for the methods of docs/notebook/strain-solve.md (fixed passes, plain Jacobi, and
Chebyshev-accelerated Jacobi with restarts), on the hanging cloth at one implicit step a frame from 10^2
to 160^2 and on the speed matrix's sphere and self-collision cloths at 64^2.

    python tools/strain_solve_probe.py OUT.json [--device cpu] [--rho-sweep | --contacts | --matrix N ...]
                                                [--methods M ...]

docs/results/strain-solve-cpu.json is its output on this project's CPU. With --rho-sweep it runs instead
Chebyshev at spectral radii 0.95, 0.97 and 0.99 on the 80-row hanging cloth and on seed_default (60
frames, at most 400 passes): docs/results/strain-solve-rho-cpu.json. With --contacts, the fixed passes
against Chebyshev (0.95) (or --methods) on the built-in scenes with particle collision, 72 frames, with the
crossing triangle pairs and the closest contact of every frame: docs/results/strain-solve-contacts-cpu.json.
(The results files' chebyshev+long_range and multilevel rows were made with long-range limits and the
multilevel solve, both retired after e9307d5.) With --matrix N ... (on a GPU) it times the speed
matrix's sphere and self-collision cloths (symplectic; with --integrator implicit, springs 50 times
stiffer) at those sizes over 48 frames after 2 (the swing onto the sphere and the drape), each method in
turn, and measures their strain over a second run of 50 frames."""

import argparse
import dataclasses
import io
import json
import statistics
import time

import warp as wp

import warp_cloth as wc
from warp_cloth.lab.bench import environment, matrix_scene, seconds_of_runs
from warp_cloth.diagnostics import CheckReport
from warp_cloth.limit_solve import SolveChoices, lab_hooks

METHODS = {"fixed": ("fixed", 0.0), "jacobi": ("converged", 0.0), "chebyshev": ("converged", 0.99)}


def configured(scene: wc.Scene, method: str, max_passes: int, rho: float | None = None) -> tuple[wc.Scene, float]:
    """The scene with the method's solve and cap, and the Chebyshev radius to build its simulator with
    (``limit_solve.lab_hooks``)."""
    solve, default_rho = METHODS[method]
    rho = default_rho if rho is None or not default_rho else rho  # plain Jacobi stays plain
    return dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve=solve, limit_max_passes=max_passes)), rho


def hanging(n: int) -> wc.Scene:
    scene = wc.load_scene("hanging")
    cloth = scene.cloths[0]
    cloth = dataclasses.replace(cloth, resolution=(n, n), mass=cloth.mass * 100 / (n * n))
    return dataclasses.replace(scene, name=f"hanging_{n}", cloths=(cloth,), simulation=dataclasses.replace(
        scene.simulation, integrator="implicit", dt=0.04165, substeps=None))


def measure(scene: wc.Scene, frames: int, device: str) -> dict:
    sim = wc.Simulator(scene, device=device)
    monitor = wc.StrainMonitor()
    started = time.perf_counter()
    try:
        sim.run(frames, writers=[monitor])
        stable = True
    except wc.UnstableSimulation:
        stable = False
    seconds = time.perf_counter() - started
    stats, report = sim.solver_stats(), monitor.report()
    return {"seconds": round(seconds, 2), "stable": stable, "stretch": report.stretch, "compression": report.compression,
            "passes": stats.limit_passes if stats and stats.limit_passes is not None else None,
            "mean_passes": round(stats.limit_mean_passes, 2) if stats and stats.limit_passes is not None else None,
            "residual": stats.limit_residual if stats and stats.limit_residual is not None else None,
            "closest_contact": sim.closest_contact()}


def timed(scene: wc.Scene, frames: int, device: str, repeats: int) -> dict:
    """Milliseconds a frame (median of ``repeats`` runs of ``frames`` after 2), the passes the solve took
    over them, then the strain over every frame of a fresh run of 2 + ``frames`` frames."""
    sim = wc.Simulator(scene, device=device)
    try:
        sim.run(2)
        sim.solver_stats()
        seconds = seconds_of_runs(sim, frames, repeats)
    except wc.UnstableSimulation:
        return {"stable": False}
    stats = sim.solver_stats()
    converged = stats is not None and stats.limit_passes is not None
    row = {"stable": True, "ms_per_frame": round(1e3 * statistics.median(seconds) / frames, 4),
           "passes": stats.limit_passes if converged else None,
           "mean_passes": round(stats.limit_mean_passes, 2) if converged else None,
           "residual": stats.limit_residual if converged else None}
    strain = measure(scene, 2 + frames, device)
    return {**row, "stretch": strain["stretch"], "compression": strain["compression"],
            "strain_run_stable": strain["stable"], "closest_contact": strain["closest_contact"]}


def contacts(scene: wc.Scene, frames: int, device: str) -> dict:
    """The worst strain, crossing triangle pairs and closest contact over every frame."""
    sim = wc.Simulator(scene, device=device)
    monitor = wc.StrainMonitor()
    check = CheckReport(io.StringIO(), monitor)
    sim.run(frames, writers=[monitor, check])
    stats, report = sim.solver_stats(), monitor.report()
    return {"stretch": report.stretch, "compression": report.compression,
            "passes": stats.limit_passes if stats and stats.limit_passes is not None else None,
            "mean_passes": round(stats.limit_mean_passes, 2) if stats and stats.limit_passes is not None else None,
            "residual": stats.limit_residual if stats and stats.limit_passes is not None else None,
            "crossings": check.worst_intersections[0], "closest_contact": check.closest_contact[0]}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--rho-sweep", action="store_true")
    parser.add_argument("--contacts", action="store_true")
    parser.add_argument("--matrix", type=int, nargs="+")
    parser.add_argument("--methods", nargs="+", choices=list(METHODS))
    parser.add_argument("--rho", type=float, default=None)
    parser.add_argument("--cap", type=int, default=400)
    parser.add_argument("--integrator", default="symplectic", choices=["symplectic", "implicit"])
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    if args.matrix:
        rows = []
        for n in args.matrix:
            for variant in ("sphere", "self"):
                for method in args.methods or list(METHODS):
                    scene, rho = configured(matrix_scene(variant, n, args.integrator), method, args.cap, args.rho)
                    with lab_hooks(SolveChoices(chebyshev_rho=rho)):
                        row = {"scene": scene.name, "method": method, "rho": rho,
                               "cap": args.cap, **timed(scene, 48, args.device, 3 if n <= 256 else 1)}
                    rows.append(row)
                    print(row, flush=True)
                    json.dump({"environment": environment(args.device), "rows": rows}, open(args.out, "w"), indent=1)
        return
    if args.contacts:
        rows = []
        for name in ("seed_default", "pile", "fold"):
            chosen = [(m, None) for m in args.methods] if args.methods else [("fixed", None),
                                                                              ("chebyshev", 0.95)]
            for method, rho in chosen:
                scene, radius = configured(wc.load_scene(name), method, 400, rho)
                with lab_hooks(SolveChoices(chebyshev_rho=radius)):
                    row = {"scene": name, "frames": 72, "method": method, "rho": rho,
                           **contacts(scene, 72, args.device)}
                rows.append(row)
                print(row, flush=True)
        json.dump({"environment": environment(args.device), "rows": rows}, open(args.out, "w"), indent=1)
        return
    if args.rho_sweep:
        cases = [(scene, frames, "chebyshev", rho, cap) for scene, frames, cap in
                 ((hanging(80), 24, 1000), (wc.load_scene("seed_default"), 60, 400)) for rho in (0.95, 0.97, 0.99)]
    else:
        cases = [(hanging(n), 24, m, None, 1000) for n in (10, 20, 40, 80) for m in METHODS
                 if not (n == 80 and m == "jacobi")]
        cases += [(hanging(160), 24, m, None, 1000) for m in ("fixed", "chebyshev")]
        cases += [(matrix_scene(v, 64, "symplectic"), 60, m, None, 1000) for v in ("sphere", "self") for m in METHODS]
    rows = []
    for scene, frames, method, rho, cap in cases:
        scene, radius = configured(scene, method, cap, rho)
        with lab_hooks(SolveChoices(chebyshev_rho=radius)):
            row = {"scene": scene.name, "frames": frames, "method": method,
                   "rho": METHODS[method][1] if rho is None else rho, **measure(scene, frames, args.device)}
        rows.append(row)
        print(row, flush=True)
    json.dump({"environment": environment(args.device), "rows": rows}, open(args.out, "w"), indent=1)


if __name__ == "__main__":
    main()
