"""The explicit integrators' step of one particle (the implicit one is warp_cloth/implicit.py's).

A step reads the state at t and writes the state at t + h into other buffers, because a particle's spring
forces read its neighbours' old positions. Particles with inverse mass 0 (pinned) keep their state: the
pins' motion drives them.
"""

import warp as wp


@wp.func
def explicit_move(v: wp.vec3, w: float, f: wp.vec3, acceleration: wp.vec3, h: float, semi_implicit: int):
    """The move and the velocity after one step of a particle of inverse mass w under the internal force f
    and the external ``acceleration``: v' = v + h (acceleration + w f); the move h v (forward Euler, the
    seed's) or h v' (``semi_implicit`` = 1, symplectic Euler)."""
    if w == 0.0:
        return wp.vec3(0.0), v
    v_new = v + h * (acceleration + w * f)
    if semi_implicit != 0:
        return h * v_new, v_new
    return h * v, v_new


@wp.func
def compensated_sum(x: wp.vec3, dx: wp.vec3, carried: wp.vec3):
    """x + dx by Kahan's compensated summation: ``carried`` is what the sum before rounded away (0 at the
    start); returns the sum and what this one rounded away. A float32 position far from the origin loses
    most of a small move to rounding, and over thousands of substeps that loss adds up."""
    y = dx - carried
    t = x + y
    return t, (t - x) - y
