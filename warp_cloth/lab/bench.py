"""Benchmarks: wall time of whole runs, median of repeats, printed as a table and written as JSON with the
device and versions. Never a test: time is measured here and asserted nowhere.

The scenes built here run with ``limit_solve = "fixed"`` (``fixed_solve``): they time the seed's loop (a set
number of limit passes a substep) and the speed matrix as first measured, and every row says the worst strain
that bought; what solving the limit to a tolerance costs is tools/strain_solve_probe.py's
(docs/notebook/strain-solve.md). The built-in scenes run as their files say.

    python -m warp_cloth.lab.bench --suite core --device cpu --json out/bench-core-cpu.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np
import warp as wp

from ..progress import Progress
from ..scene import Cloth, Collision, Ground, Limit, Oscillation, Pin, Scene, Simulation, Sphere, SpringKind
from ..scene_file import load_scene
from ..errors import EXIT_BAD_INPUT, SceneError, UnstableSimulation
from ..batch import Batch
from ..simulator import Simulator, resolve_device
from ..stability import UnstableStepWarning
from ..strain import StrainMonitor, StrainReport
from ..writers import PolyWriter, UsdWriter
from .bench_meshes import RINGS_FOR_100K, as_mesh_cloth, sphere_triangles, with_mesh_sphere
from .newton_compare import SOLVERS as NEWTON_SOLVERS, SPHERE_CENTER, SPHERE_RADIUS, SWING_DEGREES, swung_origin
from .. import neighbour_lists, state
from ..wording import counted

# The seed's C++ on this machine kind (docs/seed-baseline.md). It always ran its O(n^2)
# self collision, so only the "+self" rows do the same work and get a ratio (seed_25x25, without
# collision, is compared with its 2.64 s in the docs' text only); its seed_default held particles apart,
# not surfaces: the row without a thickness.
SEED_CPP_SECONDS = {"seed_25x25+self": 2.64, "seed_default_60x60x2 without a thickness": 193.4,
                    **{f"seed_{n}x{n}+self explicit dt=0.0025": t
                       for n, t in ((5, 0.0222), (10, 0.135), (15, 0.468), (20, 1.20), (25, 2.64))},
                    **{f"seed_{n}x{n}+self implicit dt=0.0208": t
                       for n, t in ((5, 0.224), (10, 2.30), (15, 14.7), (20, 66.7), (25, 157.9))}}


def fixed_solve(**settings) -> Simulation:
    """A benchmark scene's [simulation]: the fixed limit solve (see above) and ``settings``."""
    return Simulation(limit_solve="fixed", **settings)


def seed_cloth_scene(n: int, self_collision: bool = False, integrator: str = "explicit", dt: float = 0.0025) -> Scene:
    """The seed's single-cloth benchmark loop: an n x n cloth (L0 = 1 m, 0.025 kg a particle, k = 10,
    b = 1) pinned at two corners, explicit Euler at dt 0.0025 (17 substeps a frame), 6 strain-limit
    passes, ground, and the moving sphere of its main loop; with its self collision if asked (then the
    6 passes each also push particles apart)."""
    cloth = Cloth(resolution=(n, n), size=(float(n), float(n)), orientation="horizontal",
                  origin=(0.0, float(n), 0.0), mass=0.025, jitter=0.05, limit=Limit(0.1, 0.1),
                  pins=(Pin(corners=("top-left", "top-right")),))
    sphere = Sphere(name="ball", center=(5.0, 5.0, 0.0), radius=2.0,
                    motion=Oscillation(axis=(0.0, 0.0, 1.0), amplitude=5.0, frequency=0.1, phase=np.pi / 4))
    return Scene(name=f"seed_{n}x{n}", cloths=(cloth,), ground=Ground(), spheres=(sphere,),
                 collision=Collision(iterations=1) if self_collision else None,
                 simulation=fixed_solve(fps=24, frames=240, dt=dt, integrator=integrator, limit_iterations=6))


