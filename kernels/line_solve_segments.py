"""The lab's line solve (kernels/line_solve.py) with each line cut into segments, a thread a segment, for
GPUs, where a thread a line leaves a family's few hundred threads each walking a whole line (issue 33). The
partition method: a line's springs are cut by separators (every ``size``-th spring, not its last); a
segment is the springs between two separators (or a line's end), its thread eliminating them for three
right sides at once (the line's, and a unit coupling to each separator); one thread a line then solves the
small tridiagonal system of its separators (their Schur complement), and the segments' threads finish their
springs from it and move their particles. The same system as one thread a line solves, to float64 rounding.
"""

import warp as wp

from .line_solve import ClothLines, spring_equation


@wp.struct
class LineSegments:
    first: wp.array(dtype=int)  # (segments,) a segment's first slot
    end: wp.array(dtype=int)  # one past its last: its right separator's slot, or its line's last particle
    left: wp.array(dtype=int)  # the separator's slot before it (-1: it starts its line)
    right: wp.array(dtype=int)  # the separator's slot after it (-1: it ends its line)
    separator_start: wp.array(dtype=int)  # (lines + 1,) line l's separators are separator[start[l]:start[l + 1]]
    separator: wp.array(dtype=int)  # their slots, in order along the line
    diagonal: wp.array(dtype=wp.float64)  # per slot, set at separators: scratch, the system's entries
    lower: wp.array(dtype=wp.float64)  # at separators and segments' first slots: the coupling with the slot before
    right_side: wp.array(dtype=wp.float64)
    solution: wp.array(dtype=wp.float64)  # per slot: the segment's solution for the line's right side, then dlambda
    from_left: wp.array(dtype=wp.float64)  # per slot: its solution for the left separator's coupling
    from_right: wp.array(dtype=wp.float64)  # per slot: its solution for the right separator's coupling
    upper: wp.array(dtype=wp.float64)  # per slot: scratch, the eliminated upper diagonal


@wp.kernel
def eliminate_segments(lines: ClothLines, segments: LineSegments, inv_mass: wp.array(dtype=float),
                       hold_margin: float, x: wp.array(dtype=wp.vec3)):
    """Segment s's springs' equations, eliminated for the line's right side and a unit coupling to each
    separator; its right separator's equation (and the springs' directions into ``lines.normal``) kept for
    the separators' solve and the finish. One pass builds and eliminates: a separate launch for the
    equations cost as much again on an H100 (docs/notebook/strain-solve.md)."""
    s = wp.tid()
    first = segments.first[s]
    end = segments.end[s]
    has_left = segments.left[s] >= 0
    has_right = segments.right[s] >= 0
    normal_before = wp.vec3(0.0)
    if has_left:
        normal_before, unused_diagonal, unused_right = spring_equation(lines, inv_mass, hold_margin, x, first - 1)
    pivot_before = wp.float64(1.0)
    solution_before = wp.float64(0.0)
    left_before = wp.float64(0.0)
    right_before = wp.float64(0.0)
    for k in range(first, end):
        normal, diagonal, right = spring_equation(lines, inv_mass, hold_margin, x, k)
        lines.normal[k] = normal
        coupling = wp.float64(-inv_mass[lines.particle[k]] * wp.dot(normal_before, normal))
        lower = wp.float64(0.0)
        upper_before = wp.float64(0.0)
        to_left = wp.float64(0.0)
        if k == first:
            to_left = coupling  # with the left separator (0 where there is none)
            segments.lower[k] = coupling
        else:
            lower = coupling
            upper_before = lower / pivot_before
            segments.upper[k - 1] = upper_before
        to_right = wp.float64(0.0)
        if k == end - 1 and has_right:
            separator_normal, separator_diagonal, separator_right = spring_equation(lines, inv_mass, hold_margin,
                                                                                    x, end)
            to_right = wp.float64(-inv_mass[lines.particle[end]] * wp.dot(normal, separator_normal))
            lines.normal[end] = separator_normal
            segments.lower[end] = to_right
            segments.diagonal[end] = separator_diagonal
            segments.right_side[end] = separator_right
        pivot = wp.max(diagonal - lower * upper_before, wp.float64(1.0e-9) * diagonal)
        solution_before = (right - lower * solution_before) / pivot
        left_before = (to_left - lower * left_before) / pivot
        right_before = (to_right - lower * right_before) / pivot
        segments.solution[k] = solution_before
        segments.from_left[k] = left_before
        segments.from_right[k] = right_before
        pivot_before = pivot
        normal_before = normal
    for step in range(1, end - first):
        k = end - 1 - step
        upper = segments.upper[k]
        segments.solution[k] = segments.solution[k] - upper * segments.solution[k + 1]
        segments.from_left[k] = segments.from_left[k] - upper * segments.from_left[k + 1]
        segments.from_right[k] = segments.from_right[k] - upper * segments.from_right[k + 1]


