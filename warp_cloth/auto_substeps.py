"""Substeps chosen frame by frame (``substeps = "auto"``, the default where a scene sets neither
``substeps`` nor ``dt``): each frame takes the fewest substeps whose solves converge within their caps and
whose step is stable.

A run starts at the stable floor (``stability.automatic_substeps``). After each frame the simulator reads
the frame's solve figures and the blow-up guard, and ``judge`` says how it went:

- a miss (a solve stopped at its cap outside its tolerance, or the guard flagged the frame): the frame is
  made again from its start (``FrameStart``, a copy on the device) with twice the substeps, up to the most
  a frame may take; a frame that misses there is kept, and the run goes on as with a set step (its
  summary says how many were kept so);
- a stalled miss (made again with twice the substeps, the frame's solves missed by at least ``STALLED`` of
  their last miss, ``miss_size``): more substeps do not help, because what the solve is asked cannot be
  held (a sphere pushed through a cloth pinned on both sides past its strain limit: its miss stayed at 5.6
  tolerances from 16 to 4096 substeps a frame, and at 10000, whose capped solves cannot settle, the cloth
  blew up). The frame is kept and the next starts from the count before the doubling (the summary says
  how many were kept so);
- a stalled blow-up (made again with twice the substeps, the guard flagged the frame again, no later in
  the frame than before): the frame starts from a state no step can carry on from (seed_default's explicit
  step at 0.8 of its bound threw its particles to 200 m/s; the next frame, made again with up to 10000
  substeps, blew up at the first of them, a smaller step only making the same correction faster). It is
  kept, and the run stops as at a set step;
- room (every solve within its tolerance in at most half its cap): the next frame tries 3/4 of the
  substeps (rounded up), never below the floor nor at or below a count that missed in the last
  ``MISS_MEMORY`` frames, so that the count does not bounce across the boundary every frame;
- otherwise the count stays.

Nothing here reads a clock: the same scene chooses the same counts on every run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .implicit import SolveStats

MISS_MEMORY = 24  # frames a count that missed is remembered: the count does not come back down to it
ROOM = 0.5  # a solve has room where it took at most this fraction of its cap
MISS, HOLD, DOWN = "miss", "hold", "room"  # what a frame's solves and guard say (``judge``)
# A frame made again with twice the substeps whose miss is at least this fraction of the last one's stalled:
# halving the step shrinks the violation each substep makes, so a miss that is a matter of substeps falls
# with them (the swing of tests/test_auto_substeps.py: 1.5 tolerances to within them).
STALLED = 0.9


@dataclass(frozen=True)
class SolveCaps:
    """The caps and tolerances a frame's solves are judged by; None for a solve the scene does not have
    (or, for Newton, a single step: nothing to converge)."""

    limit_passes: int | None = None  # the converged limit solve's passes a substep (tolerance: a residual of 1)
    cg_iterations: int | None = None
    cg_tolerance: float = 0.0
    newton_iterations: int | None = None
    newton_tolerance: float = 0.0


def judge(stats: SolveStats | None, flagged: bool, caps: SolveCaps) -> str:
    """``MISS``, ``DOWN`` (room) or ``HOLD`` for a frame whose solves ended with ``stats`` (the worst over its
    substeps; None: the scene solves nothing) and whose guard ``flagged`` a substep or not."""
    if flagged:
        return MISS
    solves: list[tuple[bool, bool]] = []  # (missed, with room) of each kind of solve
    if stats is not None and caps.limit_passes is not None and stats.limit_solves:
        solves.append((stats.limit_residual > 1.0, stats.limit_passes <= ROOM * caps.limit_passes))
    if stats is not None and caps.cg_iterations is not None and stats.cg_iterations is not None:
        solves.append((stats.cg_iterations >= caps.cg_iterations and stats.cg_relative_residual > caps.cg_tolerance,
                       stats.cg_iterations <= ROOM * caps.cg_iterations))
    if stats is not None and caps.newton_iterations is not None and stats.newton_residual is not None:
        solves.append((stats.newton_iterations >= caps.newton_iterations
                       and stats.newton_residual > caps.newton_tolerance,
                       stats.newton_iterations <= ROOM * caps.newton_iterations))
    if any(missed for missed, _ in solves):
        return MISS
    return DOWN if all(room for _, room in solves) else HOLD


def miss_size(stats: SolveStats | None, flagged: bool, caps: SolveCaps) -> float:
    """How far a frame's solves ended from their tolerances, in tolerances (the worst of them; inf where the
    guard flagged the frame: more substeps are what steadies a step)."""
    if flagged:
        return math.inf
    sizes = [0.0]
    if stats is not None and caps.limit_passes is not None and stats.limit_solves and stats.limit_residual:
        sizes.append(stats.limit_residual)
    if stats is not None and caps.cg_iterations is not None and stats.cg_relative_residual is not None:
        sizes.append(stats.cg_relative_residual / caps.cg_tolerance)
    if stats is not None and caps.newton_iterations is not None and stats.newton_residual is not None:
        sizes.append(stats.newton_residual / caps.newton_tolerance)
    return max(sizes)


def flagged_at(status: np.ndarray) -> float | None:
    """How far through its frame the guard first flagged a substep (a fraction: 1 / substeps at the first),
    from the frame's flags (substeps, worlds); None where it flagged none."""
    flagged = status.any(axis=1)
    if not flagged.any():
        return None
    return (int(np.argmax(flagged)) + 1) / len(flagged)


