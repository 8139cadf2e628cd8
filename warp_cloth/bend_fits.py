"""Bending at the particles of a mesh's triangles: each particle's curvature along the warp and the weft from
the quadratic that fits it and its neighbours at rest (materials.py's docstring says why not hinges).

Around particle i, flat at rest, take its tangent plane's axes u (the warp) and v, and the coordinates
(s, t) of i and of its neighbours by sides. The least-squares fit of z = c0 + c1 s + c2 t + 1/2 (a s^2 +
2 b s t + c t^2) to heights z_r at those points reads a = sum_r w_r z_r, with weights w that sum to zero,
vanish on every linear function and make the sum exact for every quadratic, however the points lie. Applied
to the positions, d = sum_r w_r x_r is the curvature along u times the normal, as a row's stencil's is
(kernels/bending.py), and zero on any flat placement of the rest state; c likewise along v. The twist b is
read apart from both, so it neither adds to a bend nor lets one off, and costs nothing, as on the rows.

On a border the neighbours lie on one side, in one row but for the border's own: the fit cannot tell the
curvature across the border from the position of the row beside it. A free border carries no moment
across itself, so the fit takes that curvature as zero (the plate's free edge: M_n = 0, which is
kappa_nn = 0 where, as here, a bend along one direction does not bend the other), and reads the bend along
the border, as a hem bends in a drape's folds. Where the border turns by more than ``_STRAIGHT`` at a
particle (a corner), it has no such direction and the fit none but what its points tell.

A quadratic has six coefficients: a particle with fewer points than that to fit (one of four neighbours
inside the mesh; a hem's with one neighbour inside, whose free edge gives one equation more) cannot tell
a bend from a twist, and was left unbent (of the drape specimen's 207 rim particles at 30 cells 38 both
ways and 2 one way; 76 and 5 of 421 at 60). Such a particle is fitted to the nearest of its neighbours
and their neighbours instead (up to seven), which tell every quadratic; a corner's stays as its own points
tell (a free corner carries no moment either way).
"""

from __future__ import annotations

import numpy as np

from .adjacency import Adjacency
from .cloth_mesh import BendStencils, lumped_masses, shared_edges
from .mesh_io import face_edges, face_starts, pair_keys, unique_pairs

# The most a fit may read at rest, as a dihedral angle per side's length, for the particle to count as flat
# (the model takes the rest state flat; a particle curved as modelled has no fit).
_FLAT = 1e-4
# A fit whose weights sum (in absolute value) to more than this over its mean side squared leans on points
# too nearly on one conic to tell a bend apart: that direction is left to the rows or unbent.
_MOST_WEIGHT = 64.0
# The most points a fit reads: its particle and its nearest seven neighbours by sides.
_WIDTH = 8
# The most a border may turn at a particle, as sin^2 of the angle between its two sides, for the fit there
# to take the curvature across it as zero (below 30 degrees).
_STRAIGHT = 0.25


def flat_triangle_bends(points, counts, indices, bends) -> tuple[np.ndarray, np.ndarray]:
    """Which of the bend springs ``bends`` join the far corners of two triangles that share an edge (theirs
    only) and lie flat at rest, and the particles of those triangles (whose fits bend them in its place)."""
    starts = face_starts(counts)[counts == 3]
    corners = indices[starts[:, None] + np.arange(3)]
    edge = np.concatenate([corners[:, [0, 1]], corners[:, [1, 2]], corners[:, [2, 0]]])
    far = np.concatenate([corners[:, 2], corners[:, 0], corners[:, 1]])
    n = len(points)
    first, second, only_two = shared_edges(edge, n)
    first, second = first[only_two], second[only_two]
    x0, x1, x2, x3 = points[edge[first, 0]], points[edge[first, 1]], points[far[first]], points[far[second]]
    normal_0, normal_1 = np.cross(x1 - x0, x2 - x0), np.cross(x3 - x0, x1 - x0)
    turned = np.linalg.norm(np.cross(normal_0, normal_1), axis=1) / (
        np.linalg.norm(normal_0, axis=1) * np.linalg.norm(normal_1, axis=1))
    flat = turned < _FLAT
    replaced = np.isin(pair_keys(bends, n), pair_keys(np.stack([far[first], far[second]], axis=1)[flat], n))
    involved = np.unique(np.concatenate([edge[first[flat]].ravel(), far[first[flat]], far[second[flat]]]))
    return replaced, involved