def large_cloth_scene(n: int, substeps: int = 10) -> Scene:
    """An n x n cloth falling onto a sphere and the ground: springs + strain limit + sphere + ground,
    symplectic Euler. Springs soft enough for the explicit step at this resolution (the limit holds the
    shape), so that the timing is of a stable run."""
    soft = SpringKind(stiffness=0.2, damping=0.01)
    cloth = Cloth(resolution=(n - 1, n - 1), size=(10.0, 10.0), orientation="horizontal", origin=(-5.0, 3.0, 5.0),
                  mass=1e-3, structural=soft, shear=soft,
                  bend=SpringKind(stiffness=0.1, damping=0.005, acts="compression", damping_acts="compression"),
                  limit=Limit(0.1, 0.1))
    return Scene(name=f"drop_{n}x{n}", cloths=(cloth,), ground=Ground(friction=0.3),
                 spheres=(Sphere(name="ball", center=(0.0, 1.5, 0.0), radius=1.5, friction=0.3),),
                 simulation=fixed_solve(fps=24, frames=48, substeps=substeps, integrator="symplectic"))


@dataclass(frozen=True)
class Case:
    name: str
    scene: Scene
    frames: int
    outputs: bool = False
    fresh: bool = True  # each repeat starts from t = 0 (else frames continue on one warmed simulator)
    threads_per_particle: int | None = None  # the Simulator's (None: chosen by size)
    worlds: int = 1  # copies of the scene stepped together as the worlds of one batch


def simulator_for(case: Case, device: str) -> Simulator:
    """The case's simulator: of its scene, or of the batch of its copies (through ``Batch``'s simulator)."""
    if case.worlds == 1:
        return Simulator(case.scene, device=device, threads_per_particle=case.threads_per_particle)
    return Batch([case.scene] * case.worlds, device=device, threads_per_particle=case.threads_per_particle).simulator


@dataclass(frozen=True)
class Result:
    """``stable`` is False where a run of the case blew up (``UnstableSimulation``: a state not finite or
    too fast, in any world of a batch), at frame ``unstable_frame``: it has no time or strain that is a result."""

    case: str
    device: str
    particles: int
    substeps_per_frame: int
    frames: int
    outputs: bool
    seconds: list[float]
    stable: bool = True
    max_strain: float | None = None  # worst edge strain (stretch or compression) over every frame the runs made
    strain: dict | None = None  # its StrainReport in figures: stretch, compression, percentiles, share past 11%
    unstable_frame: int | None = None

    @property
    def median_seconds(self) -> float:
        return statistics.median(self.seconds) if self.seconds else float("nan")

    @property
    def particle_substeps_per_second(self) -> float:
        return self.particles * self.substeps_per_frame * self.frames / self.median_seconds

    @property
    def ms_per_frame(self) -> float:
        return 1e3 * self.median_seconds / self.frames


def core_cases(device: str) -> list[Case]:
    cases = [Case("seed_25x25", seed_cloth_scene(25), 240),
             Case("seed_25x25+usd+poly", seed_cloth_scene(25), 240, outputs=True)]
    sizes = [64, 256] if device == "cpu" else [256, 1024, 2048]
    cases += [Case(f"drop_{n}x{n}", large_cloth_scene(n), 24 if device == "cpu" else 48, fresh=False)
              for n in sizes]
    return cases


def stacked_layers_scene(particles: int, layers: int = 4, substeps: int = 1) -> Scene:
    """``layers`` square cloths of ``particles / layers`` particles stacked 0.9 contact distances apart, so
    that every particle touches the layers next to it: particle collision's working load."""
    side = max(2, int(round((particles / layers) ** 0.5)))
    cell = 0.01
    contact = 2.1 * 0.25 * cell * 2 ** 0.5 * 1.1
    cloths = tuple(Cloth(name=f"layer{k}", resolution=(side - 1, side - 1), size=(cell * (side - 1),) * 2,
                         orientation="horizontal", origin=(0.0, 0.9 * contact * k, 0.0), jitter=0.02, seed=k,
                         limit=Limit(0.1, 0.1)) for k in range(layers))
    return Scene(name=f"layers_{particles}", cloths=cloths,
                 collision=Collision(iterations=4),
                 simulation=fixed_solve(fps=24, frames=1, substeps=substeps, gravity=(0.0, 0.0, 0.0)))


def hanging_cloth_scene(n: int, integrator: str, substeps: int) -> Scene:
    """An n x n particle cloth of the seed's material scaled down to 10 m (density of 0.025 kg per 1 m^2
    cell, k = 10), hanging from its two top corners."""
    cloth = Cloth(resolution=(n - 1, n - 1), size=(10.0, 10.0), orientation="vertical", density=0.025,
                  limit=Limit(0.1, 0.1), pins=(Pin(corners=("top-left", "top-right")),),
                  structural=SpringKind(10.0, 0.1), shear=SpringKind(10.0, 0.1),
                  bend=SpringKind(10.0, 0.1, "compression", "compression"))
    return Scene(name=f"hanging_{n}x{n}", cloths=(cloth,),
                 simulation=fixed_solve(fps=24, frames=48, substeps=substeps, integrator=integrator))