@dataclass
class SubstepChoice:
    """The substeps of the next frame (``substeps``), between the stable ``floor`` and the ``most`` a frame
    may take, and the counts that missed lately (``missed``: frame -> the largest count that missed there).
    ``frames`` keeps each kept frame's substeps (of this simulator's frames: the run's summary)."""

    floor: int
    most: int
    substeps: int = 0
    missed: dict[int, int] = field(default_factory=dict)
    frames: list[int] = field(default_factory=list)
    kept_missing: int = 0  # frames kept at ``most`` substeps though they missed
    kept_stalled: int = 0  # frames kept though they missed, where twice the substeps did not shrink the miss
    # the frame's misses so far: (substeps, size, where the guard first flagged it or None)
    _tries: list[tuple[int, float, float | None]] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self.substeps = self.substeps or self.floor

    def redo(self, frame: int, verdict: str, miss: float = math.inf, flagged_at: float | None = None) -> int | None:
        """After frame ``frame`` ran at ``substeps`` with ``verdict``, missing by ``miss`` (``miss_size``'s) and
        first flagged by the guard ``flagged_at`` of the way through it (the function ``flagged_at``'s fraction;
        None: not flagged): the substeps to make it again with (a miss below the most, not stalled), now the
        count; None: keep it."""
        if verdict != MISS:
            return None
        if self._tries:
            _, last_miss, last_flagged_at = self._tries[-1]
            if math.isfinite(miss) and miss >= STALLED * last_miss:
                return None
            if flagged_at is not None and last_flagged_at is not None and flagged_at <= last_flagged_at:
                return None
        self._tries.append((self.substeps, miss, flagged_at))
        self.missed[frame] = max(self.missed.get(frame, 0), self.substeps)
        if self.substeps >= self.most:
            return None
        self.substeps = min(2 * self.substeps, self.most)
        return self.substeps

    def keep(self, frame: int, verdict: str) -> int:
        """Frame ``frame`` is kept at ``substeps`` with ``verdict``: the next frame's substeps."""
        self.frames.append(self.substeps)
        stalled = verdict == MISS and self._tries and self._tries[-1][0] < self.substeps
        tries, self._tries = self._tries, []
        if stalled:
            self.kept_stalled += 1
            if len(tries) > 1:
                self.missed[frame] = tries[-2][0]
            else:
                self.missed.pop(frame, None)
            self.substeps = tries[-1][0]
            return self.substeps
        self.kept_missing += verdict == MISS
        self.missed = {f: count for f, count in self.missed.items() if f > frame - MISS_MEMORY}
        if verdict == DOWN:
            lowest = max([self.floor] + [count + 1 for count in self.missed.values()])
            self.substeps = min(self.substeps, max(lowest, -(-3 * self.substeps // 4)))
        return self.substeps

    def carried(self) -> dict:
        """What a checkpoint keeps, so that a resumed run chooses as the run it was taken from would."""
        return {"substeps": self.substeps, "missed": sorted(self.missed.items())}

    def restore(self, carried: dict) -> None:
        self.substeps = int(carried["substeps"])
        self.missed = {int(f): int(count) for f, count in carried["missed"]}


class FrameStart:
    """A copy on the device of what a frame starts from (the state's and the plan's carried arrays, by name,
    and the buffers' parity), taken before each frame and put back to make it again."""

    def __init__(self, arrays: dict[str, wp.array]) -> None:
        self.copies = {name: wp.empty_like(array) for name, array in arrays.items()}
        self.parity = 0

    def take(self, arrays: dict[str, wp.array], parity: int) -> None:
        self.parity = parity
        for name, array in arrays.items():
            wp.copy(self.copies[name], array)

    def put_back(self, arrays: dict[str, wp.array]) -> None:
        """Into ``arrays`` (read at the parity taken), which may be another plan's of the same names."""
        for name, array in arrays.items():
            wp.copy(array, self.copies[name])
