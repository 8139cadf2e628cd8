"""Which particles each pin of a scene holds: ``geometry_checks.validate`` checks the pins with it, and the
model pins them. It reads a cloth's initial pose (the grid's or the mesh's positions) and the colliders where
they start, without building the model.

A cloth's boundary is the sides of its faces that belong to one face only. ``edges = ["boundary"]`` selects
every vertex on them; ``corners = ["boundary"]`` those where the boundary turns by more than
``CORNER_ANGLE`` degrees (the angle between the boundary's side arriving at the vertex and the one leaving
it; a vertex where the boundary meets itself, with other than two boundary sides, is a corner too). A
rectangle's four corners turn by 90; a circle of more than 8 sides turns by less than 45 at each vertex and
has none. On a grid they are its four edges and four corners.
"""

from __future__ import annotations

import math

import numpy as np

from .cloth_grid import grid_corner, grid_edge, grid_positions
from .errors import SceneError
from .keyed_motion import collider_points_at
from .mesh_cloth import mesh_positions
from .mesh_io import face_edges, unique_pairs
from .scene import BOUNDARY, RESERVED_NAME, Cloth, Pin, Scene
from .shot_clock import shot_clock

CORNER_ANGLE = 45.0  # degrees: the boundary turns by more than this at a corner
_PAIRS_A_CHUNK = 1 << 21  # particle-triangle pairs measured at once near a mesh collider


def select_pins(scene: Scene) -> list[list[np.ndarray]]:
    """Per cloth, per pin, the particles it selects (cloth-local indices); a SceneError if a pin selects
    nothing, an index out of range, or a particle another pin already holds."""
    selections = []
    for c, cloth in enumerate(scene.cloths):
        if not cloth.pins:
            selections.append([])
            continue
        # Only a region, proximity or a mesh's boundary need the positions: skipped for a grid's corners and edges.
        positions = initial_positions(cloth) if any(_needs_positions(cloth, pin) for pin in cloth.pins) else None
        owner: dict[int, str] = {}
        chosen_per_pin = []
        for p, pin in enumerate(cloth.pins):
            key = f"cloth[{c}].pins[{p}]"
            chosen = pinned_indices(scene, cloth, pin, positions, key)
            for i in chosen.tolist():
                if i in owner:
                    raise SceneError(key, f"pins that select each particle once (particle {i} is also pinned "
                                          f"by {owner[i]})", has_got=False)
                owner[i] = key
            chosen_per_pin.append(chosen)
        selections.append(chosen_per_pin)
    return selections


def initial_positions(cloth: Cloth) -> np.ndarray:
    """A cloth's particles in its initial pose, (n, 3) float64, without building the rest of it."""
    return grid_positions(cloth) if cloth.mesh is None else mesh_positions(cloth)


def _needs_positions(cloth: Cloth, pin: Pin) -> bool:
    return pin.region is not None or pin.near is not None or (cloth.mesh is not None and bool(pin.corners))


def pinned_indices(scene: Scene, cloth: Cloth, pin: Pin, positions: np.ndarray | None, key: str) -> np.ndarray:
    """The particles a pin selects, sorted and unique; an error if it selects none or one out of range.
    ``positions`` (the cloth's initial pose) is needed by a region, proximity and a mesh's boundary corners."""
    n = cloth.particle_count
    chosen: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    for k, i in enumerate(pin.indices):
        if i >= n:
            raise SceneError(f"{key}.indices[{k}]", f"a particle index < {n} (the cloth has {n})", i)
        chosen.append(np.array([i]))
    for name in pin.corners:
        if name != BOUNDARY:
            chosen.append(np.array([grid_corner(cloth, name)]))
        else:
            chosen.append(boundary_corners(cloth, positions))
    for name in pin.edges:
        chosen.append(grid_edge(cloth, name) if name != BOUNDARY else boundary_vertices(cloth))
    if pin.group is not None:
        groups = cloth.surface().groups
        if pin.group not in groups:
            raise SceneError(f"{key}.group", "the name of a group of the cloth's mesh (a USD GeomSubset or point "
                             "primvar, an OBJ g group: "
                             + (", ".join(sorted(groups)) or "it has none") + ")", pin.group)
        chosen.append(groups[pin.group])
    if pin.region is not None:
        inside = np.all((positions >= np.asarray(pin.region.min)) & (positions <= np.asarray(pin.region.max)),
                        axis=1)
        if not inside.any():
            raise SceneError(f"{key}.region", "a box containing at least one particle of the cloth",
                             {"min": list(pin.region.min), "max": list(pin.region.max)})
        chosen.append(np.nonzero(inside)[0])
    if pin.near is not None:
        close = np.nonzero(distance_to_collider(scene, pin.near.collider, positions) <= pin.near.distance)[0]
        if len(close) == 0:
            raise SceneError(f"{key}.near.distance", f"a distance that reaches at least one particle of the cloth "
                             f"(none is within it of '{pin.near.collider}' where they start)", pin.near.distance)
        chosen.append(close)
    selected = np.unique(np.concatenate(chosen)).astype(np.int64)
    if len(selected) == 0:  # only boundary corners can come back empty: a boundary that turns nowhere
        raise SceneError(f"{key}.corners", f"a boundary with a corner (it turns by more than {CORNER_ANGLE:g} "
                                           "degrees nowhere; pin its edges or a region)", list(pin.corners))
    return selected