def integrator_cases(device: str) -> list[Case]:
    """The seed's sweeps: sizes 5..25 (explicit at 0.0025, implicit at 0.0208) and steps 0.0025..0.04165
    at size 20, both integrators, on the seed's loop with self collision; and on a GPU a 256^2 cloth at
    one implicit step per frame."""
    cases = []
    for n in (5, 10, 15, 20, 25):
        for integrator, dt in (("explicit", 0.0025), ("implicit", 0.0208)):
            cases.append(Case(f"seed_{n}x{n}+self {integrator} dt={dt}", seed_cloth_scene(n, True, integrator, dt),
                              240))
    for dt in (0.0025, 0.0052, 0.0104, 0.0208, 0.04165):
        for integrator in ("explicit", "implicit"):
            name = f"seed_20x20+self {integrator} dt={dt}"
            if not any(c.name == name for c in cases):
                cases.append(Case(name, seed_cloth_scene(20, True, integrator, dt), 240))
    if device != "cpu":
        cases.append(Case("hanging_256x256 implicit 1 step/frame", hanging_cloth_scene(256, "implicit", 1), 48,
                          fresh=False))
    return cases


def collision_cases(device: str) -> list[Case]:
    seed_default = load_scene("seed_default")
    particles_alone = dataclasses.replace(seed_default.collision, thickness=None)
    return [Case("seed_25x25+self", seed_cloth_scene(25, self_collision=True), 240),
            Case("seed_default_60x60x2", seed_default, 240),
            Case("seed_default_60x60x2 without a thickness", dataclasses.replace(seed_default, collision=particles_alone),
                 240)]


@dataclass(frozen=True)
class CollisionResult:
    particles: int
    broad_phase: str
    lists: str  # "remade" every substep, or "kept" while no particle moved far enough
    device: str
    seconds_per_substep: float

    @property
    def ns_per_particle(self) -> float:
        return 1e9 * self.seconds_per_substep / self.particles


@contextmanager
def broad_phase_forced(brute_force: bool, every_substep: bool) -> Iterator[None]:
    """Simulators made inside check all pairs whatever their size (else they use the hash grid) and, with
    ``every_substep``, remake their lists every substep: the hooks the tests' oracles use."""
    saved = state.BRUTE_FORCE_UP_TO, neighbour_lists.REMAKE_EVERY_SUBSTEP
    state.BRUTE_FORCE_UP_TO = sys.maxsize if brute_force else 0
    neighbour_lists.REMAKE_EVERY_SUBSTEP = every_substep
    try:
        yield
    finally:
        state.BRUTE_FORCE_UP_TO, neighbour_lists.REMAKE_EVERY_SUBSTEP = saved


def time_collision_substep(particles: int, broad_phase: str, device: str, repeats: int,
                         remake_lists: bool = True) -> CollisionResult:
    """Median time per substep of stacked layers at rest, whose substep is mostly particle collision (the
    explicit step, which begins the contacts; the neighbour lists from the spatial hash or brute force; 4
    projection passes; the velocity pass), replayed as a captured frame of 10 substeps. The layers do not
    move, so kept lists are never remade: ``remake_lists`` remakes them every substep, to time the broad
    phase."""
    with broad_phase_forced(broad_phase == "brute_force", remake_lists):
        sim = Simulator(stacked_layers_scene(particles, substeps=10), device=device)
    sim.run(1)
    seconds = []
    for _ in range(repeats):
        wp.synchronize_device(sim.device)
        started = time.perf_counter()
        sim.step()
        wp.synchronize_device(sim.device)
        seconds.append((time.perf_counter() - started) / 10)
    return CollisionResult(sim.model.particle_count, broad_phase, "remade" if remake_lists else "kept",
                           str(sim.device), statistics.median(seconds))


def collision_scaling(device: str, repeats: int) -> list[CollisionResult]:
    sizes = [1024, 4096, 16384, 65536] + ([262144, 1048576, 4194304] if device != "cpu" else [])
    brute_limit = 4096 if device == "cpu" else 65536
    results = []
    for n in sizes:
        results.append(time_collision_substep(n, "hash_grid", device, repeats))
        if n <= brute_limit:
            results.append(time_collision_substep(n, "brute_force", device, repeats))
        results.append(time_collision_substep(n, "hash_grid", device, repeats, remake_lists=False))
    return results


