"""One cloth as arrays, whatever made it: particles, masses, springs, faces, UVs.

A grid (cloth_grid.py) is one way of making a cloth; a user's mesh (mesh_io.py) is another. From a mesh's
faces: structural springs on its edges, shear springs on both diagonals of each quad, and a bend spring
across every interior edge between the vertices on either side of it: two triangles' opposite vertices,
or, across an edge a-b between two quads, each end's neighbour on the far side of either quad (on a grid,
exactly the seed's springs two cells apart along rows and columns).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh_io import face_areas, face_edges, face_starts, face_table, fan_triangles, pair_keys, unique_pairs

STRUCTURAL, SHEAR, BEND = 0, 1, 2
SPRING_KINDS = ("structural", "shear", "bend")


@dataclass(frozen=True)
class BendStencils:
    """A material's bending linear in the curvature (materials.py; kernels/bending.py), each stencil as wide
    as it is (a row's three particles, a particle's fit its particle and up to seven neighbours, bend_fits.py):
    stencil s's particles and weights are entries ``starts[s]`` to ``starts[s + 1]`` of ``particles`` and
    ``weights``; then the stencil's stiffness and damping."""

    starts: np.ndarray  # (b + 1,) int
    particles: np.ndarray  # (e,) int: a row's ends and middle, p, m, q; a fit's particle and its neighbours
    weights: np.ndarray  # (e,) 1/m^2: whose sum over a stencil's particles is its curvature vector
    stiffness: np.ndarray  # (b,) N m^3
    damping: np.ndarray  # (b,) N m^3 s

    @staticmethod
    def of_table(particles: np.ndarray, weights: np.ndarray, used: np.ndarray, stiffness: np.ndarray,
                 damping: np.ndarray) -> "BendStencils":
        """The stencils of the rows of ``particles`` and ``weights`` (b, w), each of its ``used`` entries."""
        starts = np.zeros(len(particles) + 1, dtype=np.int64)
        np.cumsum(used.sum(axis=1), out=starts[1:])
        return BendStencils(starts, particles[used], weights[used], stiffness, damping)

    def shifted(self, offset: int) -> "BendStencils":
        return BendStencils(self.starts, self.particles + offset, self.weights, self.stiffness, self.damping)

    @staticmethod
    def joined(parts: "list[BendStencils]") -> "BendStencils":
        begins = np.cumsum([0] + [len(p.particles) for p in parts])
        starts = np.concatenate([[0]] + [p.starts[1:] + begin for p, begin in zip(parts, begins)])
        return BendStencils(starts.astype(np.int64), *(np.concatenate([getattr(p, key) for p in parts])
                                                       for key in ("particles", "weights", "stiffness", "damping")))

    def owners(self) -> np.ndarray:
        """Each entry's stencil."""
        return np.repeat(np.arange(len(self.stiffness)), np.diff(self.starts))

    def sums(self, values: np.ndarray) -> np.ndarray:
        """Per stencil, the sum of ``values`` (one a row per entry) over its entries."""
        return np.add.reduceat(values, self.starts[:-1], axis=0)

    def curvatures(self, x: np.ndarray) -> np.ndarray:
        """(b, 3): each stencil's curvature vector d = sum_r w_r x_r at the positions ``x``."""
        return self.sums(self.weights[:, None] * x[self.particles])

    def incidences(self, particle_count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(offsets (n + 1,), stencil, entry): each particle's incidences in order (those of weight zero left
        out), each naming a stencil and the particle's entry in it, as kernels/bending.py gathers them."""
        entry = np.nonzero(self.weights != 0.0)[0]
        owner = self.particles[entry]
        order = np.lexsort((entry, owner))
        offsets = np.zeros(particle_count + 1, dtype=np.int32)
        np.cumsum(np.bincount(owner, minlength=particle_count), out=offsets[1:])
        return offsets, self.owners()[entry[order]].astype(np.int32), entry[order].astype(np.int32)


@dataclass(frozen=True)
class DerivedSprings:
    """Per spring of a cloth made of a material (materials.derive_springs), in its ``ClothMesh``'s order."""

    stiffness: np.ndarray  # (s,) N, the force per unit strain
    damping: np.ndarray  # (s,) N s/m
    stretch_limit: np.ndarray | None  # (s,) fraction of the rest length; None: the material sets none
    compression_limit: np.ndarray | None
    bending: BendStencils | None = None  # the stencils that bend the cloth in place of bend springs
    stenciled: np.ndarray | None = None  # (s,) bool: the bend springs the stencils replace (left out of the model)


@dataclass(frozen=True)
class ClothMesh:
    positions: np.ndarray  # (n, 3) float64
    masses: np.ndarray  # (n,)
    springs: np.ndarray  # (s, 2) int64 particle pairs
    spring_kind: np.ndarray  # (s,) STRUCTURAL / SHEAR / BEND
    rest_lengths: np.ndarray  # (s,)
    face_counts: np.ndarray  # (f,) 3 or 4
    face_indices: np.ndarray  # (sum of face_counts,) each face's particles, counter-clockwise seen from its front
    uvs: np.ndarray | None  # (n, 2) per particle (a grid), or (sum of face_counts, 2) per face corner, or None
    derived: DerivedSprings | None = None  # a material's springs; None: the cloth's spring kinds' numbers

    @property
    def triangles(self) -> np.ndarray:
        return fan_triangles(self.face_counts, self.face_indices)

    @property
    def is_edge(self) -> np.ndarray:
        """(s,) bool: which springs are edges (structural or shear), whose strain the strain limit bounds."""
        return np.isin(self.spring_kind, (STRUCTURAL, SHEAR))

    def face_table(self) -> np.ndarray:
        """(f, 4) particles of each face, -1 as a triangle's fourth."""
        return face_table(self.face_counts, self.face_indices)


