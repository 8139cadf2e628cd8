"""The converged limit solve by rounds of line solves (``lab_hooks(line_solve=True)``, plain or with
Chebyshev's acceleration; ``lines-segments``: the same a thread a segment of 32 springs; ``lines-held-all``:
every spring of a line held and one linearised step a round, as before the 256^2 stall was explained) against
the default (Jacobi passes in pairs, Chebyshev with its estimated radius), back to back on the speed matrix's
sphere cloth (symplectic, 10 substeps a frame): the worst edge strain over every frame (stretch and
compression, structural and shear), passes (for the line solve, rounds) a substep on average and at most,
frames with a solve at the cap, and the wall time. ``--cloth triangles`` (or ``quads``): the same cloth read
from an OBJ of each quad as two triangles (or of its quads), whose lines are a mesh's (warp_cloth/
cloth_lines.py). ``--variant self``: the speed matrix's self-collision cloth instead (the same cloth with
particle collision, whose converged solve projects the contacts with the limits: by default jointly, then
sequentially; with line rounds, each round's separating pass after it, warp_cloth/plan.py), which adds the
closest contact (a fraction of the contact distance, 1.0: no overlap) and the most crossing triangle pairs at
a frame's end (warp_cloth/diagnostics.py, as tools/contact_quality.py and ``warp-cloth run --check`` count
them). ``--bounds``: each run also with the lab's displacement bounds (warp_cloth/displacement_bounds.py;
``off``, ``on`` or ``radius=R,gamma=G,rounds=K``), which adds the particles they held short a substep.

    python tools/line_solve_probe.py OUT.json [--sizes 32 64 128] [--methods jacobi lines ...] [--frames 48]
        [--cloth grid triangles quads] [--variant sphere self] [--bounds off on ...]

docs/notebook/strain-solve.md ("Held line solves in dynamics") quotes its output on this project's CPU."""

import argparse
import dataclasses
import json
import time

import numpy as np
import warp as wp

import warp_cloth as wc
from warp_cloth.lab.bench import environment, matrix_scene
from warp_cloth.diagnostics import TriangleIntersections
from warp_cloth.displacement_bounds import BoundSettings
from warp_cloth.displacement_bounds import lab_hooks as bound_hooks
from warp_cloth.lab.bench_meshes import as_mesh_cloth
from warp_cloth.limit_solve import lab_hooks

# method: the hooks its simulator is built with
METHODS = {"jacobi": {}, "lines": {"line_solve": True, "chebyshev_rho": 0.0},
           "lines+chebyshev": {"line_solve": True},
           "lines-segments": {"line_solve": True, "chebyshev_rho": 0.0, "line_segment": 32},
           "lines-held-all": {"line_solve": True, "chebyshev_rho": 0.0, "line_hold_margin": 1.0,
                              "line_newton_steps": 1}}


def measure(n: int, method: str, frames: int, cap: int, device: str, cloth: str = "grid",
            variant: str = "sphere", bounds: str = "off") -> dict:
    scene = matrix_scene(variant, n, "symplectic")
    if cloth != "grid":
        scene = as_mesh_cloth(scene, triangles=cloth == "triangles")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_max_passes=cap))
    with lab_hooks(**METHODS[method]), bound_hooks(BoundSettings.parse(bounds)):
        sim = wc.Simulator(scene, device=device)
    edges, rest = sim.model.edges, sim.model.edge_rest
    stretch = compression = 0.0
    most, passes, solves, capped, seconds = 0, 0.0, 0, 0, 0.0
    stable = True
    crossings = TriangleIntersections(sim) if scene.collision is not None else None
    closest, most_crossings, held_short = float("inf"), 0, 0
    sim.prepare()  # compiles before the clock starts
    sim.solver_stats()
    for _ in range(frames):
        started = time.perf_counter()
        try:
            sim.step()
        except wc.UnstableSimulation:
            stable = False
            break
        wp.synchronize_device(sim.device)
        seconds += time.perf_counter() - started
        stats = sim.solver_stats()
        most = max(most, stats.limit_passes)
        passes += stats.limit_mean_passes * stats.limit_solves
        solves += stats.limit_solves
        capped += stats.limit_passes >= cap
        if sim.plan.bounds is not None:
            held_short += sim.plan.bounds.read_stats()[0][-1]
        x = sim.positions()
        strain = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1) / rest - 1.0
        stretch, compression = max(stretch, float(strain.max())), max(compression, float(-strain.min()))
        if crossings is not None:
            closest, most_crossings = min(closest, sim.closest_contact()), max(most_crossings, crossings(sim))
    contacts = {} if crossings is None else {"closest_contact": round(closest, 4), "most_crossings": most_crossings}
    if sim.plan.bounds is not None:
        contacts |= {"bounds": bounds, "held_short_a_substep": round(held_short / max(solves, 1), 1)}
    return {"n": n, "variant": variant, "cloth": cloth, "method": method, "frames": frames, "cap": cap,
            "stable": stable, "stretch": round(stretch, 4), "compression": round(compression, 4),
            "mean_passes": round(passes / max(solves, 1), 2), "most_passes": most, "frames_capped": capped,
            "seconds": round(seconds, 2), **contacts}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 128])
    parser.add_argument("--methods", nargs="+", choices=list(METHODS), default=list(METHODS))
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--cap", type=int, default=200)
    parser.add_argument("--cloth", nargs="+", choices=["grid", "triangles", "quads"], default=["grid"])
    parser.add_argument("--variant", choices=["sphere", "self"], default="sphere")
    parser.add_argument("--bounds", nargs="+", default=["off"])
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    rows = []
    for n in args.sizes:
        for cloth in args.cloth:
            for method, bounds in ((m, b) for m in args.methods for b in args.bounds):
                rows.append(measure(n, method, args.frames, args.cap, args.device, cloth, args.variant, bounds))
                print(rows[-1], flush=True)
                json.dump({"environment": environment(args.device), "rows": rows}, open(args.out, "w"), indent=1)


if __name__ == "__main__":
    main()