def format_collision_table(results: list[CollisionResult]) -> str:
    header = f"{'particles':>9} {'broad phase':<12} {'lists':<7} {'device':<8} {'ms/substep':>10} {'ns/particle':>12}"
    lines = [header, "-" * len(header)]
    lines += [f"{r.particles:>9} {r.broad_phase:<12} {r.lists:<7} {r.device:<8} {1e3 * r.seconds_per_substep:>10.3f} "
              f"{r.ns_per_particle:>12.1f}" for r in results]
    return "\n".join(lines)


MATRIX_VARIANTS = ("hanging", "sphere", "self")
SPRINGS_ONLY = "springs"  # the hanging cloth without its strain limit: springs and the integrator alone
MATRIX_FPS, MATRIX_SUBSTEPS = 24, 10


def matrix_scene(variant: str, n: int, integrator: str, substeps: int = MATRIX_SUBSTEPS) -> Scene:
    """The speed matrix's cloth (the same as ``newton_compare`` builds in Newton): n x n particles, 10 m
    square, in the XY plane hanging from its whole top edge at y = 10, z = 0, 2.5 kg in all, 10 substeps a
    frame (or ``substeps``); ``sphere`` adds a 2 m sphere at (5, 5, 1.5), ``self`` adds self collision to
    that. The sphere pokes 0.5 m through the plane the cloth hangs in, so in those two the cloth starts
    swung back by ``SWING_DEGREES`` about its top edge, clear of the sphere, and swings onto it. Springs are
    as stiff as the explicit step allows at this resolution and step (h w = 0.7: stiffer as 1/h^2 with more
    substeps, as Newton's are), 50 times that for the implicit integrator; the 10% strain limit, with
    long-range attachments to the pinned edge, holds the shape either way."""
    h = 1.0 / (MATRIX_FPS * substeps)
    mass = 2.5 / (n * n)
    cell = 10.0 / (n - 1)
    stiffness = 0.5 * mass * cell / (8.0 * h * h) * (50.0 if integrator == "implicit" else 1.0)
    damping = 0.1 * mass / (8.0 * h)
    spring = SpringKind(stiffness, damping)
    with_sphere = variant in ("sphere", "self")
    cloth = Cloth(resolution=(n - 1, n - 1), size=(10.0, 10.0), orientation="vertical", mass=mass,
                  origin=swung_origin(SWING_DEGREES if with_sphere else 0.0),
                  rotation=(SWING_DEGREES if with_sphere else 0.0, 0.0, 0.0),
                  limit=None if variant == SPRINGS_ONLY else Limit(0.1, 0.1, attachments=True),
                  pins=(Pin(edges=("top",)),), structural=spring, shear=spring,
                  bend=SpringKind(stiffness, damping, "compression", "compression"))
    spheres = (Sphere(name="ball", center=SPHERE_CENTER, radius=SPHERE_RADIUS),) if with_sphere else ()
    return Scene(name=f"{variant}_{n}x{n}", cloths=(cloth,), spheres=spheres,
                 collision=Collision(iterations=2) if variant == "self" else None,
                 simulation=fixed_solve(fps=MATRIX_FPS, frames=48, substeps=substeps, integrator=integrator,
                                       limit_iterations=2))


def matrix_sizes(device: str) -> list[int]:
    return [64, 128] if device == "cpu" else [64, 256, 1024, 2048]


def matrix_frames(n: int, device: str) -> int:
    return 10 if device == "cpu" else (24 if n >= 2048 else 48)


def matrix_cases(device: str) -> list[Case]:
    cases = [Case(f"{variant} {n}^2 {integrator}", matrix_scene(variant, n, integrator), matrix_frames(n, device),
                  fresh=False)
             for variant in MATRIX_VARIANTS for n in matrix_sizes(device) for integrator in ("symplectic", "implicit")]
    return cases + [Case(f"{SPRINGS_ONLY} {n}^2 symplectic", matrix_scene(SPRINGS_ONLY, n, "symplectic"),
                         matrix_frames(n, device), fresh=False) for n in matrix_sizes(device)]


