"""Stacked sheets draped over a sphere (issue 34's case): how well the layers stay apart and the limit holds.

``sheets`` square grid cloths of ``n`` x ``n`` particles, ``size`` metres square, laid horizontally ``gap``
metres apart, each pinned at two corners of one edge, fall from ``drop`` metres above a sphere of radius
``sphere_radius`` and drape over it, ``frames`` frames at ``fps``; the issue's own case is 5 sheets of
128^2, 2 m, 1 cm apart, a 5% strain limit, a 0.5 m sphere, 100 frames at 60 fps. The material (density,
springs) is the built-in drape scene's; the step is the simulator's choice unless ``--substeps`` fixes it.
One run per contact setting: ``--radius`` in metres (the particles' sphere; "default" for the project's own
rule, ``Collision``'s docstring), with self and cloth-cloth collision and friction as asked.

Per run, over every frame written (frame 0 included):
- worst edge strain, stretch and compression, of every structural and shear edge (all limited here), as
  ``StrainMonitor`` measures it;
- crossing triangle pairs (``TriangleIntersections``, the counter of ``warp-cloth run --check`` and
  tools/contact_quality.py): the most in a frame, its frame, and the first frame with any;
- the closest contact of two particles that may collide, among the pairs the simulation listed last (so
  measuring leaves the run as it would be unmeasured): as a fraction of the contact distance, in metres
  and as a fraction of the gap;
- the converged limit solve's passes a substep (mean, most, the cap) and the frames whose solve ended at
  its cap outside its tolerance;
- wall time of the frames (kernels loaded before the clock starts), substeps a frame; per frame also its
  seconds, its limit solve's mean passes and its CG's most iterations (where the step is implicit);
- the closest surfaces: the least distance of a vertex-triangle or edge-edge pair that is a contact (sharing
  no vertex; warp_cloth/surface_pairs.py), at most the gap (kernels/primitive_distances.py), over every frame (of triangles that cross, no such pair need
  touch: an edge through a face's middle).
A run the start check refuses, or that blows up, is reported as such: that is a result too.

``--thickness`` runs each contact setting once per value: ``off``, or the scene key ``[collision] thickness``
in metres (surface contacts: edge and face contacts held that far apart, the displacement bounds of that
thickness and the solve's check of their pairs; ``Collision``'s docstring). Every run reports its closest
surfaces also as a fraction of the thickness (where one is set), the particle
lists' overflow and the surface lists' (the pairs within reach that full lists left out).

``--bounds`` runs each of those once per spec: ``off`` (the scene's own: its thickness's bounds, none
without one), or the lab's displacement bounds (warp_cloth/displacement_bounds.py) as ``on`` or
comma-separated ``radius=``, ``gamma=``, ``rounds=``, ``again=`` (say ``rounds=3``: a 1 cm radius, a 4 mm
thickness's); a bounded run adds the particles held short a substep (first and last round), the distance given
up, the rounds a substep in which the bounds were measured again (``again``), the particles left held at
their bounds with their rounds spent (summed over substeps), and the settings it ran with.

    python tools/stacked_drape.py --sheets 3 --n 32 --frames 60 --radius 0.004 default --device cpu \\
        --json docs/results/stacked-drape-cpu.json

``--scene NAME`` measures a built-in scene (or a scene file) the same way instead of the stack, once per
``--thickness`` (its own contact radius; give ``--radius default`` for one run each), with
``--auto-substeps`` at the simulator's choice of step rather than the scene's:

    python tools/stacked_drape.py --scene fold --frames 48 --thickness off 0.004 --radius default --device cpu

Prints a table and writes the runs and the environment as one JSON object (docs/results/stacked-drape-*.json,
read by docs/notebook/layers.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time

import numpy as np
import warp as wp

import warp_cloth as wc
from warp_cloth.diagnostics import TriangleIntersections
from warp_cloth.displacement_bounds import BoundSettings, DisplacementBounds, lab_hooks
from warp_cloth.lab.bench import environment
from warp_cloth.progress import Progress

DRAPE_MATERIAL = {"density": 0.2, "structural": wc.SpringKind(50.0, 0.05), "shear": wc.SpringKind(50.0, 0.05),
                  "bend": wc.SpringKind(20.0, 0.02, "compression", "compression")}  # scenes/drape.toml's


def stacked_drape_scene(sheets: int = 5, n: int = 128, gap: float = 0.01, limit: float = 0.05, frames: int = 100,
                        fps: float = 60.0, size: float = 2.0, sphere_radius: float = 0.5, drop: float = 0.05,
                        radius: float | None = None, self_collision: bool = True, between_cloths: bool = True,
                        friction: float = 0.0, substeps: int | None = None,
                        thickness: float | None = None, integrator: str = "symplectic") -> wc.Scene:
    """The stacked drape: the sphere's centre at the origin, the lowest sheet ``drop`` above its top, the
    sheets centred over it, ``gap`` apart; ``radius`` None is the project's contact rule, ``thickness`` the
    surface contacts' (None: none)."""
    base = sphere_radius + drop
    cloths = tuple(wc.Cloth(name=f"sheet{k}", resolution=(n - 1, n - 1), size=(size, size),
                            orientation="horizontal", origin=(-size / 2, base + k * gap, size / 2),
                            limit=wc.Limit(limit, limit), pins=(wc.Pin(corners=("top-left", "top-right")),),
                            **DRAPE_MATERIAL) for k in range(sheets))
    return wc.Scene(name=f"stacked_{sheets}x{n}", cloths=cloths,
                    spheres=(wc.Sphere(name="ball", center=(0.0, 0.0, 0.0), radius=sphere_radius),),
                    collision=wc.Collision(self_collision=self_collision, between_cloths=between_cloths,
                                           radius=radius, friction=friction,
                                           thickness=thickness),
                    simulation=wc.Simulation(fps=fps, frames=frames, substeps=substeps, integrator=integrator))


