"""A grid cloth as a ``ClothMesh``: particle positions, masses, springs, quads, UVs and pinned particles.

Grid particle (x, y) has index ``x + (nx + 1) * y``, as in the seed. Springs: structural to the right and
upper neighbours, shear on both diagonals of each quad, bend two apart along rows and columns (the springs
``cloth_mesh.mesh_springs`` makes of the same quads, in the seed's order).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .cloth_mesh import BEND, SHEAR, STRUCTURAL, ClothMesh
from .materials import derive_springs
from .scene import Cloth


def rotation_matrix(degrees_xyz: tuple[float, float, float]) -> np.ndarray:
    """Rotation about X, then Y, then Z (extrinsic), in degrees."""
    ax, ay, az = (math.radians(a) for a in degrees_xyz)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def cloth_frame(cloth: Cloth) -> np.ndarray:
    """Columns: the world directions of grid u, grid v and the cloth normal."""
    if cloth.orientation == "vertical":
        frame = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).T
    else:
        frame = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]).T
    return rotation_matrix(cloth.rotation) @ frame


def _grid_coordinates(cloth: Cloth) -> tuple[np.ndarray, np.ndarray]:
    nx, ny = cloth.resolution
    gx, gy = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="xy")
    return gx.ravel(), gy.ravel()


def grid_positions(cloth: Cloth) -> np.ndarray:
    """World positions of the cloth's particles in its initial pose, shape (n, 3)."""
    nx, ny = cloth.resolution
    dx, dy = cloth.size[0] / nx, cloth.size[1] / ny
    gx, gy = _grid_coordinates(cloth)
    local = np.stack([gx * dx, gy * dy, np.zeros_like(gx, dtype=float)], axis=1)
    if cloth.jitter > 0:
        rng = np.random.default_rng(cloth.seed)
        local[:, 2] = rng.uniform(-1.0, 1.0, len(local)) * cloth.jitter * min(dx, dy)
    if cloth.twist != 0.0:
        angle = np.radians(cloth.twist) * gy / ny
        across = local[:, 0] - 0.5 * cloth.size[0]
        local[:, 0] = 0.5 * cloth.size[0] + across * np.cos(angle) - local[:, 2] * np.sin(angle)
        local[:, 2] = across * np.sin(angle) + local[:, 2] * np.cos(angle)
    return local @ cloth_frame(cloth).T + np.asarray(cloth.origin, dtype=float)


def build_grid(cloth: Cloth) -> ClothMesh:
    nx, ny = cloth.resolution
    dx, dy = cloth.size[0] / nx, cloth.size[1] / ny
    gx, gy = _grid_coordinates(cloth)
    springs, kinds, rests = _grid_springs(nx, ny, dx, dy)
    idx = lambda x, y: x + (nx + 1) * y  # noqa: E731
    qx, qy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    qx, qy = qx.ravel(), qy.ravel()
    quads = np.stack([idx(qx, qy), idx(qx + 1, qy), idx(qx + 1, qy + 1), idx(qx, qy + 1)], axis=1)
    uvs = np.stack([gx / nx, gy / ny], axis=1)
    mesh = ClothMesh(grid_positions(cloth), _masses(cloth, gx, gy, dx, dy), springs, kinds, rests,
                     np.full(len(quads), 4, dtype=np.int64), quads.ravel().astype(np.int64), uvs)
    if cloth.material is None:
        return mesh
    flat = np.stack([gx * dx, gy * dy, np.zeros(len(gx))], axis=1)  # the rest the springs' lengths are of
    return dataclasses.replace(mesh, derived=derive_springs(cloth.material, flat, mesh))


def _grid_springs(nx: int, ny: int, dx: float, dy: float):
    idx = lambda x, y: x + (nx + 1) * y  # noqa: E731
    pairs, kinds, rests = [], [], []

    def add(x0, y0, x1, y1, kind, rest):
        pairs.append(np.stack([idx(x0, y0), idx(x1, y1)], axis=1).reshape(-1, 2))
        kinds.append(np.full(pairs[-1].shape[0], kind, dtype=np.int32))
        rests.append(np.full(pairs[-1].shape[0], rest))

    def grid(xs, ys):
        gx, gy = np.meshgrid(xs, ys, indexing="xy")
        return gx.ravel(), gy.ravel()

    x, y = grid(np.arange(nx), np.arange(ny + 1))
    add(x, y, x + 1, y, STRUCTURAL, dx)
    x, y = grid(np.arange(nx + 1), np.arange(ny))
    add(x, y, x, y + 1, STRUCTURAL, dy)
    diagonal = math.hypot(dx, dy)
    x, y = grid(np.arange(nx), np.arange(ny))
    add(x, y, x + 1, y + 1, SHEAR, diagonal)
    add(x + 1, y, x, y + 1, SHEAR, diagonal)
    if nx >= 2:
        x, y = grid(np.arange(nx - 1), np.arange(ny + 1))
        add(x, y, x + 2, y, BEND, 2 * dx)
    if ny >= 2:
        x, y = grid(np.arange(nx + 1), np.arange(ny - 1))
        add(x, y, x, y + 2, BEND, 2 * dy)
    return np.concatenate(pairs), np.concatenate(kinds), np.concatenate(rests)


def _masses(cloth: Cloth, gx: np.ndarray, gy: np.ndarray, dx: float, dy: float) -> np.ndarray:
    uniform = cloth.particle_mass()
    if uniform is not None:
        return np.full(len(gx), uniform)
    nx, ny = cloth.resolution
    wx = np.where((gx == 0) | (gx == nx), 0.5, 1.0)
    wy = np.where((gy == 0) | (gy == ny), 0.5, 1.0)
    return cloth.areal_density * dx * dy * wx * wy


def grid_corner(cloth: Cloth, name: str) -> int:
    """The particle at a named corner of a grid (left/right along its first direction, bottom/top its second)."""
    nx, ny = cloth.resolution
    x, y = {"bottom-left": (0, 0), "bottom-right": (nx, 0), "top-left": (0, ny), "top-right": (nx, ny)}[name]
    return x + (nx + 1) * y


def grid_edge(cloth: Cloth, name: str) -> np.ndarray:
    """The particles along a named edge of a grid, in order."""
    nx, ny = cloth.resolution
    if name in ("bottom", "top"):
        return np.arange(nx + 1) + (nx + 1) * (0 if name == "bottom" else ny)
    return (0 if name == "left" else nx) + (nx + 1) * np.arange(ny + 1)
