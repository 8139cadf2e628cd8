"""Strain limits and particle separation projected together, in one Jacobi pass.

A pass of the collision stage that both limits and separates reads one buffer of positions for both:
each free particle moves by the mean of its out-of-range limits' corrections (as limits.py) plus the mean
of its pushes out of overlapping pairs (as particle_collision.py), then is held to its pin and put out of
the rigid colliders, which mark whom they hold up. Limit corrections lie mostly along the cloth and
pushes across it, so adding the two means moves a particle about as far as the two passes one after
the other did, in one launch instead of two (at 64^2 on a GPU a launch, not the arithmetic, is what a
pass costs).
"""

import functools

import warp as wp

from .colliders import RigidColliders
from .lanes import FAST_MATH, lane_particle, lane_sum
from .limits import gather_limit_corrections, move_and_hold
from .particle_collision import gather_pushes

wp.set_module_options(FAST_MATH)


@wp.func
def finish_joint_pass(i: int, xi: wp.vec3, limit_sum: wp.vec3, violated: int, push_sum: wp.vec3, touching: int,
                      x: wp.array(dtype=wp.vec3), attachment_pin: wp.array(dtype=int),
                      attachment_length: wp.array(dtype=float), h: float, colliders: RigidColliders,
                      resting: wp.array(dtype=int), read_bit: int, x_out: wp.array(dtype=wp.vec3),
                      v: wp.array(dtype=wp.vec3), pushed: wp.array(dtype=float)):
    correction = wp.vec3(0.0)
    if violated > 0:
        correction = limit_sum / float(violated)
    if touching > 0:
        push = push_sum / float(touching)
        pushed[i] = pushed[i] + wp.length(push)
        against = wp.dot(correction, push)
        if against < 0.0:
            correction = correction - (against / wp.length_sq(push)) * push
        correction = correction + push
    move_and_hold(i, xi, correction, x, attachment_pin, attachment_length, h, colliders, resting, read_bit, x_out, v)


@wp.kernel
def project_limits_and_separation(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                                  offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                                  min_length: wp.array(dtype=float), max_length: wp.array(dtype=float),
                                  attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float),
                                  radius: wp.array(dtype=float), separation: float, h: float,
                                  neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                                  resting: wp.array(dtype=int), read_bit: int, colliders: RigidColliders,
                                  x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                  pushed: wp.array(dtype=float)):
    i = wp.tid()
    xi = x[i]
    wi = inv_mass[i]
    if wi == 0.0:
        x_out[i] = xi
        return
    limit_sum, violated = gather_limit_corrections(i, offsets[i], 1, xi, wi, x, inv_mass, offsets, other,
                                                   min_length, max_length)
    push_sum, touching = gather_pushes(i, 0, 1, xi, wi, x, inv_mass, radius, separation, neighbors, counts,
                                       max_neighbors, resting, read_bit)
    finish_joint_pass(i, xi, limit_sum, violated, push_sum, touching, x, attachment_pin, attachment_length, h,
                      colliders, resting, read_bit, x_out, v, pushed)


@functools.cache
def project_limits_and_separation_lanes(lanes: int, block: int) -> wp.Kernel:
    """``project_limits_and_separation`` with ``lanes`` threads per particle (see lanes.py)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def project_limits_and_separation(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                                      offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                                      min_length: wp.array(dtype=float), max_length: wp.array(dtype=float),
                                      attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float),
                                      radius: wp.array(dtype=float), separation: float, h: float,
                                      neighbors: wp.array(dtype=int), counts: wp.array(dtype=int),
                                      max_neighbors: int, resting: wp.array(dtype=int), read_bit: int,
                                      colliders: RigidColliders, x_out: wp.array(dtype=wp.vec3),
                                      v: wp.array(dtype=wp.vec3), pushed: wp.array(dtype=float)):
        block_id, lane = wp.tid()
        i, slot, owner, xi, wi = lane_particle(block_id, lane, wp.static(per_block), wp.static(lanes), x, inv_mass)
        limit_sum = wp.vec3(0.0)
        violated = int(0)
        push_sum = wp.vec3(0.0)
        touching = int(0)
        if wi != 0.0:
            limit_sum, violated = gather_limit_corrections(i, offsets[i] + slot, wp.static(lanes), xi, wi, x,
                                                           inv_mass, offsets, other, min_length, max_length)
            push_sum, touching = gather_pushes(i, slot, wp.static(lanes), xi, wi, x, inv_mass, radius,
                                               separation, neighbors, counts, max_neighbors, resting, read_bit)
        limit_sum = sum_over_lanes(limit_sum, lane)
        violated = sum_over_lanes(violated, lane)
        push_sum = sum_over_lanes(push_sum, lane)
        touching = sum_over_lanes(touching, lane)
        if owner:
            if wi == 0.0:
                x_out[i] = xi
            else:
                finish_joint_pass(i, xi, limit_sum, violated, push_sum, touching, x, attachment_pin,
                                  attachment_length, h, colliders, resting, read_bit, x_out, v, pushed)

    return project_limits_and_separation
