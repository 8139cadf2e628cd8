"""The blow-up guard: after every substep, flag the substep of a world (a scene alone is one) if any of its
particles' state is non-finite or moving faster than a bound no cloth in the scene should reach."""

import warp as wp

TOO_FAST = wp.constant(1)
NOT_FINITE = wp.constant(2)


@wp.kernel
def check_state(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), world: wp.array(dtype=int), max_speed: float,
                done: wp.array(dtype=int), offset: int, status: wp.array2d(dtype=int)):
    """status[substep, w] becomes the worst finding of that substep in world w (NOT_FINITE over TOO_FAST
    over 0), the substep being ``done[0] + offset`` (the frame's substeps before the round it is in, and its
    place there). A substep past the end of ``status`` is flagged in its last row, never written out of
    bounds."""
    i = wp.tid()
    substep = wp.min(done[0] + offset, status.shape[0] - 1)
    w = world[i]
    p = x[i]
    u = v[i]
    if not (wp.isfinite(p) and wp.isfinite(u)):
        wp.atomic_max(status, substep, w, NOT_FINITE)
    elif wp.length_sq(u) > max_speed * max_speed:
        wp.atomic_max(status, substep, w, TOO_FAST)
