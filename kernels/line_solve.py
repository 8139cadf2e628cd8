"""The strain limits of a cloth's lines solved directly (after the converged solve's first Jacobi pair; issue
33). A line is a chain of limited springs (on a grid a row, a column or a diagonal) whose ends are its only
pinned particles. A spring out of its range, or within ``hold_margin`` (a fraction of the limit's length) of
either end of it, is held: the first at the nearer end of the range, the second at its current length; the
others are left out of the solve, which cuts the line there. Holding every spring makes a line rigid: a
correction then slides the whole rest of the line along itself against its neighbours, breaking the other
families' springs all along it, and at 256^2 the rounds stalled; holding only the violated ones lets the
spring beside a correction, at its limit, take all of it (docs/notebook/strain-solve.md). The linearised
projection J W J^T dlambda = -C along a line is tridiagonal, eliminated in float64; the particles then move
by W J^T dlambda and their velocities by that over h. The lines of one family share no free particle, so a
family's threads move their particles in place.

A thread a segment of a line, by the partition method: a line's springs are cut by separators; a segment is
the springs between two separators (or a line's end), its thread eliminating them for three right sides at
once (the line's, and a unit coupling to each separator); one thread a line then solves the small
tridiagonal system of its separators (their Schur complement), and the segments' threads finish their
springs from it and move their particles. A line with no separator is one segment: Thomas' algorithm.

The per-slot arrays are stored in a layout the host chooses (warp_cloth/line_solve.py): segment s's j-th slot
(j = 0 .. its springs, the last being its right separator's slot or its line's last particle) at storage
index ``base[s] + j * step``, and what a segment reads of another's slots through storage indices given
with it.
"""

import warp as wp

from .attachments import Attachments, hold_to_pin
from .colliders import RigidColliders, collide_particle


@wp.struct
class ClothLines:
    """A family's lines, per slot in storage."""
    particle: wp.array(dtype=int)
    min_length: wp.array(dtype=float)  # the spring from the slot's particle to the next slot's: its range
    max_length: wp.array(dtype=float)
    normal: wp.array(dtype=wp.vec3)  # scratch: the spring's direction (zero where it is left out)


@wp.struct
class LineSegments:
    """A family's segments and separators, as storage indices, and the solve's per-slot scratch."""
    base: wp.array(dtype=int)  # (segments,) the storage index of a segment's first slot
    length: wp.array(dtype=int)  # its springs: its slot j = length is its right separator's or its line's last
    step: int  # from a segment's slot to its next in storage
    left: wp.array(dtype=int)  # the separator's slot before it (-1: it starts its line)
    right: wp.array(dtype=int)  # the separator's slot that ends it (-1: it ends its line)
    after_right: wp.array(dtype=int)  # the slot after that separator (the next segment's first)
    separator_start: wp.array(dtype=int)  # (lines + 1,) line l's separators are separator[start[l]:start[l + 1]]
    separator: wp.array(dtype=int)  # their slots, in order along the line
    before_separator: wp.array(dtype=int)  # the slot before each (the last spring of the segment it ends)
    after_separator: wp.array(dtype=int)  # the slot after each (the first of the segment after)
    diagonal: wp.array(dtype=wp.float64)  # per slot, set at separators: scratch, the system's entries
    lower: wp.array(dtype=wp.float64)  # at separators and segments' first slots: the coupling with the slot before
    right_side: wp.array(dtype=wp.float64)
    solution: wp.array(dtype=wp.float64)  # per slot: the segment's solution for the line's right side, then dlambda
    from_left: wp.array(dtype=wp.float64)  # per slot: its solution for the left separator's coupling
    from_right: wp.array(dtype=wp.float64)  # per slot: its solution for the right separator's coupling
    upper: wp.array(dtype=wp.float64)  # per slot: scratch, the eliminated upper diagonal


