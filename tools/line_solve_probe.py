"""The converged limit solve by rounds of line solves (``default``: as the simulator builds it; ``lines``: a
thread a whole line on any device, plain, and with particle collision line rounds too; ``lines-segments``: the same a thread a segment
of 32 springs, each in the device's layout (CUDA: interleaved; CPU: contiguous); ``lines-segments-contiguous``
and ``-interleaved``: either layout on any device; ``lines-held-all``: every spring of a line held and one
linearised step a round, as before the 256^2 stall was explained) and ``jacobi`` (Jacobi passes in pairs alone,
Chebyshev with its estimated radius), back to back on the speed matrix's
sphere cloth (symplectic, 10 substeps a frame): the worst edge strain over every frame (stretch and
compression, structural and shear), passes (for the line solve, rounds) a substep on average and at most,
frames with a solve at the cap, and the wall time. ``--cloth triangles`` (or ``quads``): the same cloth read
from an OBJ of each quad as two triangles (or of its quads), whose lines are a mesh's (warp_cloth/
cloth_lines.py). ``--variant self``: the speed matrix's self-collision cloth instead (the same cloth with
particle collision, whose converged solve projects the contacts with the limits: by default jointly, then
sequentially; with line rounds, each round's separating pass after it, warp_cloth/plan.py), which adds the
closest contact (a fraction of the contact distance, 1.0: no overlap) and the most crossing triangle pairs at
a frame's end (warp_cloth/diagnostics.py, as tools/contact_quality.py and ``warp-cloth run --check`` count
them). ``--scenes``: built-in scenes instead, each as ``warp-cloth run NAME`` loads it (its own step, substeps
auto where it sets none, and cap), which add the substeps a frame (min, median, max; frames made again) and
count a limited spring's strain only (a cloth's structural and shear springs where it has a limit; bend
springs never are, which each row checks); ``--scene-frames NAME=N`` runs that scene for N frames instead;
``--repeats R`` runs a scene's methods in turn R times and keeps each one's least wall and CPU times.
``--substeps``: the matrix runs at each of these substeps a frame (its springs as stiff as each step allows).
``--segments``: the matrix runs with their lines cut into segments of each of these springs (the lab's
``line_segment``; by default the device's, warp_cloth/line_solve.py's segment_for_device on CUDA).
``--bounds``: each matrix run also with the lab's displacement bounds (warp_cloth/displacement_bounds.py;
``off``, ``on`` or ``radius=R,gamma=G,rounds=K``), which adds the particles they held short a substep.

    python tools/line_solve_probe.py OUT.json [--sizes 32 64 128] [--methods jacobi lines ...] [--frames 48]
        [--cloth grid triangles quads] [--variant sphere self] [--bounds off on ...] [--substeps 10 40]
        [--segments 8 16 32]
    python tools/line_solve_probe.py OUT.json --scenes NAME ... [--methods ...] [--frames 48]
        [--scene-frames seed_default=12] [--repeats 3]

docs/notebook/strain-solve.md ("Held line solves in dynamics", "Line solves on the built-in scenes") quotes its
output on this project's CPU."""

import argparse
import dataclasses
import json
import os
import statistics
import time

import numpy as np
import warp as wp

import warp_cloth as wc
from warp_cloth.lab.bench import MATRIX_SUBSTEPS, environment, matrix_scene
from warp_cloth.diagnostics import TriangleIntersections
from warp_cloth.displacement_bounds import BoundSettings
from warp_cloth.displacement_bounds import lab_hooks as bound_hooks
from warp_cloth.lab.bench_meshes import as_mesh_cloth
from warp_cloth.cloth_mesh import BEND
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from warp_cloth.stability import at_substeps

WHOLE_LINES = 1 << 30  # a segment longer than any line (the layout keeps only the longest's slots)
# method: the solver's choices its simulator is built with
LINES = SolveChoices(line_solve=True, line_contacts=True, chebyshev_rho=0.0, line_segment=WHOLE_LINES)
METHODS = {"default": SolveChoices(), "jacobi": SolveChoices(line_solve=False), "lines": LINES,
           "lines-segments": dataclasses.replace(LINES, line_segment=32),
           "lines-segments-contiguous": dataclasses.replace(LINES, line_segment=32, line_interleaved=False),
           "lines-segments-interleaved": dataclasses.replace(LINES, line_segment=32, line_interleaved=True),
           "lines-held-all": dataclasses.replace(LINES, line_hold_margin=1.0, line_newton_steps=1)}