def mesh_cases(device: str) -> list[Case]:
    """The speed matrix's sphere cloth as a grid, read from an OBJ of its quads, and of its triangles (their
    attachments along the mesh's edges); then with its sphere made a mesh of about 100k triangles."""
    cases = []
    for n in [64] if device == "cpu" else [256, 1024]:
        grid = matrix_scene("sphere", n, "symplectic")
        frames = matrix_frames(n, device)
        cases += [Case(f"grid {n}^2", grid, frames, fresh=False),
                  Case(f"mesh quads {n}^2", as_mesh_cloth(grid, triangles=False), frames, fresh=False),
                  Case(f"mesh triangles {n}^2", as_mesh_cloth(grid, triangles=True), frames, fresh=False),
                  Case(f"grid {n}^2, sphere as {sphere_triangles(RINGS_FOR_100K) // 1000}k-triangle mesh",
                       with_mesh_sphere(grid, RINGS_FOR_100K), frames, fresh=False)]
    return cases


SOLVED = "limit solved"  # the worlds suite's cases with the strain limit solved to its tolerance


def world_cases(device: str) -> list[Case]:
    """The matrix's self-collision cloth at 32^2 as the worlds of one batch, against one cloth of as many
    particles with the same effects; the same worlds with the strain limit solved to its tolerance (the
    converged solve, its Chebyshev radius estimated); and with the implicit step, against one such world alone."""
    counts, single = ([4, 16], 128) if device == "cpu" else ([64, 1024, 4096], 1024)
    frames = matrix_frames(32, device)
    world, implicit = matrix_scene("self", 32, "symplectic"), matrix_scene("self", 32, "implicit")
    solved = dataclasses.replace(world, simulation=dataclasses.replace(world.simulation, limit_solve="converged"))
    return ([Case(f"self {single}^2, one cloth", matrix_scene("self", single, "symplectic"), frames, fresh=False)]
            + [Case(f"self 32^2 x {k} worlds", world, frames, fresh=False, worlds=k) for k in counts]
            + [Case(f"self 32^2 x {k} worlds, {SOLVED}", solved, frames, fresh=False, worlds=k) for k in counts[:2]]
            + [Case("self 32^2 implicit, one world", implicit, frames, fresh=False)]
            + [Case(f"self 32^2 implicit x {k} worlds", implicit, frames, fresh=False, worlds=k) for k in counts[:2]])


@dataclass(frozen=True)
class Suite:
    cases: Callable[[str], list[Case]]  # of the device ("cpu" or "cuda")
    measures: str  # for --help


SUITES = {
    "core": Suite(core_cases, "the seed's 25x25 loop (explicit Euler, 240 frames) without and with USD and .poly "
                              "output, and large cloths falling onto a sphere and the ground (64^2 and 256^2 on the "
                              "CPU, 256^2 to 2048^2 on a GPU)"),
    "collision": Suite(collision_cases, "the seed's 25x25 loop with its self collision and the seed's default scene "
                                        "(two 60x60 cloths, a moving sphere), against the seed's C++ times, and that "
                                        "scene without its edge contacts (what they cost); then the "
                                        "substep of stacked layers (mostly particle collision) of 1k to 64k "
                                        "particles (to 4M on a GPU), hash grid against brute force, in ms per substep"),
    "integrators": Suite(integrator_cases, "what stability and accuracy cost: the seed's sweeps with self collision, "
                                           "sizes 5x5 to 25x25 and steps 0.0025 to 0.04165 s at 20x20, explicit and "
                                           "implicit, against the seed's C++ times (on a GPU also a 256^2 cloth at "
                                           "one implicit step a frame)"),
    "matrix": Suite(matrix_cases, "a cloth hanging from its top edge, swinging onto a sphere, and onto a sphere with "
                                  "self collision, 64^2 and 128^2 on the CPU (to 2048^2 on a GPU), symplectic and "
                                  "implicit, and springs only, each with its worst edge strain; with --newton the "
                                  "same cloths in Newton's solvers"),
    "meshes": Suite(mesh_cases, "the matrix's sphere cloth as a grid and read back from OBJ files of its quads and "
                                "of its triangles, then with its sphere a mesh collider of 100k triangles (64^2 on "
                                "the CPU, 256^2 and 1024^2 on a GPU)"),
    "worlds": Suite(world_cases, "the matrix's self-collision cloth at 32^2 as 4 and 16 worlds of one batch on the "
                                 "CPU (64, 1024 and 4096 on a GPU), against one 128^2 cloth (1024^2 on a GPU) with "
                                 "the same effects; the first two with the strain limit solved, and with the "
                                 "implicit step against one world alone"),
}