@wp.func
def spring_equation(lines: ClothLines, inv_mass: wp.array(dtype=float), hold_margin: float,
                    x: wp.array(dtype=wp.vec3), k: int, next_slot: int):
    """The spring from slot k's particle to slot ``next_slot``'s in its line's system: its direction, its diagonal
    entry and its right side (a spring left out, or that nothing can move, gets direction 0: dlambda 0,
    coupled to no neighbour)."""
    a = lines.particle[k]
    b = lines.particle[next_slot]
    d = x[b] - x[a]
    length = wp.length(d)
    normal = wp.vec3(0.0)
    if length > 1.0e-12:
        normal = d / length
    diagonal = wp.float64(inv_mass[a] + inv_mass[b])
    longest = lines.max_length[k]
    shortest = lines.min_length[k]
    right = wp.float64(wp.clamp(length, shortest, longest) - length)
    held = length >= (1.0 - hold_margin) * longest or length <= (1.0 + hold_margin) * shortest
    if diagonal == wp.float64(0.0) or length <= 1.0e-12 or not held:
        diagonal = wp.float64(1.0)
        right = wp.float64(0.0)
        normal = wp.vec3(0.0)
    return normal, diagonal, right


@wp.kernel
def eliminate_segments(lines: ClothLines, segments: LineSegments, inv_mass: wp.array(dtype=float),
                       hold_margin: float, x: wp.array(dtype=wp.vec3)):
    """Segment s's springs' equations, eliminated for the line's right side and a unit coupling to each
    separator; its right separator's equation (and the springs' directions into ``lines.normal``) kept for
    the separators' solve and the finish. One pass builds and eliminates: a separate launch for the
    equations cost as much again on an H100 (docs/notebook/strain-solve.md)."""
    s = wp.tid()
    base = segments.base[s]
    length = segments.length[s]
    step = segments.step
    left = segments.left[s]
    separator = segments.right[s]
    normal_before = wp.vec3(0.0)
    if left >= 0:
        normal_before, unused_diagonal, unused_right = spring_equation(lines, inv_mass, hold_margin, x, left, base)
    pivot_before = wp.float64(1.0)
    solution_before = wp.float64(0.0)
    left_before = wp.float64(0.0)
    right_before = wp.float64(0.0)
    for j in range(length):
        k = base + j * step
        normal, diagonal, right = spring_equation(lines, inv_mass, hold_margin, x, k, k + step)
        lines.normal[k] = normal
        coupling = wp.float64(-inv_mass[lines.particle[k]] * wp.dot(normal_before, normal))
        lower = wp.float64(0.0)
        upper_before = wp.float64(0.0)
        to_left = wp.float64(0.0)
        if j == 0:
            to_left = coupling  # with the left separator (0 where there is none)
            segments.lower[k] = coupling
        else:
            lower = coupling
            upper_before = lower / pivot_before
            segments.upper[k - step] = upper_before
        to_right = wp.float64(0.0)
        if j == length - 1 and separator >= 0:
            separator_normal, separator_diagonal, separator_right = spring_equation(
                lines, inv_mass, hold_margin, x, separator, segments.after_right[s])
            to_right = wp.float64(-inv_mass[lines.particle[separator]] * wp.dot(normal, separator_normal))
            lines.normal[separator] = separator_normal
            segments.lower[separator] = to_right
            segments.diagonal[separator] = separator_diagonal
            segments.right_side[separator] = separator_right
        pivot = wp.max(diagonal - lower * upper_before, wp.float64(1.0e-9) * diagonal)
        solution_before = (right - lower * solution_before) / pivot
        left_before = (to_left - lower * left_before) / pivot
        right_before = (to_right - lower * right_before) / pivot
        segments.solution[k] = solution_before
        if left >= 0:  # a side with no separator has no coupling to solve for (a whole line has neither)
            segments.from_left[k] = left_before
        if separator >= 0:
            segments.from_right[k] = right_before
        pivot_before = pivot
        normal_before = normal
    for back in range(1, length):
        k = base + (length - 1 - back) * step
        upper = segments.upper[k]
        segments.solution[k] = segments.solution[k] - upper * segments.solution[k + step]
        if left >= 0:
            segments.from_left[k] = segments.from_left[k] - upper * segments.from_left[k + step]
        if separator >= 0:
            segments.from_right[k] = segments.from_right[k] - upper * segments.from_right[k + step]


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
        before = segments.before_separator[begin + i]  # the last spring of the segment before
        after = segments.after_separator[begin + i]  # the first of the segment after
        lower_in = segments.lower[k]
        upper_in = segments.lower[after]
        diagonal = segments.diagonal[k] - lower_in * segments.from_right[before] - upper_in * segments.from_left[after]
        right = segments.right_side[k] - lower_in * segments.solution[before] - upper_in * segments.solution[after]
        lower = wp.float64(0.0)
        upper_before = wp.float64(0.0)
        if i > 0:
            lower = -lower_in * segments.from_left[before]
            upper_before = lower / pivot_before
            segments.upper[segments.separator[begin + i - 1]] = upper_before
        pivot = wp.max(diagonal - lower * upper_before, wp.float64(1.0e-9) * segments.diagonal[k])
        solution_before = (right - lower * solution_before) / pivot
        segments.solution[k] = solution_before
        pivot_before = pivot
    for back in range(1, count):
        k = segments.separator[begin + count - 1 - back]
        after = segments.separator[begin + count - back]
        segments.solution[k] = segments.solution[k] - segments.upper[k] * segments.solution[after]


