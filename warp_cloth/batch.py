"""Many independent scenes stepped together: worlds in one particle buffer, one launch per pass.

A batch packs its scenes (its worlds) into one scene whose cloths, spheres and mesh colliders are the
worlds' in world order, renamed ``w<world>_<name>``, and a ``model.Worlds`` that says which world each
belongs to and what each world has of its own: gravity and ground. The kernels then keep every world to
itself: colliders act on their world's particles only, particles of different worlds never collide, and
the spatial hash puts each world's cells apart. What a pass does for a world is what it does for that
scene alone, so each world's frames are those of its scene run by itself, to rounding (see ``Batch``).
Each world takes the step its scene alone takes (its own, or the one chosen for it: ``stability``), and
worlds whose steps differ cannot share a launch (every kernel takes one substep length): a batch packs
each step's worlds apart and steps those groups one after another.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence

import numpy as np

from .errors import SceneError, UnstableSimulation
from .geometry_checks import validate
from .model import Model, Worlds, build_model
from .output import RunOutcome
from .pin_selection import select_pins
from .scene import Pin, Scene
from .shot_clock import with_start
from .simulator import RunSummary, Simulator
from .start_projection import StartedPast, StartReport
from .stability import resolve_step, scene_with_step

def shared_settings(scene: Scene) -> dict[str, object]:
    """What the worlds of a batch share, by key (``simulation.substeps``, ``collision``, ...): every
    setting of the scene's ``[simulation]`` but gravity (each world's own) and frames (the run's), and its
    ``[collision]``, ``[implicit]`` and ``[wind]`` tables whole. Its clock's start is its shot's where it
    sets none: worlds of shots that start apart are stepped apart."""
    scene = with_start(scene)
    shared = {f"simulation.{k}": v for k, v in dataclasses.asdict(scene.simulation).items()
              if k not in ("gravity", "frames")}
    for table in ("collision", "implicit", "wind"):
        settings = getattr(scene, table)
        shared[table] = None if settings is None else dataclasses.asdict(settings)
    return shared


def step_key(scene: Scene) -> str:
    """``shared_settings`` of the scene as a simulator runs it (``stability.scene_with_step``: substeps auto
    where it sets no step), as one text: scenes with the same key can be stepped by the same launches, each
    at the step it takes alone, or with substeps auto, from the stable floor it starts at alone (part of the
    key), at the counts the simulator chooses for all of them. Cheap for a scene whose step is set; else
    it builds the scene's model."""
    if scene.simulation.auto_substeps:
        scene, choice = resolve_step(scene, build_model(scene))
        return json.dumps({**shared_settings(scene), "substeps auto, from": choice.substeps}, sort_keys=True,
                          default=str)
    return json.dumps(shared_settings(scene_with_step(scene)), sort_keys=True, default=str)


def step_groups(scenes: Sequence[Scene]) -> list[list[int]]:
    """The scenes' indices by step (``step_key``), each group in order, the groups in the order their
    first scene comes."""
    groups: dict[str, list[int]] = {}
    keys: dict[int, str] = {}  # by scene: copies of one scene keyed once
    for w, scene in enumerate(scenes):
        if id(scene) not in keys:
            keys[id(scene)] = step_key(scene)
        groups.setdefault(keys[id(scene)], []).append(w)
    return list(groups.values())


def _renamed(name: str, world: int) -> str:
    return f"w{world}_{name}"


def _pin_in_world(pin: Pin, world: int, chosen: np.ndarray | None) -> Pin:
    """A pin of world ``world`` in the packed scene: its names renamed as its world's, and where ``chosen``
    (the particles it selected in its own scene), pinning those by index."""
    changes: dict = {}
    if pin.target is not None and not pin.target.startswith("/"):
        changes["target"] = _renamed(pin.target, world)
    if pin.name is not None:
        changes["name"] = _renamed(pin.name, world)
    if chosen is not None:
        changes.update(indices=tuple(int(i) for i in chosen), corners=(), edges=(), region=None, group=None,
                       near=None)
    return dataclasses.replace(pin, **changes) if changes else pin


def pack(scenes: Sequence[Scene]) -> tuple[Scene, Worlds]:
    """The one scene that scenes of one step (``step_key``) are simulated as, and its worlds. Give it the
    scenes with their step set (``scene_with_step``): the packed scene takes the first's."""
    first = scenes[0]
    cloths, spheres, colliders, seams = [], [], [], []
    cloth_world, sphere_start, mesh_start = [], [0], [0]
    for w, scene in enumerate(scenes):
        seams += [dataclasses.replace(seam, a=dataclasses.replace(seam.a, cloth=_renamed(seam.a.cloth, w)),
                                      b=dataclasses.replace(seam.b, cloth=_renamed(seam.b.cloth, w)))
                  for seam in scene.seams]
        # pins near a collider select in their own world (the packed scene has no ground): by index here
        near = any(pin.near is not None for cloth in scene.cloths for pin in cloth.pins)
        selections = select_pins(scene) if near else None
        for c, cloth in enumerate(scene.cloths):
            pins = tuple(_pin_in_world(pin, w, selections[c][p] if near and pin.near is not None else None)
                         for p, pin in enumerate(cloth.pins))
            cloths.append(dataclasses.replace(cloth, name=_renamed(cloth.name, w), pins=pins))
            cloth_world.append(w)
        spheres += [dataclasses.replace(s, name=_renamed(s.name, w)) for s in scene.spheres]
        colliders += [dataclasses.replace(c, name=_renamed(c.name, w)) for c in scene.colliders]
        sphere_start.append(len(spheres))
        mesh_start.append(len(colliders))
    grounds = [scene.ground for scene in scenes]
    worlds = Worlds(np.asarray(cloth_world, dtype=np.int32),
                    np.asarray([scene.simulation.gravity for scene in scenes], dtype=np.float32),
                    np.asarray([g is not None for g in grounds], dtype=np.int32),
                    np.asarray([g.surface if g is not None else 0.0 for g in grounds], dtype=np.float32),
                    np.asarray([g.friction if g is not None else 0.0 for g in grounds], dtype=np.float32),
                    np.asarray(sphere_start, dtype=np.int32), np.asarray(mesh_start, dtype=np.int32))
    packed = dataclasses.replace(with_start(first), name="batch", cloths=tuple(cloths), spheres=tuple(spheres),
                                 colliders=tuple(colliders), seams=tuple(seams), ground=None)
    return packed, worlds


@dataclasses.dataclass(frozen=True)
class StepGroup:
    """The worlds of a batch that share a step (``step_key``): one simulator of their packed scene."""

    members: tuple[int, ...]  # the batch's world indices, in order
    worlds: Worlds
    simulator: Simulator
    starts: np.ndarray  # (members + 1,): where each member's particles start in the simulator's buffer

    def particles(self, k: int) -> slice:
        return slice(int(self.starts[k]), int(self.starts[k + 1]))


class Batch:
    """Scenes (worlds) stepped together on one device: one particle buffer, one launch per pass for all
    that share a step.

    Each world keeps its own cloths, colliders, pins, gravity and ground, and never touches another. Worlds
    that share the step, the solves' settings, collision and wind settings (``shared_settings``) are
    packed together; those that differ there are packed apart, a ``StepGroup`` for each step, and the
    groups are stepped one after another (``groups``: each world's own step, at the cost of its group's
    launches). Worlds whose scenes set no step (substeps auto) are grouped by the stable floor each starts
    at alone (``step_key``, so worlds of one scene in other densities or stiffnesses may fall in
    groups of their own); a group takes one count of substeps a frame for all its worlds, chosen frame by
    frame, a frame that misses in any world made again with more for all (``warp_cloth.auto_substeps``). A
    converged
    strain solve runs until every world of its group is
    within tolerance, so a world may take more passes than alone: its frames then differ from its scene's
    alone within that tolerance; a fixed solve gives them to rounding. With the implicit step each world
    runs its own Newton loop and conjugate gradient (its own sums, step lengths and stopping test:
    kernels/cg.py), so it takes the iterations it would alone; its sums add up in another order than
    alone, so its frames equal its scene's alone to rounding and the solve's tolerance.

    A world that blows up is stopped (put back where it started, at rest, and held) and the others go on:
    ``stopped_worlds`` holds each such world's ``UnstableSimulation`` (its frame and cause); its frames from
    that one on are not valid. Once every world has stopped, ``step`` and ``run`` raise the first one's.

    ``step()`` advances every world one frame, ``run(frames)`` several; ``positions(w)`` and
    ``velocities(w)`` read world ``w``'s particles (its cloths' in order, as its scene alone has them).
    """

    def __init__(self, scenes: Sequence[Scene], device: str | None = None, graph: bool = True,
                 threads_per_particle: int | None = None) -> None:
        self.scenes = tuple(scenes)
        if not self.scenes:
            raise SceneError("scenes", "at least one scene", 0)
        # Each scene with the step it takes alone; copies of one scene (a benchmark's worlds) resolved once.
        resolved: dict[int, Scene] = {}
        for w, scene in enumerate(self.scenes):
            if id(scene) not in resolved:
                try:
                    validate(scene)
                except SceneError as exc:
                    raise exc.within(f"scenes[{w}]") from None
                resolved[id(scene)] = scene_with_step(scene)
        stepped = [resolved[id(scene)] for scene in self.scenes]
        self.groups: list[StepGroup] = []
        for members in step_groups(stepped):
            packed, worlds = pack([stepped[w] for w in members])
            sim = Simulator(packed, device=device, graph=graph, threads_per_particle=threads_per_particle,
                            worlds=worlds)
            self.groups.append(StepGroup(tuple(members), worlds, sim, sim.model.world_start))
        self._place = {w: (group, k) for group in self.groups for k, w in enumerate(group.members)}
        self._views: dict[int, WorldView] = {}

    @property
    def world_count(self) -> int:
        return len(self.scenes)

    @property
    def simulator(self) -> Simulator:
        """The simulator of a batch whose worlds share one step."""
        if len(self.groups) > 1:
            raise ValueError(f"this batch's worlds have {len(self.groups)} steps, a simulator for each: see groups")
        return self.groups[0].simulator

    @property
    def frame(self) -> int:
        """The frame every world has reached."""
        return min(group.simulator.frame for group in self.groups)

    @property
    def stopped_worlds(self) -> dict[int, UnstableSimulation]:
        return {group.members[k]: stopped for group in self.groups
                for k, stopped in group.simulator.stopped_worlds.items()}

    @property
    def start_projections(self) -> dict[int, StartReport]:
        """Each world whose cloths started past their strain limits, and what projected them onto the limits
        (``Simulator.start_projection``, with the world's own cloth indices and names; the passes and the
        solve's end are its step group's)."""
        reports: dict[int, StartReport] = {}
        for group in self.groups:
            report = group.simulator.start_projection
            if report is None:
                continue
            cloth_world = group.worlds.cloth_world  # the group's cloths are its worlds', in world order
            first_cloth = np.searchsorted(cloth_world, np.arange(len(group.members)))
            cloths: dict[int, list[StartedPast]] = {}
            for c in report.cloths:
                k = int(cloth_world[c.cloth])
                w, own = group.members[k], c.cloth - int(first_cloth[k])
                cloths.setdefault(w, []).append(dataclasses.replace(c, cloth=own, name=self.scenes[w].cloths[own].name))
            reports.update({w: dataclasses.replace(report, cloths=tuple(mine)) for w, mine in cloths.items()})
        return dict(sorted(reports.items()))

    def place(self, w: int) -> tuple[StepGroup, int]:
        """World ``w``'s group and its index there."""
        if not 0 <= w < self.world_count:
            raise IndexError(f"world {w} of a batch of {self.world_count}")
        return self._place[w]

    def step(self) -> None:
        self._each_group(lambda group: group.simulator.step())

    def run(self, frames: int, writers: dict[int, list] | None = None, progress: bool = False,
            monitors: Sequence = ()) -> RunSummary:
        """Simulate ``frames`` frames, after the preroll where a group's scenes have one still ahead, one group
        after another; ``writers``: each world's own (``UsdWriter``, ``PolyWriter``, ...), by world. A world that blows up has its writers abandoned there,
        as a run alone that fails (its frames kept under the failed names), while the others' go on.
        ``monitors``: writers of the whole batch (``strain.WorldStrain``), for a batch of one step. The
        summary counts every group's particles, substeps and time; an interrupted group ends the run."""
        if monitors and len(self.groups) > 1:
            raise ValueError("a batch's monitors read one simulator: its worlds must share one step")
        summaries: list[RunSummary] = []

        def run_group(group: StepGroup) -> None:
            if summaries and summaries[-1].interrupted:
                return
            mine = {w: writers[w] for w in group.members if writers and w in writers}
            chosen = [WorldWriters(self, mine)] if mine else []
            sim = group.simulator
            ahead = frames + max(0, sim.clock.start - sim.frame)
            summaries.append(sim.run(ahead, writers=[*chosen, *monitors], progress=progress))

        self._each_group(run_group)
        particle_substeps = sum(s.particles * s.substeps for s in summaries)
        particles = sum(s.particles for s in summaries)
        stop = next((s for s in summaries if s.interrupted), None)
        alone = summaries[0] if len(summaries) == 1 else RunSummary(0, 0, 0, 0.0, False)
        return RunSummary(min(s.frames for s in summaries), particle_substeps // max(1, particles), particles,
                          sum(s.wall_seconds for s in summaries), stop is not None,
                          None if stop is None else stop.stop_signal, frame_substeps=alone.frame_substeps,
                          kept_missing=alone.kept_missing, kept_stalled=alone.kept_stalled)

    def _each_group(self, act) -> None:
        """``act`` on every group; a group whose worlds have all stopped is left, and once every world has
        stopped the first one's ``UnstableSimulation`` is raised."""
        for group in self.groups:
            if len(group.simulator.stopped_worlds) < len(group.members):
                try:
                    act(group)
                except UnstableSimulation:
                    pass
        stopped = self.stopped_worlds
        if len(stopped) == self.world_count:
            raise stopped[min(stopped, key=lambda w: stopped[w].frame)]

    def view(self, w: int) -> "WorldView":
        """World ``w`` as its writers see it (made once)."""
        if w not in self._views:
            self._views[w] = WorldView(self, w)
        return self._views[w]

    def closest_contacts(self) -> np.ndarray | None:
        """Each world's closest approach of colliding particles, as a fraction of their contact distance
        (infinite where a world has no pair listed; None without particle collision)."""
        found = [(group, group.simulator.closest_contacts()) for group in self.groups]
        if all(contacts is None for _, contacts in found):
            return None
        closest = np.full(self.world_count, np.inf)
        for group, contacts in found:
            if contacts is not None:
                closest[list(group.members)] = contacts
        return closest

    def positions(self, w: int) -> np.ndarray:
        group, k = self.place(w)
        return group.simulator.positions()[group.particles(k)]

    def velocities(self, w: int) -> np.ndarray:
        group, k = self.place(w)
        return group.simulator.velocities()[group.particles(k)]

    def masses(self, w: int) -> np.ndarray:
        group, k = self.place(w)
        return group.simulator.model.masses[group.particles(k)]


class WorldView:
    """One world of a batch as a writer sees a simulator: its own scene (its names, its colliders), its own
    model's arrays (the faces and collider keys the writers read), and its particles' state now."""

    def __init__(self, batch: Batch, w: int) -> None:
        self.batch, self.world = batch, w
        self.scene = batch.scenes[w]
        self.model: Model = build_model(self.scene)
        self.group, k = batch.place(w)
        self.device = self.group.simulator.device
        self.clock = self.group.simulator.clock
        spheres = self.group.worlds.sphere_start
        self._spheres = slice(int(spheres[k]), int(spheres[k + 1]))

    @property
    def frame(self) -> int:
        return self.group.simulator.frame

    def positions(self) -> np.ndarray:
        return self.batch.positions(self.world)

    def velocities(self) -> np.ndarray:
        return self.batch.velocities(self.world)

    def cloth_positions(self, cloth: int, positions: np.ndarray | None = None) -> np.ndarray:
        return (self.positions() if positions is None else positions)[self.model.cloth_slice(cloth)]

    def sphere_centers(self) -> np.ndarray:
        return self.group.simulator.sphere_centers()[self._spheres]


class WorldWriters:
    """The frame writer a batch runs with: each world's writers, handed that world's view. A world that is
    stopped has its writers abandoned at the first frame it did not make, as a failed run's."""

    def __init__(self, batch: Batch, writers: dict[int, list]) -> None:
        self.batch = batch
        self.writers = {w: list(ws) for w, ws in writers.items() if ws}
        self.ended: set[int] = set()

    def _live(self):
        for w, writers in self.writers.items():
            if w not in self.ended:
                yield w, self.batch.view(w), writers

    def begin(self, sim) -> None:
        for _, view, writers in self._live():
            for writer in writers:
                writer.begin(view)

    def write_frame(self, sim, frame: int) -> None:
        stopped_worlds = self.batch.stopped_worlds
        for w, view, writers in list(self._live()):
            stopped = stopped_worlds.get(w)
            if stopped is not None:
                self._end(w, view, writers, RunOutcome(interrupted=False, error=stopped), frame - 1)
                continue
            for writer in writers:
                writer.write_frame(view, frame)

    def sync(self, sim) -> None:
        for _, view, writers in self._live():
            for writer in writers:
                if hasattr(writer, "sync"):
                    writer.sync(view)

    def finish(self, sim, frames_written: int) -> None:
        for w, view, writers in list(self._live()):
            for writer in writers:
                writer.finish(view, frames_written)
            self.ended.add(w)

    def abandon(self, sim, frames_written: int, outcome: RunOutcome) -> None:
        for w, view, writers in list(self._live()):
            self._end(w, view, writers, outcome, frames_written)

    def _end(self, w: int, view: WorldView, writers: list, outcome: RunOutcome, frames_written: int) -> None:
        self.ended.add(w)
        for writer in writers:
            if hasattr(writer, "abandon"):
                writer.abandon(view, frames_written, outcome)

    @property
    def outputs(self) -> list:
        return [path for writers in self.writers.values() for writer in writers
                for path in getattr(writer, "outputs", [])]
