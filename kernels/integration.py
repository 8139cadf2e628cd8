"""Explicit time integrators. A step reads the state at t and writes the state at t + h into other
buffers, because a particle's spring forces read its neighbours' old positions. Particles with inverse
mass 0 (pinned) are copied unchanged: the pin stage drives them.

Where particle collision follows the step directly, the step also begins its contacts
(``particle_collision.begin_contact``) on the state it writes, which saves the collision stage a pass over
the particles; ``v_start`` is then the contacts' array, empty otherwise."""

import functools

import warp as wp

from .colliders import RigidColliders
from .lanes import FAST_MATH, lane_layout, lane_sum
from .particle_collision import begin_contact
from .springs import gather_spring_forces

wp.set_module_options(FAST_MATH)


@wp.func
def integrate(i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
              inv_mass: wp.array(dtype=float), gravity: wp.vec3, drag: float, h: float, semi_implicit: int,
              colliders: RigidColliders, x_built: wp.array(dtype=wp.vec3), rebuild_distance: float,
              x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
              resting: wp.array(dtype=int), rebuild: wp.array(dtype=int)):
    """v' = v + h a(x, v); x' = x + h v (forward Euler, the seed's) or x' = x + h v' (semi_implicit = 1,
    symplectic Euler). a = gravity - drag v + f / m. Then the contacts' start, if asked."""
    w = inv_mass[i]
    x_new = x[i]
    v_new = v[i]
    if w != 0.0:
        v_old = v_new
        v_new = v_old + h * (gravity - drag * v_old + w * f)
        if semi_implicit != 0:
            x_new = x_new + h * v_new
        else:
            x_new = x_new + h * v_old
    if v_start.shape[0] > 0:
        x_new, v_new = begin_contact(i, x_new, v_new, w, colliders, h, x_built, rebuild_distance, v_start, resting,
                                     rebuild)
    x_out[i] = x_new
    v_out[i] = v_new


@wp.kernel
def euler_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
               gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
               other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
               stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
               colliders: RigidColliders, x_built: wp.array(dtype=wp.vec3), rebuild_distance: float,
               x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
               resting: wp.array(dtype=int), rebuild: wp.array(dtype=int)):
    """Spring forces and one explicit or symplectic Euler step, a thread per particle."""
    i = wp.tid()
    f = wp.vec3(0.0)
    if inv_mass[i] != 0.0:
        f = gather_spring_forces(i, offsets[i], 1, x, v, offsets, other, spring, rest, stiffness, damping, flags)
    integrate(i, f, x, v, inv_mass, gravity, drag, h, semi_implicit, colliders, x_built, rebuild_distance, x_out,
              v_out, v_start, resting, rebuild)


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
                   colliders: RigidColliders, x_built: wp.array(dtype=wp.vec3), rebuild_distance: float,
                   x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3),
                   v_start: wp.array(dtype=wp.vec3), resting: wp.array(dtype=int), rebuild: wp.array(dtype=int)):
        block_id, lane = wp.tid()
        i, slot, owner = lane_layout(block_id, lane, wp.static(per_block), wp.static(lanes), x.shape[0])
        f = wp.vec3(0.0)
        if i >= 0:
            if inv_mass[i] != 0.0:
                f = gather_spring_forces(i, offsets[i] + slot, wp.static(lanes), x, v, offsets, other, spring, rest,
                                         stiffness, damping, flags)
        total = sum_over_lanes(f, lane)
        if owner:
            integrate(i, total, x, v, inv_mass, gravity, drag, h, semi_implicit, colliders, x_built,
                      rebuild_distance, x_out, v_out, v_start, resting, rebuild)

    return euler_step