@wp.kernel
def finish_segments(lines: ClothLines, segments: LineSegments, inv_mass: wp.array(dtype=float), h: float,
                    x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Segment s's springs' dlambda from its separators', and its particles moved by W J^T dlambda (their
    velocities by the move over h): from its first slot's to its right separator's first particle, or to its
    line's last. Each dlambda is used where it is made, never stored: only the separators' are read across
    segments."""
    s = wp.tid()
    base = segments.base[s]
    length = segments.length[s]
    step = segments.step
    left = segments.left[s]
    right = segments.right[s]
    from_left = wp.float64(0.0)
    before = wp.float64(0.0)  # the dlambda of the spring before the particle
    normal_before = wp.vec3(0.0)
    if left >= 0:
        from_left = segments.solution[left]
        before = from_left
        normal_before = lines.normal[left]
    from_right = wp.float64(0.0)
    if right >= 0:
        from_right = segments.solution[right]
    for j in range(length + 1):
        k = base + j * step
        after = from_right  # the separator's, or 0 after a line's last particle
        normal = wp.vec3(0.0)
        if j < length:
            after = segments.solution[k]
            if left >= 0:
                after = after - from_left * segments.from_left[k]
            if right >= 0:
                after = after - from_right * segments.from_right[k]
        if j < length or right >= 0:
            normal = lines.normal[k]
        p = lines.particle[k]
        w = inv_mass[p]
        if w > 0.0:
            move = w * (float(before) * normal_before - float(after) * normal)
            x[p] = x[p] + move
            v[p] = v[p] + move / h
        before = after
        normal_before = normal


@wp.kernel
def turn_order(reversed: wp.array(dtype=int)):
    """The next round of line solves takes the families in the other order."""
    reversed[0] = 1 - reversed[0]


@wp.kernel
def hold_and_collide(attachments: Attachments, colliders: RigidColliders, inv_mass: wp.array(dtype=float), h: float,
                     x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """The end of a round of line solves, as of a limit pass: free particle i held to its pin, then put out
    of the rigid colliders (reading only pins, which do not move, it can write in place)."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p, vel = hold_to_pin(attachments, colliders, i, x[i], v[i], h, x)
    p, vel, hit = collide_particle(i, p, vel, colliders, h)
    x[i] = p
    v[i] = vel