def fitted_stencils(points, counts, indices, sides, tensors, particles, rows, bending: tuple[float, float],
                    damping: float) -> BendStencils:
    """The stencils of ``particles`` along u and v (see the module's docstring), each standing for its
    particle's area with the stiffness ``bending`` (B_u, B_v) times it, but along a direction a row's stencil
    already bends the particle in (``rows``: each row's middle particle and direction), or where it is not
    flat at rest. A particle whose neighbours cannot tell a direction (a hem's particle with one neighbour
    inside, one of four neighbours: fewer points than a quadratic has coefficients) is fitted to the nearest
    of its neighbours and theirs instead. ``tensors`` (n, 3, 3) sum the warp's directions at each particle
    (None: no UVs, u along its first side)."""
    if not len(particles):
        return BendStencils(np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
                            np.zeros(0))
    adjacency = Adjacency.of(sides, len(points))
    along_border, straight, corner = _border(points, counts, indices, particles)
    ring = _rings(points, adjacency, particles, 1)
    u, first = _fits(points, tensors, particles, ring, along_border, straight)
    # the second ring, only where the first cannot tell a direction (and not at a corner)
    short = np.flatnonzero(~corner & ~(first[0][1] & first[1][1]))
    ring_2 = _rings(points, adjacency, particles[short], 2)
    _, wider = _fits(points, tensors, particles[short], ring_2, along_border[short], straight[short])
    covered = _row_directions(rows, particles, u)
    area = lumped_masses(points, counts, indices, 1.0)[particles]
    parts = []
    for axis, stiff in enumerate(bending):
        (weights, told, at_rest), (weights_2, told_2, at_rest_2) = first[axis], wider[axis]
        widen = ~told[short] & told_2  # where the first ring cannot tell: every other fit as it was
        widened = short[widen]
        stencil, weights, keep = ring.copy(), weights.copy(), told & at_rest
        stencil[widened], weights[widened], keep[widened] = ring_2[widen], weights_2[widen], at_rest_2[widen]
        keep &= ~covered[:, axis]
        stiffness = stiff * area[keep]
        parts.append(BendStencils.of_table(stencil[keep], weights[keep], stencil[keep] >= 0, stiffness,
                                           damping * stiffness))
    return BendStencils.joined(parts)


def _rings(points, adjacency: Adjacency, particles, depth: int) -> np.ndarray:
    """(p, _WIDTH): each particle and the nearest _WIDTH - 1 of the particles within ``depth`` sides of it
    (-1 where there are fewer)."""
    ring = np.full((len(particles), _WIDTH), -1, dtype=np.int64)
    ring[:, 0] = particles
    for k, i in enumerate(particles):
        near = {int(i)}
        for _ in range(depth):
            near |= {int(o) for j in near for o in adjacency.other[adjacency.offsets[j]:adjacency.offsets[j + 1]]}
        others = np.array(sorted(near - {int(i)}), dtype=np.int64)
        nearest = others[np.argsort(np.linalg.norm(points[others] - points[i], axis=1), kind="stable")]
        ring[k, 1:1 + min(len(nearest), _WIDTH - 1)] = nearest[:_WIDTH - 1]
    return ring