@wp.kernel
def solve_separators(segments: LineSegments):
    """Line l's separators' dlambda, from their Schur complement (tridiagonal, one row a separator)."""
    l = wp.tid()
    begin = segments.separator_start[l]
    count = segments.separator_start[l + 1] - begin
    pivot_before = wp.float64(1.0)
    solution_before = wp.float64(0.0)
    for i in range(count):
        k = segments.separator[begin + i]
        lower_in = segments.lower[k]  # with the last spring of the segment before (slot k - 1)
        upper_in = segments.lower[k + 1]  # with the first of the segment after (slot k + 1)
        diagonal = segments.diagonal[k] - lower_in * segments.from_right[k - 1] - upper_in * segments.from_left[k + 1]
        right = segments.right_side[k] - lower_in * segments.solution[k - 1] - upper_in * segments.solution[k + 1]
        lower = wp.float64(0.0)
        upper_before = wp.float64(0.0)
        if i > 0:
            lower = -lower_in * segments.from_left[k - 1]
            upper_before = lower / pivot_before
            segments.upper[segments.separator[begin + i - 1]] = upper_before
        pivot = wp.max(diagonal - lower * upper_before, wp.float64(1.0e-9) * segments.diagonal[k])
        solution_before = (right - lower * solution_before) / pivot
        segments.solution[k] = solution_before
        pivot_before = pivot
    for step in range(1, count):
        k = segments.separator[begin + count - 1 - step]
        after = segments.separator[begin + count - step]
        segments.solution[k] = segments.solution[k] - segments.upper[k] * segments.solution[after]


@wp.kernel
def finish_segments(lines: ClothLines, segments: LineSegments, inv_mass: wp.array(dtype=float), h: float,
                    x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Segment s's springs' dlambda from its separators', and its particles moved by W J^T dlambda (their
    velocities by the move over h): from its first slot's to its right separator's first particle, or to its
    line's last. Each dlambda is used where it is made, never stored: only the separators' are read across
    segments."""
    s = wp.tid()
    first = segments.first[s]
    end = segments.end[s]
    left = segments.left[s]
    right = segments.right[s]
    from_left = wp.float64(0.0)
    before = wp.float64(0.0)  # the dlambda of the spring before the particle (slot k - 1)
    normal_before = wp.vec3(0.0)
    if left >= 0:
        from_left = segments.solution[left]
        before = from_left
        normal_before = lines.normal[left]
    from_right = wp.float64(0.0)
    if right >= 0:
        from_right = segments.solution[right]
    for k in range(first, end + 1):
        after = from_right  # the separator's, or 0 after a line's last particle
        normal = wp.vec3(0.0)
        if k < end:
            after = segments.solution[k] - from_left * segments.from_left[k] - from_right * segments.from_right[k]
        if k < end or right >= 0:
            normal = lines.normal[k]
        p = lines.particle[k]
        w = inv_mass[p]
        if w > 0.0:
            move = w * (float(before) * normal_before - float(after) * normal)
            x[p] = x[p] + move
            v[p] = v[p] + move / h
        before = after
        normal_before = normal