def measure(n: int, method: str, frames: int, cap: int, device: str, cloth: str = "grid",
            variant: str = "sphere", bounds: str = "off", substeps: int = MATRIX_SUBSTEPS,
            segment: int | None = None) -> dict:
    """The speed matrix's cloth at ``n``^2 (``variant``, as a grid or a ``cloth`` mesh) at ``substeps`` a frame
    (its springs as stiff as that step allows) and ``cap`` rounds, with the displacement ``bounds``
    (BoundSettings.parse's), its lines cut into segments of ``segment`` springs (None: as the method has it)."""
    scene = matrix_scene(variant, n, "symplectic", substeps)
    if cloth != "grid":
        scene = as_mesh_cloth(scene, triangles=cloth == "triangles")
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_max_passes=cap))
    return {"n": n, "variant": variant, "cloth": cloth, "method": method, "frames": frames, "cap": cap,
            "frame_substeps": substeps, "segment": segment,
            **measure_run(scene, method, frames, device, bounds, segment)}


def measure_scene(name: str, method: str, frames: int, device: str) -> dict:
    """A built-in scene as ``warp-cloth run NAME --frames FRAMES`` loads it, with its own step and cap."""
    scene = wc.load_scene(name)
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, frames=frames))
    return {"scene": name, "method": method, "frames": frames, **measure_run(scene, method, frames, device)}


def limited_springs(model) -> tuple[np.ndarray, np.ndarray, bool]:
    """The springs a strain limit bounds (structural and shear where a cloth has a limit), their rest
    lengths, and whether any of them is a bend spring."""
    springs = model.springs
    if springs is None:
        return np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=np.float32), False
    limited = np.isfinite(springs.limit_max)
    return springs.pairs[limited], springs.rest[limited], bool(np.any(springs.kind[limited] == BEND))


def cap_of_frame(sim: wc.Simulator) -> int:
    """The cap on the limit solve's passes (rounds) of the frame just kept (with substeps auto, fitted to
    that frame's substeps, as the simulator fits it)."""
    if sim.auto is None:
        return sim.limit_solve.max_passes
    return at_substeps(sim.scene, sim.frame_substeps).simulation.limit_max_passes


def measure_run(scene: wc.Scene, method: str, frames: int, device: str, bounds: str = "off",
                segment: int | None = None) -> dict:
    """``frames`` frames of ``scene`` under ``method``'s hooks: the worst strain of a limited spring over
    every frame (the start's included), the solve's passes (rounds) a substep, frames with a solve at the
    cap, substeps a frame, the wall time of the frames (kernels loaded before) and the process's CPU time in
    them (on a CPU shared with other work, steadier than the wall time; the machine's load, the 1-minute
    average as the run starts, says how shared), and with particle collision the closest contact and the
    most crossing triangle pairs at a frame's end; with ``bounds`` on, the particles they held short a
    substep on average. A scene the simulator refuses, or a run that blows up, is a row too."""
    load = round(os.getloadavg()[0], 2)
    try:
        choices = METHODS[method] if segment is None else dataclasses.replace(METHODS[method], line_segment=segment)
        with lab_hooks(choices), bound_hooks(BoundSettings.parse(bounds)):
            sim = wc.Simulator(scene, device=device)
    except wc.SceneError as exc:
        return {"stable": None, "refused": str(exc), "load_average": load}
    pairs, rest, bend_limited = limited_springs(sim.model)
    stretch = compression = 0.0
    most, passes, solves, capped, residual, seconds, cpu_seconds = 0, 0.0, 0, 0, 0.0, 0.0, 0.0
    substeps: list[int] = []
    stable, failure = True, None
    crossings = TriangleIntersections(sim) if scene.collision is not None else None
    closest, most_crossings, held_short = float("inf"), 0, 0

    def measure_frame() -> None:
        nonlocal stretch, compression, closest, most_crossings
        x = sim.positions()
        if len(pairs):
            strain = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1) / rest - 1.0
            stretch, compression = max(stretch, float(strain.max())), max(compression, float(-strain.min()))
        if crossings is not None:
            closest, most_crossings = min(closest, sim.closest_contact()), max(most_crossings, crossings(sim))

    sim.prepare()  # compiles before the clock starts
    sim.solver_stats()
    measure_frame()
    made_again = 0  # substeps of frames made again with more (substeps auto)
    for _ in range(frames):
        substeps_before = sim.substeps_run
        started, cpu_started = time.perf_counter(), time.process_time()
        try:
            sim.step()
        except wc.UnstableSimulation as exc:
            stable, failure = False, str(exc)
            break
        wp.synchronize_device(sim.device)
        seconds += time.perf_counter() - started
        cpu_seconds += time.process_time() - cpu_started
        substeps.append(sim.frame_substeps)
        made_again += sim.substeps_run - substeps_before - sim.frame_substeps
        stats = sim.solver_stats()
        if stats is not None and stats.limit_solves:
            most = max(most, stats.limit_passes)
            passes += stats.limit_mean_passes * stats.limit_solves
            solves += stats.limit_solves
            capped += stats.limit_passes >= cap_of_frame(sim)
            residual = max(residual, stats.limit_residual)
        if sim.plan.bounds is not None:
            held_short += sim.plan.bounds.read_stats().held_short[-1]
        measure_frame()
    contacts = {} if crossings is None else {"closest_contact": round(closest, 4), "most_crossings": most_crossings}
    if sim.plan.bounds is not None:
        contacts |= {"bounds": bounds, "held_short_a_substep": round(held_short / max(solves, 1), 1)}
    return {"stable": stable, **({"failure": failure} if failure else {}), "frames_run": len(substeps),
            "limited_springs": len(pairs), "bend_limited": bend_limited,
            "stretch": round(stretch, 4), "compression": round(compression, 4),
            "mean_passes": round(passes / max(solves, 1), 2), "most_passes": most, "frames_capped": capped,
            "worst_residual": round(residual, 3), "auto_substeps": sim.auto is not None,
            "substeps": {"min": min(substeps, default=None), "median": statistics.median(substeps) if substeps
                         else None, "max": max(substeps, default=None), "made_again": made_again},
            "seconds": round(seconds, 2), "cpu_seconds": round(cpu_seconds, 2), "load_average": load, **contacts}