def suites_help() -> str:
    lines = textwrap.wrap("suites: each case is timed as whole runs after a warm-up, the median of --repeats, in "
                          "particle-substeps per second. The seed is the C++ course project warp-cloth grew from "
                          "(github.com/loshjawrence/ClothSim); its times are its C++ on a 2-core AMD EPYC "
                          "(docs/seed-baseline.md).", width=79)
    for name, suite in SUITES.items():
        lines += textwrap.wrap(suite.measures, width=79, initial_indent=f"  {name:<12} ", subsequent_indent=" " * 15)
    return "\n".join(lines)


def time_case(case: Case, device: str, repeats: int) -> Result:
    warm = simulator_for(case, device)
    result = lambda seconds, stable=True, frame=None: Result(  # noqa: E731
        case.name, str(warm.device), warm.model.particle_count, warm.substeps_per_frame, case.frames, case.outputs,
        seconds, stable, unstable_frame=frame)
    covered = case.frames if case.fresh else 2 + repeats * case.frames
    try:
        warm.run(2)  # compiles kernels, captures graphs
        check_every_world(warm)
        seconds = []
        for _ in range(repeats):
            sim = simulator_for(case, device) if case.fresh else warm
            with tempfile.TemporaryDirectory() as tmp:
                writers = [UsdWriter(Path(tmp) / "run.usdc"), PolyWriter(Path(tmp) / "poly")] if case.outputs else []
                wp.synchronize_device(sim.device)
                started = time.perf_counter()
                sim.run(case.frames, writers=writers)
                wp.synchronize_device(sim.device)
                seconds.append(time.perf_counter() - started)
                check_every_world(sim)
        report = strain_over(case, device, covered)
    except UnstableSimulation as exc:
        return result([], stable=False, frame=exc.frame)
    figures = {"stretch": report.stretch, "compression": report.compression, "frames": report.frames,
               "p99": report.percentiles[99.0], "p99.9": report.percentiles[99.9], "beyond_11": report.beyond}
    return dataclasses.replace(result(seconds), max_strain=report.worst, strain=figures)


def check_every_world(sim: Simulator) -> None:
    """Raise the first blow-up of a batch's worlds: a batch goes on past a world that blew up (it is held
    where it started), which for a timing is a case that blew up."""
    if sim.stopped_worlds:
        raise min(sim.stopped_worlds.values(), key=lambda stopped: stopped.frame)


def seconds_of_runs(sim: Simulator, frames: int, repeats: int) -> list[float]:
    """Wall seconds of ``repeats`` runs of ``frames`` frames each, one after the other, the device idle at
    both ends of each."""
    seconds = []
    for _ in range(repeats):
        wp.synchronize_device(sim.device)
        started = time.perf_counter()
        sim.run(frames)
        wp.synchronize_device(sim.device)
        seconds.append(time.perf_counter() - started)
    return seconds


def strain_over(case: Case, device: str, frames: int) -> StrainReport:
    """Edge strain over every frame of a run of the case as the timed runs made it (those go unmeasured:
    measuring every frame waits for each), from t = 0."""
    sim = simulator_for(case, device)
    monitor = StrainMonitor()
    sim.run(frames, writers=[monitor])
    check_every_world(sim)
    return monitor.report()


def environment(device: str) -> dict:
    dev = wp.get_device(device)
    commit = os.environ.get("WARP_CLOTH_COMMIT")  # set where the checkout travels without .git
    if commit is None:
        try:
            commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                    cwd=Path(__file__).parent, timeout=10).stdout.strip() or None
        except (OSError, subprocess.SubprocessError):
            commit = None
    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"device": dev.name, "device_alias": dev.alias, "cpu": cpu, "warp": wp.__version__,
            "numpy": np.__version__, "python": platform.python_version(), "commit": commit,
            "date": time.strftime("%Y-%m-%d %H:%M:%S")}


