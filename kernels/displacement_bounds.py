"""A substep's displacements clamped to conservative per-vertex bounds (Offset Geometric Contact, Chen et al.
2025): vertex v moves at most b_v = gamma * nearest_v from where its step started, nearest_v being the least
distance, at most r, of a vertex-triangle or edge-edge pair sharing no vertex that v belongs to
(primitive_distances.py), and gamma < 1/2. Then no pair of triangles sharing no vertex that are apart at the
start crosses at the end:

On the straight path from start to end a point of a primitive, an average of its vertices, moves no farther
than they do: a vertex-triangle or edge-edge pair d apart stays d - 2 gamma min(d, r) > 0 apart all along. Two
triangles sharing no vertex, while apart, are as far apart as their closest such pair: apart at the start,
they never touch on the path (their distance would reach 0 where such a pair's did), so cannot cross at its end.

That is exact arithmetic. A pair that the solve keeps pressing together closes to (1 - 2 gamma) of its gap a
substep, so in some twenty substeps to the rounding of float32 positions (2.4e-7 m at 2 m from the origin),
where the stacked drape's layers then crossed (docs/notebook/layers.md): a particle nearer than
``LEAST_GAP`` to a primitive it may cross does not move at all, which keeps a margin of (1 - 2 gamma)
LEAST_GAP, some forty roundings at 2 m, above the rounding.

(A particle with no inverse mass, pinned, goes where its pass put it, unbounded: the guarantee holds where
pins stand still. A clamp ends on the segment from the start to where the solve put the particle, both
outside the rigid colliders: inside a sphere of radius R by at most b^2 / 8R.)
"""

import warp as wp

LEAST_GAP = wp.constant(1.0e-4)  # metres: see the module's docstring


@wp.func
def bound_of(nearest: float, gamma: float) -> float:
    """A particle's bound: gamma times its nearest pair's distance, none nearer than LEAST_GAP."""
    if nearest >= LEAST_GAP:
        return gamma * nearest
    return 0.0


@wp.kernel
def clamp_to_bounds(target: wp.array(dtype=wp.vec3), nearest: wp.array(dtype=float), gamma: float,
                    inv_mass: wp.array(dtype=float), position: wp.array(dtype=wp.vec3),
                    clamped: wp.array(dtype=int), slot: int):
    """Moves each free particle from ``position`` toward ``target`` by at most its bound, gamma * nearest
    (a pinned one all the way; none nearer than LEAST_GAP), counting in ``clamped[slot]`` the particles held
    short."""
    i = wp.tid()
    step = target[i] - position[i]
    length = wp.length(step)
    bound = bound_of(nearest[i], gamma)
    if inv_mass[i] == 0.0 or length <= bound:
        position[i] = target[i]
    else:
        position[i] = position[i] + step * (bound / length)
        wp.atomic_add(clamped, slot, 1)


@wp.kernel
def take_bounded_step(start: wp.array(dtype=wp.vec3), position: wp.array(dtype=wp.vec3), inv_h: float,
                      x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), held_back: wp.array(dtype=float)):
    """Each particle held short of where the solve put it (``x``) goes where its clamps left it, with the
    velocity of its step from ``start`` over the substep; ``held_back[0]`` adds up the distances given up."""
    i = wp.tid()
    short = x[i] - position[i]
    if wp.length_sq(short) > 0.0:
        wp.atomic_add(held_back, 0, wp.length(short))
        x[i] = position[i]
        v[i] = (position[i] - start[i]) * inv_h


@wp.kernel
def hold_within_bounds(start: wp.array(dtype=wp.vec3), nearest: wp.array(dtype=float), gamma: float,
                       inv_mass: wp.array(dtype=float), inv_h: float, x: wp.array(dtype=wp.vec3),
                       v: wp.array(dtype=wp.vec3)):
    """Inside the solve: each free particle farther from where the substep started than its bound (gamma *
    nearest, none nearer than LEAST_GAP) put back onto it, toward the start, its velocity changed by the move
    over the substep (in place: it reads only its own particle)."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    step = x[i] - start[i]
    length = wp.length(step)
    bound = bound_of(nearest[i], gamma)
    if length > bound:
        held = start[i] + step * (bound / length)
        v[i] = v[i] + (held - x[i]) * inv_h
        x[i] = held
