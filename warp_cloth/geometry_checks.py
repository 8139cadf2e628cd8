"""The checks of a scene that need its geometry: its mesh files read, a mesh cloth's masses lumped from its
faces, its particles counted, the particles each pin selects in the cloths' initial pose.

A scene's dataclasses check each value on its own when made and read no file (scene.py); ``validate`` does
the rest, in one step. Loading a scene file runs it (``scene_file.scene_from_dict``), so that a file's
error comes before anything is simulated or written; ``Simulator`` and ``Batch`` run it on the scenes they
are given, built in Python or not. The meshes it reads stay cached for the model (``mesh_io.load_mesh``).
Its errors are keyed from the scene (``cloth[0].mesh``), as a dataclass's are once a scene file names them.
"""

from __future__ import annotations

from .errors import SceneError
from .mesh_io import SurfaceMesh, load_transform_motion
from .pin_selection import select_pins
from .seams import sew
from .scene import MAX_EXTENT, MAX_PARTICLES, MIN_CELL, Cloth, MeshCollider, Scene


def validate(scene: Scene) -> None:
    """A ``SceneError`` for the first check of ``scene`` that needs its geometry and fails."""
    for c, cloth in enumerate(scene.cloths):
        if cloth.mesh is not None:
            try:
                _check_mesh_cloth(cloth)
            except SceneError as exc:
                raise exc.within(f"cloth[{c}]") from None
            if cloth.masses_from_mesh:
                scene.check_weight(c, cloth.mass_range()[1])
    for k, collider in enumerate(scene.colliders):
        try:
            _check_collider(collider)
        except SceneError as exc:
            raise exc.within(f"collider[{k}]") from None
    total = sum(c.particle_count for c in scene.cloths)
    if total > MAX_PARTICLES:
        raise SceneError("cloth", f"at most {MAX_PARTICLES} particles in all", total)
    _check_target_prims(scene)
    select_pins(scene)
    sew(scene)


def _check_mesh_cloth(cloth: Cloth) -> None:
    surface = cloth.surface()
    if len(surface.points) > MAX_PARTICLES:
        raise SceneError("mesh", f"at most {MAX_PARTICLES} vertices", len(surface.points))
    if surface.shortest_edge < MIN_CELL:
        raise SceneError("mesh", f"edges of at least {MIN_CELL:g} m (float32 positions cannot resolve shorter "
                                 "springs)", f"an edge of {surface.shortest_edge:.3g} m")
    _check_within_extent(surface)
    points = surface.points
    cloth.check_placement(surface.shortest_edge, float((points.max(axis=0) - points.min(axis=0)).max()))
    if cloth.masses_from_mesh:
        cloth.check_masses(*cloth.mass_range())


def _check_collider(collider: MeshCollider) -> None:
    surface = collider.surface()
    _check_within_extent(surface)
    if collider.keys and surface.key_points is not None:
        raise SceneError("keys", "no keys on a mesh its USD file already animates", has_got=False)


def _check_within_extent(surface: SurfaceMesh) -> None:
    farthest = float(abs(surface.points).max())
    if not farthest <= MAX_EXTENT:
        raise SceneError("mesh", f"metres of magnitude at most {MAX_EXTENT:g}", farthest)


def _check_target_prims(scene: Scene) -> None:
    """A pin's target that is a prim path: a transformable prim of the cloth's USD file."""
    for c, cloth in enumerate(scene.cloths):
        for p, pin in enumerate(cloth.pins):
            if pin.target is None or not pin.target.startswith("/"):
                continue
            try:
                load_transform_motion(cloth.usd_file(), pin.target)
            except SceneError as exc:
                raise SceneError(f"cloth[{c}].pins[{p}].target", exc.expected, exc.got, exc.source,
                                 exc.has_got) from None
