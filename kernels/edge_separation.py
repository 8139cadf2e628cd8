"""The edge separation pass: contact edges moved a thickness apart (edge_collision.py), ending with the rigid
colliders. See gathering.py for the form of a gathering kernel.
"""

import functools
from typing import Any

import warp as wp

from .colliders import RigidColliders, collide_particle
from .edge_collision import EdgeContacts, edge_pushes
from .gathering import FAST_MATH, gathering_kernel, gathers
from .limits import mean_of

wp.set_module_options(FAST_MATH)


@wp.struct
class EdgeSeparationPassArgs:
    edges: EdgeContacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders


@wp.func
def gather_edge_pushes(args: EdgeSeparationPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                       v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return edge_pushes(args.edges, i, first, stride, x, args.inv_mass)


@wp.func
def finish_contact_move(args: Any, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                        x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its pairs' moves (its velocity by that over h), then out of the
    rigid colliders: the finish of a pass whose ``args`` carry ``inv_mass``, ``h`` and ``colliders`` (the edge
    contacts' and the face contacts')."""
    xi = x[i]
    if args.inv_mass[i] == 0.0 or total[3] == 0.0:
        x_out[i] = xi
        return
    move = mean_of(total)
    p, vel, unused_hit = collide_particle(i, xi + move, v[i] + move / args.h, args.colliders, args.h)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def edge_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("edge_separation_pass", EdgeSeparationPassArgs, gather_edge_pushes,
                            finish_contact_move, threads)
