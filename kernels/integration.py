"""The explicit integrators' step of one particle (the implicit one is warp_cloth/implicit.py's).

A step reads the state at t and writes the state at t + h into other buffers, because a particle's spring
forces read its neighbours' old positions. Particles with inverse mass 0 (pinned) keep their state: the
pins' motion drives them.
"""

import warp as wp


@wp.func
def explicit_step(x: wp.vec3, v: wp.vec3, w: float, f: wp.vec3, acceleration: wp.vec3, h: float,
                  semi_implicit: int):
    """Position and velocity after one step of a particle of inverse mass w under the internal force f and
    the external ``acceleration``: v' = v + h (acceleration + w f); x' = x + h v (forward Euler, the
    seed's) or x' = x + h v' (``semi_implicit`` = 1, symplectic Euler)."""
    if w == 0.0:
        return x, v
    v_new = v + h * (acceleration + w * f)
    if semi_implicit != 0:
        return x + h * v_new, v_new
    return x + h * v, v_new

