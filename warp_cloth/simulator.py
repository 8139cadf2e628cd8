"""The simulator: a scene's model on a device, the plan of a substep (warp_cloth/plan.py), and the frame loop."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Protocol

import numpy as np
import warp as wp

from warp_cloth.kernels import guard

from .auto_substeps import FrameStart, SolveCaps, SubstepChoice, flagged_at, judge, miss_size
from .checkpoint import Checkpoint, load_checkpoint, restore, save_checkpoint
from .collider_kinds import Meshes
from .errors import SceneError, UnstableSimulation
from .geometry_checks import validate
from .model import Model, Worlds, build_model
from .output import RunOutcome
from .progress import Progress, SlowStepNotice
from .device_model import DeviceModel
from .implicit import SolveStats
from .integrators import Integrator, integrator_for
from .pin_reach import check_pins_within_reach
from .displacement_bounds import DisplacementBounds
from .face_contacts import FaceContacts
from .limit_solve import LimitSolveSettings
from .cloth_lines import cloth_lines
from .line_solve import LineSolves
from .control import Control
from .plan import Plan, build_plan
from .scene import Scene
from .shot_clock import ShotClock, shot_clock
from .stability import (AUTOMATIC_MAX_SUBSTEPS, MAX_PASSES_PER_FRAME, UnstableStepWarning, at_substeps,
                        beyond_bound_message, resolve_step)
from .start_projection import StartReport
from .state import DeviceState
from .substep_rounds import SubstepRounds
from .surface_start import refuse_surfaces_closer_than_thickness
from .warp_init import init_warp

# Rough upper bounds per particle, to refuse a scene before allocating: host arrays while building
# (float64 grids, spring lists, sorting) and device arrays (state, springs and their adjacency).
HOST_BYTES_PER_PARTICLE = 900
DEVICE_BYTES_PER_PARTICLE = 320  # and the integrator's own (``Integrator.device_bytes_per_particle``)
COLLISION_DEVICE_BYTES_PER_PARTICLE = 320  # neighbour lists, spatial hash buckets, contact state
# A mesh collider: its triangles' indices and BVH nodes, its vertices' points and velocities, and for an
# animated one its samples (float64 on the host as read, float32 on the device).
COLLIDER_BYTES_PER_TRIANGLE = 96
COLLIDER_BYTES_PER_VERTEX = 24
HOST_BYTES_PER_SAMPLED_VERTEX = 36
DEVICE_BYTES_PER_SAMPLED_VERTEX = 12



class FrameWriter(Protocol):
    """Receives the state after every frame the run writes, by its number on the shot's clock (the first is
    the initial state, or the state the preroll left; see ``warp_cloth.shot_clock``).

    ``finish`` ends a run that completed. A writer may also have ``sync(sim)``, called every
    ``Simulator.SYNC_SECONDS`` and before the run ends, to make the frames so far safe on disk, and
    ``abandon(sim, frames_written, outcome)``, called instead of ``finish`` when the run was stopped by a
    signal or failed (``warp_cloth.output.RunOutcome``); a writer without it gets ``finish``. A writer with
    kernels of its own may have ``load_kernels(sim)``, called with the simulator's, before the run's clock starts.
    """

    def begin(self, sim: "Simulator") -> None: ...

    def write_frame(self, sim: "Simulator", frame: int) -> None: ...

    def finish(self, sim: "Simulator", frames_written: int) -> None: ...


@dataclass(frozen=True)
class RunSummary:
    frames: int
    substeps: int  # simulated, frames made again with more substeps included
    particles: int
    wall_seconds: float
    interrupted: bool
    stop_signal: int | None = None  # the signal that stopped an interrupted run
    prepare_seconds: float = 0.0  # before the clock of ``wall_seconds``: kernels compiled or loaded (``prepare``)
    frame_substeps: tuple[int, ...] = ()  # with substeps auto: each frame's, as kept
    kept_missing: int = 0  # with substeps auto: frames kept at the most substeps a frame takes though they missed
    kept_stalled: int = 0  # with substeps auto: frames kept though they missed, more substeps not shrinking the miss

    @property
    def particle_substeps_per_second(self) -> float:
        return self.particles * self.substeps / self.wall_seconds if self.wall_seconds > 0 else float("inf")


def resolve_device(device: str | None) -> wp.context.Device:
    init_warp()
    name = device or ("cuda" if wp.is_cuda_available() else "cpu")
    if name.startswith("cuda") and not wp.is_cuda_available():
        raise SceneError("device", "'cpu' (no CUDA device is available here)", name)
    try:
        return wp.get_device(name)
    except (RuntimeError, ValueError):
        raise SceneError("device", "'cpu', 'cuda' or 'cuda:N' of an existing GPU", name) from None


def collider_bytes(scene: Scene) -> tuple[int, int]:
    """(host, device) bytes the scene's mesh colliders take beyond what reading them took."""
    host = device = 0
    for collider in scene.colliders:
        surface = collider.surface()
        samples = 0
        if surface.key_points is not None:
            samples = len(surface.key_times)
        elif collider.keys:
            samples = len(collider.keys) + int((collider.keys[-1].time - collider.keys[0].time) * scene.simulation.fps) + 1
        vertices = len(surface.points)
        host += samples * vertices * HOST_BYTES_PER_SAMPLED_VERTEX
        device += (len(surface.triangles()) * COLLIDER_BYTES_PER_TRIANGLE + vertices * COLLIDER_BYTES_PER_VERTEX
                   + samples * vertices * DEVICE_BYTES_PER_SAMPLED_VERTEX)
    return host, device