def contact_distance(sim: wc.Simulator) -> float:
    """Two particles' contact distance in metres: ``separation`` times their radius (one radius for sheets of
    one grid)."""
    return sim.scene.collision.separation * float(np.min(sim.model.contacts.radius))


def measure(scene: wc.Scene, gap: float, device: str, bounds: BoundSettings | None = None) -> dict:
    """One run of ``scene``, measured in every frame (see the module's docstring); ``bounds``: the lab's
    (None: the scene's own)."""
    try:
        with lab_hooks(bounds):
            sim = wc.Simulator(scene, device=device)
    except wc.SceneError as refused:
        return {"outcome": "refused at start", "message": str(refused)}
    surfaces = DisplacementBounds(sim.model, sim.device_model, BoundSettings(radius=gap))
    started = time.perf_counter()
    sim.prepare()
    prepare_seconds = time.perf_counter() - started
    strain, crossings = wc.StrainMonitor(), TriangleIntersections(sim)
    strain.begin(sim)
    distance = contact_distance(sim)
    thickness = scene.collision.thickness if scene.collision is not None else None
    per_frame = {"crossings": [], "closest_contact": [], "seconds": [], "substeps": [], "limit_passes": [],
                 "limit_mean_passes": [], "limit_residual": [], "cg_iterations": [],
                 "closest_surfaces": [], "held_short_first": [], "held_short_last": [], "held_back_m": [],
                 "measured_again": [], "left_held": []}
    stepping, outcome = 0.0, "completed"

    def measure_frame(frame: int) -> None:
        strain.write_frame(sim, frame)
        per_frame["crossings"].append(crossings(sim))
        per_frame["closest_contact"].append(float(sim.closest_contacts(remake=False).min()))
        surfaces.measure_at(sim.state.x)
        per_frame["closest_surfaces"].append(float(surfaces.nearest.numpy().min()))

    measure_frame(0)
    bar = Progress(scene.simulation.frames, f"{scene.name} on {device}")
    for frame in range(1, scene.simulation.frames + 1):
        started = time.perf_counter()
        try:
            sim.step()
            wp.synchronize_device(sim.device)
        except wc.UnstableSimulation as unstable:
            outcome = f"unstable at frame {frame}: {unstable}"
            break
        per_frame["seconds"].append(time.perf_counter() - started)
        stepping += per_frame["seconds"][-1]
        stats = sim.solver_stats()
        per_frame["substeps"].append(sim.frame_substeps)
        per_frame["limit_passes"].append(stats.limit_passes)
        per_frame["limit_mean_passes"].append(stats.limit_mean_passes)
        per_frame["cg_iterations"].append(stats.cg_iterations)
        per_frame["limit_residual"].append(stats.limit_residual)
        if sim.plan.bounds is not None:
            bound_stats = sim.plan.bounds.read_stats()
            per_frame["held_short_first"].append(bound_stats.held_short[0] / sim.frame_substeps)
            per_frame["held_short_last"].append(bound_stats.held_short[-1] / sim.frame_substeps)
            per_frame["held_back_m"].append(bound_stats.held_back)
            per_frame["measured_again"].append(bound_stats.measured_again / sim.frame_substeps)
            per_frame["left_held"].append(bound_stats.left_held)
        measure_frame(frame)
        bar.update(frame)
    bar.close()
    report = strain.report()
    total = sim.solver_stats(since_start=True)
    counts = per_frame["crossings"]
    crossed = [f for f, c in enumerate(counts) if c > 0]
    closest = min(per_frame["closest_contact"])  # infinite where no particle pair was ever listed: none
    listed = math.isfinite(closest)
    return {"outcome": outcome, "frames": len(counts) - 1, "particles": sim.model.particle_count,
            "step_seconds": stepping, "prepare_seconds": prepare_seconds,
            "substeps_mean": float(np.mean(per_frame["substeps"])) if per_frame["substeps"] else None,
            "substeps_most": max(per_frame["substeps"], default=None),
            "stretch": report.stretch, "stretch_frame": report.stretch_frame,
            "compression": report.compression, "compression_frame": report.compression_frame,
            "most_crossings": max(counts), "most_crossings_frame": int(np.argmax(counts)),
            "first_crossing_frame": crossed[0] if crossed else None, "frames_with_crossings": len(crossed),
            "contact_distance": distance, "closest_contact": closest if listed else None,
            "closest_contact_m": closest * distance if listed else None,
            "closest_contact_of_gap": closest * distance / gap if listed else None,
            "start_contact_of_gap": per_frame["closest_contact"][0] * distance / gap if listed else None,
            "limit_passes_mean": total and total.limit_mean_passes, "limit_passes_most": total and total.limit_passes,
            "limit_passes_cap": sim.limit_solve.max_passes,
            "frames_ending_outside_tolerance": sum(r > 1.0 for r in per_frame["limit_residual"]),
            "closest_surfaces_m": min(per_frame["closest_surfaces"]),
            "thickness": thickness, "closest_surfaces_of_thickness": None if thickness is None else min(per_frame["closest_surfaces"]) / thickness,
            "surface_thickness": scene.collision.thickness, "lists_overflow": sim.plan.lists.overflow,
            "surface_lists_dropped": sim.plan.lists.surface_dropped,
            "bounds": None if sim.plan.bounds is None else vars(sim.plan.bounds.settings),
            "held_short_mean": float(np.mean(per_frame["held_short_first"])) if per_frame["held_short_first"] else None,
            "held_short_last_mean": float(np.mean(per_frame["held_short_last"]))
            if per_frame["held_short_last"] else None,
            "held_back_m": float(np.sum(per_frame["held_back_m"])) if per_frame["held_back_m"] else None,
            "measured_again_mean": float(np.mean(per_frame["measured_again"])) if per_frame["measured_again"] else None,
            "measured_again_most": max(per_frame["measured_again"], default=None),
            "left_held": int(np.sum(per_frame["left_held"])) if per_frame["left_held"] else None,
            "per_frame": per_frame | {"stretch": report.per_frame[:, 1].tolist(),
                                      "compression": report.per_frame[:, 2].tolist()}}


