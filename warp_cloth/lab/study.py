"""What accuracy costs in time: a scene run over integrators, time steps and resolutions, each run timed and
compared frame by frame with a reference run at a much smaller step.

    warp-cloth study hanging --dt 0.0025 0.00125 --frames 48

For each run: wall time per simulated second (the median frame's ``Simulator.step()`` after warm-up, no
output I/O), RMS and max position error against the reference, max strain, energy drift, and whether it
went unstable. Writes
``study.csv``, ``study.json`` and three PNG plots.

The reference is the same scene and resolution run with symplectic Euler at a step much smaller than the
study's, checked against the same run at half that step; a run's error is resolved when it is at least 10
times the difference between the two, and the reference is converged when every stable run's error is
resolved. Positions are float32, so the reference adds each step's move with compensation
(``Simulation.compensated``): without it, the thousands of small moves of a cloth far from the origin lose
their low bits (seed_default's, 66 m up, stopped converging below 0.65 ms). Refining further is still not
always better: past some step the rounding of the velocities and of the limit's passes outgrows the
truncation error (on the seed's hanging cloth, below about 0.15 ms the difference between a step and its
half grew as the step shrank, before compensation). So the study chooses the reference
step: it divides the smallest study step by 2, 4, 8, ... 32 while the difference between each step and
the next keeps shrinking, and takes the step of the smallest difference (``--reference-refinement N``
fixes the step at the smallest study step / N instead). Where a scene's motion amplifies small
differences (a fold that can fall either way), no step converges over every frame; the check then says
over how many first frames it does.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import statistics
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import warp as wp

from ..cloth_mesh import STRUCTURAL
from ..errors import EXIT_BAD_INPUT, SceneError, UnstableSimulation
from ..model import FLAG_ELASTIC_COMPRESSION, FLAG_ELASTIC_TENSION, Model, Springs
from ..progress import Progress
from ..scene import INTEGRATORS, MAX_SUBSTEPS, Cloth, Scene
from ..scene_file import load_scene
from ..simulator import Simulator, resolve_device
from ..stability import UnstableStepWarning, cap_that_fits, scene_with_step
from .bench import environment

REFERENCE_INTEGRATOR = "symplectic"
REFERENCE_REFINEMENTS = (2, 4, 8, 16, 32)  # the reference steps tried: the smallest study step over these
# A first-order reference's own error is about twice its difference from the half-step run, so requiring a
# measured error of 10 such differences keeps the reference's share of it under about a fifth.
RESOLVED_FACTOR = 10.0
WARMUP_FRAMES = 2  # compile kernels and capture the frame graph at both buffer parities: never timed
BLOWUP_DISTANCE = 1e4  # metres from the origin: a particle this far out counts as a blow-up
# A strain limit keeps a blown-up cloth bounded (it boils in place at hundreds of m/s), so a limited spring
# this many times past its limit counts as a blow-up too; an unlimited one past twice its rest length.
BLOWUP_LIMIT_FACTOR = 3.0
DEFAULT_MAX_FRAMES = 48

DEFINITIONS = {
    "seconds_per_simulated_second": f"median over the frames after the first {WARMUP_FRAMES} (kernel compilation, "
                                    "graph capture) of the wall time of Simulator.step() (device synchronised, no "
                                    "output I/O), over the frame's simulated time; the median so that a shared, noisy "
                                    "machine's hiccups do not count",
    "error_rms": "sqrt of the mean over frames 1..N and particles of |x - x_ref|^2, metres",
    "error_max": "max over frames 1..N and particles of |x - x_ref|, metres",
    "max_strain": "max over frames 0..N of |l/L - 1| over strain-limited and structural springs",
    "energy_drift": "max over frames of |E(t) - E(0)| / max(|E(0)|, 1e-12), E = kinetic + gravitational "
                    "(-m g . x, datum at the origin) + spring potential k L / 2 (l/L - 1)^2 of springs in their "
                    "elastic regime; damping, strain limits and contacts remove energy, so compare with the "
                    "reference's drift",
    "unstable_frame": "frame at which Simulator.step() raised UnstableSimulation, a position became non-finite "
                      f"or farther than {BLOWUP_DISTANCE:g} m from the origin, or a reported spring's strain went "
                      f"{BLOWUP_LIMIT_FACTOR:g} times past its strain limit (past 1 where it has none); such runs "
                      "get no numbers",
    "resolved": f"error_rms >= {RESOLVED_FACTOR:g} x the RMS difference between the reference and its half step",
    "converged_frames": "the most frames 1..K over which every stable run's error_rms would be resolved",
    "order": "least-squares slope of log error_rms against log dt over stable resolved runs, one intercept per "
             "resolution",
}


@dataclass(frozen=True)
class StudyRun:
    """One (integrator, dt, resolution) run. Unstable runs carry only ``unstable_frame``."""

    integrator: str
    resolution: int | None  # quads per side of every cloth; None: the scene's own
    particles: int
    dt_requested: float
    dt: float  # the step taken: whole substeps per frame
    substeps: int
    frames: int
    seconds_per_simulated_second: float | None
    error_rms: float | None
    error_max: float | None
    max_strain: float | None
    energy_drift: float | None
    unstable_frame: int | None
    unstable_reason: str | None
    resolved: bool | None


@dataclass(frozen=True)
class ReferenceCheck:
    """The reference of one resolution against the same run at half its step."""

    resolution: int | None
    particles: int
    integrator: str
    dt: float
    dt_half: float
    difference_rms: float
    difference_max: float
    energy_drift: float
    converged: bool
    converged_frames: int  # the first frames over which it is converged (all of them where ``converged``)


@dataclass(frozen=True)
class Study:
    scene: str
    device: str
    frames: int
    fps: float
    reference_refinements: list[int]  # the one chosen (or given) for each resolution
    runs: list[StudyRun]
    references: list[ReferenceCheck]
    orders: dict[str, float | None]
    environment: dict

    @property
    def converged(self) -> bool:
        return all(r.converged for r in self.references)


# --- Scenes -------------------------------------------------------------------------------------------


def with_resolution(scene: Scene, resolution: int) -> Scene:
    """Every cloth at (r, r) quads, with its size and total mass kept."""
    return dataclasses.replace(scene, cloths=tuple(_cloth_at(cloth, resolution) for cloth in scene.cloths))


def _cloth_at(cloth: Cloth, resolution: int) -> Cloth:
    if cloth.mesh is not None:
        raise SceneError(f"cloth {cloth.name!r}", "grid cloths with --resolutions (this one is a mesh, whose "
                         "vertices are as modelled)", has_got=False)
    if any(pin.indices for pin in cloth.pins):
        raise SceneError(f"cloth {cloth.name!r} pins", "pins by corners, edges or region with --resolutions "
                         "(indices name particles of one grid)", has_got=False)
    mass = cloth.particle_mass()  # None for density cloths, which lump area and need nothing
    if mass is not None:
        mass *= cloth.particle_count / (resolution + 1) ** 2
    return dataclasses.replace(cloth, resolution=(resolution, resolution), mass=mass)


def with_step(scene: Scene, integrator: str, frames: int, dt: float | None = None,
              substeps: int | None = None, compensated: bool = False) -> Scene:
    """The scene at a step; a converged limit solve's cap, where the scene sets one, lowered where the step's
    substeps times it would pass the bound on a frame's passes (``check_work``, which counts the cap; an
    unset cap the simulator chooses within it): the fine steps of a reference take a few passes a
    substep, far below any cap. ``compensated``: its moves summed with compensation (the references'), as
    they are anyway where the scene says so."""
    simulation = dataclasses.replace(scene.simulation, integrator=integrator, frames=frames, dt=dt,
                                     substeps=substeps, compensated=compensated or scene.simulation.compensated)
    cap, substeps = simulation.limit_max_passes, simulation.substeps_per_frame
    if simulation.limit_solve == "converged" and cap is not None and substeps is not None:
        simulation = dataclasses.replace(simulation, limit_max_passes=cap_that_fits(cap, substeps))
    return dataclasses.replace(scene, simulation=simulation)


def _option_error(option: str, exc: SceneError) -> SceneError:
    return SceneError(option, exc.expected, exc.got, "command line", exc.has_got)


# --- Measuring one run --------------------------------------------------------------------------------


def strain(springs: Springs, x: np.ndarray) -> np.ndarray:
    lengths = np.linalg.norm(x[springs.pairs[:, 0]] - x[springs.pairs[:, 1]], axis=1)
    return lengths / springs.rest.astype(np.float64) - 1.0


def strained_springs(model: Model) -> np.ndarray:
    """Mask of the springs whose strain is reported: strain-limited ones and structural ones."""
    springs = model.springs
    return (springs.kind == STRUCTURAL) | np.isfinite(springs.limit_max)


def strain_bounds(springs: Springs, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per reported spring, the strains past which a run counts as blown up."""
    rest = springs.rest[mask].astype(np.float64)
    limited = np.isfinite(springs.limit_max[mask])
    high = np.where(limited, BLOWUP_LIMIT_FACTOR * (springs.limit_max[mask] / rest - 1.0), 1.0)
    low = np.where(limited, -BLOWUP_LIMIT_FACTOR * (1.0 - springs.limit_min[mask] / rest), -np.inf)
    return low, high


def total_energy(model: Model, gravity: Sequence[float], x: np.ndarray, v: np.ndarray) -> float:
    """Kinetic + gravitational + elastic spring energy, for the strain-based force -k (l/L - 1) n."""
    m = model.masses.astype(np.float64)
    energy = 0.5 * np.sum(m * np.sum(v * v, axis=1)) - np.sum(m * (x @ np.asarray(gravity, dtype=np.float64)))
    springs = model.springs
    if springs is not None:
        s = strain(springs, x)
        acting = np.where(s > 0, springs.flags & FLAG_ELASTIC_TENSION, springs.flags & FLAG_ELASTIC_COMPRESSION)
        energy += np.sum(0.5 * springs.stiffness * springs.rest.astype(np.float64) * s * s * (acting != 0))
    return float(energy)


def instability(x: np.ndarray, strains: np.ndarray | None, bounds: tuple[np.ndarray, np.ndarray] | None) -> str | None:
    """Why this state counts as blown up, or None."""
    if not np.isfinite(x).all() or float(np.abs(x).max()) > BLOWUP_DISTANCE:
        return f"a position is non-finite or farther than {BLOWUP_DISTANCE:g} m"
    if strains is not None and ((strains < bounds[0]) | (strains > bounds[1])).any():
        return f"a spring's strain is {BLOWUP_LIMIT_FACTOR:g} times past its limit"
    return None


def timed_step(sim: Simulator) -> float:
    wp.synchronize_device(sim.device)
    started = time.perf_counter()
    sim.step()
    wp.synchronize_device(sim.device)
    return time.perf_counter() - started


@dataclass
class Trajectory:
    """What one simulated run gives; ``positions`` (frames 1..N) is kept for references only."""

    dt: float
    substeps: int
    particles: int
    frames: int
    frame_seconds: list[float] = dataclasses.field(default_factory=list)  # after the warm-up frames
    energies: list[float] = dataclasses.field(default_factory=list)
    max_strain: float | None = None
    unstable_frame: int | None = None
    unstable_reason: str | None = None
    positions: list[np.ndarray] = dataclasses.field(default_factory=list)
    frame_squared_errors: list[float] = dataclasses.field(default_factory=list)  # frames 1..N
    error_max: float = 0.0

    @property
    def seconds_per_simulated_second(self) -> float | None:
        return statistics.median(self.frame_seconds) / (self.substeps * self.dt) if self.frame_seconds else None

    @property
    def error_rms(self) -> float:
        return math.sqrt(sum(self.frame_squared_errors) / (len(self.frame_squared_errors) * self.particles))

    @property
    def energy_drift(self) -> float:
        e = np.asarray(self.energies)
        return float(np.max(np.abs(e - e[0])) / max(abs(e[0]), 1e-12))

    def record(self, energy: float, strains: np.ndarray | None, x: np.ndarray, reference: np.ndarray | None) -> None:
        self.energies.append(energy)
        if strains is not None:
            self.max_strain = max(self.max_strain or 0.0, float(np.abs(strains).max()))
        if reference is not None:
            distance = np.linalg.norm(x - reference, axis=1)
            self.frame_squared_errors.append(float(np.sum(distance * distance)))
            self.error_max = max(self.error_max, float(distance.max()))


def simulate(scene: Scene, device: str, frames: int, reference: Sequence[np.ndarray] | None = None,
             keep_positions: bool = False, tick: Callable[[int], None] = lambda n: None) -> Trajectory:
    """Run ``frames`` frames, timing only ``Simulator.step()`` after the warm-up frames; the state is read
    after each timed step, outside the timed region."""
    with warnings.catch_warnings():  # a study runs steps past the stable bound on purpose, and measures them
        warnings.simplefilter("ignore", UnstableStepWarning)
        sim = Simulator(scene, device=device)
    model, gravity, springs = sim.model, scene.simulation.gravity, sim.model.springs
    mask = strained_springs(model) if springs is not None else None
    bounds = strain_bounds(springs, mask) if springs is not None else None
    run = Trajectory(sim.dt, sim.substeps_per_frame, model.particle_count, frames)
    x = sim.positions().astype(np.float64)
    run.record(total_energy(model, gravity, x, sim.velocities().astype(np.float64)),
               None if mask is None else strain(springs, x)[mask], x, None)
    for frame in range(1, frames + 1):
        try:
            seconds = timed_step(sim)
            positions = sim.positions()
            x = positions.astype(np.float64)
            strains = None if mask is None else strain(springs, x)[mask]
            run.unstable_reason = instability(x, strains, bounds)
        except UnstableSimulation as exc:
            run.unstable_reason = exc.reason
        if run.unstable_reason is not None:
            run.unstable_frame = frame
            tick(frames - frame + 1)
            return run
        if frame > WARMUP_FRAMES:
            run.frame_seconds.append(seconds)
        run.record(total_energy(model, gravity, x, sim.velocities().astype(np.float64)), strains, x,
                   None if reference is None else reference[frame - 1])
        if keep_positions:
            run.positions.append(positions)
        tick(1)
    return run


# --- The study ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Planned:
    integrator: str
    dt: float
    resolution: int | None
    scene: Scene


def _plan(scene: Scene, integrators: Sequence[str], dts: Sequence[float], resolutions: Sequence[int | None],
          frames: int) -> list[_Planned]:
    """Every run's scene, built (and so checked) before anything runs."""
    if not integrators:
        raise SceneError("--integrators", "at least one of " + ", ".join(INTEGRATORS), has_got=False,
                         source="command line")
    planned = []
    for resolution in resolutions:
        if resolution is not None and resolution < 1:
            raise SceneError("--resolutions", "quads per side, whole numbers >= 1", resolution, "command line")
        try:
            base = scene if resolution is None else with_resolution(scene, resolution)
        except SceneError as exc:
            raise _option_error("--resolutions", exc) from None
        for integrator in integrators:
            if integrator not in INTEGRATORS:
                raise SceneError("--integrators", "one of " + ", ".join(INTEGRATORS), integrator, "command line")
            for dt in dts:
                try:
                    planned.append(_Planned(integrator, dt, resolution, with_step(base, integrator, frames, dt=dt)))
                except SceneError as exc:
                    raise _option_error(f"--{exc.key}", exc) from None
    return planned


def _reference_run(scene: Scene, device: str, frames: int, substeps: int, tick: Callable[[int], None],
                   compared_with: Trajectory | None = None) -> Trajectory:
    """A candidate reference (kept frame by frame), compared with the one at twice its step where given."""
    reference = with_step(scene, REFERENCE_INTEGRATOR, frames, substeps=substeps, compensated=True)
    run = simulate(reference, device, frames, None if compared_with is None else compared_with.positions,
                   keep_positions=True, tick=tick)
    if run.unstable_frame is not None:
        raise SceneError("reference", f"a scene that stays stable with {REFERENCE_INTEGRATOR} Euler at dt "
                         f"{run.dt:.3g} s (at frame {run.unstable_frame}: {run.unstable_reason})",
                         has_got=False, source=scene.name)
    return run


def _check_reference(scene: Scene, device: str, frames: int, study_substeps: int, refinements: Sequence[int],
                     tick: Callable[[int], None]) -> tuple[int, Trajectory, Trajectory]:
    """The reference's refinement, the reference and the same at half its step, compared with it: of
    ``refinements`` (each twice the one before) the one whose difference from half its step is the
    smallest, trying finer ones only while that difference shrinks."""
    best = None
    coarser = _reference_run(scene, device, frames, refinements[0] * study_substeps, tick)
    for k, refinement in enumerate(refinements):
        half = _reference_run(scene, device, frames, 2 * refinement * study_substeps, tick, compared_with=coarser)
        if best is not None and half.error_rms >= best[2].error_rms:
            tick(frames * (len(refinements) - k - 1))
            break
        best = (refinement, coarser, half)
        coarser = half
    return best


def converged_frames(reference_check: Trajectory, runs: Sequence[Trajectory]) -> int:
    """The most first frames 1..K over which every stable run's error is at least RESOLVED_FACTOR times the
    reference's difference from its half step (RMS over those frames)."""
    check = np.cumsum(reference_check.frame_squared_errors)
    stable = [np.cumsum(r.frame_squared_errors) for r in runs if r.unstable_frame is None]
    resolved = np.ones(len(check), dtype=bool)
    for errors in stable:
        resolved &= errors >= RESOLVED_FACTOR ** 2 * check
    return int(np.flatnonzero(resolved)[-1]) + 1 if resolved.any() else 0


def _study_run(planned: _Planned, run: Trajectory, resolved_above: float) -> StudyRun:
    stable = run.unstable_frame is None
    rms = run.error_rms if stable else None
    return StudyRun(planned.integrator, planned.resolution, run.particles, planned.dt, run.dt, run.substeps,
                    run.frames, run.seconds_per_simulated_second if stable else None, rms,
                    run.error_max if stable else None, run.max_strain if stable else None,
                    run.energy_drift if stable else None, run.unstable_frame, run.unstable_reason,
                    rms >= resolved_above if stable else None)


def convergence_order(runs: Sequence[StudyRun]) -> float | None:
    """Slope of log error against log dt over the stable resolved runs, one intercept per resolution."""
    dx, dy = [], []
    for resolution in {r.resolution for r in runs}:
        group = [(math.log(r.dt), math.log(r.error_rms)) for r in runs
                 if r.resolution == resolution and r.resolved and r.error_rms > 0]
        if len({x for x, _ in group}) < 2:
            continue
        mx, my = np.mean([x for x, _ in group]), np.mean([y for _, y in group])
        dx += [x - mx for x, _ in group]
        dy += [y - my for _, y in group]
    if not dx:
        return None
    return float(np.dot(dx, dy) / np.dot(dx, dx))


def run_study(scene: Scene | str | Path, integrators: Sequence[str] = INTEGRATORS, dts: Sequence[float] | None = None,
              resolutions: Sequence[int] | None = None, frames: int | None = None, device: str | None = None,
              reference_refinement: int | None = None, progress: bool = True) -> Study:
    """Run every (integrator, dt, resolution) of a scene (a ``Scene``, a built-in name or a TOML path) and
    measure it against a reference. Defaults: the scene's step and its half and quarter, the scene's
    resolution, the scene's frames up to 48, the reference's step chosen (see above) unless
    ``reference_refinement`` fixes it. Bad input raises ``SceneError`` before anything runs."""
    scene = scene if isinstance(scene, Scene) else load_scene(scene)
    step = scene_with_step(scene).simulation.time_step
    dts = list(dts) if dts else [step, step / 2, step / 4]
    frames = frames if frames is not None else min(scene.simulation.frames, DEFAULT_MAX_FRAMES)
    if frames <= WARMUP_FRAMES:
        raise SceneError("--frames", f"a whole number > {WARMUP_FRAMES} (the first {WARMUP_FRAMES} are not timed)",
                         frames, "command line")
    if reference_refinement is not None and reference_refinement < 1:
        raise SceneError("--reference-refinement", "a whole number >= 1", reference_refinement, "command line")
    resolutions_or_own: list[int | None] = list(resolutions) if resolutions else [None]
    planned = _plan(scene, integrators, dts, resolutions_or_own, frames)
    try:
        dev = resolve_device(device).alias
    except SceneError as exc:
        raise _option_error("--device", exc) from None
    study_substeps = max(p.scene.simulation.substeps_per_frame for p in planned)
    if reference_refinement is not None:
        refinements = [reference_refinement]
        if 2 * reference_refinement * study_substeps > MAX_SUBSTEPS:  # checked against one at half its step
            raise SceneError("--reference-refinement", f"a reference of at most {MAX_SUBSTEPS} substeps a frame at "
                             f"half its step (the smallest study step / N), {2 * reference_refinement * study_substeps}"
                             " asked: a smaller N or larger --dt", reference_refinement, "command line")
    else:
        refinements = [r for r in REFERENCE_REFINEMENTS if 2 * r * study_substeps <= MAX_SUBSTEPS]
        if not refinements:
            coarsest = 2 * REFERENCE_REFINEMENTS[0]
            shortest = coarsest / (scene.simulation.fps * MAX_SUBSTEPS)
            raise SceneError("--dt", f"a smallest step of at least {shortest:.3g} s (the reference is {coarsest} "
                                     f"times finer, at most {MAX_SUBSTEPS} substeps a frame)", min(dts), "command line")
    bar = Progress(frames * (len(planned) + (len(refinements) + 1) * len(resolutions_or_own)),
                   f"study {scene.name} on {dev}") if progress else None
    tick = (lambda n: bar.update(bar.done + n)) if bar else (lambda n: None)
    runs, references, chosen = [], [], []
    try:
        for resolution in resolutions_or_own:
            at_resolution = [p for p in planned if p.resolution == resolution]
            refinement, reference, half = _check_reference(at_resolution[0].scene, dev, frames, study_substeps,
                                                           refinements, tick)
            resolved_above = RESOLVED_FACTOR * half.error_rms
            trajectories = [simulate(p.scene, dev, frames, reference.positions, tick=tick) for p in at_resolution]
            group = [_study_run(p, run, resolved_above) for p, run in zip(at_resolution, trajectories)]
            runs += group
            chosen.append(refinement)
            references.append(ReferenceCheck(resolution, reference.particles, REFERENCE_INTEGRATOR, reference.dt,
                                             half.dt, half.error_rms, half.error_max, reference.energy_drift,
                                             all(r.resolved for r in group if r.unstable_frame is None),
                                             converged_frames(half, trajectories)))
    finally:
        if bar:
            bar.close()
    orders = {i: convergence_order([r for r in runs if r.integrator == i]) for i in integrators}
    return Study(scene.name, dev, frames, scene.simulation.fps, chosen, runs, references, orders,
                 environment(dev))


# --- Output -------------------------------------------------------------------------------------------


def study_json(study: Study) -> dict:
    return {"scene": study.scene, "device": study.device, "frames": study.frames, "fps": study.fps,
            "environment": study.environment, "definitions": DEFINITIONS,
            "reference": {"integrator": REFERENCE_INTEGRATOR, "refinements": study.reference_refinements,
                          "rule": "same scene and resolution, smallest study step / refinement (for each "
                                  "resolution, of 2, 4, ..., 32 the one whose difference from half its step is the "
                                  "smallest, unless given), positions summed with compensation; checked against "
                                  "half its step",
                          "converged": study.converged,
                          "checks": [dataclasses.asdict(r) for r in study.references]},
            "orders": study.orders, "runs": [dataclasses.asdict(r) for r in study.runs]}


def write_csv(study: Study, path: Path) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=[f.name for f in dataclasses.fields(StudyRun)])
        writer.writeheader()
        writer.writerows(dataclasses.asdict(r) for r in study.runs)


