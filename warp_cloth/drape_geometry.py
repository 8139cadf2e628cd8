"""The geometry of the Cusick drape test (BS 5058, ISO 9073-9): its specimen and support meshes, and the drape
coefficient of a draped specimen from its projection onto the horizontal plane.

The specimen: a disc of ``SPECIMEN_DIAMETER`` in the XZ plane, facing +Y, meshed so that the material's
directions mean what they say (materials.py): a square grid of ``resolution`` cells across the diameter, warp
(u) along +X and weft (v) along -Z, of which every cell whose corners all lie within the disc shrunk by
``BORDER`` of a cell is kept as a quad; the ring between that staircase and the disc's circle is filled
with triangles, walking the staircase and as many points on the circle as a cell's width spaces round it,
advancing whichever is behind in angle (as tools/make_scene_meshes.py rings its tablecloth). So the
middle, where the folds form, is the grid whose springs the materials module derives exactly, its bend
springs straight along rows and columns; the rim is round. UVs are the plan view's, so the triangles'
sides take their direction's stiffness too.

The support: a closed cylinder of ``SUPPORT_DIAMETER`` and ``SUPPORT_HEIGHT``, its top at y = 0, in
``SUPPORT_SIDES`` sides.

The drape coefficient DC = (A_shadow - A_disc) / (A_specimen - A_disc), A_shadow the area of the union of
the specimen's triangles projected onto the XZ plane, A_disc the support's (its nominal circle's, as the
standard takes it) and A_specimen the specimen mesh's area at rest (its polygon, within 0.1% of the
nominal circle's at 30 cells, so that a flat specimen gives exactly 1). The union is rasterised: the
triangles are filled into a square raster of ``pixel`` (default 0.2 mm) cells, each cell counted where its
centre falls inside some triangle. A cell is miscounted only where the union's boundary crosses it, so the
area's error is at most the area of the raster's boundary cells (those counted with a neighbour not, and
those not counted with a neighbour counted), which ``Projection.error`` reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SPECIMEN_DIAMETER = 0.30  # metres: the standard's specimen
SUPPORT_DIAMETER = 0.18  # metres: the standard's support disc
SUPPORT_HEIGHT = 0.01  # metres: a plate, the cloth hanging below it touching nothing else
SUPPORT_SIDES = 96
SUPPORT_AREA = math.pi * (SUPPORT_DIAMETER / 2.0) ** 2  # the standard's A_disc
BORDER = 0.35  # of a cell: how far inside the circle the kept grid's corners stay
DEFAULT_RESOLUTION = 30  # cells across the specimen's diameter: 1 cm cells
PIXEL = 2e-4  # metres: the raster's cell


@dataclass(frozen=True)
class Specimen:
    points: np.ndarray  # (n, 3) at rest, y = 0
    face_counts: np.ndarray  # (f,) 4 (the grid's cells) or 3 (the rim's triangles)
    face_indices: np.ndarray
    uvs: np.ndarray  # (n, 2) per vertex: u along +X, v along -Z, over [0, 1] across the diameter

    @property
    def area(self) -> float:
        from .mesh_io import face_areas

        return float(face_areas(self.points, self.face_counts, self.face_indices).sum())

    def triangles(self) -> np.ndarray:
        from .mesh_io import fan_triangles

        return fan_triangles(self.face_counts, self.face_indices)


def specimen(resolution: int = DEFAULT_RESOLUTION, diameter: float = SPECIMEN_DIAMETER) -> Specimen:
    """The specimen disc of ``resolution`` grid cells across ``diameter`` (see the module's docstring)."""
    if resolution < 4:
        raise ValueError(f"resolution must be at least 4 cells across, got {resolution}")
    radius, cell = diameter / 2.0, diameter / resolution
    inside = radius - BORDER * cell
    # Grid vertices at (i - n/2) cell in x and in z, kept where a kept cell has them.
    coordinate = (np.arange(resolution + 1) - resolution / 2.0) * cell
    x, z = np.meshgrid(coordinate, coordinate, indexing="ij")
    corner_in = np.hypot(x, z) <= inside
    cell_in = corner_in[:-1, :-1] & corner_in[1:, :-1] & corner_in[1:, 1:] & corner_in[:-1, 1:]
    used = np.zeros_like(corner_in)
    for di, dk in ((0, 0), (1, 0), (1, 1), (0, 1)):
        used[di:resolution + di, dk:resolution + dk] |= cell_in
    index = np.full(used.shape, -1, dtype=np.int64)
    index[used] = np.arange(used.sum())
    grid_points = np.stack([x[used], z[used]], axis=1)
    i, k = np.nonzero(cell_in)
    # Counter-clockwise seen from +Y (x right, z toward the viewer): (i, k), (i, k+1), (i+1, k+1), (i+1, k).
    quads = np.stack([index[i, k], index[i, k + 1], index[i + 1, k + 1], index[i + 1, k]], axis=1)

    loop = _outer_loop(quads, grid_points)
    count = max(8, int(math.ceil(2.0 * math.pi * radius / cell)))
    angles = 2.0 * math.pi * np.arange(count) / count
    rim_points = radius * np.stack([np.cos(angles), -np.sin(angles)], axis=1)  # counter-clockwise from +Y
    rim = len(grid_points) + np.arange(count)
    plan = np.concatenate([grid_points, rim_points])
    triangles = _strip(loop, rim, plan)

    points = np.stack([plan[:, 0], np.zeros(len(plan)), plan[:, 1]], axis=1)
    counts = np.concatenate([np.full(len(quads), 4), np.full(len(triangles), 3)]).astype(np.int64)
    indices = np.concatenate([quads.ravel(), triangles.ravel()]).astype(np.int64)
    uvs = np.stack([0.5 + plan[:, 0] / diameter, 0.5 - plan[:, 1] / diameter], axis=1)
    return Specimen(points, counts, indices, uvs)


def _angle(plan: np.ndarray) -> np.ndarray:
    """Each plan point's angle counter-clockwise seen from +Y (from +X towards -Z), in [0, 2 pi)."""
    return np.mod(np.arctan2(-plan[:, 1], plan[:, 0]), 2.0 * math.pi)


def _outer_loop(quads: np.ndarray, plan: np.ndarray) -> np.ndarray:
    """The kept cells' boundary, as vertex indices counter-clockwise from the one of least angle. The kept
    cells are the grid's within a circle about its centre, so every row and column of them is one run about
    the middle: the boundary is one loop, met by each ray from the centre once."""
    edges = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    reverse = {(int(b), int(a)) for a, b in edges}
    following = {int(a): int(b) for a, b in edges if (int(a), int(b)) not in reverse}
    start = min(following, key=lambda v: _angle(plan[[v]])[0])
    loop = [start]
    while following[loop[-1]] != start:
        loop.append(following[loop[-1]])
    if len(loop) != len(following):
        raise AssertionError("the kept cells' boundary is not one loop")
    return np.array(loop, dtype=np.int64)


def _strip(inner: np.ndarray, outer: np.ndarray, plan: np.ndarray) -> np.ndarray:
    """Triangles between two closed loops, both counter-clockwise and each starting at its least angle:
    each step joins the current vertices of both to the next of one loop, the one whose new side (the
    strip's diagonal) is the shorter, unless that triangle would turn over (then the other's)."""
    i = j = 0
    triangles = []
    while i < len(inner) or j < len(outer):
        a, b = inner[i % len(inner)], outer[j % len(outer)]
        by_outer = (a, b, outer[(j + 1) % len(outer)]) if j < len(outer) else None
        by_inner = (a, b, inner[(i + 1) % len(inner)]) if i < len(inner) else None
        if by_outer is not None and by_inner is not None:
            shorter_outer = np.linalg.norm(plan[by_outer[2]] - plan[a]) <= np.linalg.norm(plan[by_inner[2]] - plan[b])
            preferred, other = (by_outer, by_inner) if shorter_outer else (by_inner, by_outer)
            by_outer_taken = shorter_outer if _turn(plan, preferred) > 0 else not shorter_outer
        else:
            by_outer_taken = by_outer is not None
        if by_outer_taken:
            triangles.append(by_outer)
            j += 1
        else:
            triangles.append(by_inner)
            i += 1
    return np.array(triangles, dtype=np.int64)


def _turn(plan: np.ndarray, triangle: tuple[int, int, int]) -> float:
    """Twice a plan triangle's signed area, positive counter-clockwise seen from +Y."""
    p, q, r = (plan[v] for v in triangle)
    return float((q[0] - p[0]) * (p[1] - r[1]) - (p[0] - r[0]) * (q[1] - p[1]))


def support(diameter: float = SUPPORT_DIAMETER, height: float = SUPPORT_HEIGHT,
            sides: int = SUPPORT_SIDES) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    """The support: a closed cylinder about +Y, its top at y = 0; (points, faces) every face outward."""
    radius = diameter / 2.0
    ring = [(radius * math.cos(2 * math.pi * i / sides), -radius * math.sin(2 * math.pi * i / sides))
            for i in range(sides)]
    points = np.array([(x, -height, z) for x, z in ring] + [(x, 0.0, z) for x, z in ring]
                      + [(0.0, -height, 0.0), (0.0, 0.0, 0.0)])
    bottom, top = 2 * sides, 2 * sides + 1
    faces: list[tuple[int, ...]] = []
    for i in range(sides):
        j = (i + 1) % sides
        faces += [(i, j, sides + j, sides + i), (sides + i, sides + j, top), (j, i, bottom)]
    return points, faces


def write_obj(path, title: str, points: np.ndarray, faces, uvs: np.ndarray | None = None) -> None:
    """An OBJ of ``points`` and ``faces`` (lists of vertex indices), with per-vertex UVs where given."""
    lines = [f"# {title}\n"] + [f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in points]
    if uvs is None:
        lines += ["f " + " ".join(str(i + 1) for i in face) + "\n" for face in faces]
    else:
        lines += [f"vt {u:.7f} {v:.7f}\n" for u, v in uvs]
        lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in face) + "\n" for face in faces]
    with open(path, "w") as out:
        out.writelines(lines)