HEADER = (f"{'run':<44} {'frames':>6} {'step s':>8} {'substeps':>8} {'stretch':>8} {'compress':>8} "
          f"{'most crossings':>15} {'first':>5} {'closest':>7} {'m':>8} {'of gap':>6} {'passes mean/most/cap':>20} "
          f"{'capped':>6} {'surfaces m':>10} {'of thick':>8} {'held short':>10} {'again':>5}")


def table_lines(row: dict) -> list[str]:
    """A run's line in the table (and a line saying how it ended, where it did not complete)."""
    if row["outcome"] == "refused at start":
        return [f"{row['run']:<44} refused at start: {row['message']}"]
    if row["frames"] == 0:
        return [f"{row['run']:<44} {row['outcome']}"]
    first = row["first_crossing_frame"]
    lines = [f"{row['run']:<44} {row['frames']:>6} {row['step_seconds']:>8.1f} {row['substeps_mean']:>8.1f} "
             f"{100 * row['stretch']:>+7.1f}% {-100 * row['compression']:>+7.1f}% "
             f"{row['most_crossings']:>7} (f {row['most_crossings_frame']:>3}) {'-' if first is None else first:>5} "
             + (f"{row['closest_contact']:>7.3f} {row['closest_contact_m']:>8.5f} {row['closest_contact_of_gap']:>6.3f} "
                if row["closest_contact"] is not None else f"{'-':>7} {'-':>8} {'-':>6} ") +
             f"{row['limit_passes_mean']:>7.1f}/{row['limit_passes_most']:>4}/{row['limit_passes_cap']:>5} "
             f"{row['frames_ending_outside_tolerance']:>6} {row['closest_surfaces_m']:>10.5f} "
             f"{'-' if row['closest_surfaces_of_thickness'] is None else format(row['closest_surfaces_of_thickness'], '.3f'):>8} "
             f"{'-' if row['held_short_mean'] is None else format(row['held_short_mean'], '.1f'):>10} "
             f"{'-' if row['measured_again_mean'] is None else format(row['measured_again_mean'], '.2f'):>5}"]
    if row["outcome"] != "completed":
        lines.append(f"{'':<44} {row['outcome']}")
    return lines


