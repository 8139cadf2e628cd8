"""The line solve of the strain limits (issue 33; kernels/line_solve.py): the families of lines that
cloth_lines.py finds, and a round of it as the passes a converged solve repeats after its first Jacobi pair
(plan.line_projection, for cloths without particle collision; ``limit_solve.SolveChoices.line_solve``, which
the lab turns off): the families, their lines cut into segments a thread each and stored in the layout this
module chooses for the device, then the pins and the colliders (with particle collision, only where the lab asks,
``line_contacts``: warp_cloth/plan.py follows it with the contacts' separating passes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.line_solve import (ClothLines, LineSegments, SeparatorRows, eliminate_segments,
                                           finish_segments, hold_and_collide, reduce_separators,
                                           solve_separator_chains, turn_order)

from .cloth_lines import Family
from .device_model import DeviceModel
from .limit_solve import SolveChoices
from .passes import attachments_of
from .state import DeviceState


# The separators a thread eliminates one after another, at most: a step of cyclic reduction halves each
# line's chain at the cost of a launch, and on an H200 a launch cost about as much as walking 8 (the 1024^2
# sphere cloth's 31 separators a line took 59 us walked by one thread, 43 us in five steps of cyclic
# reduction, 33 us in two steps and chains of 8: docs/notebook/strain-solve.md, "Segments as long as the
# square root of a line").
CHAIN = 8


def segment_for_device(longest: int) -> int:
    """Springs a segment on CUDA for lines of at most ``longest`` springs: the power of two nearest a 64th
    of the longest line, at least 4 and at most 16. A segment's thread walks its springs one after another
    and the separators' solve grows only with the log of their number, so a short segment is cheap, but
    at fewer than about 64 segments a line the card's threads are not filled, and past 16 springs a walk
    costs more than its threads save (on an H200, the sphere cloth's frame at 256^2, 512^2, 1024^2 and
    2048^2 was fastest at 4, 8, 16 and 16 among 2 to 48: docs/notebook/strain-solve.md, "Segments for the
    card's threads")."""
    return min(16, max(4, 2 ** round(math.log2(max(longest, 1) / 64))))


def longest_line(lines: list[Family]) -> int:
    """The springs of the longest line of ``lines``: a segment size from which lines are solved whole."""
    return max(int(np.diff(starts).max()) - 1 for starts, *_ in lines)


def line_segments(starts: np.ndarray, size: int, closed: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The lines' (``starts`` as a family of cloth_lines.py's gives them) separators, every ``size``-th spring
    of a line but its last, and the segments between them (kernels/line_solve.py): per segment its first
    slot, one past its last, and the separators' slots before and after it (-1: none); per line its
    separators. A ``closed`` line (a ring, its first particle its last) that is cut has its one particle at
    both ends moved by its first segment alone, which also takes the ring's last spring (its slot,
    ``ring_spring``, and the separator before the segment that ends the ring, ``ring_separator``), while its
    last segment leaves it (``ring_end``): two threads moving one particle at once would lose one move."""
    per_segment = {name: [] for name in ("first", "end", "left", "right", "ring_spring", "ring_separator",
                                         "ring_end")}
    separator_start, separator = [0], []
    for line, (begin, stop) in enumerate(zip(starts[:-1].tolist(), starts[1:].tolist())):
        last = stop - 1  # the line's springs are slots begin..last-1
        cuts = [begin + j for j in range(size - 1, last - begin - 1, size)]
        bounds = [begin - 1] + cuts + [last]
        ring = closed is not None and bool(closed[line]) and len(cuts) > 0
        for i in range(len(bounds) - 1):
            per_segment["first"].append(bounds[i] + 1)
            per_segment["end"].append(bounds[i + 1])
            per_segment["left"].append(bounds[i] if i > 0 else -1)
            per_segment["right"].append(bounds[i + 1] if i < len(bounds) - 2 else -1)
            per_segment["ring_spring"].append(last - 1 if ring and i == 0 else -1)
            per_segment["ring_separator"].append(cuts[-1] if ring and i == 0 else -1)
            per_segment["ring_end"].append(int(ring and i == len(bounds) - 2))
        separator += cuts
        separator_start.append(len(separator))
    as_int = lambda values: np.asarray(values, dtype=np.int32)  # noqa: E731
    return {name: as_int(values) for name, values in per_segment.items()} | dict(
        separator_start=as_int(separator_start), separator=as_int(separator))


@dataclass(frozen=True)
class SlotLayout:
    """Where a family's per-slot values are stored: segment s's j-th slot (j = 0 .. its springs, its last
    being its right separator's slot or its line's last particle) at ``base[s] + j * step``; ``storage``: each
    slot's storage index, in the order the lines give them; ``size``: the values stored."""
    base: np.ndarray
    step: int
    storage: np.ndarray
    size: int