def _boundary_sides(cloth: Cloth) -> np.ndarray:
    """(b, 2) the sides of a mesh cloth's faces that belong to one face only."""
    surface = cloth.surface()
    sides, uses = unique_pairs(face_edges(surface.face_counts, surface.face_indices), len(surface.points))
    return sides[uses == 1]


def boundary_vertices(cloth: Cloth) -> np.ndarray:
    """Every particle on the cloth's boundary, sorted."""
    if cloth.mesh is None:
        return np.unique(np.concatenate([grid_edge(cloth, name) for name in ("bottom", "top", "left", "right")]))
    return np.unique(_boundary_sides(cloth))


def boundary_corners(cloth: Cloth, positions: np.ndarray | None) -> np.ndarray:
    """The particles where the cloth's boundary turns by more than ``CORNER_ANGLE`` (see the module's
    docstring), sorted; ``positions``: a mesh cloth's initial pose."""
    if cloth.mesh is None:
        return np.unique([grid_corner(cloth, name) for name in ("bottom-left", "bottom-right", "top-left",
                                                                 "top-right")])
    sides = _boundary_sides(cloth)
    ends = sides.ravel()
    vertices, count = np.unique(ends, return_counts=True)
    # each boundary vertex's two neighbours along the boundary: the other ends of its sides, sorted by vertex
    order = np.argsort(ends, kind="stable")
    other = sides[:, ::-1].ravel()[order]
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    simple = count == 2
    v = vertices[simple]
    arriving = positions[v] - positions[other[first[simple]]]
    leaving = positions[other[first[simple] + 1]] - positions[v]
    cosine = np.einsum("ij,ij->i", arriving, leaving) / (np.linalg.norm(arriving, axis=1) *
                                                          np.linalg.norm(leaving, axis=1))
    turned = cosine < math.cos(math.radians(CORNER_ANGLE))
    return np.sort(np.concatenate([v[turned], vertices[~simple]]))


def distance_to_collider(scene: Scene, name: str, positions: np.ndarray) -> np.ndarray:
    """Each point's distance to the surface of the collider ``name`` (a sphere, a mesh collider or the
    ground) where it is when the run begins: a sphere's and the ground's as drawn (without their thickness),
    a mesh's to its nearest face."""
    begins = shot_clock(scene).first_time
    if name == RESERVED_NAME:
        return np.abs(positions[:, 1] - scene.ground.height)
    for sphere in scene.spheres:
        if sphere.name == name:
            centre = np.add(sphere.center, sphere.keyed_offset(begins)) + \
                (0.0 if sphere.motion is None else np.asarray(sphere.motion.offset(begins)))
            return np.abs(np.linalg.norm(positions - centre, axis=1) - sphere.radius)
    collider = next(c for c in scene.colliders if c.name == name)
    points = collider_points_at(collider, scene.simulation.fps, begins)
    return distance_to_triangles(positions, points[collider.surface().triangles()])


def distance_to_triangles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Each point's distance to the nearest of ``triangles`` (t, 3, 3), by brute force in chunks (the
    closest point on a triangle by its Voronoi regions, Ericson's Real-Time Collision Detection 5.1.5)."""
    nearest = np.full(len(points), np.inf)
    step = max(1, _PAIRS_A_CHUNK // max(1, len(triangles)))
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    for start in range(0, len(points), step):
        p = points[start:start + step, None, :]
        nearest[start:start + step] = np.linalg.norm(p - _closest_on_triangles(p, a, b, c), axis=2).min(axis=1)
    return nearest


def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The closest point to each p (m, 1, 3) on each triangle abc (t, 3): (m, t, 3)."""
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    dot = lambda u, w: np.einsum("...k,...k->...", u, w)  # noqa: E731
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = va + vb + vc
        v = np.where(denominator != 0, vb / denominator, 0.0)
        w = np.where(denominator != 0, vc / denominator, 0.0)
        result = a + v[..., None] * ab + w[..., None] * ac  # inside the face
        t_ab = np.clip(d1 / np.where(d1 - d3 != 0, d1 - d3, 1.0), 0, 1)
        t_ac = np.clip(d2 / np.where(d2 - d6 != 0, d2 - d6, 1.0), 0, 1)
        t_bc = np.clip((d4 - d3) / np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) + (d5 - d6), 1.0), 0, 1)
    on = lambda mask, point: np.where(mask[..., None], point, result)  # noqa: E731
    result = on((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + t_bc[..., None] * (c - b))
    result = on((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + t_ac[..., None] * ac)
    result = on((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + t_ab[..., None] * ab)
    result = on((d6 >= 0) & (d5 <= d6), np.broadcast_to(c, result.shape))
    result = on((d3 >= 0) & (d4 <= d3), np.broadcast_to(b, result.shape))
    return on((d1 <= 0) & (d2 <= 0), np.broadcast_to(a, result.shape))
