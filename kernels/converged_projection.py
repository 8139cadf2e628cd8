"""A converged projection's kernels besides its passes: Chebyshev's acceleration of an iteration, ending with
the rigid colliders, the check of how far limits and contacts are from holding, and each particle's
violation of its limits (a run's start is measured by it: warp_cloth/start_projection.py). solve_loop.py
keeps the loop's bookkeeping; warp_cloth/limit_solve.py runs them.
"""

import warp as wp

from .attachments import Attachments, attachment_violation
from .colliders import RigidColliders, collide_particle
from .edge_collision import EdgeContacts, deepest_edge_overlap
from .face_collision import FaceContacts, deepest_face_overlap
from .gathering import FAST_MATH
from .limits import StrainLimits, limit_violation
from .particle_collision import Contacts, deepest_overlap
from .solve_loop import chebyshev_extrapolation

wp.set_module_options(FAST_MATH)


@wp.kernel
def chebyshev_step_and_colliders(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                 inv_mass: wp.array(dtype=float), omega: wp.array(dtype=float), h: float,
                                 colliders: RigidColliders, x_start: wp.array(dtype=wp.vec3),
                                 x_before: wp.array(dtype=wp.vec3)):
    """The extrapolated position (solve_loop.chebyshev_extrapolation), put out of the rigid colliders as
    every pass's move is; the velocity changed by both moves over h (extrapolating the velocities
    themselves blew the matrix's sphere cloth up). A solve's first iteration (and its second where it began
    close; see solve_loop.start_chebyshev), and the first after a restart, are plain ones: the iterates
    only shift, and the positions stay as the pass left them."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    xi = x[i]
    if omega[2] < 1.5:
        x_before[i] = x_start[i]
        x_start[i] = xi
        return
    xn = chebyshev_extrapolation(i, x, omega, x_start, x_before)
    p, vel, hit = collide_particle(i, xn, v[i] + (xn - xi) / h, colliders, h)
    x[i] = p
    v[i] = vel


@wp.struct
class ResidualArgs:
    limits: StrainLimits
    attachments: Attachments
    check_limits: int  # 0: the scene limits no strain (the limits' arrays are empty)
    limit_tolerance: float  # of an allowed length
    contacts: Contacts
    check_contacts: int  # 0: no particle collision
    contact_tolerance: float  # of a contact distance; of the thickness for the edge and face pairs
    edges: EdgeContacts  # the edge contacts' pairs (edge_collision.py), read where check_edges
    check_edges: int  # 0: not checked (the edges' arrays may be empty)
    faces: FaceContacts  # the face contacts' pairs (face_collision.py), read where check_faces
    check_faces: int
    inv_mass: wp.array(dtype=float)
    colliders: RigidColliders  # the spheres that attachments run around


@wp.func
def limits_and_attachments_violation(args: ResidualArgs, i: int, x: wp.array(dtype=wp.vec3)) -> float:
    """The worst of particle i's limit and attachment violations, as a fraction of the allowed length."""
    worst = limit_violation(args.limits, i, x)
    if args.attachments.pin.shape[0] > 0:
        worst = wp.max(worst, attachment_violation(args.attachments, args.colliders, i, x))
    return worst


@wp.kernel
def limit_violations(x: wp.array(dtype=wp.vec3), args: ResidualArgs, violation: wp.array(dtype=float)):
    """violation[i]: free particle i's worst limit or attachment violation, as a fraction of the allowed
    length (0 or less where all hold, and for a pinned particle)."""
    i = wp.tid()
    violation[i] = 0.0
    if args.inv_mass[i] != 0.0:
        violation[i] = limits_and_attachments_violation(args, i, x)


@wp.kernel
def projection_residual(x: wp.array(dtype=wp.vec3), args: ResidualArgs, residual: wp.array(dtype=float)):
    """residual[0] becomes the worst of each free particle's limit violation and contact overlap (particle
    contacts', and the edge and face pairs' where checked), each in its own tolerances (1: at the
    tolerance), where some exceed theirs (where none does it is left as is)."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        return
    worst = float(0.0)
    if args.check_limits != 0:
        worst = limits_and_attachments_violation(args, i, x) / args.limit_tolerance
    if args.check_contacts != 0:
        worst = wp.max(worst, deepest_overlap(args.contacts, i, x) / args.contact_tolerance)
    if args.check_edges != 0:
        worst = wp.max(worst, deepest_edge_overlap(args.edges, i, x) / args.contact_tolerance)
    if args.check_faces != 0:
        worst = wp.max(worst, deepest_face_overlap(args.faces, i, x) / args.contact_tolerance)
    if worst > 1.0:
        wp.atomic_max(residual, 0, worst)
