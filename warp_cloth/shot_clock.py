"""The run's clock, which is its shot's: which frame it begins at, which it writes, where it ends.

Frames are numbered as the shot numbers them, and time is frame / fps seconds on that clock, for every
motion and key of the scene (a USD collider keyed at time code 1001 at 24 fps moves at 41.71 s). A run
begins ``preroll`` frames before ``start``, with the initial state, simulates those without writing them,
then writes ``start`` and the ``frames`` after it. A simulator's ``frame`` and a checkpoint's are on this
clock (for a scene of no shot, as before: 0 is the initial state).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .errors import SceneError
from .scene import MAX_FRAMES


@dataclass(frozen=True)
class ShotClock:
    start: int  # the first written frame
    preroll: int  # frames simulated before it, not written
    frames: int  # frames written after it
    fps: float

    @property
    def first(self) -> int:
        """The frame the run begins at: the scene's initial state."""
        return self.start - self.preroll

    @property
    def end(self) -> int:
        """The last frame of the run."""
        return self.start + self.frames

    @property
    def first_time(self) -> float:
        """Where the run begins, in seconds."""
        return self.first / self.fps

    @property
    def end_time(self) -> float:
        return self.end / self.fps

    def writes(self, frame: int) -> bool:
        """Whether ``frame`` is one the run writes (not one of its preroll)."""
        return frame >= self.start


def shot_clock(scene) -> ShotClock:
    """The scene's clock: ``simulation.start``, or where it is left out, the start of its shot
    (``shot_start``)."""
    sim = scene.simulation
    start = sim.start if sim.start is not None else shot_start(scene)
    return ShotClock(start, sim.preroll, sim.frames, sim.fps)


def shot_start(scene) -> int:
    """The frame at the simulation's fps (rounded) of the start time code of the first USD file among the
    scene's colliders', then its cloths', that sets one; 0 where none does."""
    from .mesh_io import USD_SUFFIXES, shot_start_seconds

    for item in (*scene.colliders, *scene.cloths):
        if item.mesh is None or not item.mesh.file.lower().endswith(USD_SUFFIXES):
            continue
        seconds = shot_start_seconds(item.mesh.file)
        if seconds is not None:
            start = round(seconds * scene.simulation.fps)
            if abs(start) > MAX_FRAMES:
                raise SceneError("simulation.start", f"a frame in [-{MAX_FRAMES}, {MAX_FRAMES}], or a shot that "
                                 f"starts there ({item.mesh.file} starts at frame {start})", has_got=False)
            return start
    return 0


def with_start(scene):
    """The scene with its clock's start set (``simulation.start`` no longer left to its shot)."""
    if scene.simulation.start is not None:
        return scene
    return dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation,
                                                                     start=shot_clock(scene).start))

