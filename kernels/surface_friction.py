"""The surface friction pass: friction on the face contacts' vertex-triangle pairs and the edge contacts' pairs
(face_collision.face_friction, edge_collision.edge_friction), after the solves and the displacement bounds'
clamp, before the particle contacts' velocities. See gathering.py for the form of a gathering kernel.
"""

import functools

import warp as wp

from .edge_collision import EdgeContacts, edge_friction
from .face_collision import FaceContacts, face_friction
from .gathering import FAST_MATH, gathering_kernel, gathers
from .limits import mean_of

wp.set_module_options(FAST_MATH)


@wp.struct
class SurfaceFrictionArgs:
    faces: FaceContacts
    edges: EdgeContacts
    v_start: wp.array(dtype=wp.vec3)  # each particle's velocity at the contacts' start this substep
    inv_mass: wp.array(dtype=float)
    friction: float  # the collision table's coefficient
    cloth_friction: wp.array(dtype=float)  # (n,) each particle's cloth's coefficient, or empty: none
    slack: float  # pairs within this many thicknesses touch


@wp.func
def coefficient(args: SurfaceFrictionArgs, i: int, j: int) -> float:
    """A pair's coefficient: the larger of the collision table's and its two cloths' mean (particles i and
    j, one of each side), as the particle contacts take it."""
    if args.cloth_friction.shape[0] > 0:
        return wp.max(args.friction, 0.5 * (args.cloth_friction[i] + args.cloth_friction[j]))
    return args.friction


@wp.func
def gather_surface_friction(args: SurfaceFrictionArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                            v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    """Sum of particle i's velocity changes from its touching pairs (as a vertex, a triangle's vertex, an
    edge's end; candidates first, first + stride, ... of each list), each times its weight in the pair, and
    the sum of those weights (w)."""
    if not gathers(args, i):
        return wp.vec4(0.0)
    faces, edges = args.faces, args.edges
    total = wp.vec4(0.0)
    start = i * faces.max_neighbors
    for c in range(first, faces.vertex_counts[i], stride):
        code = faces.vertex_faces[start + c]
        change, touch = face_friction(faces, i, i, code, x, v, args.v_start, args.inv_mass,
                                      coefficient(args, i, faces.triangles[code >> 1][0]), args.slack)
        total = total + wp.vec4(change[0], change[1], change[2], touch)
    for k in range(faces.incident_offsets[i], faces.incident_offsets[i + 1]):
        t = faces.incident[k]
        for c in range(first, faces.face_counts[t], stride):
            code = faces.face_vertices[t * faces.max_neighbors + c]
            change, touch = face_friction(faces, i, code >> 1, 2 * t + (code & 1), x, v, args.v_start,
                                          args.inv_mass, coefficient(args, code >> 1, i), args.slack)
            total = total + wp.vec4(change[0], change[1], change[2], touch)
    for k in range(edges.incident_offsets[i], edges.incident_offsets[i + 1]):
        e = edges.incident[k]
        for c in range(first, edges.counts[e], stride):
            f = edges.neighbors[e * edges.max_neighbors + c]
            change, touch = edge_friction(edges, i, e, f, x, v, args.v_start, args.inv_mass,
                                          coefficient(args, edges.ends[wp.min(e, f)][0], edges.ends[wp.max(e, f)][0]),
                                          args.slack)
            total = total + wp.vec4(change[0], change[1], change[2], touch)
    return total


@wp.func
def finish_surface_friction(args: SurfaceFrictionArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                            v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                            v_out: wp.array(dtype=wp.vec3)):
    """Particle i's velocity changes by its touching pairs' changes, their mean weighted by its weight in each."""
    v_out[i] = v[i] + mean_of(total)


@functools.cache
def surface_friction_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("surface_friction", SurfaceFrictionArgs, gather_surface_friction,
                            finish_surface_friction, threads)
