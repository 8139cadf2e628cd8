"""The ``meshes`` benchmark suite's cases: what a cloth made of a mesh costs against the same grid, and what
a mesh collider of about 100k triangles costs against the analytic sphere it approximates.

The meshes are written as OBJ files into a folder that lives as long as the process (the cloths read them
through the public API, as a user's would) and is removed at its end.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path

import numpy as np

from ..cloth_grid import build_grid
from ..scene import Cloth, MeshCollider, MeshSource, Pin, Scene

_FOLDER: tempfile.TemporaryDirectory | None = None


def _folder() -> Path:
    global _FOLDER
    if _FOLDER is None:
        _FOLDER = tempfile.TemporaryDirectory(prefix="warp-cloth-bench-")
    return Path(_FOLDER.name)


def write_obj(path: Path, points: np.ndarray, faces: list[np.ndarray]) -> Path:
    """Points and faces (arrays of 0-based indices, one array per face size) as an OBJ file."""
    with open(path, "w") as out:
        out.write(("v %.9g %.9g %.9g\n" * len(points)) % tuple(points.ravel().tolist()))
        for table in faces:
            out.write((("f" + " %d" * table.shape[1] + "\n") * len(table)) % tuple((table + 1).ravel().tolist()))
    return path


def as_mesh_cloth(scene: Scene, triangles: bool) -> Scene:
    """The scene's (one) grid cloth read back from an OBJ of its quads, or of each quad as two triangles;
    its pins by the indices of the particles the grid's pins held."""
    from ..pin_selection import select_pins

    (cloth,) = scene.cloths
    grid = build_grid(cloth)
    quads = grid.face_indices.reshape(-1, 4)
    faces = [np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])] if triangles else [quads]
    name = f"{scene.name}_{'tri' if triangles else 'quad'}.obj"
    path = write_obj(_folder() / name, grid.positions, faces)
    pinned = [Pin(indices=tuple(int(i) for i in chosen)) for chosen in select_pins(scene)[0]]
    mesh_cloth = Cloth(name=cloth.name, mesh=MeshSource(str(path)), mass=cloth.mass, density=cloth.density,
                       limit=cloth.limit, pins=tuple(pinned), structural=cloth.structural, shear=cloth.shear,
                       bend=cloth.bend, velocity=cloth.velocity)
    return dataclasses.replace(scene, name=f"{scene.name}_{'tri' if triangles else 'quad'}", cloths=(mesh_cloth,))


def uv_sphere(center, radius: float, rings: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """A closed sphere of ``rings`` bands and 2 x rings segments, faces outward: quads, triangles at the
    poles (4 rings^2 - 4 rings triangles' worth)."""
    segments = 2 * rings
    theta = np.pi * np.arange(1, rings) / rings  # from the north pole, the poles apart
    phi = 2 * np.pi * np.arange(segments) / segments
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_points = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    points = np.concatenate([ring_points, [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]]) * radius + np.asarray(center)
    north, south = len(ring_points), len(ring_points) + 1
    index = np.arange(len(ring_points)).reshape(rings - 1, segments)
    following = np.roll(index, -1, axis=1)
    quads = np.stack([index[:-1], index[1:], following[1:], following[:-1]], axis=-1).reshape(-1, 4)
    top = np.stack([np.full(segments, north), index[0], following[0]], axis=-1)
    bottom = np.stack([np.full(segments, south), following[-1], index[-1]], axis=-1)
    return points, [quads, np.concatenate([top, bottom])]


def with_mesh_sphere(scene: Scene, rings: int) -> Scene:
    """The scene with its (one) sphere replaced by a mesh collider of it, no thickness."""
    (sphere,) = scene.spheres
    points, faces = uv_sphere(sphere.center, sphere.radius, rings)
    path = write_obj(_folder() / f"sphere_{rings}.obj", points, faces)
    collider = MeshCollider(name=sphere.name, mesh=MeshSource(str(path)), thickness=0.0, friction=sphere.friction)
    return dataclasses.replace(scene, name=f"{scene.name}_mesh_sphere", spheres=(), colliders=(collider,))


def sphere_triangles(rings: int) -> int:
    return 4 * rings * rings - 4 * rings


RINGS_FOR_100K = math.ceil((1 + math.sqrt(1 + 100_000)) / 2)  # 4 r^2 - 4 r >= 100k triangles