def write_study(study: Study, out: Path) -> list[Path]:
    """study.csv, study.json and the three plots; returns the paths."""
    import matplotlib

    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "study.csv", out / "study.json"]
    write_csv(study, paths[0])
    paths[1].write_text(json.dumps(study_json(study), indent=2))
    matplotlib.use("Agg")
    for name, plot in (("error_vs_time", plot_error_vs_time), ("error_vs_dt", plot_error_vs_dt),
                       ("time_vs_resolution", plot_time_vs_resolution)):
        paths.append(out / f"{name}.png")
        plot(study, paths[-1])
    return paths


def pareto_front(runs: Sequence[StudyRun]) -> list[StudyRun]:
    """The stable runs that no other run beats in both error and time, fastest first."""
    points = [(r.seconds_per_simulated_second, r.error_rms, r) for r in runs
              if r.error_rms and r.seconds_per_simulated_second]
    front = [r for t, e, r in points if not any(u <= t and f <= e and (u, f) != (t, e) for u, f, _ in points)]
    return sorted(front, key=lambda r: r.seconds_per_simulated_second)


def _by_integrator(study: Study) -> dict[str, list[StudyRun]]:
    return {i: [r for r in study.runs if r.integrator == i and r.error_rms] for i in study.orders}


def _style(study: Study, integrator: str) -> dict:
    """One colour and marker per integrator, the same in every plot."""
    k = list(study.orders).index(integrator)
    return {"color": f"C{k}", "marker": "osD^v"[k % 5]}


