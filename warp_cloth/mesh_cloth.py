"""A cloth made of the user's mesh (``Cloth(mesh=...)``): its particles where the mesh puts them, placed by
the cloth's ``rotation`` and ``origin``, springs from its faces (cloth_mesh.py), masses from area."""

from __future__ import annotations

import dataclasses

import numpy as np

from .cloth_grid import rotation_matrix
from .cloth_mesh import ClothMesh, lumped_masses, mesh_springs
from .materials import derive_springs
from .scene import Cloth


def mesh_positions(cloth: Cloth) -> np.ndarray:
    """World positions of a mesh cloth's particles in its initial pose, shape (n, 3)."""
    points = cloth.surface().points
    return points @ rotation_matrix(cloth.rotation).T + np.asarray(cloth.origin, dtype=float)


def build_mesh_cloth(cloth: Cloth) -> ClothMesh:
    surface = cloth.surface()
    positions = mesh_positions(cloth)
    springs, kinds, rests = mesh_springs(surface.points, surface.face_counts, surface.face_indices)
    uniform = cloth.particle_mass()
    masses = np.full(len(positions), uniform) if uniform is not None else \
        lumped_masses(surface.points, surface.face_counts, surface.face_indices, cloth.areal_density)
    mesh = ClothMesh(positions, masses, springs, kinds, rests, surface.face_counts, surface.face_indices,
                     surface.uvs)
    if cloth.material is None:
        return mesh
    return dataclasses.replace(mesh, derived=derive_springs(cloth.material, surface.points, mesh))