def scene_with_thickness(name: str, thickness: float | None, frames: int, auto_substeps: bool = False) -> wc.Scene:
    """A built-in scene (or a scene file) run ``frames`` frames, with ``[collision] thickness`` set (None: as
    it is), and where ``auto_substeps`` its ``dt`` and ``substeps`` left out (the simulator's choice)."""
    scene = wc.load_scene(name)
    collision = scene.collision if thickness is None else dataclasses.replace(scene.collision, thickness=thickness)
    simulation = dataclasses.replace(scene.simulation, frames=frames)
    if auto_substeps:
        simulation = dataclasses.replace(simulation, dt=None, substeps=None)
    return dataclasses.replace(scene, collision=collision, simulation=simulation)


def write(path: str | None, device: str, settings: dict, rows: list[dict]) -> None:
    """The runs so far and the environment, where asked (after every run: a later one may take long or fail)."""
    if path:
        with open(path, "w") as out:
            json.dump({"environment": environment(device), "settings": settings, "runs": rows}, out, indent=1)
            out.write("\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sheets", type=int, default=5)
    parser.add_argument("--n", type=int, default=128, help="particles along a sheet's side")
    parser.add_argument("--gap", type=float, default=0.01, help="metres between sheets")
    parser.add_argument("--limit", type=float, default=0.05, help="strain limit, stretch and compression")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--fps", type=float, default=60.0)
    parser.add_argument("--size", type=float, default=2.0, help="metres, a sheet's side")
    parser.add_argument("--sphere-radius", type=float, default=0.5)
    parser.add_argument("--drop", type=float, default=0.05, help="metres from the sphere's top to the lowest sheet")
    parser.add_argument("--radius", nargs="+", default=["0.004", "default"],
                        help="particle contact radius in metres, or 'default' (the project's rule): one run each")
    parser.add_argument("--no-self", action="store_true", help="cloth-cloth collision only")
    parser.add_argument("--friction", type=float, default=0.0)
    parser.add_argument("--substeps", type=int, default=None, help="fixed substeps a frame (default: the simulator's)")
    parser.add_argument("--integrator", default="symplectic", choices=("symplectic", "implicit", "explicit"),
                        help="the stack's integrator")
    parser.add_argument("--thickness", nargs="+", default=["off"],
                        help="[collision] thickness in metres (surface contacts), or off; one run each")
    parser.add_argument("--bounds", nargs="+", default=["off"],
                        help="the lab's displacement bounds: off (the scene's own), on, or radius=R,gamma=G,rounds=K; "
                             "one run each")
    parser.add_argument("--scene", default=None,
                        help="a built-in scene (or a scene file) run instead of the stack, with --thickness and "
                             "--frames; its own contact radius (--radius is ignored)")
    parser.add_argument("--auto-substeps", action="store_true",
                        help="with --scene: the scene's dt and substeps left out, the simulator choosing them")
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None, help="where to write the runs and the environment")
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    wc.set_verbose(False)
    device = args.device or ("cuda" if wp.is_cuda_available() else "cpu")
    settings = {k: v for k, v in vars(args).items() if k not in ("json", "device")}
    settings["cell"] = args.size / (args.n - 1)
    rows = []
    print(HEADER, "-" * len(HEADER), sep="\n")
    radii = ["default"] if args.scene is not None else args.radius  # a scene keeps its own: one run, not one a radius
    for text, spec, surface in ((t, b, s) for t in radii for s in args.thickness for b in args.bounds):
        radius = None if text == "default" else float(text)
        thickness = None if surface == "off" else float(surface)
        if args.scene is not None:
            scene = scene_with_thickness(args.scene, thickness, args.frames, args.auto_substeps)
            own = scene.collision.thickness if scene.collision is not None else None
            rows.append({"run": f"{args.scene}{'' if thickness is None else f' thickness {1e3 * thickness:g}mm'}"
                                f"{'' if spec == 'off' else ' bounds ' + spec}"
                                f"{' substeps auto' if args.auto_substeps else ''}",
                         **measure(scene, own or args.gap, device, BoundSettings.parse(spec))})
            print(*table_lines(rows[-1]), sep="\n", flush=True)
            write(args.json, device, settings, rows)
            continue
        scene = stacked_drape_scene(args.sheets, args.n, args.gap, args.limit, args.frames, args.fps, args.size,
                                    args.sphere_radius, args.drop, radius, not args.no_self, True,
                                    args.friction, args.substeps, thickness, args.integrator)
        name = (f"{args.sheets}x{args.n}^2 r={'default' if radius is None else f'{1e3 * radius:g}mm'}"
                f"{' no-self' if args.no_self else ''}"
                f"{'' if thickness is None else f' thickness {1e3 * thickness:g}mm'}"
                f"{'' if spec == 'off' else ' bounds ' + spec}"
                f"{'' if args.integrator == 'symplectic' else ' ' + args.integrator}"
                f"{'' if args.substeps is None else f' {args.substeps} substeps'}")
        rows.append({"run": name, "radius": radius, **measure(scene, args.gap, device, BoundSettings.parse(spec))})
        print(*table_lines(rows[-1]), sep="\n", flush=True)
        write(args.json, device, settings, rows)
    print(f"{len(rows)} runs on {device}" + (f"; written to {args.json}" if args.json else ""))


if __name__ == "__main__":
    main()