def _save(figure, axes, title: str, path: Path, **legend) -> None:
    import matplotlib.pyplot as plt

    axes.set_title(title)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(**legend)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def plot_error_vs_time(study: Study, path: Path) -> None:
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7, 5))
    for integrator, runs in _by_integrator(study).items():
        timed = [r for r in runs if r.seconds_per_simulated_second]
        axes.loglog([r.seconds_per_simulated_second for r in timed], [r.error_rms for r in timed], linestyle="none",
                    label=integrator, **_style(study, integrator))
    front = pareto_front(study.runs)
    axes.loglog([r.seconds_per_simulated_second for r in front], [r.error_rms for r in front], "k--",
                drawstyle="steps-post", marker="o", markerfacecolor="none", markersize=13, label="Pareto front")
    axes.set_xlabel("wall time per simulated second (s)")
    axes.set_ylabel("RMS position error (m)")
    _save(figure, axes, f"{study.scene}: error vs cost on {study.device}", path)


def plot_error_vs_dt(study: Study, path: Path) -> None:
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7, 5))
    for integrator, runs in _by_integrator(study).items():
        order = study.orders[integrator]
        label = f"{integrator} (order {'n/a' if order is None else format(order, '.2f')})"
        axes.loglog([r.dt for r in runs], [r.error_rms for r in runs], linestyle="none", markerfacecolor="none",
                    label=label, **_style(study, integrator))
    axes.set_xlabel("time step dt (s)")
    axes.set_ylabel("RMS position error (m)")
    _save(figure, axes, f"{study.scene}: error vs time step", path)


