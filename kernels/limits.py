"""Provot-style strain limits, projected in parallel as Jacobi iterations with averaging.

Each particle gathers the corrections of its limited springs that are out of range, weighted by inverse
mass (a pinned end does not move), and moves by their average. Reading one buffer and writing another
keeps the pass free of races and deterministic. The velocity gets the same correction divided by h, so
that it stays consistent with the positions (as the seed's velocity fix does). A pass ends with the
rigid colliders (an empty ``RigidColliders`` for none), which act on each particle alone, and mark the
particles they hold up in ``resting`` (see colliders.py; empty where no collision stage reads it).
Long-range attachments (``attachment_pin``, empty for none) then pull each particle back within reach of
its pin; a pin does not move in the pass, so this needs no averaging.
"""

import functools

import warp as wp

from .colliders import RigidColliders, collide_and_mark
from .lanes import FAST_MATH, lane_particle, lane_sum

wp.set_module_options(FAST_MATH)


@wp.func
def limit_correction(xi: wp.vec3, wi: float, xj: wp.vec3, wj: float, min_length: float, max_length: float):
    """Particle i's share of the correction that brings the pair i-j within its limits, and 1 if the pair
    is out of them (else zero and 0)."""
    d = xi - xj
    length = wp.length(d)
    target = wp.clamp(length, min_length, max_length)
    if target != length and length > 1.0e-12:
        return (wi / (wi + wj)) * (target - length) * (d / length), 1
    return wp.vec3(0.0), 0


@wp.func
def hold_to_pin(p: wp.vec3, vel: wp.vec3, pin: int, max_length: float, h: float, x: wp.array(dtype=wp.vec3)):
    """A particle farther than ``max_length`` from its pin (-1: none) is put back at that distance, its
    velocity changed by that correction over h, as for every projection here. (Only removing its speed
    away from the pin instead left the fast_sphere hard case at 50 % strain with 24 crossing pairs.)"""
    if pin < 0:
        return p, vel
    d = p - x[pin]
    length = wp.length(d)
    if length <= max_length:
        return p, vel
    correction = d * (max_length / length - 1.0)
    return p + correction, vel + correction / h


@wp.func
def gather_limit_corrections(i: int, first: int, stride: int, xi: wp.vec3, wi: float, x: wp.array(dtype=wp.vec3),
                             inv_mass: wp.array(dtype=float), offsets: wp.array(dtype=int),
                             other: wp.array(dtype=int), min_length: wp.array(dtype=float),
                             max_length: wp.array(dtype=float)):
    """Sum of particle i's shares of the corrections of its limited springs first, first + stride, ...,
    and how many of them are out of their limits."""
    correction = wp.vec3(0.0)
    violated = int(0)
    for e in range(first, offsets[i + 1], stride):
        j = other[e]
        c, out = limit_correction(xi, wi, x[j], inv_mass[j], min_length[e], max_length[e])
        correction = correction + c
        violated += out
    return correction, violated


@wp.func
def move_and_hold(i: int, xi: wp.vec3, correction: wp.vec3, x: wp.array(dtype=wp.vec3),
                  attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float), h: float,
                  colliders: RigidColliders, resting: wp.array(dtype=int), read_bit: int,
                  x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Moves free particle i by ``correction`` (its velocity by correction / h), then holds it to its pin
    and puts it out of the colliders."""
    p = xi + correction
    vel = v[i] + correction / h
    if attachment_pin.shape[0] > 0:
        p, vel = hold_to_pin(p, vel, attachment_pin[i], attachment_length[i], h, x)
    p, vel = collide_and_mark(i, p, vel, colliders, h, resting, read_bit)
    x_out[i] = p
    v[i] = vel


@wp.func
def finish_limit_pass(i: int, xi: wp.vec3, correction: wp.vec3, violated: int, x: wp.array(dtype=wp.vec3),
                      attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float), h: float,
                      colliders: RigidColliders, resting: wp.array(dtype=int), read_bit: int,
                      x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its corrections (``move_and_hold``)."""
    if violated > 0:
        correction = correction / float(violated)
    move_and_hold(i, xi, correction, x, attachment_pin, attachment_length, h, colliders, resting, read_bit, x_out, v)


@wp.kernel
def project_strain_limits(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                          offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                          min_length: wp.array(dtype=float), max_length: wp.array(dtype=float),
                          attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float), h: float,
                          colliders: RigidColliders, resting: wp.array(dtype=int), read_bit: int,
                          x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    xi = x[i]
    wi = inv_mass[i]
    if wi == 0.0:
        x_out[i] = xi
        return
    correction, violated = gather_limit_corrections(i, offsets[i], 1, xi, wi, x, inv_mass, offsets, other,
                                                    min_length, max_length)
    finish_limit_pass(i, xi, correction, violated, x, attachment_pin, attachment_length, h, colliders, resting,
                      read_bit, x_out, v)


@functools.cache
def project_strain_limits_lanes(lanes: int, block: int) -> wp.Kernel:
    """``project_strain_limits`` with ``lanes`` threads per particle (see lanes.py)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def project_strain_limits(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                              offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                              min_length: wp.array(dtype=float), max_length: wp.array(dtype=float),
                              attachment_pin: wp.array(dtype=int), attachment_length: wp.array(dtype=float),
                              h: float, colliders: RigidColliders, resting: wp.array(dtype=int), read_bit: int,
                              x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
        block_id, lane = wp.tid()
        i, slot, owner, xi, wi = lane_particle(block_id, lane, wp.static(per_block), wp.static(lanes), x, inv_mass)
        correction = wp.vec3(0.0)
        violated = int(0)
        if wi != 0.0:
            correction, violated = gather_limit_corrections(i, offsets[i] + slot, wp.static(lanes), xi, wi, x,
                                                            inv_mass, offsets, other, min_length, max_length)
        correction = sum_over_lanes(correction, lane)
        violated = sum_over_lanes(violated, lane)
        if owner:
            if wi == 0.0:
                x_out[i] = xi
            else:
                finish_limit_pass(i, xi, correction, violated, x, attachment_pin, attachment_length, h, colliders,
                                  resting, read_bit, x_out, v)

    return project_strain_limits
