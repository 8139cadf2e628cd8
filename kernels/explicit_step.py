"""The explicit step as one gathering pass: spring and bending forces, external forces and one explicit or
symplectic Euler step; where the plan asks, ending with the contacts' start (the rigid colliders, the
velocities contacts start from, the lists' remake check), and that start alone where the step before cannot
end with it. See gathering.py for the form of a gathering kernel.
"""

import functools

import warp as wp

from .bending import Bending, bending_forces
from .colliders import RigidColliders, collide_particle
from .forces import ExternalForces, external_acceleration
from .gathering import FAST_MATH, gathering_kernel, gathers
from .integration import compensated_sum, explicit_move
from .particle_collision import Contacts, ListState, begin_contact
from .springs import Springs, spring_forces

wp.set_module_options(FAST_MATH)


@wp.struct
class ExplicitStepArgs:
    springs: Springs
    bending: Bending
    forces: ExternalForces
    inv_mass: wp.array(dtype=float)
    h: float
    semi_implicit: int  # 1: symplectic Euler
    rounded_away: wp.array(dtype=wp.vec3)  # (n,): positions summed with compensation; empty: plainly


@wp.struct
class ContactStartArgs:
    """The contacts' start: rigid colliders first, then what particle_collision.begin_contact records."""
    colliders: RigidColliders
    contacts: Contacts
    lists: ListState
    v_start: wp.array(dtype=wp.vec3)
    rebuild_distance: float
    inv_mass: wp.array(dtype=float)
    h: float


@wp.struct
class ExplicitStepAndContactStartArgs:
    step: ExplicitStepArgs
    start: ContactStartArgs


@wp.func
def gather_spring_forces(step: ExplicitStepArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                         v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    if not gathers(step, i):
        return wp.vec3(0.0)
    return spring_forces(step.springs, i, first, stride, x, v) + bending_forces(step.bending, i, first, stride, x, v)


@wp.func
def stepped(step: ExplicitStepArgs, i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    xi = x[i]
    vi = v[i]
    move, v_new = explicit_move(vi, step.inv_mass[i], f, external_acceleration(step.forces, i, xi, vi), step.h,
                                step.semi_implicit)
    if step.rounded_away.shape[0] == 0:
        return xi + move, v_new
    p, rounded = compensated_sum(xi, move, step.rounded_away[i])
    step.rounded_away[i] = rounded
    return p, v_new


@wp.func
def start_contacts(start: ContactStartArgs, i: int, p: wp.vec3, vel: wp.vec3):
    """Particle i's position and velocity after the rigid colliders, with the contacts' start recorded."""
    hit = int(0)
    v_before = vel
    if start.inv_mass[i] != 0.0:
        p, vel, hit = collide_particle(i, p, vel, start.colliders, start.h)
    begin_contact(i, p, v_before, hit, start.contacts, start.lists, start.v_start, start.rebuild_distance)
    return p, vel


@wp.func
def finish_explicit_step(args: ExplicitStepArgs, i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3),
                         v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    p, vel = stepped(args, i, f, x, v)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_step_of(args: ExplicitStepAndContactStartArgs, i: int, first: int, stride: int,
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    return gather_spring_forces(args.step, i, first, stride, x, v)


@wp.func
def finish_explicit_step_and_contact_start(args: ExplicitStepAndContactStartArgs, i: int, f: wp.vec3,
                                           x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                           x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    p, vel = stepped(args.step, i, f, x, v)
    p, vel = start_contacts(args.start, i, p, vel)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def explicit_step_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("explicit_step", ExplicitStepArgs, gather_spring_forces, finish_explicit_step, threads)


@functools.cache
def explicit_step_and_contact_start_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("explicit_step_and_contact_start", ExplicitStepAndContactStartArgs, gather_step_of,
                            finish_explicit_step_and_contact_start, threads)


@wp.kernel
def contact_start(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), args: ContactStartArgs):
    """The contacts' start alone, in place, where the step before cannot end with it."""
    i = wp.tid()
    p, vel = start_contacts(args, i, x[i], v[i])
    x[i] = p
    v[i] = vel
