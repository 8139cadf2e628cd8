"""Seams: which particles each ``[[seam]]`` sews to which, and what the model holds of them.

A seam's sides are selected in the cloths' initial pose and paired in order, the k-th particle of side a
with the k-th of side b (``scene.Seam``): a side given by a grid's edge runs along it, one given by a mesh's
group along the mesh's boundary from the end with the lower index (round a closed loop, such as a sleeve's
end or an armhole, from its lowest index), and where either side is not given by indices, b's order is
reversed if that puts the pairs nearer at the start (the sum of their distances), and a loop sewn to a loop
is also turned round to where its pairs are nearest.
Sides of different lengths are refused, not resampled. ``geometry_checks.validate`` checks the seams with
``sew``; the model builds its ``SewnPairs`` from it, which the strain-limit solve holds (model._limits) and
particle contacts leave alone (``sewn_neighbourhood``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cloth_mesh import rest_adjacent_pairs
from .errors import SceneError
from .mesh_io import face_starts
from .pin_selection import initial_positions
from .scene import Cloth, Scene, SeamSide


@dataclass(frozen=True)
class Sewing:
    """One seam's pairs: cloth indices and each side's particles (cloth-local), paired in order."""
    cloth_a: int
    cloth_b: int
    a: np.ndarray  # (k,) int64
    b: np.ndarray  # (k,) int64


@dataclass(frozen=True)
class SewnPairs:
    """Every seam's pairs in the model's particle numbers."""
    pairs: np.ndarray  # (k, 2) int32
    start_length: np.ndarray  # (k,) float32: the pair's distance at the start, the longest it may be then
    close_time: np.ndarray  # (k,) float32 seconds over which that shrinks to 0
    closes_at: np.ndarray  # (k,) float32: the time (on the run's clock) it reaches 0
    scale: np.ndarray  # (k,) float32: the length the solve's tolerance is a fraction of (the shortest edge of
    # the two cloths), once the pair's allowed length is shorter


def sew(scene: Scene) -> list[Sewing]:
    """Each seam's pairs; a SceneError (keyed ``seam[k]...``) for a side that selects nothing, an index out of
    range or twice, sides of different lengths, sides that share a particle, or a pair that shares a face."""
    names = {c.name: k for k, c in enumerate(scene.cloths)}
    sewings = []
    for k, seam in enumerate(scene.seams):
        key = f"seam[{k}]"
        ca, cb = names[seam.a.cloth], names[seam.b.cloth]
        a, loop_a = side_particles(scene.cloths[ca], seam.a, f"{key}.a")
        b, loop_b = side_particles(scene.cloths[cb], seam.b, f"{key}.b")
        if len(a) != len(b):
            raise SceneError(f"{key}.b", f"as many particles as side a's {len(a)} (sides are paired in order, not "
                                         "resampled)", len(b))
        if loop_a != loop_b:
            raise SceneError(f"{key}.b", "a closed loop, as side a is" if loop_a else
                             "an open path, as side a is (a closed loop is sewn to a closed loop)", seam.b.group)
        if not (seam.a.indices and seam.b.indices):
            pa, positions_b = initial_positions(scene.cloths[ca])[a], initial_positions(scene.cloths[cb])
            orders = [b, b[::-1]]
            if loop_a:
                orders = [np.roll(order, shift) for order in orders for shift in range(len(b))]
            b = min(orders, key=lambda order: np.linalg.norm(pa - positions_b[order], axis=1).sum()).copy()
        if ca == cb:
            _check_apart(scene.cloths[ca], a, b, key)
        sewings.append(Sewing(ca, cb, a, b))
    return sewings


def _check_apart(cloth: Cloth, a: np.ndarray, b: np.ndarray, key: str) -> None:
    """Sides of one cloth share no particle, and no pair shares a face (its strain limit would then hold the
    pair apart while the seam holds it together)."""
    shared = np.intersect1d(a, b)
    if len(shared):
        raise SceneError(f"{key}.b", f"particles side a does not have (particle {int(shared[0])} is in both)",
                         has_got=False)
    counts, indices = _faces(cloth)
    adjacent = rest_adjacent_pairs(counts, indices)
    pairs = np.sort(np.stack([a, b], axis=1), axis=1)
    n = cloth.particle_count
    touching = np.isin(pairs[:, 0] * n + pairs[:, 1], adjacent[:, 0].astype(np.int64) * n + adjacent[:, 1])
    if touching.any():
        first = int(np.nonzero(touching)[0][0])
        raise SceneError(key, f"pairs of particles that share no face (pair {first}: particles {int(a[first])} and "
                              f"{int(b[first])} do)", has_got=False)


def side_particles(cloth: Cloth, side: SeamSide, key: str) -> tuple[np.ndarray, bool]:
    """The particles of one side (cloth-local), in the order they are paired, and whether they are a closed
    loop of the mesh's boundary."""
    n = cloth.particle_count
    if side.indices:
        chosen = np.asarray(side.indices, dtype=np.int64)
        for k, i in enumerate(side.indices):
            if i >= n:
                raise SceneError(f"{key}.indices[{k}]", f"a particle index < {n} (the cloth has {n})", i)
        if len(np.unique(chosen)) != len(chosen):
            raise SceneError(f"{key}.indices", "each particle once", list(side.indices))
        return chosen, False
    if side.edge is not None:
        nx, ny = cloth.resolution
        if side.edge in ("bottom", "top"):
            return np.arange(nx + 1, dtype=np.int64) + (nx + 1) * (0 if side.edge == "bottom" else ny), False
        return (0 if side.edge == "left" else nx) + (nx + 1) * np.arange(ny + 1, dtype=np.int64), False
    return _group_path(cloth, side.group, f"{key}.group")