def mesh_springs(points: np.ndarray, face_counts: np.ndarray,
                 face_indices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pairs, kinds, rest lengths) of a mesh's structural, shear and bend springs, rest lengths as modelled."""
    edges = face_edges(face_counts, face_indices)
    n = len(points)
    structural = unique_pairs(edges, n)[0]
    starts = face_starts(face_counts)[face_counts == 4]
    shear = np.concatenate([np.stack([face_indices[starts], face_indices[starts + 2]], axis=1),
                            np.stack([face_indices[starts + 1], face_indices[starts + 3]], axis=1)])
    bend = _bend_pairs(face_counts, face_indices, edges, n)
    pairs = [structural, np.sort(shear, axis=1), bend]
    kinds = np.concatenate([np.full(len(p), kind, dtype=np.int32) for p, kind in zip(pairs, (STRUCTURAL, SHEAR, BEND))])
    pairs = np.concatenate(pairs).astype(np.int64)
    rests = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    return pairs, kinds, rests


def shared_edges(edges: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of the faces' edges ``edges`` (e, 2), each two that are one edge, in either direction: indices
    ``first`` and ``second`` into ``edges`` (neighbours in the edges' order by vertex pair, ``first`` the
    earlier in ``edges``), and whether the edge has only these two faces (not a mesh's fold of three or more)."""
    key = pair_keys(edges, n)
    order = np.argsort(key, kind="stable")
    key = key[order]
    shared = np.nonzero(key[1:] == key[:-1])[0]
    padded = np.concatenate([[-1], key, [-1]])
    only_two = (padded[shared] != key[shared]) & (padded[shared + 3] != key[shared])
    return order[shared], order[shared + 1], only_two


def _bend_pairs(face_counts: np.ndarray, face_indices: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray:
    """Across each interior edge a-b: for each end, its neighbour off the edge in each of the two faces
    (a triangle's is its third vertex, for both ends), joined; repeats dropped."""
    counts = np.repeat(face_counts, face_counts)
    starts = np.repeat(face_starts(face_counts), face_counts)
    position = np.arange(len(face_indices)) - starts
    # Edge k runs from corner k to the next; the corner after that is b's far neighbour, the one before a's.
    after_b = face_indices[starts + (position + 2) % counts]
    before_a = face_indices[starts + (position - 1) % counts]
    first, second, _ = shared_edges(edges, n)
    # Seen from each face, its edge runs a -> b; the second face runs it the other way (b -> a) on a
    # consistently oriented mesh, or the same way on one that is not: match the ends by vertex.
    same_way = edges[first, 0] == edges[second, 0]
    near_a_first, near_b_first = before_a[first], after_b[first]
    near_a_second = np.where(same_way, before_a[second], after_b[second])
    near_b_second = np.where(same_way, after_b[second], before_a[second])
    pairs = np.concatenate([np.stack([near_a_first, near_a_second], axis=1),
                            np.stack([near_b_first, near_b_second], axis=1)])
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]  # two triangles: both ends name the same opposite vertices
    return unique_pairs(pairs, n)[0]


def lumped_masses(points: np.ndarray, face_counts: np.ndarray, face_indices: np.ndarray,
                  density: float) -> np.ndarray:
    """Each particle's share of the area of its faces, split equally among each face's vertices, times the
    density (kg/m^2): on a grid, a cell's area per particle and a quarter at the corners."""
    shares = np.repeat(face_areas(points, face_counts, face_indices) / face_counts, face_counts)
    return density * np.bincount(face_indices, weights=shares, minlength=len(points))


def enclosing_radii(points: np.ndarray, face_counts: np.ndarray, face_indices: np.ndarray) -> np.ndarray:
    """Per particle, the largest radius of the smallest circle around one of its faces' triangles: a sphere
    twice that wide cannot pass through those faces (on a square grid, half a cell's diagonal)."""
    triangles = fan_triangles(face_counts, face_indices)
    a, b, c = (points[triangles[:, k]] for k in range(3))
    lengths = np.stack([np.linalg.norm(b - c, axis=1), np.linalg.norm(c - a, axis=1),
                        np.linalg.norm(a - b, axis=1)], axis=1)
    longest = lengths.max(axis=1)
    squares = lengths ** 2
    obtuse = 2 * squares.max(axis=1) >= squares.sum(axis=1)  # right or obtuse: the longest edge is a diameter
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    circum = lengths.prod(axis=1) / (2.0 * np.maximum(area2, 1e-300))
    radius = np.where(obtuse, 0.5 * longest, circum)
    out = np.zeros(len(points))
    np.maximum.at(out, triangles.ravel(), np.repeat(radius, 3))
    return out


def rest_adjacent_pairs(face_counts: np.ndarray, face_indices: np.ndarray) -> np.ndarray:
    """(k, 2) every pair of particles that share a face (i < j, once each): on a grid, the neighbours along
    rows, columns and diagonals."""
    starts = face_starts(face_counts)
    pairs = []
    for count in (3, 4):
        s = starts[face_counts == count]
        for a in range(count):
            for b in range(a + 1, count):
                pairs.append(np.stack([face_indices[s + a], face_indices[s + b]], axis=1))
    return unique_pairs(np.concatenate(pairs), int(face_indices.max()) + 1)[0]
