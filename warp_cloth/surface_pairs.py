"""Which vertex-triangle and edge-edge pairs are contacts (issue 34): one rule, ``kernels/edge_collision.py``'s
``EdgeRules`` (``may_touch`` there for two edges, ``face_collision.may_touch`` for a vertex and a triangle),
made here and taken by every place that forms such pairs: the edge contacts' and the face contacts' candidate
lists, the displacement bounds' distances and, through them, the surfaces' start check and the tools' closest
surfaces.

As particle contacts: pairs of one world, of two cloths where ``between_cloths``, of one where ``self``; none
that shares a particle, none that a seam keeps from colliding. With a surface thickness T, a pair of one cloth
that lies nearer than T / (1 - c) in the rest state (c the cloth's compression limit, its largest direction's)
is none: compression within the limit alone, with no fold, could bring it within the thickness, so it would
be held apart against the cloth itself (a vertex lies 0.71 of a cell from the triangles across its diagonal:
cells under 1.4 thicknesses could not start). A pair farther apart at rest comes within T only where the cloth
bends onto itself, and is a contact. The rest state is where the scene puts the cloth, whose distances the
springs' rest lengths are.

A distance, not a ring of the mesh, because the thickness is in metres: a fixed ring leaves out too little on
a fine mesh (2 mm cells at 4 mm need pairs three rings away left out) and too much on a coarse one (a ring of
25 cm cells leaves out pairs a fold brings together). It costs the rest positions (n vectors) and one distance
on them for a candidate of one cloth already found near; a ring table would hold each vertex's list of
triangles. Newton's VBD solver, by OGC's authors, has both: a ring count and a rest-shape distance
(``particle_topological_contact_filter_threshold``, ``particle_rest_shape_contact_exclusion_radius``).

The pairs left out are not guarded: two of them could cross in a fold sharper than the distance, which the
crossing count (diagnostics.TriangleIntersections) still counts."""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np
import warp as wp

from warp_cloth.kernels.edge_collision import EdgeRules
from warp_cloth.kernels.particle_collision import PairRules

from .scene import Cloth

if TYPE_CHECKING:
    from .model import Model  # the model asks rest_apart of this module


def rest_apart(cloths: Sequence[Cloth], thickness: float) -> np.ndarray:
    """(cloths,) float32: how far apart at rest a pair of each cloth must lie to be a contact, thickness /
    (1 - its compression limit)."""
    return np.array([thickness / (1.0 - c.strain_limit.compression) if c.strain_limit is not None else thickness
                     for c in cloths], dtype=np.float32)


def surface_rules(model: Model, particles: PairRules | None, device) -> EdgeRules:
    """The rule as the kernels take it: particle collision's ``particles`` rules (None: a scene without
    collision, every pair of a world, for the lab's bounds), and the rest state's where the scene sets a
    thickness."""
    rules, empty_int = EdgeRules(), wp.zeros(0, dtype=int, device=device)
    if particles is None:
        rules.world = wp.array(model.particle_world, dtype=int, device=device)
        rules.cloth_id = wp.array(model.cloth_id, dtype=int, device=device)
        rules.self_collision = rules.between_cloths = 1
        rules.sewn_offsets = rules.sewn_other = empty_int
    else:
        rules.world, rules.cloth_id = particles.world, particles.cloth_id
        rules.self_collision, rules.between_cloths = particles.self_collision, particles.between_cloths
        rules.sewn_offsets, rules.sewn_other = particles.sewn_offsets, particles.sewn_other
    apart = model.contacts.rest_apart if model.contacts is not None else None
    if apart is None:
        rules.rest = wp.zeros(0, dtype=wp.vec3, device=device)
        rules.rest_apart = wp.zeros(0, dtype=float, device=device)
    else:
        rules.rest = wp.array(model.positions, dtype=wp.vec3, device=device)
        rules.rest_apart = wp.array(apart, dtype=float, device=device)
    return rules
