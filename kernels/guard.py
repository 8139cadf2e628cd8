"""The blow-up guard: after every substep, flag the substep if any particle's state is non-finite or
moving faster than a bound no cloth in the scene should reach."""

import warp as wp

TOO_FAST = wp.constant(1)
NOT_FINITE = wp.constant(2)


@wp.kernel
def check_state(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), max_speed: float, substep: int,
                status: wp.array(dtype=int)):
    """status[substep] becomes the worst finding of that substep (NOT_FINITE over TOO_FAST over 0). A
    substep past the end of ``status`` is flagged in its last element, never written out of bounds."""
    i = wp.tid()
    substep = wp.min(substep, status.shape[0] - 1)
    p = x[i]
    u = v[i]
    if not (wp.isfinite(p) and wp.isfinite(u)):
        wp.atomic_max(status, substep, NOT_FINITE)
    elif wp.length_sq(u) > max_speed * max_speed:
        wp.atomic_max(status, substep, TOO_FAST)