def fastest(runs: tuple[dict, ...]) -> dict:
    """One row of repeated runs of a method (their motion the same: the CPU's runs are deterministic): the
    least wall and CPU times, with every run's."""
    row = dict(runs[0])
    if len(runs) > 1 and runs[0].get("refused") is None:
        for key in ("seconds", "cpu_seconds"):
            row[key] = min(r[key] for r in runs)
            row[f"{key}_each"] = [r[key] for r in runs]
        row["load_average_each"] = [r["load_average"] for r in runs]
    return row


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
    parser.add_argument("--scenes", nargs="+", metavar="NAME", help="built-in scenes instead of the matrix cloth")
    parser.add_argument("--scene-frames", nargs="+", default=[], metavar="NAME=N",
                        help="with --scenes: frames for the scenes named, instead of --frames")
    parser.add_argument("--bounds", nargs="+", default=["off"], help="the matrix runs' displacement bounds")
    parser.add_argument("--substeps", type=int, nargs="+", default=[MATRIX_SUBSTEPS],
                        help="the matrix runs' substeps a frame (the springs stiffen with the step)")
    parser.add_argument("--segments", type=int, nargs="+", default=[None],
                        help="the matrix runs' line segments, springs (default: as each method has them)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="with --scenes: each scene's methods run in turn R times; the least times kept")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    rows = []

    def keep(row: dict) -> None:
        rows.append(row)
        print(row, flush=True)
        json.dump({"environment": environment(args.device), "rows": rows}, open(args.out, "w"), indent=1)

    if args.scenes:
        frames_of = {name: int(n) for name, n in (item.split("=") for item in args.scene_frames)}
        for name in args.scenes:
            runs = [[measure_scene(name, method, frames_of.get(name, args.frames), args.device)
                     for method in args.methods] for _ in range(args.repeats)]  # the methods in turn, repeated
            for method_runs in zip(*runs):
                keep(fastest(method_runs))
        return
    for n in args.sizes:
        for cloth in args.cloth:
            for method, bounds, substeps, segment in ((m, b, k, g) for m in args.methods for b in args.bounds
                                                      for k in args.substeps for g in args.segments):
                keep(measure(n, method, args.frames, args.cap, args.device, cloth, args.variant, bounds, substeps,
                             segment))


if __name__ == "__main__":
    main()