def slot_layout(segments: dict[str, np.ndarray], interleaved: bool) -> SlotLayout:
    """The layout of the slots of ``segments`` (line_segments', in any order of segments). Contiguous (the
    CPU's, where a thread walks segment after segment): as the lines give them, a segment's base its first
    slot, step 1. Interleaved (CUDA's): base[s] = s, step the number of segments, so that at each j a warp's
    threads read consecutive addresses (contiguous, they read addresses a segment apart, and the 1024^2
    cloth's kernels waited on memory); segments x (the longest + 1) values, the shorter segments' last ones
    unused."""
    first, end = segments["first"], segments["end"]
    count = end - first + 1  # each segment's slots
    segment = np.repeat(np.arange(len(first)), count)
    j = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    if interleaved:
        base, step, size = np.arange(len(first)), len(first), len(first) * int(count.max())
    else:
        base, step, size = first, 1, int(count.sum())
    storage = np.empty(int(count.sum()), dtype=np.int32)
    storage[first[segment] + j] = base[segment] + j * step
    return SlotLayout(base.astype(np.int32), step, storage, size)


def across_lines(segments: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``segments`` with their per-segment arrays reordered so that neighbouring threads take the same
    segment of neighbouring lines (every line's first segment, then every second one, ...): on a grid the
    particles of a column's, or a diagonal's, neighbour lie beside its own, so a warp's reads of positions
    coalesce as the slots' do interleaved."""
    line = np.cumsum(segments["left"] < 0) - 1
    first_of_line = np.flatnonzero(segments["left"] < 0)
    index_in_line = np.arange(len(line)) - first_of_line[line]
    order = np.lexsort((line, index_in_line))
    return {name: values[order] if name not in ("separator_start", "separator") else values
            for name, values in segments.items()}


def in_storage(values: np.ndarray, layout: SlotLayout) -> np.ndarray:
    """Per-slot ``values`` at their storage indices (0 in the holes, which nothing reads)."""
    stored = np.zeros(layout.size, dtype=values.dtype)
    stored[layout.storage] = values
    return stored


def storage_index(slots: np.ndarray, layout: SlotLayout) -> np.ndarray:
    """The storage indices of ``slots`` (-1 stays -1: none)."""
    return np.where(slots >= 0, layout.storage[slots], -1).astype(np.int32)


def separator_number(slots: np.ndarray, separator: np.ndarray) -> np.ndarray:
    """The number of each separator's slot in ``slots`` among the family's ``separator`` slots (-1 stays -1)."""
    return np.where(slots >= 0, np.searchsorted(separator, slots), -1).astype(np.int32)


@dataclass
class FamilySolve:
    """A family's arrays as the kernels take them, its launches' threads, and its separators' solve: the
    strides of its cyclic reduction then of its chains (reduction_strides), and the two sets of rows the
    reduction takes from one into the other."""
    lines: ClothLines
    segments: LineSegments
    segment_count: int
    line_count: int
    separator_count: int
    strides: list[int]
    rows: tuple[SeparatorRows, SeparatorRows]


def upload_family(family: Family, size: int, interleaved: bool, device) -> FamilySolve:
    """A family's lines cut into segments of ``size`` springs, every per-slot array and every slot index in
    the layout ``interleaved`` chooses (slot_layout)."""
    starts, particles, lo, hi = family
    segments = line_segments(starts, size, closed=particles[starts[:-1]] == particles[starts[1:] - 1])
    if interleaved:
        segments = across_lines(segments)
    layout = slot_layout(segments, interleaved)
    indices = lambda values: wp.array(values, dtype=int, device=device)  # noqa: E731
    lines = ClothLines()
    lines.particle = indices(in_storage(particles, layout))
    lines.min_length = wp.array(in_storage(lo, layout), dtype=float, device=device)
    lines.max_length = wp.array(in_storage(hi, layout), dtype=float, device=device)
    lines.normal = wp.zeros(layout.size, dtype=wp.vec3, device=device)
    uploaded = LineSegments()
    uploaded.base = indices(layout.base)
    uploaded.length = indices(segments["end"] - segments["first"])
    uploaded.step = layout.step
    right, separator = segments["right"], segments["separator"]
    uploaded.left = indices(storage_index(segments["left"], layout))
    uploaded.right = indices(storage_index(right, layout))
    uploaded.after_right = indices(storage_index(np.where(right >= 0, right + 1, -1), layout))
    uploaded.left_separator = indices(separator_number(segments["left"], separator))
    uploaded.right_separator = indices(separator_number(right, separator))
    uploaded.ring_spring = indices(storage_index(segments["ring_spring"], layout))
    uploaded.ring_separator = indices(separator_number(segments["ring_separator"], separator))
    uploaded.ring_end = indices(segments["ring_end"])
    uploaded.separator_start = indices(segments["separator_start"])
    uploaded.separator_line = indices(np.repeat(np.arange(len(starts) - 1), np.diff(segments["separator_start"])))
    for name in ("solution", "from_left", "from_right", "upper"):
        setattr(uploaded, name, wp.zeros(layout.size, dtype=wp.float64, device=device))
    for name in ("own_diagonal", "diagonal_from_before", "right_from_before", "coupling", "diagonal_from_after",
                 "right_from_after", "separator_upper", "separator_solution"):
        setattr(uploaded, name, separator_values(len(separator), device))
    rows = (separator_rows_scratch(len(separator), device), separator_rows_scratch(len(separator), device))
    return FamilySolve(lines, uploaded, len(layout.base), len(starts) - 1, len(separator),
                       reduction_strides(segments), rows)


def separator_values(count: int, device) -> wp.array:
    """A float64 value for each of ``count`` separators (one where there are none: Warp's struct members
    take no empty array)."""
    return wp.zeros(max(count, 1), dtype=wp.float64, device=device)


def separator_rows_scratch(count: int, device) -> SeparatorRows:
    """The rows of ``count`` separators, for cyclic reduction to reduce into."""
    rows = SeparatorRows()
    for name in ("lower", "diagonal", "upper", "right"):
        setattr(rows, name, separator_values(count, device))
    return rows


def reduction_strides(segments: dict[str, np.ndarray]) -> list[int]:
    """The strides of the cyclic reduction's steps for the separators of ``segments``' lines (1, 2, 4, ...),
    and last the stride of the chains that Thomas' algorithm then solves: as many steps as leave no chain
    longer than CHAIN."""
    most = int(np.diff(segments["separator_start"]).max(initial=0))
    strides = [1]
    while -(-most // strides[-1]) > CHAIN:
        strides.append(2 * strides[-1])
    return strides


class LineSolves:
    """The families' line solves, one family after another, moving the positions in place: springs within
    ``hold_margin`` of a limit held, ``newton_steps`` linearised steps a line (kernels/line_solve.py), each
    line cut into segments of ``segment`` springs (one, where it is at least the longest line), a thread a
    segment, every per-slot array stored ``interleaved`` or contiguous (slot_layout). Rounds take the families
    forwards and backwards in turn: in one order, a family's corrections where it meets the last family are undone
    by the first family of the next round, round after round, and the 1024^2 sphere cloth's solves reached
    their cap (docs/notebook/strain-solve.md, "Families forwards and backwards")."""

    def __init__(self, model: DeviceModel, lines: list[Family], hold_margin: float, newton_steps: int,
                 segment: int, interleaved: bool) -> None:
        if segment < 2:
            raise ValueError(f"line segments of {segment} springs: at least 2")
        self.model = model
        self.name = (f"line solves ({len(lines)} families, each {newton_steps} times: eliminate_segments, "
                     "reduce_separators, solve_separator_chains, finish_segments; forwards and backwards in turn: "
                     "turn_order)")
        self.hold_margin, self.newton_steps = hold_margin, newton_steps
        self.segment, self.interleaved = segment, interleaved
        self.families = []
        for family in lines:
            self.families.append(upload_family(family, segment, interleaved, model.device))

    @classmethod
    def of(cls, model: DeviceModel, lines: list[Family], choices: SolveChoices) -> LineSolves:
        """The line solves of ``lines`` as the solver's ``choices`` (or the lab's) ask, or where they leave it to
        the device (None): on CUDA segments of segment_for_device's springs, interleaved; on the CPU whole lines,
        contiguous."""
        cuda = model.device.is_cuda
        segment = choices.line_segment
        if segment is None:
            longest = longest_line(lines)
            segment = segment_for_device(longest) if cuda else max(longest, 2)
        interleaved = cuda if choices.line_interleaved is None else choices.line_interleaved
        return cls(model, lines, choices.line_hold_margin, choices.line_newton_steps, segment, interleaved)

    def run(self, state: DeviceState) -> None:
        wp.capture_if(state.lines_backwards, on_true=lambda: self._solve(self.families[::-1], state),
                      on_false=lambda: self._solve(self.families, state))
        wp.launch(turn_order, dim=1, outputs=[state.lines_backwards], device=state.device)

    def _solve(self, families: list[FamilySolve], state: DeviceState) -> None:
        inv_mass, device = self.model.inv_mass, state.device
        for family in families:
            for _ in range(self.newton_steps):
                wp.launch(eliminate_segments, dim=family.segment_count,
                          inputs=[family.lines, family.segments, inv_mass, self.hold_margin, state.x], device=device)
                if family.separator_count:
                    self._solve_separators(family, device)
                wp.launch(finish_segments, dim=family.segment_count,
                          inputs=[family.lines, family.segments, inv_mass, self.model.h],
                          outputs=[state.x, state.v], device=device)


    @staticmethod
    def _solve_separators(family: FamilySolve, device) -> None:
        rows, reduced = family.rows
        *steps, chains = family.strides
        from_segments = 1  # the first launch reads the rows as the segments left them
        for stride in steps:
            wp.launch(reduce_separators, dim=family.separator_count,
                      inputs=[family.segments, stride, from_segments, rows], outputs=[reduced], device=device)
            rows, reduced, from_segments = reduced, rows, 0
        wp.launch(solve_separator_chains, dim=family.line_count * chains,
                  inputs=[family.segments, chains, from_segments, rows], device=device)


class HoldAndCollide:
    """The attachments to the pins, then the rigid colliders, in place."""

    name = "pins+colliders"

    def __init__(self, model: DeviceModel, rigid: RigidColliders | None) -> None:
        self.model = model
        self.attachments = attachments_of(model)
        self.colliders = rigid if rigid is not None else model.no_colliders()

    def run(self, state: DeviceState) -> None:
        wp.launch(hold_and_collide, dim=state.x.shape[0],
                  inputs=[self.attachments, self.colliders, self.model.inv_mass, self.model.h],
                  outputs=[state.x, state.v], device=state.device)
