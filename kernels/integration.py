"""Explicit time integrators. A step reads the state at t and writes the state at t + h into other
buffers, because a particle's spring forces read its neighbours' old positions. Particles with inverse
mass 0 (pinned) are copied unchanged: the pin stage drives them."""

import warp as wp

from .springs import gather_spring_forces


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
    v_new = v[i] + h * (gravity - drag * v[i] + w * f)
    v_out[i] = v_new
    if semi_implicit != 0:
        x_out[i] = x[i] + h * v_new
    else:
        x_out[i] = x[i] + h * v[i]
