"""The Jacobi passes that project: the strain limits (with the attachments to pins), particle separation,
and both in one kernel, each ending with the rigid colliders. See gathering.py for the form of a gathering
kernel; warp_cloth/plan.py says which of them a substep runs, in which order.
"""

import functools
from typing import Any

import warp as wp

from .attachments import Attachments, hold_to_pin
from .colliders import RigidColliders, collide_and_mark
from .gathering import FAST_MATH, gathering_kernel, gathers
from .limits import StrainLimits, limit_corrections, mean_of
from .particle_collision import Contacts, mean_push, pushes

wp.set_module_options(FAST_MATH)

vec8 = wp.types.vector(length=8, dtype=float)


@wp.struct
class LimitPassArgs:
    limits: StrainLimits
    attachments: Attachments  # empty arrays: none
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders  # empty arrays and no ground: none
    resting: wp.array(dtype=int)  # empty: no marks
    read_bit: int


@wp.struct
class SeparationPassArgs:
    contacts: Contacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders
    read_bit: int


@wp.struct
class LimitAndSeparationPassArgs:
    limits: StrainLimits
    attachments: Attachments
    contacts: Contacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders
    read_bit: int


@wp.func
def held_and_collided(args: Any, i: int, p: wp.vec3, vel: wp.vec3, x: wp.array(dtype=wp.vec3),
                      resting: wp.array(dtype=int)):
    """The end of a pass that limits: the particle held to its pin, then put out of the colliders."""
    p, vel = hold_to_pin(args.attachments, args.colliders, i, p, vel, args.h, x)
    return collide_and_mark(i, p, vel, args.colliders, args.h, resting, args.read_bit)


@wp.func
def gather_limits(args: LimitPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return limit_corrections(args.limits, i, first, stride, x[i], args.inv_mass[i], x, args.inv_mass)


@wp.func
def finish_limit_pass(args: LimitPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                      v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its limit corrections (its velocity by that over h)."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    correction = mean_of(total)
    p, vel = held_and_collided(args, i, xi + correction, v[i] + correction / args.h, x, args.resting)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_pushes(args: SeparationPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return pushes(args.contacts, i, first, stride, x[i], args.inv_mass[i], x, args.inv_mass, args.read_bit)


@wp.func
def finish_separation_pass(args: SeparationPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                           v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                           v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its pushes out of overlapping pairs (its velocity by that over
    h), then out of the rigid colliders, which mark whom they hold up."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    push = mean_push(args.contacts, i, total)
    vel = v[i]
    if total[3] > 0.0:
        vel = vel + push / args.h
    p, vel = collide_and_mark(i, xi + push, vel, args.colliders, args.h, args.contacts.resting, args.read_bit)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_limits_and_pushes(args: LimitAndSeparationPassArgs, i: int, first: int, stride: int,
                             x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> vec8:
    if not gathers(args, i):
        return vec8(0.0)
    xi = x[i]
    wi = args.inv_mass[i]
    a = limit_corrections(args.limits, i, first, stride, xi, wi, x, args.inv_mass)
    b = pushes(args.contacts, i, first, stride, xi, wi, x, args.inv_mass, args.read_bit)
    return vec8(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])


@wp.func
def finish_limit_and_separation_pass(args: LimitAndSeparationPassArgs, i: int, total: vec8,
                                     x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                     x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its limits' corrections plus the mean of its pushes, both from
    the same positions, less the part of the limit's correction that would pull it into a contact; then
    holds it to its pin and puts it out of the colliders. Limit corrections lie mostly along the cloth and
    pushes across it, so this moves a particle about as far as the two passes one after the other did,
    in one launch instead of two."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    correction = mean_of(wp.vec4(total[0], total[1], total[2], total[3]))
    pushed = wp.vec4(total[4], total[5], total[6], total[7])
    if pushed[3] > 0.0:
        push = mean_push(args.contacts, i, pushed)
        against = wp.dot(correction, push)
        if against < 0.0:
            correction = correction - (against / wp.length_sq(push)) * push
        correction = correction + push
    p, vel = held_and_collided(args, i, xi + correction, v[i] + correction / args.h, x, args.contacts.resting)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def limit_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("limit_pass", LimitPassArgs, gather_limits, finish_limit_pass, threads)


@functools.cache
def separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("separation_pass", SeparationPassArgs, gather_pushes, finish_separation_pass,
                            threads)


@functools.cache
def limit_and_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("limit_and_separation_pass", LimitAndSeparationPassArgs, gather_limits_and_pushes,
                            finish_limit_and_separation_pass, threads)
