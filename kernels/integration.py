"""Explicit time integrators. A step reads the state at t and writes the state at t + h into other
buffers, because a particle's spring forces read its neighbours' old positions. Particles with inverse
mass 0 (pinned) are copied unchanged: the pin stage drives them."""

import warp as wp

from .springs import gather_spring_forces


@wp.func
def advance(xi: wp.vec3, vi: wp.vec3, w: float, f: wp.vec3, gravity: wp.vec3, drag: float, h: float,
            semi_implicit: int):
    """One particle's new position and velocity from its spring force f (w: inverse mass)."""
    v_new = vi + h * (gravity - drag * vi + w * f)
    if semi_implicit != 0:
        return xi + h * v_new, v_new
    return xi + h * vi, v_new


@wp.kernel
def euler_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
               gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
               other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
               stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
               x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """v' = v + h a(x, v); x' = x + h v (forward Euler, the seed's) or x' = x + h v' (semi_implicit = 1,
    symplectic Euler). a = gravity - drag v + f / m."""
    i = wp.tid()
    w = inv_mass[i]
    if w == 0.0:
        x_out[i] = x[i]
        v_out[i] = v[i]
        return
    f = gather_spring_forces(i, x, v, offsets, other, spring, rest, stiffness, damping, flags)
    x_new, v_new = advance(x[i], v[i], w, f, gravity, drag, h, semi_implicit)
    x_out[i] = x_new
    v_out[i] = v_new