def _group_path(cloth: Cloth, group: str, key: str) -> tuple[np.ndarray, bool]:
    """A mesh group's vertices on the mesh's boundary, in order along it from the end with the lower index,
    or round a closed loop from its lowest index towards its lower-numbered neighbour; and whether it is a
    loop."""
    surface = cloth.surface()
    if group not in surface.groups:
        raise SceneError(key, "the name of a group of the cloth's mesh (a USD GeomSubset or point primvar, an OBJ "
                              "g group: " + (", ".join(sorted(surface.groups)) or "it has none") + ")", group)
    members = np.zeros(len(surface.points), dtype=bool)
    members[surface.groups[group]] = True
    edges = boundary_edges(surface.face_counts, surface.face_indices)
    edges = edges[members[edges].all(axis=1)]
    on_boundary = np.unique(edges)
    if len(on_boundary) == 0:
        raise SceneError(key, "a group with an edge on the mesh's boundary (a seam's side runs along it)", group)
    neighbours: dict[int, list[int]] = {int(v): [] for v in on_boundary}
    for i, j in edges.tolist():
        neighbours[i].append(j)
        neighbours[j].append(i)
    ends = sorted(v for v, around in neighbours.items() if len(around) == 1)
    loop = not ends
    if (len(ends) != 2 and not loop) or any(len(around) > 2 for around in neighbours.values()):
        raise SceneError(key, "a group whose boundary vertices form one open path or one closed loop along the "
                              "mesh's boundary", group)
    first = ends[0] if not loop else min(neighbours)
    path, previous = [first], -1 if not loop else max(neighbours[first])
    while len(path) < len(neighbours):
        following = [v for v in neighbours[path[-1]] if v != previous]
        previous = path[-1]
        path.append(following[0])
    if (not loop and path[-1] != ends[1]) or (loop and first not in neighbours[path[-1]]) or \
            len(set(path)) != len(path):
        raise SceneError(key, "a group whose boundary vertices form one open path or one closed loop along the "
                              "mesh's boundary (these form more than one)", group)
    return np.asarray(path, dtype=np.int64), loop


def boundary_edges(face_counts: np.ndarray, face_indices: np.ndarray) -> np.ndarray:
    """(e, 2) the edges that only one face has (i < j)."""
    starts = face_starts(face_counts)
    sides = []
    for count in (3, 4):
        s = starts[face_counts == count]
        for corner in range(count):
            sides.append(np.stack([face_indices[s + corner], face_indices[s + (corner + 1) % count]], axis=1))
    sides = np.sort(np.concatenate(sides), axis=1)
    unique, uses = np.unique(sides, axis=0, return_counts=True)
    return unique[uses == 1]