def faces_of(counts: np.ndarray, indices: np.ndarray) -> list[tuple[int, ...]]:
    ends = np.cumsum(counts)
    return [tuple(int(v) for v in indices[end - c:end]) for c, end in zip(counts, ends)]


@dataclass(frozen=True)
class Projection:
    """The projected area of a draped specimen (m^2) and the most its raster may be off by."""

    area: float
    error: float
    mask: np.ndarray  # (rows, cols) bool: the raster, rows along z, columns along x
    extent: tuple[float, float, float, float]  # x min, x max, z min, z max of the raster


def projected_area(points: np.ndarray, triangles: np.ndarray, pixel: float = PIXEL) -> Projection:
    """The area of the union of ``triangles`` projected onto the XZ plane, rasterised (module docstring)."""
    plan = points[:, [0, 2]]
    low, high = plan.min(axis=0) - 2 * pixel, plan.max(axis=0) + 2 * pixel
    cols, rows = (np.ceil((high - low) / pixel).astype(int))
    mask = np.zeros((rows, cols), dtype=bool)
    a, b, c = plan[triangles[:, 0]], plan[triangles[:, 1]], plan[triangles[:, 2]]
    first = np.floor((np.minimum(np.minimum(a, b), c) - low) / pixel - 0.5).astype(int)
    last = np.ceil((np.maximum(np.maximum(a, b), c) - low) / pixel - 0.5).astype(int)
    for t in range(len(triangles)):
        (c0, r0), (c1, r1) = np.maximum(first[t], 0), np.minimum(last[t], [cols - 1, rows - 1])
        xs = low[0] + (np.arange(c0, c1 + 1) + 0.5) * pixel
        zs = low[1] + (np.arange(r0, r1 + 1) + 0.5) * pixel
        px, pz = np.meshgrid(xs, zs)
        d1, d2, d3 = (_side(p, q, px, pz) for p, q in ((a[t], b[t]), (b[t], c[t]), (c[t], a[t])))
        inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
        mask[r0:r1 + 1, c0:c1 + 1] |= inside
    edge = np.zeros_like(mask)
    edge[:, 1:] |= mask[:, 1:] != mask[:, :-1]
    edge[:, :-1] |= mask[:, 1:] != mask[:, :-1]
    edge[1:, :] |= mask[1:, :] != mask[:-1, :]
    edge[:-1, :] |= mask[1:, :] != mask[:-1, :]
    cell = pixel * pixel
    extent = (float(low[0]), float(low[0] + cols * pixel), float(low[1]), float(low[1] + rows * pixel))
    return Projection(float(mask.sum()) * cell, float(edge.sum()) * cell, mask, extent)


def _side(p: np.ndarray, q: np.ndarray, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Twice the signed area of (p, q, point): which side of p-q each point lies on."""
    return (q[0] - p[0]) * (z - p[1]) - (q[1] - p[1]) * (x - p[0])


def drape_coefficient(shadow: float, specimen_area: float, support_area: float = SUPPORT_AREA) -> float:
    """DC = (A_shadow - A_disc) / (A_specimen - A_disc), a fraction."""
    return (shadow - support_area) / (specimen_area - support_area)
