"""The contact velocities pass: inelastic contacts with friction (particle_collision.velocity_changes), and
the end of the substep's list remake. See gathering.py for the form of a gathering kernel.
"""

import functools

import warp as wp

from .gathering import FAST_MATH, gathering_kernel, gathers
from .limits import mean_of
from .particle_collision import Contacts, ListState, end_remake, velocity_changes

wp.set_module_options(FAST_MATH)


@wp.struct
class ContactVelocitiesArgs:
    contacts: Contacts
    lists: ListState
    v_start: wp.array(dtype=wp.vec3)
    inv_mass: wp.array(dtype=float)
    contact_slack: float
    friction: float
    h: float


@wp.func
def gather_velocity_changes(args: ContactVelocitiesArgs, i: int, first: int, stride: int,
                            x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return velocity_changes(args.contacts, i, first, stride, x, v, args.v_start, args.inv_mass,
                            args.contact_slack, args.friction, args.h)


@wp.func
def finish_contact_velocities(args: ContactVelocitiesArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                              v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                              v_out: wp.array(dtype=wp.vec3)):
    """Particle i's velocity changes by the mean of its contacts' changes; its pushes of this substep are
    forgotten; and (by one thread) the lists' remake ends."""
    v_out[i] = v[i] + mean_of(total)
    args.contacts.pushed[i] = 0.0
    if i == 0:
        end_remake(args.lists)


@functools.cache
def contact_velocities_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("contact_velocities_and_end_remake", ContactVelocitiesArgs, gather_velocity_changes,
                            finish_contact_velocities, threads)
