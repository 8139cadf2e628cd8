"""The face separation pass: vertices moved a thickness off triangles (face_collision.py), ending with the rigid
colliders. See gathering.py for the form of a gathering kernel.
"""

import functools

import warp as wp

from .colliders import RigidColliders
from .edge_separation import finish_contact_move
from .face_collision import FaceContacts, face_pushes
from .gathering import FAST_MATH, gathering_kernel, gathers

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


@functools.cache
def face_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("face_separation_pass", FaceSeparationPassArgs, gather_face_pushes,
                            finish_contact_move, threads)
