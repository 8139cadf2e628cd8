"""Many independent scenes stepped together: worlds in one particle buffer, one launch per pass.

A batch packs its scenes (its worlds) into one scene whose cloths, spheres and mesh colliders are the
worlds' in world order, renamed ``w<world>_<name>``, and a ``model.Worlds`` that says which world each
belongs to and what each world has of its own: gravity and ground. The kernels then keep every world to
itself: colliders act on their world's particles only, particles of different worlds never collide, and
the spatial hash puts each world's cells apart. What a pass does for a world is what it does for that
scene alone, so each world's frames are those of its scene run by itself, to rounding, where the steps
are the same (see ``Batch``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from .errors import SceneError, UnstableSimulation
from .model import Worlds
from .scene import Scene
from .simulator import RunSummary, Simulator

def _shared_simulation(simulation) -> dict:
    """A scene's simulation settings but those each world has of its own (gravity) or a run sets (frames)."""
    fields = dataclasses.asdict(simulation)
    fields.pop("gravity")
    fields.pop("frames")
    return fields


def _first_difference(a: dict, b: dict, prefix: str) -> str | None:
    for key in a:
        if a[key] != b[key]:
            return f"{prefix}.{key}"
    return None


def _renamed(name: str, world: int) -> str:
    return f"w{world}_{name}"


def pack(scenes: Sequence[Scene]) -> tuple[Scene, Worlds]:
    """The one scene the batch simulates, and its worlds. Settings every world must share are checked:
    the first that differs from world 0's is refused, naming the world and the key."""
    if not scenes:
        raise SceneError("scenes", "at least one scene", 0)
    first = scenes[0]
    if first.simulation.integrator == "implicit":  # its CG's scalars are sums over every particle
        raise SceneError("scenes[0].simulation.integrator", "explicit or symplectic in a batch (the implicit step's "
                         "solve would couple the worlds; run implicit scenes alone)", "implicit")
    shared = _shared_simulation(first.simulation)
    for w, scene in enumerate(scenes[1:], start=1):
        for key, mine, theirs in (("simulation", _shared_simulation(scene.simulation), shared),
                                  ("collision", _as_dict(scene.collision), _as_dict(first.collision)),
                                  ("implicit", _as_dict(scene.implicit), _as_dict(first.implicit)),
                                  ("wind", _as_dict(scene.wind), _as_dict(first.wind))):
            differs = _first_difference(mine, theirs, key) if mine.keys() == theirs.keys() else key
            if differs is not None:
                raise SceneError(f"scenes[{w}].{differs}", "the same as scenes[0]'s: a batch's worlds share their "
                                 "step, solves, collision and wind settings (batch them apart, or make them equal)",
                                 has_got=False)
    cloths, spheres, colliders = [], [], []
    cloth_world, sphere_start, mesh_start = [], [0], [0]
    for w, scene in enumerate(scenes):
        for cloth in scene.cloths:
            pins = tuple(dataclasses.replace(pin, target=_renamed(pin.target, w))
                         if pin.target is not None and not pin.target.startswith("/") else pin for pin in cloth.pins)
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
                    np.asarray([g.height if g is not None else 0.0 for g in grounds], dtype=np.float32),
                    np.asarray([g.friction if g is not None else 0.0 for g in grounds], dtype=np.float32),
                    np.asarray(sphere_start, dtype=np.int32), np.asarray(mesh_start, dtype=np.int32))
    packed = dataclasses.replace(first, name="batch", cloths=tuple(cloths), spheres=tuple(spheres),
                                 colliders=tuple(colliders), ground=None)
    return packed, worlds


def _as_dict(settings) -> dict:
    return {} if settings is None else dataclasses.asdict(settings)


class Batch:
    """Scenes (worlds) stepped together on one device: one particle buffer, one launch per pass for all.

    Each world keeps its own cloths, colliders, pins, gravity and ground, and never touches another; all
    share the step, the solves' settings, collision and wind settings (a batch of scenes that differ there
    is refused: batch them apart). Where the scenes set no step, the batch takes the finest any of its
    cloths needs, which may be finer than a world alone would take. A converged strain solve runs until
    every world is within tolerance, so a world may take more passes than alone: its frames then differ
    from its scene's alone within that tolerance; a fixed solve gives them to rounding. The implicit
    integrator is refused (its solve's sums run over every world).

    A world that blows up is stopped (put back where it started, at rest, and held) and the others go on:
    ``stopped_worlds`` holds each such world's ``UnstableSimulation`` (its frame and cause); its frames from
    that one on are not valid. Once every world has stopped, ``step`` raises the first one's.

    ``step()`` advances every world one frame, ``run(frames)`` several; ``positions(w)`` and
    ``velocities(w)`` read world ``w``'s particles (its cloths' in order, as its scene alone has them).
    """

    def __init__(self, scenes: Sequence[Scene], device: str | None = None, graph: bool = True,
                 threads_per_particle: int | None = None) -> None:
        self.scenes = tuple(scenes)
        packed, worlds = pack(self.scenes)
        self.worlds = worlds
        self.simulator = Simulator(packed, device=device, graph=graph, threads_per_particle=threads_per_particle,
                                   worlds=worlds)
        offsets = np.asarray(self.simulator.model.offsets)
        first_cloth = np.searchsorted(worlds.cloth_world, np.arange(len(self.scenes) + 1))
        self._starts = offsets[first_cloth]

    @property
    def world_count(self) -> int:
        return len(self.scenes)

    @property
    def frame(self) -> int:
        return self.simulator.frame

    @property
    def stopped_worlds(self) -> dict[int, UnstableSimulation]:
        return self.simulator.stopped_worlds

    def world_slice(self, w: int) -> slice:
        """World ``w``'s particles in the batch's buffer."""
        if not 0 <= w < self.world_count:
            raise IndexError(f"world {w} of a batch of {self.world_count}")
        return slice(int(self._starts[w]), int(self._starts[w + 1]))

    def step(self) -> None:
        self.simulator.step()

    def run(self, frames: int, progress: bool = False) -> RunSummary:
        return self.simulator.run(frames, progress=progress)

    def positions(self, w: int) -> np.ndarray:
        return self.simulator.positions()[self.world_slice(w)]

    def velocities(self, w: int) -> np.ndarray:
        return self.simulator.velocities()[self.world_slice(w)]