def format_table(results: list[Result]) -> str:
    width = max(22, *(len(r.case) for r in results))
    strains = any(r.max_strain is not None for r in results)
    header = f"{'case':<{width}} {'device':<8} {'particles':>9} {'substeps':>8} {'frames':>6} {'median s':>9} " \
             f"{'ms/frame':>9} {'particle-substeps/s':>20} {'seed C++ s':>10} {'speed-up':>9}" + \
             (f" {'worst strain':>12}" if strains else "")
    lines = [header, "-" * len(header)]
    for r in results:
        seed = SEED_CPP_SECONDS.get(r.case)
        seed_text = f"{seed:10.3g}" if seed and not r.outputs else ""
        if not r.stable:  # no time, speed-up or strain: none of them is a result
            lines.append(f"{r.case:<{width}} {r.device:<8} {r.particles:>9} {r.substeps_per_frame:>8} {r.frames:>6} "
                         f"{f'blew up at frame {r.unstable_frame}':>40} {seed_text:>10}")
            continue
        ratio = f"{seed / r.median_seconds:8.1f}x" if seed and not r.outputs else ""
        strain = f" {100 * r.max_strain:>11.1f}%" if r.max_strain is not None else ""
        lines.append(f"{r.case:<{width}} {r.device:<8} {r.particles:>9} {r.substeps_per_frame:>8} {r.frames:>6} "
                     f"{r.median_seconds:>9.3f} {r.ms_per_frame:>9.3f} {r.particle_substeps_per_second:>20.3g} "
                     f"{seed_text:>10} {ratio:>9}{strain}")
    return "\n".join(lines)


def newton_comparison(results: list[Result], device: str, repeats: int, solvers: Sequence[str]) -> list[dict]:
    """The matrix's cloths in Newton's solvers on the same device, each row with the ratio of our
    symplectic run's particle-substeps per second to the solver's."""
    ours = {r.case: r for r in results}
    pairs = [(ours[case], variant, n, 1, None) for variant in MATRIX_VARIANTS for n in matrix_sizes(device)
             for case in [f"{variant} {n}^2 symplectic"] if case in ours]
    return _newton_rows(pairs, device, repeats, solvers, f"newton on {device}")


def newton_world_comparison(results: list[Result], device: str, repeats: int, solvers: Sequence[str]) -> list[dict]:
    """The worlds suite's symplectic batches in Newton's solvers, as that many Newton worlds of one model on
    the same device, each row with the ratio of our batch's particle-substeps per second to the solver's,
    with the fixed limit solve and (where measured) with the limit solved."""
    ours = {r.case: r for r in results}
    pairs = [(r, "self", 32, k, ours.get(f"{r.case}, {SOLVED}")) for r in results
             for k in [int(r.case.split(" x ")[1].split()[0])] if r.case == f"self 32^2 x {k} worlds"]
    return _newton_rows(pairs, device, repeats, solvers, f"newton worlds on {device}")


def _newton_rows(pairs: list[tuple[Result, str, int, int, Result | None]], device: str, repeats: int,
                 solvers: Sequence[str], label: str) -> list[dict]:
    """Each (our result, variant, n, worlds, our result with the limit solved) timed in each of ``solvers``
    of Newton's, for as many frames."""
    from .newton_compare import newton_available, time_newton

    if not newton_available():
        print("newton is not installed (pip install 'warp-cloth[bench]'): no comparison", file=sys.stderr)
        return []
    rows = []
    bar = Progress(len(pairs) * len(solvers), label)
    for mine, variant, n, worlds, solved in pairs:
        for solver in solvers:
            row = time_newton(variant, n, solver, device, frames=mine.frames, substeps=MATRIX_SUBSTEPS,
                              repeats=repeats, worlds=worlds)
            theirs = row["particle_substeps_per_second"]
            for key, ours in (("", mine), ("_solved", solved)):
                if ours is not None:
                    row[f"ours{key}_symplectic_particle_substeps_per_second"] = ours.particle_substeps_per_second
                    row[f"ours{key}_max_strain"] = ours.max_strain
                    row[f"ratio{key}"] = ours.particle_substeps_per_second / theirs if theirs and ours.stable else None
            rows.append(row)
            bar.update(len(rows))
    bar.close()
    return rows


