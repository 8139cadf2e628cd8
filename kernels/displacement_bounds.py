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


@wp.func
def held_at_bound(i: int, anchor: wp.array(dtype=wp.vec3), nearest: wp.array(dtype=float), gamma: float,
                  inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3),
                  predicted: wp.array(dtype=wp.vec3)) -> bool:
    """Whether free particle i stands at its bound (to a thousandth of it) with its predicted position
    beyond: the bounds, not the solve, stopped it there."""
    if inv_mass[i] == 0.0:
        return False
    bound = bound_of(nearest[i], gamma)
    return bound > 0.0 and wp.length(x[i] - anchor[i]) >= 0.999 * bound and \
        wp.length(predicted[i] - anchor[i]) > bound


@wp.kernel
def start_round(rounds: wp.array(dtype=int), again: wp.array(dtype=int)):
    """One thread, before ``find_held``: counts a round down (``rounds[0]`` left) and clears ``again``."""
    again[0] = 0
    rounds[0] = rounds[0] - 1


@wp.kernel
def find_held(anchor: wp.array(dtype=wp.vec3), nearest: wp.array(dtype=float), gamma: float,
              inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3), predicted: wp.array(dtype=wp.vec3),
              rounds: wp.array(dtype=int), again: wp.array(dtype=int), measured: wp.array(dtype=int),
              left_held: wp.array(dtype=int)):
    """Sets ``again[0]`` where a round is left and some particle is held at its bound with its predicted
    position beyond (``held_at_bound``), counting the round in ``measured[0]`` (once, by the first such);
    with no round left, counts the particles so held in ``left_held[0]``."""
    i = wp.tid()
    if not held_at_bound(i, anchor, nearest, gamma, inv_mass, x, predicted):
        return
    if rounds[0] < 0:
        wp.atomic_add(left_held, 0, 1)
    elif wp.atomic_max(again, 0, 1) == 0:
        wp.atomic_add(measured, 0, 1)


@wp.kernel
def send_on(nearest: wp.array(dtype=float), gamma: float, inv_mass: wp.array(dtype=float),
            predicted: wp.array(dtype=wp.vec3), inv_h: float, anchor: wp.array(dtype=wp.vec3),
            x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Before the bounds are measured again: each particle's anchor moved to where the solve left it, and a
    particle held at its old bound sent on to its predicted position, its velocity changed by the move over
    the substep (in place: it reads only its own particle)."""
    i = wp.tid()
    held = held_at_bound(i, anchor, nearest, gamma, inv_mass, x, predicted)
    anchor[i] = x[i]
    if held:
        v[i] = v[i] + (predicted[i] - x[i]) * inv_h
        x[i] = predicted[i]
