"""Face contacts (issue 34; a scene's ``[collision] thickness``): every vertex kept a thickness in metres
from the triangles it is not a vertex of, inside the converged solve beside the edge contacts' pass
(kernels/face_collision.py); the thickness, the scene's ``[collision] thickness``, is the one both kinds hold.

The simulator makes one ``FaceContacts`` where the scene sets a thickness, and hands it to every plan it
builds (warp_cloth/plan.py): the particle lists' remake then remakes its candidate lists too
(``remake_if_asked``), each vertex's triangles and each triangle's vertices, where the substep started and
within the thickness plus both sides' allowances (kernels/surface_reach.py: how far a particle may move
before a pair left out could touch: the displacement bounds' reach; the bounds are then read off the lists),
found through a spatial hash of the particles whose cells are as wide as the largest reach plus the longest
triangle side at the remake; the edge contacts' lists take the same positions and allowances; and its pass
(``separation_pass``) joins the edge contacts' passes of the solve, whose check then reads its pairs; with a
friction coefficient, its ``friction_pass`` takes sliding off both kinds' touching pairs after the solve. The
lists, and where and with what allowances they were made, are the plan's carried arrays (``carried``), so
that a checkpoint or a frame made again keeps them."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_cloth.kernels import edge_collision, face_collision, surface_reach
from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.face_collision import FaceContacts as FaceContactsArgs
from warp_cloth.kernels.face_separation import FaceSeparationPassArgs, face_separation_pass_kernel
from warp_cloth.kernels.neighbour_search import gather_face_vertices, gather_vertex_faces
from warp_cloth.kernels.particle_collision import ListState
from warp_cloth.kernels.surface_friction import SurfaceFrictionArgs, surface_friction_kernel

from .counted_hash import CountedHash
from .device_model import DeviceModel
from .displacement_bounds import DisplacementBounds
from .model import Model
from .passes import CONTACT_SLACK, GatheringPass, edge_contacts_args
from .state import DeviceState, hash_table_size


FACE_NEIGHBORS = 32  # pairs a vertex's or a triangle's list holds (the nearest; more are counted in its overflow)


def incidence(triangles: np.ndarray, n: int, columns: slice = slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """Each particle's triangles (CSR offsets and triangle indices, in index order) among those it is a
    vertex of in ``columns`` (all three, or the first alone)."""
    corners = triangles[:, columns].reshape(len(triangles), -1)
    owner = corners.ravel()
    triangle = np.repeat(np.arange(len(triangles)), corners.shape[1])
    order = np.lexsort((triangle, owner))
    offsets = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(np.bincount(owner, minlength=n), out=offsets[1:])
    return offsets, triangle[order].astype(np.int32)


class FaceContacts:
    """The face contacts' arrays, the remake of their lists and their pass, made once per simulator."""

    def __init__(self, model: Model, device_model: DeviceModel) -> None:
        contacts = device_model.contacts
        device = self.device = device_model.device
        n = self.n = model.particle_count
        triangles = model.triangles
        self.triangle_count = len(triangles)
        self.thickness = contacts.settings.thickness  # the edge contacts' too
        self.inv_mass = device_model.inv_mass
        rest = model.positions[triangles]
        self.longest = float(np.linalg.norm(rest - np.roll(rest, 1, axis=1), axis=2).max(initial=0.0))
        self.rules = contacts.surface_rules
        args = self.args = FaceContactsArgs()
        args.triangles = wp.array(triangles, dtype=wp.vec3i, device=device)
        offsets, incident = incidence(triangles, n)
        args.incident_offsets = wp.array(offsets, dtype=int, device=device)
        args.incident = wp.array(incident, dtype=int, device=device)
        args.vertex_faces = wp.zeros(n * FACE_NEIGHBORS, dtype=int, device=device)
        args.vertex_counts = wp.zeros(n, dtype=int, device=device)
        args.face_vertices = wp.zeros(self.triangle_count * FACE_NEIGHBORS, dtype=int, device=device)
        args.face_counts = wp.zeros(self.triangle_count, dtype=int, device=device)
        args.max_neighbors = FACE_NEIGHBORS
        args.thickness = self.thickness
        owned_offsets, owned = incidence(triangles, n, slice(0, 1))
        self.owned_offsets = wp.array(owned_offsets, dtype=int, device=device)
        self.owned = wp.array(owned, dtype=int, device=device)
        self.hash = CountedHash(n, hash_table_size(n), device)
        self.built = wp.full(n, wp.vec3(1.0e30), dtype=wp.vec3, device=device)  # lists never made: remake at once
        self.allowance = wp.zeros(n, dtype=float, device=device)
        self.widest = wp.zeros(1, dtype=float, device=device)
        # surface pairs within reach left out of full lists (the farthest: the bounds read the nearest, so no
        # crossing follows, but a pair left out is not held a thickness apart), this list's and the edges'
        self.dropped = wp.zeros(1, dtype=int, device=device)
        # the gathers' scratch: the listed pairs' gaps while the lists are made, first the vertices', then the
        # triangles'
        self.gaps = wp.zeros(max(args.vertex_faces.shape[0], args.face_vertices.shape[0]), dtype=float, device=device)

    @classmethod
    def of(cls, model: Model, device_model: DeviceModel) -> FaceContacts | None:
        """The face contacts of a scene with a surface thickness (None: none set)."""
        contacts = device_model.contacts
        return cls(model, device_model) if contacts is not None and contacts.settings.thickness is not None else None

    asking = [surface_reach.ask_if_beyond_allowance]  # as ask_if_moved launches them
    allowing = [surface_reach.start_allowances, surface_reach.allow]  # as allow launches them
    kernels = [edge_collision.start_edge_cells, face_collision.widen_face_cells, *CountedHash.kernels,
               gather_vertex_faces, gather_face_vertices]  # as remake_if_asked launches them

    def ask_if_moved(self, start: wp.array, x: wp.array, bounds: DisplacementBounds, lists: ListState) -> None:
        """Asks for the lists' remake where a particle's move from where they were made, plus its reach this
        substep (the bounds' largest, gamma times their query radius, or a pin's move to ``x``), passes its
        allowance."""
        wp.launch(surface_reach.ask_if_beyond_allowance, dim=self.n,
                  inputs=[start, x, bounds.query, bounds.settings.gamma, self.inv_mass, self.built, self.allowance],
                  outputs=[lists.rebuild], device=self.device)

    def allow(self, start: wp.array, x: wp.array, bounds: DisplacementBounds, lists: ListState) -> None:
        """Where the lists are to be remade: each particle's allowance and where they are made (``start``),
        before the remake of these lists and the edge contacts'."""
        wp.launch(surface_reach.start_allowances, dim=1, inputs=[lists.rebuild], outputs=[self.widest],
                  device=self.device)
        wp.launch(surface_reach.allow, dim=self.n,
                  inputs=[start, x, bounds.query, bounds.settings.gamma, self.inv_mass, lists.rebuild],
                  outputs=[self.built, self.allowance, self.widest], device=self.device)

    def remake_if_asked(self, x: wp.array, lists: ListState) -> None:
        """Both candidate lists from positions ``x`` (where the substep started: no pair has crossed there, so
        each pair takes the side its vertex lies on there; the step's predicted positions may have passed a
        vertex through a triangle, which the solve would then hold on the wrong side), where the particle
        lists' ``rebuild`` is set (after ``allow``, before the end of the remake)."""
        device, args, rules, buckets = self.device, self.args, self.rules, self.hash.buckets
        wp.launch(edge_collision.start_edge_cells, dim=1,
                  inputs=[lists.rebuild, self.longest, self.thickness, self.widest], outputs=[buckets.inv_width],
                  device=device)
        wp.launch(face_collision.widen_face_cells, dim=self.triangle_count,
                  inputs=[x, args.triangles, lists.rebuild, self.longest, self.thickness, self.widest],
                  outputs=[buckets.inv_width], device=device)
        self.hash.fill(x, rules.world, lists.rebuild)
        wp.launch(gather_vertex_faces, dim=self.n,
                  inputs=[x, args, rules, lists, self.allowance, self.widest, self.owned_offsets, self.owned,
                          buckets, self.gaps, self.dropped],
                  device=device)
        wp.launch(gather_face_vertices, dim=self.triangle_count,
                  inputs=[x, args, rules, lists, self.allowance, self.widest, buckets, self.gaps, self.dropped],
                  device=device)

    def separation_pass(self, device_model: DeviceModel, threads: int, bundle: RigidColliders | None) -> GatheringPass:
        """One Jacobi pass moving every listed pair closer than the thickness apart, then the colliders in
        ``bundle`` (None: none)."""
        args = FaceSeparationPassArgs()
        args.faces, args.inv_mass, args.h = self.args, device_model.inv_mass, device_model.h
        args.colliders = bundle if bundle is not None else device_model.no_colliders()
        return GatheringPass("face_separation" + ("+colliders" if bundle is not None else ""),
                             face_separation_pass_kernel(threads), threads, args, device_model.device)

    def friction_pass(self, device_model: DeviceModel, state: DeviceState, threads: int) -> GatheringPass | None:
        """Friction on the face and edge contacts' touching pairs (kernels/surface_friction.py), at the
        collision table's ``friction`` or the cloths' materials' (the larger, as particle contacts take it);
        None where the table's is zero and no material sets one."""
        contacts = device_model.contacts
        if contacts.settings.friction == 0.0 and device_model.cloth_friction.shape[0] == 0:
            return None
        args = SurfaceFrictionArgs()
        args.faces, args.edges = self.args, edge_contacts_args(device_model, state)
        args.v_start, args.inv_mass = state.contacts.v_start, device_model.inv_mass
        args.friction, args.cloth_friction = contacts.settings.friction, device_model.cloth_friction
        args.slack = CONTACT_SLACK
        return GatheringPass("surface_friction", surface_friction_kernel(threads), threads, args, self.device,
                             new_positions=False, new_velocities=True)

    def carried(self) -> dict[str, wp.array]:
        """The lists a substep reads before it remakes them, and where and with what allowances they were made,
        by name (for the plan's carried arrays)."""
        args = self.args
        return {"faces.vertex_faces": args.vertex_faces, "faces.vertex_counts": args.vertex_counts,
                "faces.face_vertices": args.face_vertices, "faces.face_counts": args.face_counts,
                "faces.built": self.built, "faces.allowance": self.allowance, "faces.dropped": self.dropped}