def plot_time_vs_resolution(study: Study, path: Path) -> None:
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(9, 5))
    for integrator in study.orders:
        dts = sorted({r.dt for r in study.runs if r.integrator == integrator})
        for k, dt in enumerate(dts):
            runs = sorted((r for r in study.runs if r.integrator == integrator and r.dt == dt
                           and r.seconds_per_simulated_second), key=lambda r: r.particles)
            if runs:
                axes.loglog([r.particles for r in runs], [r.seconds_per_simulated_second for r in runs],
                            alpha=1.0 - 0.6 * k / max(1, len(dts) - 1), label=f"{integrator} dt {dt * 1e3:.3g} ms",
                            **_style(study, integrator))
    axes.set_xlabel("particles")
    axes.set_ylabel("wall time per simulated second (s)")
    _save(figure, axes, f"{study.scene}: cost vs resolution on {study.device} (fainter: larger dt)", path,
          loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")


def _number(value: float | None, width: int, spec: str = ".3g") -> str:
    return f"{'-' if value is None else format(value, spec):>{width}}"


def format_table(study: Study) -> str:
    header = (f"{'integrator':<10} {'res':>5} {'particles':>9} {'dt ms':>8} {'substeps':>8} {'s/sim s':>9} "
              f"{'rms err m':>10} {'max err m':>10} {'max strain':>10} {'E drift':>9}  status")
    lines = [header, "-" * len(header)]
    for r in study.runs:
        status = (f"unstable at frame {r.unstable_frame}: {r.unstable_reason}" if r.unstable_frame is not None
                  else "ok" if r.resolved else "below reference resolution")
        lines.append(f"{r.integrator:<10} {r.resolution or 'scene':>5} {r.particles:>9} {r.dt * 1e3:>8.4g} "
                     f"{r.substeps:>8} {_number(r.seconds_per_simulated_second, 9)} {_number(r.error_rms, 10)} "
                     f"{_number(r.error_max, 10)} {_number(r.max_strain, 10)} {_number(r.energy_drift, 9)}  {status}")
    for c in study.references:
        lines.append(f"reference {c.resolution or 'scene'}: {c.integrator} dt {c.dt * 1e3:.4g} ms vs "
                     f"{c.dt_half * 1e3:.4g} ms: difference rms {c.difference_rms:.3g} m, max "
                     f"{c.difference_max:.3g} m, energy drift {c.energy_drift:.3g}; "
                     + ("converged" if c.converged else "NOT converged (some errors are below its resolution)"
                        + (f"; converged over frames 1..{c.converged_frames} (--frames {c.converged_frames})"
                           if c.converged_frames > WARMUP_FRAMES else "")))
    return "\n".join(lines)


def summary_line(study: Study, out: Path) -> str:
    unstable = sum(r.unstable_frame is not None for r in study.runs)
    orders = ", ".join(f"{i} {'n/a' if o is None else format(o, '.2f')}" for i, o in study.orders.items())
    horizon = min(c.converged_frames for c in study.references)
    reference = "" if study.converged else "; reference NOT converged" + (
        f" (it is over frames 1..{horizon})" if horizon > WARMUP_FRAMES else "")
    return (f"study {study.scene}: {len(study.runs)} runs ({unstable} unstable) on {study.device}; orders {orders}"
            f"{reference}; wrote {out}/")


# --- Command line -------------------------------------------------------------------------------------


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="warp-cloth study",
        description="What accuracy costs in time: run a scene over integrators, time steps and resolutions; "
                    "time each run and compare it frame by frame with a reference at a much smaller step.")
    parser.add_argument("scene", help="built-in scene name or path to a .toml file")
    parser.add_argument("--integrators", nargs="+", choices=INTEGRATORS, default=list(INTEGRATORS))
    parser.add_argument("--dt", nargs="+", type=float, help="time steps in seconds (default: the scene's, /2, /4)")
    parser.add_argument("--resolutions", nargs="+", type=int,
                        help="quads per side of every cloth, size and total mass kept (default: the scene's)")
    parser.add_argument("--frames", type=int,
                        help=f"frames per run (default: the scene's, at most {DEFAULT_MAX_FRAMES})")
    parser.add_argument("--device", help="cpu, cuda or cuda:N (default: cuda if available, else cpu)")
    parser.add_argument("--reference-refinement", type=int, metavar="N",
                        help="reference step = smallest study step / N (default: of 2, 4, ..., 32 the one whose "
                             "difference from half its step is the smallest)")
    parser.add_argument("--out", type=Path, help="output folder (default: out/study-SCENE)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    wp.config.log_level = wp.LOG_ERROR
    try:
        study = run_study(args.scene, args.integrators, args.dt, args.resolutions, args.frames, args.device,
                          args.reference_refinement)
    except SceneError as exc:
        print(f"warp-cloth study: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    out = args.out or Path("out") / f"study-{study.scene}"
    write_study(study, out)
    print(format_table(study))
    print(summary_line(study, out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
