"""Explicit time integrators. A step reads the state at t and writes the state at t + h into other
buffers, because a particle's spring forces read its neighbours' old positions. Particles with inverse
mass 0 (pinned) are copied unchanged: the pin stage drives them."""

import functools

import warp as wp

from .lanes import FAST_MATH, lane_layout, lane_sum
from .springs import gather_spring_forces

wp.set_module_options(FAST_MATH)


@wp.func
def integrate(i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
              inv_mass: wp.array(dtype=float), gravity: wp.vec3, drag: float, h: float, semi_implicit: int,
              x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """v' = v + h a(x, v); x' = x + h v (forward Euler, the seed's) or x' = x + h v' (semi_implicit = 1,
    symplectic Euler). a = gravity - drag v + f / m."""
    w = inv_mass[i]
    xi = x[i]
    vi = v[i]
    if w == 0.0:
        x_out[i] = xi
        v_out[i] = vi
        return
    v_new = vi + h * (gravity - drag * vi + w * f)
    v_out[i] = v_new
    if semi_implicit != 0:
        x_out[i] = xi + h * v_new
    else:
        x_out[i] = xi + h * vi


@wp.kernel
def euler_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
               gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
               other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
               stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
               x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Spring forces and one explicit or symplectic Euler step, a thread per particle."""
    i = wp.tid()
    f = wp.vec3(0.0)
    if inv_mass[i] != 0.0:
        f = gather_spring_forces(i, offsets[i], 1, x, v, offsets, other, spring, rest, stiffness, damping, flags)
    integrate(i, f, x, v, inv_mass, gravity, drag, h, semi_implicit, x_out, v_out)


@functools.cache
def euler_step_lanes(lanes: int, block: int) -> wp.Kernel:
    """``euler_step`` with ``lanes`` threads per particle (see lanes.py)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def euler_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                   gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
                   other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                   stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
                   x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
        block_id, lane = wp.tid()
        i, slot, owner = lane_layout(block_id, lane, wp.static(per_block), wp.static(lanes), x.shape[0])
        f = wp.vec3(0.0)
        if i >= 0:
            if inv_mass[i] != 0.0:
                f = gather_spring_forces(i, offsets[i] + slot, wp.static(lanes), x, v, offsets, other, spring, rest,
                                         stiffness, damping, flags)
        total = sum_over_lanes(f, lane)
        if owner:
            integrate(i, total, x, v, inv_mass, gravity, drag, h, semi_implicit, x_out, v_out)

    return euler_step