def check_memory(scene: Scene, device: wp.context.Device) -> None:
    """Refuse a scene that cannot fit, before any large allocation."""
    n = sum(c.particle_count for c in scene.cloths)
    host_free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    device_bytes = (DEVICE_BYTES_PER_PARTICLE + integrator_for(scene.simulation.integrator).device_bytes_per_particle
                    + (COLLISION_DEVICE_BYTES_PER_PARTICLE if scene.collision is not None else 0))
    collider_host, collider_device = collider_bytes(scene)
    what = f"{n} particles" + (" and the mesh colliders" if scene.colliders else "")
    key = "collider" if collider_host + collider_device > n * (HOST_BYTES_PER_PARTICLE + device_bytes) else "cloth"
    need = n * HOST_BYTES_PER_PARTICLE + collider_host + ((n * device_bytes + collider_device) if device.is_cpu else 0)
    if need > host_free:
        raise SceneError(key, f"a scene that fits in memory: {what} need about {need / 2**30:.1f} GiB of host "
                              f"memory, {host_free / 2**30:.1f} GiB is free", has_got=False)
    if device.is_cuda:
        free = device.free_memory
        need = n * device_bytes + collider_device
        if need > free:
            raise SceneError(key, f"a scene that fits on {device.name}: {what} need about {need / 2**30:.1f} GiB, "
                                  f"{free / 2**30:.1f} GiB is free", has_got=False)


def check_work(scene: Scene, substeps: int) -> None:
    """Refuse a frame that would take too long to end: substeps x passes a substep (the strain limit's or
    the collision's iterations, or the most the integrator's solve may take, whichever is more), of a scene
    as ``resolve_step`` leaves it (with substeps auto, as it runs at ``substeps``: ``stability.at_substeps``)."""
    total, factors = frame_work(at_substeps(scene, substeps) if scene.simulation.auto_substeps else scene, substeps)
    if total > MAX_PASSES_PER_FRAME:
        key = max(factors, key=factors.get)
        raise SceneError(key, f"at most {MAX_PASSES_PER_FRAME:,} passes a frame, so that a frame ends: "
                              f"{substeps} substeps x {total // substeps} passes a substep is {total:,}", factors[key])


def most_substeps(scene: Scene) -> int:
    """With substeps auto, the most a frame takes: at most ``AUTOMATIC_MAX_SUBSTEPS``, and as many as keep a
    frame within ``MAX_PASSES_PER_FRAME`` passes (the limit solve's cap fitted to them)."""
    low, high = 1, AUTOMATIC_MAX_SUBSTEPS
    while low < high:
        middle = (low + high + 1) // 2
        fits = frame_work(at_substeps(scene, middle), middle)[0] <= MAX_PASSES_PER_FRAME
        low, high = (middle, high) if fits else (low, middle - 1)
    return low


def frame_work(scene: Scene, substeps: int) -> tuple[int, dict[str, int]]:
    """The most passes a frame of ``substeps`` may take (see ``check_work``), and the scene keys that set
    them with their values."""
    sim = scene.simulation
    factors = {"simulation.dt" if sim.dt is not None else "simulation.substeps": substeps}
    limited = any(c.strain_limit for c in scene.cloths)
    converged = sim.limit_solve == "converged" and (limited or scene.collision is not None)
    iterations = {"simulation.limit_iterations": sim.limit_iterations if limited and not converged else 0,
                  "simulation.limit_max_passes": sim.limit_max_passes if converged else 0,
                  "collision.iterations": scene.collision.iterations if scene.collision is not None and not converged
                  else 0}
    iterations.update(integrator_for(sim.integrator, scene.implicit).solve_passes())
    passes = 1 + max(iterations.values())
    factors.update(iterations)
    return substeps * passes, factors


STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class StopOnSignal:
    """Turns the first Ctrl-C, SIGTERM or SIGHUP into a request to stop after the frame in progress (a second
    one stops at once), so that writers are never cut off in the middle of a frame."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._previous: dict = {}

    @property
    def requested(self) -> bool:
        return self.signal is not None

    def __enter__(self) -> "StopOnSignal":
        if threading.current_thread() is threading.main_thread():
            for number in STOP_SIGNALS:
                self._previous[number] = signal.signal(number, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum

    def __exit__(self, *exc) -> None:
        for number, previous in self._previous.items():
            signal.signal(number, previous)


class Simulator:
    """Steps a scene on a device. ``step()`` advances one frame; ``run()`` a number of frames with writers.

    Each frame's launches are captured once as a graph and replayed, on a GPU or the CPU (``graph=False``
    turns that off). Positions and velocities read back as numpy arrays of shape (particles, 3).
    ``threads_per_particle`` sets how many GPU threads gather each particle's springs, limits and contacts
    (None: chosen by the cloth's size; see kernels/gathering.py); a power of two up to 64, 1 on the CPU.
    ``plan`` is the substep's passes in order (``print(sim.plan)`` shows them); ``step_choice`` the step it
    takes and why (``print(sim)`` says it in one line, with the scene, device and particles); ``integrator``
    the scene's (warp_cloth/integrators.py); ``limit_solve`` how the plan solves the strain limits and
    contacts (warp_cloth/limit_solve.py); ``start_projection`` which cloths started past their strain
    limits and were projected onto them before the first substep (None: the state starts as the scene
    gives it, or, after ``restore``, as the checkpoint does; warp_cloth/start_projection.py).
    """

    # of the contact distance: closer starting pairs are refused. The first substep's contacts push such a pair
    # apart, and the push becomes velocity (overlap / step): 3 sheets 1 cm apart at a 1.26 cm contact distance
    # (0.80 of it) were thrown apart at 27 m/s, and every frame made again with more substeps threw them
    # faster, until a frame of 10,000 blew up (docs/notebook/layers.md).
    INITIAL_OVERLAP_LIMIT = 1.0
    INITIAL_COLLIDER_DEPTH_LIMIT = 0.5  # of a cell: particles starting deeper in a collider are refused
    SYNC_SECONDS = 2.0  # how often ``run`` has its writers make their frames safe on disk

    def __init__(self, scene: Scene, device: str | None = None, graph: bool = True,
                 threads_per_particle: int | None = None, worlds: Worlds | None = None) -> None:
        validate(scene)
        self.device = resolve_device(device)
        allowed = (1,) if self.device.is_cpu else (1, 2, 4, 8, 16, 32, 64)
        if threads_per_particle is not None and threads_per_particle not in allowed:
            raise ValueError(f"threads_per_particle must be None or a power of two up to 64 (1 on the CPU), "
                             f"got {threads_per_particle!r}")
        check_memory(scene, self.device)
        self.model: Model = build_model(scene, worlds)
        # The step (and the limit solve's cap), chosen here where the scene sets none: from now on the scene
        # is the one with them (with substeps auto, the step choice's substeps are where the run starts).
        self.scene, self.step_choice = resolve_step(scene, self.model)
        self._substeps = self.step_choice.substeps  # the next frame's (``substeps_per_frame``)
        auto = self.scene.simulation.auto_substeps
        check_work(self.scene, self.substeps_per_frame)
        if self.step_choice.beyond_bound:
            warnings.warn(UnstableStepWarning(beyond_bound_message(self.step_choice, scene.simulation)), stacklevel=2)
        self.integrator: Integrator = integrator_for(self.scene.simulation.integrator, self.scene.implicit)
        self.device_model = DeviceModel(self.model, self.scene, self.step_choice.step, self.device,
                                        masses=self.integrator.needs_masses)
        self.clock: ShotClock = shot_clock(self.scene)
        self.frame = self.clock.first  # the shot's frame number; 0 where the scene has no shot
        self.substep_count = self.clock.first * self.substeps_per_frame  # the clock: substeps since time 0
        self.substeps_run = 0  # substeps simulated, frames made again included
        self.state = DeviceState(self.model.positions, self.model.velocities, self.device_model, self.substep_count)
        self.limit_solve = LimitSolveSettings.of(
            at_substeps(self.scene, self.substeps_per_frame).simulation if auto else self.scene.simulation)
        self._threads = threads_per_particle
        # the line solves (line_solve.py): their lines found and uploaded once, for every plan built
        # (none where no cloth is limited: a seam's limited springs make no line)
        solve = self.limit_solve
        wanted = solve.line_rounds and (self.device_model.contacts is None or solve.choices.line_contacts)
        families = cloth_lines(self.model, self.scene) if wanted and self.model.limits is not None else []
        self._lines = LineSolves.of(self.device_model, families, solve.choices) if families else None
        # the displacement bounds (displacement_bounds.py: a thickness's or the lab's): made once, for every plan
        self._bounds = DisplacementBounds.of(self.model, self.device_model)
        self._control: Control | None = None  # made when first asked for (``control``)
        # the face contacts of a surface thickness (face_contacts.py): made once, for every plan built
        self._faces = FaceContacts.of(self.model, self.device_model)
        self.plan: Plan = build_plan(self.device_model, self.state, self.integrator, self.limit_solve,
                                     threads_per_particle, self._lines, self._bounds, faces=self._faces)
        # with substeps auto: their choice from frame to frame, and a copy of each frame's start to make it again
        self.auto = SubstepChoice(self.substeps_per_frame, most_substeps(self.scene)) if auto else None
        self._frame_start = FrameStart(self.carried()) if auto else None
        self._stats_since_start: SolveStats | None = None
        self._stats_unread: SolveStats | None = None  # of frames kept, read by the substeps' choice
        # An animated mesh collider's BVH refit is a host call on the CPU, which a CPU graph does not record
        # (a CUDA graph records the refit's kernels): there, launch pass by pass.
        meshes_move = self.device_model.collider_kinds[Meshes].motion
        self.use_graph = graph and not (self.device.is_cpu and meshes_move)
        self._graphs: dict[tuple[int, int], tuple[wp.Graph, int]] = {}
        self._launches_recorded = False  # without graphs: prepare() has recorded a frame (its modules are loaded)
        self._rounds = SubstepRounds(self.device, loops=not meshes_move)
        self._guard_flags()
        if self.device.is_cuda:
            self._frame_done = [wp.Event(self.device), wp.Event(self.device)]
        self.stopped_worlds: dict[int, UnstableSimulation] = {}  # of a batch: each world stopped, and why
        refuse_surfaces_closer_than_thickness(self.scene, self.model, self.device_model, self._bounds,
                                              self.state.x)
        self._refuse_initial_overlap()
        self._refuse_start_inside_colliders()
        check_pins_within_reach(self.scene, self.model)
        # cloths that start past their strain limits projected onto them (warp_cloth/start_projection.py)
        self.start_projection: StartReport | None = None if self.plan.start is None else self.plan.start.project(
            np.asarray(self.model.offsets), [c.name for c in self.scene.cloths])
        if self.start_projection is not None and self.plan.lists is not None:
            self.plan.lists.remake_now(self.state.x)  # from where the cloths now start

    def _guard_flags(self) -> None:
        """One flag per substep of a frame, set by the blow-up guard (see kernels/guard.py), in two slots
        that alternate by frame, so that a frame can run while the one before it is checked. On a GPU each
        frame ends by copying its slot to pinned host memory, and an event says when it is there."""
        flags = (2, self.substeps_per_frame, self.device_model.world_count)
        self._guard_status = wp.zeros(flags, dtype=int, device=self.device)
        if self.device.is_cuda:
            self._guard_host = wp.zeros(flags, dtype=int, device="cpu", pinned=True)

    def _refuse_initial_overlap(self) -> None:
        """Cloths that start inside each other's (or their own) contact distance would be shot apart: refuse
        them, naming the closest pair's cloths, particles and gap."""
        closest = self.plan.lists.closest_pair(self.state.x) if self.plan.lists is not None else None
        if closest is None or closest[0] >= self.INITIAL_OVERLAP_LIMIT:
            return
        ratio, i, j, distance = closest
        model = self.model
        names = [f"particle {p - model.offsets[c]} of '{self.scene.cloths[c].name}'"
                 for p, c in ((i, int(model.cloth_id[i])), (j, int(model.cloth_id[j])))]
        raise SceneError("cloth", f"cloths that start apart: {names[0]} and {names[1]} start {ratio * distance:.3g} m "
                                  f"apart, {ratio:.2f} of their contact distance of {distance:.3g} m (at least "
                                  f"{self.INITIAL_OVERLAP_LIMIT:g} needed: the first substep would push them apart "
                                  "at their overlap over a substep); move the cloths apart, make the "
                                  "contact radius smaller or leave collision out", has_got=False)

    def _refuse_start_inside_colliders(self) -> None:
        """A particle that starts deeper than half a cell below the ground or inside a static sphere is thrown
        out at depth / step and tears its cloth (a 4 m cloth around a 1.5 m sphere blows up in its second
        substep): refuse it, as ``_refuse_initial_overlap`` refuses cloths that start inside each other.
        Shallower, the push is a contact like any other. A moving sphere may start in a cloth: that is a
        moment of its motion, as in the fast_sphere hard case, which stays stable. A mesh collider, animated
        or not, is checked where it starts (inside: behind its nearest face, or within its thickness)."""
        x = self.model.positions.astype(np.float64)
        scene = self.scene
        cells = np.array([c.shortest_edge() for c in scene.cloths])
        allowed = self.INITIAL_COLLIDER_DEPTH_LIMIT * cells[self.model.cloth_id]
        depths = []  # (the first particle, the depths from it on, collider): each its own world's particles
        for kind in self.device_model.collider_kinds.values():
            depths += kind.start_depths(x, self.model, allowed)
        for first, depth, collider in depths:
            deep = np.nonzero(depth > allowed[first:first + len(depth)])[0]
            if len(deep) == 0:
                continue
            i = first + int(deep[np.argmax(depth[deep])])
            c = int(self.model.cloth_id[i])
            raise SceneError(f"cloth[{c}]", f"a cloth that starts outside the static colliders: particle "
                                            f"{i - self.model.offsets[c]} of '{scene.cloths[c].name}' starts "
                                            f"{depth[i - first]:.3g} m inside {collider} (at most {allowed[i]:.3g} m, "
                                            "half a cell); move the cloth or the collider", has_got=False)

    def __repr__(self) -> str:
        return (f"<Simulator {self.scene.name} on {self.device.alias}: {self.model.particle_count} particles, frame "
                f"{self.frame}; {self.step_choice.describe()}>")

    @property
    def dt(self) -> float:
        """The substep's length in seconds."""
        return self.plan.h

    @property
    def time(self) -> float:
        """Seconds on the shot's clock (``frame / fps`` between frames)."""
        return self.substep_count * self.dt

    def positions(self) -> np.ndarray:
        """A copy of the current positions, shape (particles, 3)."""
        return self._host_copy(self.state.x)

    def velocities(self) -> np.ndarray:
        """A copy of the current velocities, shape (particles, 3)."""
        return self._host_copy(self.state.v)

    def _host_copy(self, array: wp.array) -> np.ndarray:
        # On the CPU numpy() is a view of a buffer the next stage overwrites.
        values = array.numpy()
        return values.copy() if self.device.is_cpu else values

    def cloth_positions(self, cloth: int, positions: np.ndarray | None = None) -> np.ndarray:
        """Positions of one cloth (from ``positions`` if given, else read from the device)."""
        all_positions = self.positions() if positions is None else positions
        return all_positions[self.model.cloth_slice(cloth)]

    def sphere_centers(self) -> np.ndarray:
        """Sphere centres at the current time, shape (spheres, 3)."""
        return self._host_copy(self.state.sphere_center)

    def closest_contact(self) -> float | None:
        """The closest approach of two particles that may collide, as a fraction of their contact distance
        (1.0 or more: no pair overlaps; infinite where no pair is listed, as with a surface thickness, whose
        particles' contact distance is below it; None without particle collision). It waits for the device and
        remakes the candidate lists from the current positions."""
        contacts = self.closest_contacts()
        return None if contacts is None else float(contacts.min())

    def closest_contacts(self, remake: bool = True) -> np.ndarray | None:
        """``closest_contact`` of each world (see ``Batch``; a scene alone is one); without ``remake``, of the
        pairs the simulation listed last (no list changes, so the run goes on as it would unmeasured)."""
        if self.plan.lists is None:
            return None
        return self.plan.lists.closest_contacts(self.state.x, self.device_model.world_count, remake)

    def solver_stats(self, since_start: bool = False) -> "SolveStats | None":
        """The worst figures of the substeps since the last call, or with ``since_start`` of every substep
        since the simulator was made (reading them waits for the device): the implicit integrator's CG and
        Newton iterations and residuals, and a converged limit solve's passes and residual; None where the
        scene has neither."""
        stats = _merged(self._stats_unread, self._read_stats())
        self._stats_unread = None
        if stats is not None:
            self._stats_since_start = stats if self._stats_since_start is None else \
                self._stats_since_start.merged(stats)
        return self._stats_since_start if since_start else stats

    def _read_stats(self) -> SolveStats | None:
        """The plan's solve figures since they were last read (waits for the device), and none kept."""
        stats = self.plan.solve.read_stats() if self.plan.solve is not None else None
        if self.plan.projection is not None:
            most, residual, mean, solves = self.plan.projection.read_stats()
            stats = dataclasses.replace(stats or SolveStats(), limit_passes=most, limit_residual=residual,
                                        limit_mean_passes=mean, limit_solves=solves)
        return stats

    @property
    def substeps_per_frame(self) -> int:
        """The next frame's substeps (read only: the guard's flags, the graphs and the plan are sized for them;
        with substeps auto the simulator changes them between frames)."""
        return self._substeps

    @property
    def frame_substeps(self) -> int:
        """The substeps the last frame took (with substeps auto, as kept; before any frame, the next's)."""
        return self.auto.frames[-1] if self.auto is not None and self.auto.frames else self.substeps_per_frame

    def substep(self) -> None:
        """Advance one substep, launching pass by pass (for tests and debugging; frames are faster)."""
        self.plan.run_substep(self.state)
        self.substep_count += 1

    def step(self) -> None:
        """Advance one frame.

        A frame's launches are captured once for each buffer parity and guard slot and replayed (a CUDA
        graph on a GPU, a Warp CPU graph on the CPU); ``graph=False`` launches pass by pass instead.
        Raises ``UnstableSimulation`` if the blow-up guard flagged any of its substeps (with substeps auto,
        only at the most substeps a frame takes: below, the frame is made again with more; see
        ``warp_cloth.auto_substeps``).
        """
        if self.auto is not None:
            self._auto_frame()
        else:
            self._check_frame(self._launch_frame())

    def _auto_frame(self) -> None:
        """A frame with substeps auto: made again from its start with twice the substeps while it misses
        (below the most), then kept, and the next frame's substeps chosen."""
        arrays = self.carried()
        self._frame_start.take(arrays, self.state.parity)
        caps = self._solve_caps()
        while True:
            frame = self._launch_frame()
            status = self._guard_status_of(frame)
            stats = self._read_stats()
            flagged = bool(status.any())
            verdict = judge(stats, flagged, caps)
            more = self.auto.redo(frame, verdict, miss_size(stats, flagged, caps), flagged_at(status))
            if more is None:
                break
            self.frame -= 1
            self.state.parity = self._frame_start.parity
            self._set_substeps(more)
            self._frame_start.put_back(self.carried())
            self._set_clock()
            caps = self._solve_caps()
        self._stats_unread = _merged(self._stats_unread, stats)
        self._check_status(frame, status)
        following = self.auto.keep(frame, verdict)
        if following != self.substeps_per_frame:
            self._set_substeps(following)
            self._set_clock()

    def carried(self) -> dict[str, wp.array]:
        """What a frame starts from, by name: the state's carried arrays and the plan's (what a frame made
        again from its start puts back, what a checkpoint keeps)."""
        return {**self.state.carried(), **self.plan.carried()}

    def _solve_caps(self) -> SolveCaps:
        """The caps and tolerances of the solves at the current substeps (``auto_substeps.judge``)."""
        limit = self.limit_solve.max_passes if self.plan.projection is not None else None
        if self.plan.solve is None:
            return SolveCaps(limit)
        implicit = self.scene.implicit
        newton = implicit.newton_iterations if implicit.newton_iterations > 1 else None
        return SolveCaps(limit, implicit.cg_max_iterations, implicit.cg_tolerance, newton, implicit.newton_tolerance)

    def _set_substeps(self, substeps: int) -> None:
        """Take ``substeps`` a frame from the current frame on (with substeps auto, between frames): the
        device model's step and the plan built again for it (the old plan freed, the converged solve's
        estimated radius carried over), its frame graphs captured anew. The clock is ``_set_clock``'s."""
        self._substeps = substeps
        self.limit_solve = LimitSolveSettings.of(at_substeps(self.scene, substeps).simulation)
        self.device_model.set_step(1.0 / (self.scene.simulation.fps * substeps))
        self._build_plan_again()
        self._guard_flags()

    def _build_plan_again(self) -> None:
        """The plan built again (at the device model's step, with the control's passes once it has sent
        something), its carried arrays copied over from the old one, whose frame graphs are dropped."""
        carried = self.plan.carried()
        self._graphs.clear()
        control = self._control.passes(self.device_model) if self._control is not None and self._control.started \
            else None
        self.plan = build_plan(self.device_model, self.state, self.integrator, self.limit_solve, self._threads,
                               self._lines, self._bounds, control, faces=self._faces)
        for name, array in self.plan.carried().items():
            wp.copy(array, carried[name])

    @property
    def control(self) -> Control:
        """What a script drives between frames: named pins, spheres and mesh colliders, sent by name
        (warp_cloth/control.py: ``sim.control.pins["hand"].set_transform(translate=(0.1, 0, 0))``, then
        ``sim.step()``)."""
        if self._control is None:
            self._control = Control(self.model, self.device_model, self.state, self.scene, lambda: self.frame,
                                    self._take_control)
        return self._control

    def _take_control(self) -> None:
        """Before the control's first send: its passes in the plan, the clock (which the plan may not have
        advanced until now) set to the current frame. A mesh's refit is a host call on the CPU, which a CPU
        graph does not record: there, with mesh colliders, frames launch pass by pass from now on; on a GPU
        they no longer loop (warp_cloth/substep_rounds.py)."""
        self._control.started = True
        if self._control.moves_meshes:
            self.use_graph = self.use_graph and not self.device.is_cpu
            self._rounds.loops = False
        self._build_plan_again()
        self.state.clock.fill_(self.substep_count)

    def _set_clock(self) -> None:
        """The clock at the current frame at the current substeps, so that time stays frame / fps."""
        self.substep_count = self.frame * self.substeps_per_frame
        self.state.clock.fill_(self.substep_count)

    def _launch_frame(self) -> int:
        """Queue the next frame and return its number (its check is ``_check_frame``'s)."""
        slot = self.frame % 2
        if not self.use_graph:
            self._frame_substeps(slot)
        else:
            graph, parity_after = self._frame_graph(slot)
            wp.capture_launch(graph)
            self.state.parity = parity_after
        if self.device.is_cuda:
            wp.record_event(self._frame_done[slot])
        self.substep_count += self.substeps_per_frame
        self.substeps_run += self.substeps_per_frame
        self.frame += 1
        return self.frame

    def frame_graph(self) -> wp.Graph:
        """The captured graph of the next frame (captured now if it was not yet), for profiling its replay;
        ``step()`` is what advances the simulation."""
        return self._frame_graph(self.frame % 2)[0]

    def _frame_graph(self, slot: int) -> tuple[wp.Graph, int]:
        """The graph of a frame that starts at the current buffer parity with guard slot ``slot`` (captured
        at first use), and the parity it ends at."""
        key = (self.state.parity, slot)
        if key not in self._graphs:
            before = self.state.parity
            with wp.ScopedCapture(device=self.device) as capture:
                self._frame_substeps(slot, captured=True)
            self._graphs[key] = (capture.graph, self.state.parity)
            self.state.parity = before
        return self._graphs[key]

    def _check_frame(self, frame: int) -> None:
        """Wait for frame ``frame``'s guard flags and raise ``UnstableSimulation`` if any is set; in a batch,
        stop each world flagged instead (see ``_stop_world``), and raise only once every world has stopped."""
        self._check_status(frame, self._guard_status_of(frame))

    def _guard_status_of(self, frame: int) -> np.ndarray:
        """Frame ``frame``'s guard flags, (substeps, worlds), once the device has set them."""
        slot = (frame - 1) % 2
        if self.device.is_cuda:
            wp.synchronize_event(self._frame_done[slot])
            return self._guard_host.numpy()[slot]
        return self._guard_status.numpy()[slot]

    def _check_status(self, frame: int, status: np.ndarray) -> None:
        """``_check_frame`` of the flags ``status`` read."""
        if not status.any():
            return
        if self.model.worlds is None:
            raise self._unstable(frame, status[:, 0])
        for w in np.nonzero(status.any(axis=0))[0].tolist():
            if w not in self.stopped_worlds:
                self.stopped_worlds[w] = self._unstable(frame, status[:, w])
                self._stop_world(w)
        if len(self.stopped_worlds) == self.device_model.world_count:
            raise self.stopped_worlds[min(self.stopped_worlds, key=lambda w: self.stopped_worlds[w].frame)]

    def _stop_world(self, w: int) -> None:
        """A batch's world that blew up is put back where it started, at rest, and held there (its particles
        pinned), so that the others go on; its frames after ``stopped_worlds[w].frame - 1`` are not valid."""
        world = self.model.particle_world == w
        inv_mass = self.device_model.inv_mass.numpy()
        inv_mass[world] = 0.0
        self.device_model.inv_mass.assign(inv_mass)
        for array, start in ((self.state.x, self.model.positions), (self.state.v, np.zeros_like(self.model.positions))):
            values = array.numpy()
            values[world] = start[world]
            array.assign(values)

    def _unstable(self, frame: int, status: np.ndarray) -> UnstableSimulation:
        """What a frame whose substeps have the guard's ``status`` flags says of its blow-up."""
        first = int(np.nonzero(status)[0][0])
        sim = self.scene.simulation
        if status[first] == guard.NOT_FINITE:
            reason = "positions or velocities are no longer finite"
        else:
            reason = f"a particle moves faster than max_speed = {sim.max_speed:g} m/s"
        advice = (f"Try a smaller step than h = {self.dt:.4g} s (--dt or --substeps)"
                  f"{self.integrator.unstable_advice}; frames up to {frame - 1} are valid.")
        return UnstableSimulation(frame, first + 1, reason, advice)

    def prepare(self) -> None:
        """Compile and load the kernels of a frame now (Warp builds a kernel module at its first launch:
        seconds on a first run, a load from its cache after). ``run`` calls it before its clock starts, so
        that its wall time and progress count simulation only.

        With graphs it captures the next frame's graph; without, on the CPU, it records a frame's launches
        and runs none of them, once: a later ``run`` finds the modules loaded. Without graphs on a GPU, where
        capture may be what the user avoids, the first frame compiles."""
        slot = self.frame % 2
        if self.use_graph:
            self._frame_graph(slot)
        elif self.device.is_cpu and not self._launches_recorded:
            parity = self.state.parity
            with wp.ScopedCapture(device=self.device):
                self._frame_substeps(slot)
            self.state.parity = parity
            self._launches_recorded = True

    def save_checkpoint(self, path: str | Path) -> None:
        """Write the state the next frame needs (see ``warp_cloth.checkpoint``)."""
        save_checkpoint(self, path)

    def restore(self, checkpoint: "str | Path | Checkpoint") -> None:
        """Go back to a checkpoint of this scene (a path or a loaded ``Checkpoint``); the frames that follow
        are those the run it was taken from made. Raises ``SceneError`` if the scene changed since."""
        if not isinstance(checkpoint, Checkpoint):
            source = str(checkpoint)
            checkpoint = load_checkpoint(checkpoint)
        else:
            source = "checkpoint"
        if self.auto is not None and checkpoint.substeps_choice is None:
            raise SceneError("checkpoint", "a checkpoint of a run with substeps auto (one that keeps the substeps "
                                           "chosen)", has_got=False, source=source)
        restore(self, checkpoint, source)
        if self.auto is not None:
            self.auto.restore(checkpoint.substeps_choice)
            if self.auto.substeps != self.substeps_per_frame:
                self._set_substeps(self.auto.substeps)
            self._set_clock()
        self.start_projection = None

    def run(self, frames: int | None = None, writers: Iterable[FrameWriter] = (), progress: bool = False) -> RunSummary:
        """Simulate ``frames`` frames (default: the scene's, and its preroll where it is still ahead), handing
        every frame from the clock's start on to the writers (see ``warp_cloth.shot_clock``).

        Writers get the initial state as the start's frame when the simulation has not moved yet and has no
        preroll to run; the preroll's frames are simulated and not written. A first Ctrl-C,
        SIGTERM or SIGHUP stops the run after the frame in progress: the writers are synced and abandoned
        (see ``FrameWriter``) with every completed frame, and the summary says which signal stopped it. A
        failure (``UnstableSimulation``, a writer's error) abandons them too, then is raised. Without writers,
        each frame's blow-up check waits until the next frame is queued, so the device never idles between
        frames; ``UnstableSimulation`` then names the same frame, but the state has gone one frame further
        (with substeps auto, each frame is checked before the next is chosen).
        """
        if frames is None:
            frames = self.scene.simulation.frames + max(0, self.clock.start - self.frame)
        writers = list(writers)
        preparing = time.perf_counter()
        with SlowStepNotice("compiling kernels") if progress else contextlib.nullcontext():
            self.prepare()
            for w in writers:
                if hasattr(w, "load_kernels"):
                    w.load_kernels(self)
        prepare_seconds = time.perf_counter() - preparing
        bar = Progress(frames, f"{self.scene.name} on {self.device.alias}") if progress else None
        begun: list[FrameWriter] = []
        written = 0
        start_substeps = self.substeps_run
        start_frames, start_missing, start_stalled = ((len(self.auto.frames), self.auto.kept_missing,
                                                       self.auto.kept_stalled) if self.auto else (0, 0, 0))
        started = time.perf_counter()
        try:
            with StopOnSignal() as stop:
                for w in writers:
                    w.begin(self)
                    begun.append(w)
                if self.frame == self.clock.first and self.clock.writes(self.frame):
                    for w in writers:
                        w.write_frame(self, self.frame)
                last_sync, sync_every = time.perf_counter(), self.SYNC_SECONDS
                unchecked = None  # without writers, a frame is checked while the next one runs
                for _ in range(frames):
                    if stop.requested:
                        break
                    if self.auto is not None:  # each frame judged before the next is chosen
                        self._auto_frame()
                    else:
                        launched = self._launch_frame()
                        if writers:
                            self._check_frame(launched)
                        elif unchecked is not None:
                            self._check_frame(unchecked)
                        unchecked = None if writers else launched
                    if self.clock.writes(self.frame):
                        for w in writers:
                            w.write_frame(self, self.frame)
                    written += 1
                    if bar:
                        bar.update(written)
                    if writers and time.perf_counter() - last_sync >= sync_every:
                        sync_started = time.perf_counter()
                        _sync(writers, self)
                        last_sync = time.perf_counter()
                        # a large scene's saves take long: keep them to about a tenth of the run's time
                        sync_every = max(self.SYNC_SECONDS, 10 * (last_sync - sync_started))
                if unchecked is not None:
                    self._check_frame(unchecked)
                wp.synchronize_device(self.device)
                _sync(writers, self)
                stopped_by = stop.signal
                if stopped_by is not None:
                    begun = []
                    _abandon(writers, RunOutcome(interrupted=True), self)
                else:
                    for k, w in enumerate(writers):
                        try:
                            w.finish(self, self.frame)
                        except BaseException:
                            begun = writers[k:]
                            raise
                begun = []
        except BaseException as exc:
            _abandon(begun, RunOutcome(interrupted=False, error=exc), self)
            raise
        finally:
            if bar:
                bar.close()
        wall = time.perf_counter() - started
        chosen = tuple(self.auto.frames[start_frames:]) if self.auto else ()
        missing = self.auto.kept_missing - start_missing if self.auto else 0
        stalled = self.auto.kept_stalled - start_stalled if self.auto else 0
        return RunSummary(written, self.substeps_run - start_substeps, self.model.particle_count, wall,
                          stopped_by is not None, stopped_by, prepare_seconds, chosen, missing, stalled)

    def _frame_substeps(self, slot: int, captured: bool = False) -> None:
        """A frame's substeps with the guard's checks into ``slot``'s flags (``captured``: in a graph's capture,
        where they loop on the device, warp_cloth/substep_rounds.py)."""
        status = self._guard_status[slot]
        status.zero_()

        def check(done: wp.array, offset: int) -> None:
            wp.launch(guard.check_state, dim=self.model.particle_count,
                      inputs=[self.state.x, self.state.v, self.device_model.particle_world,
                              self.scene.simulation.max_speed, done, offset],
                      outputs=[status], device=self.device)

        self._rounds.launch(self.substeps_per_frame, captured, self.state, lambda: self.plan.run_substep(self.state),
                            check)
        if self.device.is_cuda:
            wp.copy(self._guard_host[slot], status)


def _merged(earlier: SolveStats | None, later: SolveStats | None) -> SolveStats | None:
    return later if earlier is None else earlier if later is None else earlier.merged(later)


def _sync(writers: list, sim: Simulator) -> None:
    for w in writers:
        if hasattr(w, "sync"):
            w.sync(sim)


def _abandon(writers: list, outcome: RunOutcome, sim: Simulator) -> None:
    """Every writer gets its ``abandon`` (or ``finish``), even when one of them fails; the first failure is
    raised after all have been called."""
    failure = None
    for w in writers:
        try:
            if hasattr(w, "abandon"):
                w.abandon(sim, sim.frame, outcome)
            else:
                w.finish(sim, sim.frame)
        except Exception as exc:
            failure = failure or exc
    if failure is not None and outcome.error is None:
        raise failure