def format_newton_table(rows: list[dict]) -> str:
    header = f"{'variant':<8} {'n^2':>9} {'Newton solver':<14} {'graph':>5} {'ms/frame':>9} " \
             f"{'particle-substeps/s':>20} {'ours (symplectic)':>18} {'ours / Newton':>13} " \
             f"{'worst strain':>12} finite"
    lines = [header, "-" * len(header)]
    for r in rows:
        ratio = f"{r['ratio']:12.1f}x" if r["ratio"] else f"{'-':>13}"
        variant = r["variant"] if r.get("worlds", 1) == 1 else f"{r['variant']} x{r['worlds']}"
        lines.append(f"{variant:<8} {r['particles']:>9} {r['solver']:<14} {str(r['graph']):>5} "
                     f"{r['ms_per_frame']:>9.3f} {r['particle_substeps_per_second']:>20.3g} "
                     f"{r['ours_symplectic_particle_substeps_per_second']:>18.3g} {ratio} "
                     f"{100 * r['max_strain']:>11.1f}% {r['finite']}")
        if r.get("ratio_solved"):
            lines.append(f"{'':<8} {'':>9} {'(ours, limit solved)':<20} {'':>9} {'':>20} "
                         f"{r['ours_solved_symplectic_particle_substeps_per_second']:>18.3g} "
                         f"{r['ratio_solved']:12.1f}x {100 * r['ours_solved_max_strain']:>11.1f}%")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="warp-cloth bench", description="Time whole runs; print a table, write JSON.",
                                     epilog=suites_help(), formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--suite", choices=sorted(SUITES), default="core", help="what to time (see below)")
    parser.add_argument("--device", default=None, help="cpu or cuda (default: cuda if available)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each case; the median is reported")
    parser.add_argument("--json", type=Path, help="where to write the results (default: out/bench-SUITE-DEVICE.json)")
    parser.add_argument("--newton", action=argparse.BooleanOptionalAction, default=True,
                        help="with the matrix and worlds suites, run the same cloths in Newton's solvers (the "
                             "'bench' extra)")
    parser.add_argument("--match", nargs="+", metavar="TEXT",
                        help="only the suite's cases whose name contains one of these texts")
    parser.add_argument("--newton-solvers", nargs="+", choices=NEWTON_SOLVERS, default=list(NEWTON_SOLVERS),
                        metavar="SOLVER", help=f"which of Newton's solvers ({', '.join(NEWTON_SOLVERS)}; default: all)")
    args = parser.parse_args(argv)
    wp.config.log_level = wp.LOG_ERROR
    try:
        if args.repeats < 1:
            raise SceneError("--repeats", "a whole number >= 1", args.repeats, "command line")
        try:
            resolve_device(args.device)
        except SceneError as exc:
            raise SceneError("--device", exc.expected, exc.got, "command line") from None
    except SceneError as exc:
        print(f"warp-cloth bench: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    # the integrators suite runs the seed's steps past the stable bound on purpose; its table says which blew up
    warnings.simplefilter("ignore", UnstableStepWarning)
    device = args.device or ("cuda" if wp.is_cuda_available() else "cpu")
    cases = [case for case in SUITES[args.suite].cases(device)
             if not args.match or any(text in case.name for text in args.match)]
    if not cases:
        print(f"warp-cloth bench: error: --match: expected text in a case's name of the {args.suite} suite, got "
              f"{' '.join(args.match)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    label = f"bench {args.suite} on {device}"
    bar = Progress(len(cases), label, every=0)  # off a terminal, a line as each case starts: a case may take minutes
    results = []
    for k, case in enumerate(cases):
        bar.update(k, f"{label}, timing {case.name}")
        results.append(time_case(case, device, args.repeats))
    bar.update(len(cases), label)
    bar.close()
    env = environment(device)
    print(f"device: {env['device']} ({env['device_alias']}), cpu: {env['cpu']}, warp {env['warp']}, "
          f"commit {env['commit']}, median of {args.repeats}")
    print(format_table(results))
    scaling = collision_scaling(device, args.repeats) if args.suite == "collision" else []
    if scaling:
        print(format_collision_table(scaling))
    compare = {"matrix": newton_comparison, "worlds": newton_world_comparison}.get(args.suite)
    newton_rows = compare(results, device, args.repeats, args.newton_solvers) if compare is not None and args.newton \
        else []
    if newton_rows:
        print(format_newton_table(newton_rows))
    path = args.json or Path("out") / f"bench-{args.suite}-{device.replace(':', '')}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"suite": args.suite, "repeats": args.repeats, "environment": env,
               "results": [dict(dataclasses.asdict(r), median_seconds=r.median_seconds,
                                particle_substeps_per_second=r.particle_substeps_per_second,
                                ms_per_frame=r.ms_per_frame) for r in results],
               "collision_substep": [dict(dataclasses.asdict(r), ns_per_particle=r.ns_per_particle) for r in scaling],
               "newton": newton_rows}
    path.write_text(json.dumps(payload, indent=2))
    stable = [r for r in results if r.stable]
    blew_up = len(results) - len(stable)
    best = max(stable, key=lambda r: r.particle_substeps_per_second) if stable else None
    print(f"bench {args.suite}: {counted(len(results), 'case')} on {env['device']}"
          + (f", {blew_up} blew up" if blew_up else "")
          + (f"; best {best.particle_substeps_per_second:.3g} particle-substeps/s ({best.case})" if best else "")
          + f"; wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
