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
once (the line's, and a unit coupling to each separator); the small tridiagonal system of a line's
separators (their Schur complement) is then solved by steps of cyclic reduction, a thread a separator,
until its chains are short, and a thread a chain; the segments' threads finish their springs from it and
move their particles. A line with no separator is one segment: Thomas' algorithm.

The per-slot arrays are stored in a layout the host chooses (warp_cloth/line_solve.py): segment s's j-th slot
(j = 0 .. its springs, the last being its right separator's slot or its line's last particle) at storage
index ``base[s] + j * step``, and what a segment reads of another's slots through storage indices given
with it.
"""

import warp as wp

from .attachments import Attachments, hold_to_pin
from .colliders import RigidColliders, collide_particle

# Every pivot (Thomas', cyclic reduction's, a chain's) is held to at least this fraction of its own spring's
# diagonal: a line that cannot reach its limit has a singular system (docs/notebook/strain-solve.md)
PIVOT_FLOOR = wp.constant(wp.float64(1.0e-9))


@wp.struct
class ClothLines:
    """A family's lines, per slot in storage."""
    particle: wp.array(dtype=int)
    min_length: wp.array(dtype=float)  # the spring from the slot's particle to the next slot's: its range
    max_length: wp.array(dtype=float)
    normal: wp.array(dtype=wp.vec3)  # scratch: the spring's direction (zero where it is left out)


@wp.struct
class LineSegments:
    """A family's segments and separators, and the solve's scratch: per slot in storage, per separator in
    the order of their lines."""
    base: wp.array(dtype=int)  # (segments,) the storage index of a segment's first slot
    length: wp.array(dtype=int)  # its springs: its slot j = length is its right separator's or its line's last
    step: int  # from a segment's slot to its next in storage
    left: wp.array(dtype=int)  # the separator's slot before it (-1: it starts its line)
    right: wp.array(dtype=int)  # the separator's slot that ends it (-1: it ends its line)
    after_right: wp.array(dtype=int)  # the slot after that separator (the next segment's first)
    left_separator: wp.array(dtype=int)  # the numbers of those separators (-1: none)
    right_separator: wp.array(dtype=int)
    # a cut ring's one particle at both ends, moved by its first segment alone (warp_cloth/line_solve.py's
    # line_segments): there the slot of the ring's last spring and the separator before the segment that
    # ends the ring (-1: not a ring's first segment); 1 for the ring's last segment, which leaves it
    ring_spring: wp.array(dtype=int)
    ring_separator: wp.array(dtype=int)
    ring_end: wp.array(dtype=int)
    separator_start: wp.array(dtype=int)  # (lines + 1,) line l's separators are start[l] .. start[l + 1] - 1
    # per slot: the forward elimination of the segment's springs for the line's right side and a unit
    # coupling to each separator (to the right one stored at the last slot only: above it, it is 0), and the
    # eliminated upper diagonal (the back substitution is the finish's)
    solution: wp.array(dtype=wp.float64)
    from_left: wp.array(dtype=wp.float64)
    from_right: wp.array(dtype=wp.float64)
    upper: wp.array(dtype=wp.float64)
    # per separator: its row of the Schur complement, as the segments before and after it leave it
    own_diagonal: wp.array(dtype=wp.float64)  # the separator spring's own diagonal entry
    diagonal_from_before: wp.array(dtype=wp.float64)
    right_from_before: wp.array(dtype=wp.float64)
    coupling: wp.array(dtype=wp.float64)  # with the separator before, through the segment between
    diagonal_from_after: wp.array(dtype=wp.float64)
    right_from_after: wp.array(dtype=wp.float64)
    separator_line: wp.array(dtype=int)  # the line it cuts
    separator_upper: wp.array(dtype=wp.float64)  # scratch: its chain's eliminated upper diagonal
    separator_solution: wp.array(dtype=wp.float64)  # its dlambda


@wp.struct
class SeparatorRows:
    """A family's separators' rows as cyclic reduction leaves them: each row couples its separator with the
    ones ``stride`` before and after it in its line (lower, upper), its diagonal and its right side."""
    lower: wp.array(dtype=wp.float64)
    diagonal: wp.array(dtype=wp.float64)
    upper: wp.array(dtype=wp.float64)
    right: wp.array(dtype=wp.float64)


@wp.func
def spring_equation(xa: wp.vec3, xb: wp.vec3, wa: float, wb: float, shortest: float, longest: float,
                    hold_margin: float):
    """A spring from a to b in its line's system: its direction, its diagonal entry and its right side (a
    spring left out, or that nothing can move, gets direction 0: dlambda 0, coupled to no neighbour)."""
    d = xb - xa
    length = wp.length(d)
    normal = wp.vec3(0.0)
    if length > 1.0e-12:
        normal = d / length
    diagonal = wp.float64(wa + wb)
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
    """Segment s's springs' equations, eliminated forwards for the line's right side and a unit coupling to
    each separator; the springs' directions into ``lines.normal``; and what the segment gives its
    separators' rows: its right separator's equation less its last spring's part, and its first spring's
    part of its left separator's (the first slot's back substitution as a running sum: with the finish
    doing the rest, no launch walks a segment twice). A spring's far particle is the next one's near one,
    and the slot after next is read a spring ahead: each spring waits on one round of loads, not three (the
    kernel waited on memory, docs/notebook/strain-solve.md)."""
    s = wp.tid()
    base = segments.base[s]
    length = segments.length[s]
    step = segments.step
    left = segments.left[s]
    separator = segments.right[s]
    a = lines.particle[base]
    xa = x[a]
    wa = inv_mass[a]
    b = lines.particle[base + step]
    normal_before = wp.vec3(0.0)
    if left >= 0:
        near = lines.particle[left]
        normal_before, unused_diagonal, unused_right = spring_equation(
            x[near], xa, inv_mass[near], wa, lines.min_length[left], lines.max_length[left], hold_margin)
    pivot_before = wp.float64(1.0)
    solution_before = wp.float64(0.0)
    left_before = wp.float64(0.0)
    to_left = wp.float64(0.0)
    product = wp.float64(1.0)  # the first slot's back substitution: the product of -upper so far
    first_solution = wp.float64(0.0)
    first_left = wp.float64(0.0)
    for j in range(length):
        k = base + j * step
        xb = x[b]
        wb = inv_mass[b]
        b_next = lines.particle[base + wp.min(j + 2, length) * step]  # unconditional: a load in a branch waits
        shortest = lines.min_length[k]
        longest = lines.max_length[k]
        normal, diagonal, right = spring_equation(xa, xb, wa, wb, shortest, longest, hold_margin)
        lines.normal[k] = normal
        coupling = wp.float64(-wa * wp.dot(normal_before, normal))
        lower = wp.float64(0.0)
        upper_before = wp.float64(0.0)
        to_left_now = wp.float64(0.0)
        if j == 0:
            to_left = coupling  # with the left separator (0 where there is none)
            to_left_now = coupling
        else:
            lower = coupling
            upper_before = lower / pivot_before
            segments.upper[k - step] = upper_before
        pivot = wp.max(diagonal - lower * upper_before, PIVOT_FLOOR * diagonal)
        solution_before = (right - lower * solution_before) / pivot
        left_before = (to_left_now - lower * left_before) / pivot
        segments.solution[k] = solution_before
        if left >= 0:  # a side with no separator has no coupling to solve for (a whole line has neither)
            segments.from_left[k] = left_before
            if j > 0:
                product = -product * upper_before
            first_solution = first_solution + product * solution_before
            first_left = first_left + product * left_before
        if j == length - 1 and separator >= 0:
            number = segments.right_separator[s]
            after = lines.particle[segments.after_right[s]]
            separator_normal, separator_diagonal, separator_right = spring_equation(
                xb, x[after], wb, inv_mass[after], lines.min_length[separator], lines.max_length[separator],
                hold_margin)
            lines.normal[separator] = separator_normal
            to_right = wp.float64(-wb * wp.dot(normal, separator_normal))
            right_before = to_right / pivot  # its right side is 0 above its last row, and so is its elimination
            segments.from_right[k] = right_before
            segments.own_diagonal[number] = separator_diagonal
            segments.diagonal_from_before[number] = separator_diagonal - to_right * right_before
            segments.right_from_before[number] = separator_right - to_right * solution_before
            segments.coupling[number] = -to_right * left_before
        pivot_before = pivot
        normal_before = normal
        xa = xb
        wa = wb
        b = b_next
    if left >= 0:
        number = segments.left_separator[s]
        segments.diagonal_from_after[number] = -to_left * first_left
        segments.right_from_after[number] = -to_left * first_solution


@wp.func
def separator_row(segments: LineSegments, rows: SeparatorRows, r: int, from_segments: int):
    """Separator r's row: as the segments before and after it left it (``from_segments``: its line's Schur
    complement, tridiagonal), or as cyclic reduction left it in ``rows``. Lower, diagonal, upper, right."""
    if from_segments == 0:
        return rows.lower[r], rows.diagonal[r], rows.upper[r], rows.right[r]
    upper = wp.float64(0.0)
    if r + 1 < segments.separator_start[segments.separator_line[r] + 1]:
        upper = segments.coupling[r + 1]
    diagonal = wp.max(segments.diagonal_from_before[r] + segments.diagonal_from_after[r],
                      PIVOT_FLOOR * segments.own_diagonal[r])
    # coupling is 0 at a line's first separator: the segment before it starts the line
    return segments.coupling[r], diagonal, upper, segments.right_from_before[r] + segments.right_from_after[r]


@wp.kernel
def reduce_separators(segments: LineSegments, stride: int, from_segments: int, rows: SeparatorRows,
                      reduced: SeparatorRows):
    """One step of cyclic reduction: separator r's row with the rows ``stride`` before and after it in its
    line eliminated, so that it couples only the separators 2 ``stride`` away: a line's separators split
    into twice as many chains, each half as long."""
    r = wp.tid()
    line = segments.separator_line[r]
    lower, diagonal, upper, right = separator_row(segments, rows, r, from_segments)
    reduced_lower = wp.float64(0.0)
    reduced_upper = wp.float64(0.0)
    if r - stride >= segments.separator_start[line]:
        lower_before, diagonal_before, upper_before, right_before = separator_row(segments, rows, r - stride,
                                                                                 from_segments)
        factor = -lower / diagonal_before
        reduced_lower = factor * lower_before
        diagonal = diagonal + factor * upper_before
        right = right + factor * right_before
    if r + stride < segments.separator_start[line + 1]:
        lower_after, diagonal_after, upper_after, right_after = separator_row(segments, rows, r + stride,
                                                                             from_segments)
        factor = -upper / diagonal_after
        reduced_upper = factor * upper_after
        diagonal = diagonal + factor * lower_after
        right = right + factor * right_after
    reduced.lower[r] = reduced_lower
    reduced.diagonal[r] = wp.max(diagonal, PIVOT_FLOOR * segments.own_diagonal[r])
    reduced.upper[r] = reduced_upper
    reduced.right[r] = right


@wp.kernel
def solve_separator_chains(segments: LineSegments, stride: int, from_segments: int, rows: SeparatorRows):
    """The separators' dlambda: a thread a chain, a line's separators ``stride`` apart from its offset,
    eliminated one after another (Thomas' algorithm on the rows that cyclic reduction left)."""
    t = wp.tid()
    line = t // stride
    begin = segments.separator_start[line] + t % stride
    end = segments.separator_start[line + 1]
    pivot_before = wp.float64(1.0)
    solution_before = wp.float64(0.0)
    upper_before = wp.float64(0.0)
    last = begin - stride
    for r in range(begin, end, stride):
        lower, diagonal, upper, right = separator_row(segments, rows, r, from_segments)
        upper_eliminated = upper_before / pivot_before
        pivot = wp.max(diagonal - lower * upper_eliminated, PIVOT_FLOOR * segments.own_diagonal[r])
        solution_before = (right - lower * solution_before) / pivot
        segments.separator_solution[r] = solution_before
        segments.separator_upper[r] = upper / pivot
        pivot_before = pivot
        upper_before = upper
        last = r
    r = last - stride
    while r >= begin:
        solution_before = segments.separator_solution[r] - segments.separator_upper[r] * solution_before
        segments.separator_solution[r] = solution_before
        r = r - stride


@wp.kernel
def finish_segments(lines: ClothLines, segments: LineSegments, inv_mass: wp.array(dtype=float), h: float,
                    x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Segment s's springs' dlambda, back substituted from its last slot to its first and combined with its
    separators', and its particles moved by W J^T dlambda (their velocities by the move over h): from its
    right separator's first particle (or its line's last) back to its first slot's. Each dlambda is used
    where it is made, never stored. Every load is unconditional and a particle's own are read a slot ahead
    (its index two), so that a slot waits on one round of loads."""
    s = wp.tid()
    base = segments.base[s]
    length = segments.length[s]
    step = segments.step
    left = segments.left[s]
    right = segments.right[s]
    from_left = wp.float64(0.0)
    before_first = wp.float64(0.0)  # the dlambda of the spring before the first slot's particle, and its direction
    normal_first = wp.vec3(0.0)
    if left >= 0:
        from_left = segments.separator_solution[segments.left_separator[s]]
        before_first = from_left
        normal_first = lines.normal[left]
    ring_spring = segments.ring_spring[s]
    if ring_spring >= 0:  # the ring's last spring: the last row of its segment, eliminated already
        ring_left = segments.separator_solution[segments.ring_separator[s]]
        before_first = segments.solution[ring_spring] - ring_left * segments.from_left[ring_spring]
        normal_first = lines.normal[ring_spring]
    ring_end = segments.ring_end[s]
    from_right = wp.float64(0.0)
    after = wp.float64(0.0)  # the dlambda of the spring after the particle: the separator's, or none
    normal_after = wp.vec3(0.0)
    if right >= 0:
        from_right = segments.separator_solution[segments.right_separator[s]]
        after = from_right
        normal_after = lines.normal[base + length * step]
    solution = wp.float64(0.0)  # the back substitution at the slot after the particle's, for each right side
    solution_left = wp.float64(0.0)
    solution_right = wp.float64(0.0)
    p = lines.particle[base + length * step]
    xp = x[p]
    vp = v[p]
    wp_ = inv_mass[p]
    p_before = lines.particle[base + wp.max(length - 1, 0) * step]
    for back in range(length + 1):
        j = length - back
        k_before = base + wp.max(j - 1, 0) * step
        upper = segments.upper[k_before]
        eliminated = segments.solution[k_before]
        eliminated_left = segments.from_left[k_before]
        eliminated_right = segments.from_right[k_before]
        normal_before = lines.normal[k_before]
        x_next = x[p_before]
        v_next = v[p_before]
        w_next = inv_mass[p_before]
        p_next = lines.particle[base + wp.max(j - 2, 0) * step]
        before = before_first  # the dlambda of the spring before the particle
        if j > 0:
            if j == length:
                upper = wp.float64(0.0)  # the last row is eliminated already
            else:
                eliminated_right = wp.float64(0.0)  # the right coupling's elimination is 0 above the last row
            solution = eliminated - upper * solution
            solution_left = eliminated_left - upper * solution_left
            solution_right = eliminated_right - upper * solution_right
            before = solution - from_left * solution_left - from_right * solution_right
        else:
            normal_before = normal_first
        if wp_ > 0.0 and (j < length or ring_end == 0):
            move = wp_ * (float(before) * normal_before - float(after) * normal_after)
            x[p] = xp + move
            v[p] = vp + move / h
        after = before
        normal_after = normal_before
        p = p_before
        xp = x_next
        vp = v_next
        wp_ = w_next
        p_before = p_next


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