def _faces(cloth: Cloth) -> tuple[np.ndarray, np.ndarray]:
    """A cloth's face counts and indices as the model builds them."""
    if cloth.mesh is not None:
        surface = cloth.surface()
        return surface.face_counts, surface.face_indices
    nx, ny = cloth.resolution
    qx, qy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    corner = qx.ravel() + (nx + 1) * qy.ravel()
    quads = np.stack([corner, corner + 1, corner + nx + 2, corner + nx + 1], axis=1)
    return np.full(len(quads), 4, dtype=np.int64), quads.ravel().astype(np.int64)


def sewn_pairs(scene: Scene, positions: np.ndarray, offsets: list[int], shortest_edges: list[float],
               begins: float) -> SewnPairs | None:
    """The model's sewn pairs (None: no seam); ``positions``: the model's, where the run starts; ``begins``:
    the run's first time (shot_clock)."""
    if not scene.seams:
        return None
    pairs, close, scale = [], [], []
    for seam, sewing in zip(scene.seams, sew(scene)):
        pairs.append(np.stack([sewing.a + offsets[sewing.cloth_a], sewing.b + offsets[sewing.cloth_b]], axis=1))
        close.append(np.full(len(sewing.a), seam.close_time))
        scale.append(np.full(len(sewing.a), min(shortest_edges[sewing.cloth_a], shortest_edges[sewing.cloth_b])))
    pairs = np.concatenate(pairs).astype(np.int32)
    close = np.concatenate(close)
    start = np.linalg.norm(positions[pairs[:, 0]].astype(np.float64) - positions[pairs[:, 1]], axis=1)
    return SewnPairs(pairs, start.astype(np.float32), close.astype(np.float32), (begins + close).astype(np.float32),
                     np.concatenate(scale).astype(np.float32))


def sewn_neighbourhood(sewn: SewnPairs, face_counts: list[np.ndarray], face_indices: list[np.ndarray],
                       offsets: list[int]) -> np.ndarray:
    """(m, 2) the pairs particle contacts skip for the seams (i < j, once each): each sewn pair, and every
    particle that shares a face with one of a pair (or is it) with every such particle of the other, so that
    the sides' faces meet at the seam without pushing each other off."""
    n = offsets[-1]
    adjacent = np.concatenate([rest_adjacent_pairs(c, i) + o for c, i, o in zip(face_counts, face_indices, offsets)])
    ring_pairs = np.concatenate([adjacent, adjacent[:, ::-1], np.repeat(np.arange(n)[:, None], 2, axis=1)])
    order = np.argsort(ring_pairs[:, 0], kind="stable")
    ring_pairs = ring_pairs[order]
    start = np.searchsorted(ring_pairs[:, 0], np.arange(n + 1))
    skipped = []
    for i, j in sewn.pairs.tolist():
        around_i = ring_pairs[start[i]:start[i + 1], 1]
        around_j = ring_pairs[start[j]:start[j + 1], 1]
        skipped.append(np.stack(np.meshgrid(around_i, around_j, indexing="ij"), axis=2).reshape(-1, 2))
    skipped = np.sort(np.concatenate(skipped), axis=1)
    skipped = skipped[skipped[:, 0] != skipped[:, 1]]
    return np.unique(skipped, axis=0)


def welded_ids(sewn: SewnPairs | None, particle_count: int) -> np.ndarray:
    """(n,) int32: each particle's number once its seams are shut, the lowest of the particles sewn together
    with it (directly or through others: a seam's end sewn in two seams), its own where it is not sewn."""
    ids = np.arange(particle_count, dtype=np.int32)
    if sewn is None:
        return ids
    changed = True
    while changed:  # each round carries the lowest number one pair further
        lowest = np.minimum(ids[sewn.pairs[:, 0]], ids[sewn.pairs[:, 1]])
        changed = bool((ids[sewn.pairs] != lowest[:, None]).any())
        np.minimum.at(ids, sewn.pairs[:, 0], lowest)
        np.minimum.at(ids, sewn.pairs[:, 1], lowest)
    return ids
