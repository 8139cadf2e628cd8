"""The lab's line solve of the strain limits on grid cloths (issue 33; kernels/line_solve.py): the lines of
each family (rows, columns, and the two diagonal families of the shear springs), found once from the grid's
layout and split at pins, and a round of it as the passes a converged solve repeats in place of the
Jacobi limit pass (``limit_solve.lab_hooks(line_solve=True)``): the four families, one launch each, then
the attachments and the colliders. Off unless the lab asks for it; grid cloths without particle collision
only."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.line_solve import GridLines, hold_and_collide, solve_lines
from warp_cloth.kernels.line_solve_segments import (LineSegments, finish_segments, segment_equations,
                                                    solve_segments, solve_separators)

from .device_model import DeviceModel
from .model import Model
from .passes import attachments_of
from .scene import Scene
from .state import DeviceState

FAMILIES = ("rows", "columns", "diagonals", "antidiagonals")


def grid_chains(nx: int, ny: int) -> dict[str, list[np.ndarray]]:
    """The particle chains of a grid of nx x ny cells (particle (x, y) is x + (nx + 1) y) along its
    structural springs (rows, columns) and its shear springs ((x, y)-(x+1, y+1) and (x+1, y)-(x, y+1))."""
    idx = lambda x, y: x + (nx + 1) * y  # noqa: E731
    rows = [idx(np.arange(nx + 1), y) for y in range(ny + 1)]
    columns = [idx(x, np.arange(ny + 1)) for x in range(nx + 1)]
    diagonals, antidiagonals = [], []
    for x0, y0 in [(x, 0) for x in range(nx)] + [(0, y) for y in range(1, ny)]:
        t = np.arange(min(nx - x0, ny - y0) + 1)
        diagonals.append(idx(x0 + t, y0 + t))
    for s in range(1, nx + ny):
        x0, y0 = min(s, nx), s - min(s, nx)
        t = np.arange(min(x0, ny - y0) + 1)
        antidiagonals.append(idx(x0 - t, y0 + t))
    return dict(rows=rows, columns=columns, diagonals=diagonals, antidiagonals=antidiagonals)


def line_pieces(chain: np.ndarray, free: np.ndarray, limited: np.ndarray) -> list[slice]:
    """The pieces of ``chain`` cut at its pinned particles (each cut particle ends one piece and starts the
    next) and at its springs that are not limited (``limited`` per spring of the chain), as slices of it;
    pieces with no free particle are left out."""
    pieces, begin = [], 0
    for k in range(1, len(chain)):
        if not limited[k - 1]:
            pieces.append(slice(begin, k))
            begin = k
        elif not free[chain[k]]:
            pieces.append(slice(begin, k + 1))
            begin = k
    pieces.append(slice(begin, len(chain)))
    return [p for p in pieces if p.stop - p.start >= 2 and free[chain[p]].any()]


def grid_lines(model: Model, scene: Scene) -> dict[str, tuple[np.ndarray, ...]]:
    """Per family: the lines' starts, their particles, and each slot's allowed length range (the spring from
    that particle to the next; 0 at a line's last particle)."""
    if scene.collision is not None or any(c.mesh is not None for c in scene.cloths):
        raise ValueError("the line solve takes grid cloths without particle collision only")
    springs = model.springs
    n = model.particle_count
    limited = np.isfinite(springs.limit_max)
    pairs = np.sort(springs.pairs[limited], axis=1).astype(np.int64)
    keys = pairs[:, 0] * n + pairs[:, 1]
    order = np.argsort(keys)
    keys, lo, hi = keys[order], springs.limit_min[limited][order], springs.limit_max[limited][order]
    free = model.inv_mass > 0
    lines: dict[str, tuple[np.ndarray, ...]] = {}
    for family in FAMILIES:
        starts, particles, slot_lo, slot_hi = [0], [], [], []
        for c, cloth in enumerate(scene.cloths):
            for chain in grid_chains(*cloth.resolution)[family]:
                chain = chain + model.offsets[c]
                a, b = np.minimum(chain[:-1], chain[1:]), np.maximum(chain[:-1], chain[1:])
                at = np.minimum(np.searchsorted(keys, a * n + b), len(keys) - 1)
                found = keys[at] == a * n + b
                for piece in line_pieces(chain, free, found):
                    slots = at[piece.start:piece.stop - 1]
                    particles.append(chain[piece])
                    slot_lo += [lo[slots], [0.0]]
                    slot_hi += [hi[slots], [0.0]]
                    starts.append(starts[-1] + piece.stop - piece.start)
        lines[family] = (np.asarray(starts, dtype=np.int32), np.concatenate(particles).astype(np.int32),
                         np.concatenate(slot_lo).astype(np.float32), np.concatenate(slot_hi).astype(np.float32))
    return lines


def upload_lines(starts: np.ndarray, particles: np.ndarray, lo: np.ndarray, hi: np.ndarray, device) -> GridLines:
    lines = GridLines()
    lines.start = wp.array(starts, dtype=int, device=device)
    lines.particle = wp.array(particles, dtype=int, device=device)
    lines.min_length = wp.array(lo, dtype=float, device=device)
    lines.max_length = wp.array(hi, dtype=float, device=device)
    lines.normal = wp.zeros(len(particles), dtype=wp.vec3, device=device)
    lines.upper = wp.zeros(len(particles), dtype=wp.float64, device=device)
    lines.multiplier = wp.zeros(len(particles), dtype=wp.float64, device=device)
    return lines


def line_segments(starts: np.ndarray, size: int) -> dict[str, np.ndarray]:
    """The lines' (``starts`` as ``grid_lines`` gives them) separators, every ``size``-th spring of a line but
    its last, and the segments between them (kernels/line_solve_segments.py): per segment its first slot,
    one past its last, and the separators' slots before and after it (-1: none); per line its separators."""
    first, end, left, right, separator_start, separator = [], [], [], [], [0], []
    for begin, stop in zip(starts[:-1].tolist(), starts[1:].tolist()):
        last = stop - 1  # the line's springs are slots begin..last-1
        cuts = [begin + j for j in range(size - 1, last - begin - 1, size)]
        bounds = [begin - 1] + cuts + [last]
        for i in range(len(bounds) - 1):
            first.append(bounds[i] + 1)
            end.append(bounds[i + 1])
            left.append(bounds[i] if i > 0 else -1)
            right.append(bounds[i + 1] if i < len(bounds) - 2 else -1)
        separator += cuts
        separator_start.append(len(separator))
    as_int = lambda values: np.asarray(values, dtype=np.int32)  # noqa: E731
    return dict(first=as_int(first), end=as_int(end), left=as_int(left), right=as_int(right),
                separator_start=as_int(separator_start), separator=as_int(separator))


def upload_segments(segments: dict[str, np.ndarray], slots: int, device) -> LineSegments:
    uploaded = LineSegments()
    for name, values in segments.items():
        setattr(uploaded, name, wp.array(values, dtype=int, device=device))
    for name in ("diagonal", "lower", "right_side", "solution", "from_left", "from_right", "upper"):
        setattr(uploaded, name, wp.zeros(slots, dtype=wp.float64, device=device))
    return uploaded


class LineSolves:
    """The four families' line solves, one family after another, moving the positions in place: springs
    within ``hold_margin`` of a limit held, ``newton_steps`` linearised steps a line (kernels/line_solve.py);
    a thread a line, or with ``segment`` springs a segment (0: whole lines) a thread a segment
    (kernels/line_solve_segments.py)."""

    name = "line solves (rows, columns, diagonals, antidiagonals)"

    def __init__(self, model: DeviceModel, lines: dict[str, tuple[np.ndarray, ...]], hold_margin: float,
                 newton_steps: int, segment: int = 0) -> None:
        self.model = model
        self.hold_margin, self.newton_steps = hold_margin, newton_steps
        self.families = [(upload_lines(*lines[f], model.device), len(lines[f][0]) - 1) for f in FAMILIES]
        self.segments = None
        if segment:
            tables = [line_segments(lines[f][0], segment) for f in FAMILIES]
            self.segments = [(upload_segments(table, len(lines[f][1]), model.device), len(table["first"]))
                             for f, table in zip(FAMILIES, tables)]

    def run(self, state: DeviceState) -> None:
        for f, (lines, count) in enumerate(self.families):
            if self.segments is None:
                wp.launch(solve_lines, dim=count,
                          inputs=[lines, self.model.inv_mass, self.hold_margin, self.newton_steps, self.model.h],
                          outputs=[state.x, state.v], device=state.device)
                continue
            segments, pieces = self.segments[f]
            for _ in range(self.newton_steps):
                wp.launch(segment_equations, dim=pieces, inputs=[lines, segments, self.model.inv_mass,
                                                                 self.hold_margin, state.x], device=state.device)
                wp.launch(solve_segments, dim=pieces, inputs=[segments], device=state.device)
                wp.launch(solve_separators, dim=count, inputs=[segments], device=state.device)
                wp.launch(finish_segments, dim=pieces, inputs=[lines, segments, self.model.inv_mass, self.model.h],
                          outputs=[state.x, state.v], device=state.device)


class HoldAndCollide:
    """The attachments to the pins, then the rigid colliders, in place."""

    name = "attachments+colliders"

    def __init__(self, model: DeviceModel, rigid: RigidColliders | None) -> None:
        self.model = model
        self.attachments = attachments_of(model)
        self.colliders = rigid if rigid is not None else model.no_colliders()

    def run(self, state: DeviceState) -> None:
        wp.launch(hold_and_collide, dim=state.x.shape[0],
                  inputs=[self.attachments, self.colliders, self.model.inv_mass, self.model.h],
                  outputs=[state.x, state.v], device=state.device)
