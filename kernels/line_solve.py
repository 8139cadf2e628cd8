"""The strain limits of a cloth's lines solved directly, one thread a line (the lab's alternative to the
Jacobi limit pass; issue 33). A line is a chain of limited springs (on a grid a row, a column or a
diagonal) whose ends are its only pinned particles. A spring out of its range, or within ``hold_margin`` (a
fraction of the limit's length) of either end of it, is held: the first at the nearer end of the range, the
second at its current length; the others are left out of the solve, which cuts the line there. Holding every
spring makes a line rigid: a correction then slides the whole rest of the line along itself against its
neighbours, breaking the other families' springs all along it, and at 256^2 the rounds stalled; holding only
the violated ones lets the spring beside a correction, at its limit, take all of it (docs/notebook/
strain-solve.md). The linearised projection J W J^T dlambda = -C along a line is tridiagonal and solved by
Thomas' algorithm, its elimination in float64; the particles then move by W J^T dlambda and their velocities
by that over h; ``newton_steps`` times, each from where the last left the line (a long line's step moves its
far particles enough that one linearisation leaves percents). The lines of one family share no free
particle, so a family's threads move their particles in place.
"""

import warp as wp

from .attachments import Attachments, hold_to_pin
from .colliders import RigidColliders, collide_particle


@wp.struct
class ClothLines:
    start: wp.array(dtype=int)  # (lines + 1,) line l's particles are particle[start[l]:start[l + 1]]
    particle: wp.array(dtype=int)
    min_length: wp.array(dtype=float)  # per slot k < a line's last: the spring particle[k]-particle[k + 1]'s range
    max_length: wp.array(dtype=float)
    normal: wp.array(dtype=wp.vec3)  # per slot: scratch, the spring's direction (zero where it is left out)
    upper: wp.array(dtype=wp.float64)  # per slot: scratch, the eliminated upper diagonal
    multiplier: wp.array(dtype=wp.float64)  # per slot: scratch, the eliminated right side, then dlambda


@wp.func
def spring_equation(lines: ClothLines, inv_mass: wp.array(dtype=float), hold_margin: float,
                    x: wp.array(dtype=wp.vec3), k: int):
    """Slot k's spring in its line's system: its direction, its diagonal entry and its right side (a spring
    left out, or that nothing can move, gets direction 0: dlambda 0, coupled to no neighbour)."""
    a = lines.particle[k]
    b = lines.particle[k + 1]
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


@wp.func
def move_by_multipliers(lines: ClothLines, multiplier: wp.array(dtype=wp.float64), inv_mass: wp.array(dtype=float),
                        h: float, k: int, after: bool, before: bool, x: wp.array(dtype=wp.vec3),
                        v: wp.array(dtype=wp.vec3)):
    """The particle at slot k moved by W J^T dlambda (``multiplier`` per slot) of the springs after it (slot
    k) and before it (slot k - 1) where it has them, its velocity by the move over h."""
    p = lines.particle[k]
    w = inv_mass[p]
    if w == 0.0:
        return
    move = wp.vec3(0.0)
    if after:
        move = move - float(multiplier[k]) * lines.normal[k]
    if before:
        move = move + float(multiplier[k - 1]) * lines.normal[k - 1]
    move = w * move
    x[p] = x[p] + move
    v[p] = v[p] + move / h


@wp.func
def held_line_step(lines: ClothLines, inv_mass: wp.array(dtype=float), hold_margin: float, h: float, first: int,
                   last: int, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """One linearised projection of the line of particles first..last, moving its free particles."""
    pivot_before = wp.float64(1.0)
    right_before = wp.float64(0.0)
    normal_before = wp.vec3(0.0)
    for k in range(first, last):
        normal, diagonal, right = spring_equation(lines, inv_mass, hold_margin, x, k)
        # the coupling with the spring before through their shared particle
        lower = wp.float64(-inv_mass[lines.particle[k]] * wp.dot(normal_before, normal))
        upper_before = wp.float64(0.0)
        if k > first:
            upper_before = lower / pivot_before
            lines.upper[k - 1] = upper_before
        pivot = diagonal - lower * upper_before
        pivot = wp.max(pivot, wp.float64(1.0e-9) * diagonal)
        right = (right - lower * right_before) / pivot
        lines.multiplier[k] = right
        lines.normal[k] = normal
        pivot_before = pivot
        right_before = right
        normal_before = normal
    after = wp.float64(0.0)
    for step in range(last - first):
        k = last - 1 - step
        m = lines.multiplier[k]
        if k < last - 1:
            m = m - lines.upper[k] * after
        lines.multiplier[k] = m
        after = m
    for k in range(first, last + 1):
        move_by_multipliers(lines, lines.multiplier, inv_mass, h, k, k < last, k > first, x, v)


@wp.kernel
def solve_lines(lines: ClothLines, inv_mass: wp.array(dtype=float), hold_margin: float, newton_steps: int, h: float,
                x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Line l's held projection, moving its free particles (and their velocities by the move over h)."""
    l = wp.tid()
    for unused in range(newton_steps):
        held_line_step(lines, inv_mass, hold_margin, h, lines.start[l], lines.start[l + 1] - 1, x, v)


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
