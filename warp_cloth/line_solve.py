"""The lab's line solve of the strain limits (issue 33; kernels/line_solve.py): the families of lines that
cloth_lines.py finds, and a round of it as the passes a converged solve repeats in place of the Jacobi limit
pass (``limit_solve.lab_hooks(line_solve=True)``): the families, one launch each, then the attachments and
the colliders (with particle collision, warp_cloth/plan.py follows it with the contacts' separating passes).
Off unless the lab asks for it."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.line_solve import ClothLines, hold_and_collide, solve_lines
from warp_cloth.kernels.line_solve_segments import (LineSegments, eliminate_segments, finish_segments,
                                                    solve_separators)

from .cloth_lines import Family
from .device_model import DeviceModel
from .limit_solve import LimitSolveSettings
from .passes import attachments_of
from .state import DeviceState

def upload_lines(starts: np.ndarray, particles: np.ndarray, lo: np.ndarray, hi: np.ndarray, device) -> ClothLines:
    lines = ClothLines()
    lines.start = wp.array(starts, dtype=int, device=device)
    lines.particle = wp.array(particles, dtype=int, device=device)
    lines.min_length = wp.array(lo, dtype=float, device=device)
    lines.max_length = wp.array(hi, dtype=float, device=device)
    lines.normal = wp.zeros(len(particles), dtype=wp.vec3, device=device)
    lines.upper = wp.zeros(len(particles), dtype=wp.float64, device=device)
    lines.multiplier = wp.zeros(len(particles), dtype=wp.float64, device=device)
    return lines


def line_segments(starts: np.ndarray, size: int) -> dict[str, np.ndarray]:
    """The lines' (``starts`` as a family of cloth_lines.py's gives them) separators, every ``size``-th spring
    of a line but its last, and the segments between them (kernels/line_solve_segments.py): per segment its
    first slot, one past its last, and the separators' slots before and after it (-1: none); per line its
    separators."""
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
    """The families' line solves, one family after another, moving the positions in place: springs
    within ``hold_margin`` of a limit held, ``newton_steps`` linearised steps a line (kernels/line_solve.py);
    a thread a line, or with ``segment`` springs a segment (0: whole lines) a thread a segment
    (kernels/line_solve_segments.py)."""

    def __init__(self, model: DeviceModel, lines: list[Family], hold_margin: float, newton_steps: int,
                 segment: int = 0) -> None:
        self.model = model
        self.name = f"line solves ({len(lines)} families)"
        self.hold_margin, self.newton_steps = hold_margin, newton_steps
        self.families = [(upload_lines(*family, model.device), len(family[0]) - 1) for family in lines]
        self.segments = None
        if segment:
            tables = [line_segments(family[0], segment) for family in lines]
            self.segments = [(upload_segments(table, len(family[1]), model.device), len(table["first"]))
                             for family, table in zip(lines, tables)]

    @classmethod
    def of(cls, model: DeviceModel, lines: list[Family], solve: LimitSolveSettings) -> LineSolves:
        """The line solves of ``lines`` as the lab's settings in ``solve`` ask."""
        return cls(model, lines, solve.line_hold_margin, solve.line_newton_steps, solve.line_segment)

    def run(self, state: DeviceState) -> None:
        for f, (lines, count) in enumerate(self.families):
            if self.segments is None:
                wp.launch(solve_lines, dim=count,
                          inputs=[lines, self.model.inv_mass, self.hold_margin, self.newton_steps, self.model.h],
                          outputs=[state.x, state.v], device=state.device)
                continue
            segments, pieces = self.segments[f]
            for _ in range(self.newton_steps):
                wp.launch(eliminate_segments, dim=pieces, inputs=[lines, segments, self.model.inv_mass,
                                                                  self.hold_margin, state.x], device=state.device)
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