def _fits(points, tensors, particles, ring, along_border, straight) -> tuple[np.ndarray, list[tuple]]:
    """Each particle's u, and per direction (u, v) the fit's weights (p, _WIDTH) on ``ring``, whether they tell
    that direction's curvature (exact for every quadratic, not leaning on points too nearly on one conic) and
    whether they read none at rest."""
    used = ring >= 0
    offsets = np.where(used[:, :, None], points[np.maximum(ring, 0)] - points[particles][:, None, :], 0.0)
    scale = np.sqrt(np.sum(offsets ** 2, axis=(1, 2)) / np.maximum(used.sum(axis=1) - 1, 1))  # mean side
    centred = (offsets - offsets.sum(axis=1, keepdims=True) / used.sum(axis=1)[:, None, None]) * used[:, :, None]
    normal = np.linalg.svd(centred)[2][:, 2]
    u = _warp_axes(tensors, particles, offsets[:, 1], normal)
    v = np.cross(normal, u)
    s, t = (np.einsum("prk,pk->pr", offsets, axis) / scale[:, None] for axis in (u, v))
    design = np.stack([np.ones_like(s), s, t, 0.5 * s * s, s * t, 0.5 * t * t], axis=2) * used[:, :, None]
    across = np.where(straight[:, None], np.cross(normal, along_border), 0.0)  # kappa across it taken as zero
    a_s, a_t = np.einsum("pk,pk->p", across, u), np.einsum("pk,pk->p", across, v)
    zero = np.zeros_like(a_s)
    free_edge = np.stack([zero, zero, zero, a_s * a_s, 2 * a_s * a_t, a_t * a_t], axis=1)  # kappa_nn = 0
    design = np.concatenate([design, free_edge[:, None, :]], axis=1)
    inverse = np.linalg.pinv(design)  # (p, 6, _WIDTH + 1): the fit's coefficients from the heights and the edge
    fits = []
    for coefficient in (3, 5):
        weights = inverse[:, coefficient, :_WIDTH] / scale[:, None] ** 2
        exact = np.abs(np.einsum("pr,prj->pj", inverse[:, coefficient, :], design)
                       - np.eye(6)[coefficient]).max(axis=1) < 1e-6
        total = np.abs(weights).sum(axis=1) * scale ** 2
        bounded = (total < _MOST_WEIGHT) & (total > 1e-6)  # none at all: a border's bend across itself
        at_rest = np.linalg.norm(np.einsum("pr,prk->pk", weights, offsets), axis=1) * scale < _FLAT
        fits.append((weights, exact & bounded, at_rest))
    return u, fits


def _border(points, counts, indices, particles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each particle's direction along the border it is on, whether the border runs straight there (turning
    by no more than ``_STRAIGHT``) and whether it is a corner (on the border, not straight)."""
    n = len(points)
    sides, uses = unique_pairs(face_edges(counts, indices), n)
    border = sides[uses == 1]
    direction = points[border[:, 1]] - points[border[:, 0]]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    spread = np.zeros((n, 3, 3))
    np.add.at(spread, border.ravel(), np.repeat(direction[:, :, None] * direction[:, None, :], 2, axis=0))
    values, vectors = np.linalg.eigh(spread[particles])
    straight = (values[:, 2] > 0) & (values[:, 1] <= _STRAIGHT * values[:, 2])
    return vectors[:, :, 2], straight, (values[:, 2] > 0) & ~straight


def _warp_axes(tensors, particles, first_side, normal) -> np.ndarray:
    """Each particle's u in its tangent plane: its faces' warp (the tensor's leading direction), else along
    its first side."""
    def in_plane(direction):
        flat = direction - np.einsum("pk,pk->p", direction, normal)[:, None] * normal
        length = np.linalg.norm(flat, axis=1, keepdims=True)
        return flat / np.where(length > 0, length, 1.0), length[:, 0]

    fallback, _ = in_plane(first_side)
    if tensors is None:
        return fallback
    warp, length = in_plane(np.linalg.eigh(tensors[particles])[1][:, :, 2])
    return np.where((length > 1e-3)[:, None], warp, fallback)


def _row_directions(rows, particles, u) -> np.ndarray:
    """(p, 2): whether a row runs through each particle mostly along u, and along v."""
    middle, direction = rows
    covered = np.zeros((len(particles), 2), dtype=bool)
    place = np.searchsorted(particles, middle)
    found = (place < len(particles)) & (particles[np.minimum(place, len(particles) - 1)] == middle)
    direction = direction[found]
    length2 = np.einsum("rk,rk->r", direction, direction)
    along_u = np.einsum("rk,rk->r", direction, u[place[found]]) ** 2 >= 0.5 * length2
    covered[place[found][along_u], 0] = True
    covered[place[found][~along_u], 1] = True
    return covered
