"""The face separation pass: vertices moved a thickness off triangles (face_collision.py), ending with the rigid
colliders. See gathering.py for the form of a gathering kernel.
"""

import functools

import warp as wp

from .colliders import RigidColliders, collide_particle
from .face_collision import FaceContacts, face_pushes
from .gathering import FAST_MATH, gathering_kernel, gathers
from .limits import mean_of

wp.set_module_options(FAST_MATH)


@wp.struct
class FaceSeparationPassArgs:
    faces: FaceContacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders


@wp.func
def gather_face_pushes(args: FaceSeparationPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                       v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return face_pushes(args.faces, i, first, stride, x, args.inv_mass)


@wp.func
def finish_face_separation_pass(args: FaceSeparationPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                                v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                                v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its pairs' moves (its velocity by that over h), then out of the
    rigid colliders."""
    xi = x[i]
    if args.inv_mass[i] == 0.0 or total[3] == 0.0:
        x_out[i] = xi
        return
    move = mean_of(total)
    p, vel, unused_hit = collide_particle(i, xi + move, v[i] + move / args.h, args.colliders, args.h)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def face_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("face_separation_pass", FaceSeparationPassArgs, gather_face_pushes,
                            finish_face_separation_pass, threads)
