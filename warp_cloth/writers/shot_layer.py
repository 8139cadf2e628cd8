"""The output's place in the user's shot: where each prim goes in the output stage, and the layer that puts
the result over the shot.

A cloth or collider read from a USD prim is written at that prim's path, everything else at
``/World/<name>``. The output stage itself keeps the project's conventions (Y up, metres, world-space
points, see ``usd.py``), so it cannot simply be layered over a shot in other units or with transforms above
those prims. Beside it, ``<output>.shot.usda`` is that layering done: it sublayers the output over the
shot(s) the meshes came from, takes the shot's up axis, units and time codes, and gives every prim of the
output a transform from the simulation's frame to the shot's, composed with the inverse of the shot's
transforms above the prim (the output's points are world-space; sampled at every frame where those move).
``!resetXformStack!`` would say the same more simply, but Blender's importer ignores it. Opened, the layer is
the shot with the simulation in it; its cloths replace the shot's meshes of the same paths. Shot normals on
a simulated cloth are blocked: they belong to its rest shape.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..mesh_io import USD_SUFFIXES, Z_UP_TO_Y_UP

SHOT_FRAME_OP = "xformOp:transform:shotFrame"
GROUND_PATH = "/World/ground"


def prim_name(name: str) -> str:
    from pxr import Tf

    return Tf.MakeValidIdentifier(name)


@dataclass(frozen=True)
class PrimPaths:
    """Each sphere's, cloth's and mesh collider's prim in the output stage, in the scene's order."""

    spheres: list[str]
    cloths: list[str]
    colliders: list[str]


def _source_prim(item) -> str | None:
    """The USD prim a cloth's or collider's mesh was read from (None: a grid, an OBJ)."""
    if item.mesh is None or Path(item.mesh.file).suffix.lower() not in USD_SUFFIXES:
        return None
    return item.surface().prim


def prim_paths(scene) -> PrimPaths:
    """A mesh read from a USD prim goes at that prim's path, unless something else has it; the rest (and
    such a mesh whose path is taken) at ``/World/<name>``, as scene names are unique."""
    spheres = [f"/World/{prim_name(s.name)}" for s in scene.spheres]
    items = (*scene.cloths, *scene.colliders)
    sources = [_source_prim(item) for item in items]
    taken = {"/World", GROUND_PATH, *spheres}
    taken.update(f"/World/{prim_name(item.name)}" for item, source in zip(items, sources) if source is None)
    paths = []
    for item, source in zip(items, sources):
        path = source if source is not None and source not in taken else f"/World/{prim_name(item.name)}"
        taken.add(path)
        paths.append(path)
    return PrimPaths(spheres, paths[:len(scene.cloths)], paths[len(scene.cloths):])


def shot_files(scene) -> list[Path]:
    """The USD files the scene's meshes came from, cloths' first, each once."""
    files: list[Path] = []
    for item in (*scene.cloths, *scene.colliders):
        if _source_prim(item) is not None:
            file = Path(item.mesh.file).absolute()
            if file not in files:
                files.append(file)
    return files


def layer_path(output: Path) -> Path:
    """``out/hanging.usdc`` -> ``out/hanging.shot.usda``."""
    return output.with_name(f"{output.name[:len(output.name) - len(output.suffix)]}.shot.usda")


def simulation_to_shot(shot_stage) -> np.ndarray:
    """The 4x4 matrix (USD's row-vector convention) from the simulation's world (Y up, metres) to the
    shot's (its up axis and units): the inverse of what ``mesh_io`` applied on reading."""
    from pxr import UsdGeom

    rotation = Z_UP_TO_Y_UP if UsdGeom.GetStageUpAxis(shot_stage) == UsdGeom.Tokens.z else np.eye(3)
    matrix = np.eye(4)
    matrix[:3, :3] = rotation / UsdGeom.GetStageMetersPerUnit(shot_stage)
    return matrix


def write_shot_layer(path: Path, output: Path, ours, shots: list[Path], simulated: list[str],
                     frames: tuple[int, int], fps: float) -> None:
    """Write the layer at ``path``: the output stage ``ours``, to be found at ``output``, over ``shots``,
    each of its geometry prims given the transform that takes its world-space points to the shot's world
    under the shot's transforms above it; ``simulated``: the cloths' paths; ``frames``: the first and last
    frames written. Written as a layer, not composed: the output is not in place yet."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    shot_stages = [Usd.Stage.Open(str(shot), Usd.Stage.LoadNone) for shot in shots]
    shot = _composed(shots)
    layer = Sdf.Layer.CreateNew(str(path))
    folder = path.parent.absolute()
    layer.subLayerPaths = [os.path.relpath(p.absolute(), folder) for p in (output, *shots)]
    layer.documentation = f"warp-cloth: {output.name} layered over {', '.join(s.name for s in shots)}"
    first = shot_stages[0]
    layer.pseudoRoot.SetInfo("upAxis", UsdGeom.GetStageUpAxis(first))
    layer.pseudoRoot.SetInfo("metersPerUnit", UsdGeom.GetStageMetersPerUnit(first))
    codes_per_frame = first.GetTimeCodesPerSecond() / fps
    layer.timeCodesPerSecond = first.GetTimeCodesPerSecond()  # the output's time codes are scaled to these
    layer.framesPerSecond = first.GetFramesPerSecond()
    first_frame, last_frame = frames
    layer.startTimeCode = first_frame * codes_per_frame
    layer.endTimeCode = last_frame * codes_per_frame
    if first.GetDefaultPrim():
        layer.defaultPrim = first.GetDefaultPrim().GetName()
    to_shot = Gf.Matrix4d(simulation_to_shot(first).tolist())
    for prim in ours.Traverse():
        if not prim.IsA(UsdGeom.Gprim):
            continue
        spec = Sdf.CreatePrimInLayer(layer, prim.GetPath())
        op = Sdf.AttributeSpec(spec, SHOT_FRAME_OP, Sdf.ValueTypeNames.Matrix4d)
        above = shot.GetPrimAtPath(prim.GetPath().GetParentPath())
        op.default = to_shot * _to_world(above, Usd.TimeCode.Default()).GetInverse()
        if _moves(above):
            for frame in range(first_frame, last_frame + 1):
                code = frame * codes_per_frame
                layer.SetTimeSample(op.path, code, to_shot * _to_world(above, Usd.TimeCode(code)).GetInverse())
        own = [o.GetOpName() for o in UsdGeom.Xformable(prim).GetOrderedXformOps()]
        order = Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
        order.default = Vt.TokenArray([SHOT_FRAME_OP, *own])
        if str(prim.GetPath()) in simulated:
            for name in ("normals", "primvars:normals"):
                type_name = _authored_type(shot_stages, prim.GetPath(), name)
                if type_name is not None:
                    Sdf.AttributeSpec(spec, name, type_name).default = Sdf.ValueBlock()
    layer.Save()


def _composed(shots: list[Path]):
    """The shots as one stage, the first strongest, as the layer composes them."""
    from pxr import Usd

    if len(shots) == 1:
        return Usd.Stage.Open(str(shots[0]), Usd.Stage.LoadNone)
    stage = Usd.Stage.CreateInMemory(load=Usd.Stage.LoadNone)
    stage.GetRootLayer().subLayerPaths = [str(shot) for shot in shots]
    return stage


def _to_world(prim, time):
    """The transform from ``prim``'s space to its stage's world (identity where the shot has no prim)."""
    from pxr import Gf, UsdGeom

    return UsdGeom.XformCache(time).GetLocalToWorldTransform(prim) if prim else Gf.Matrix4d(1.0)


def _moves(prim) -> bool:
    """Whether a transform of ``prim`` or above it is animated."""
    from pxr import UsdGeom

    while prim and not prim.IsPseudoRoot():
        xformable = UsdGeom.Xformable(prim)
        if xformable and xformable.TransformMightBeTimeVarying():
            return True
        prim = prim.GetParent()
    return False


def _authored_type(stages, path, name: str):
    """The type of attribute ``name`` of prim ``path`` where one of ``stages`` gives it a value."""
    for stage in stages:
        prim = stage.GetPrimAtPath(path)
        attr = prim.GetAttribute(name) if prim else None
        if attr and attr.HasAuthoredValue():
            return attr.GetTypeName()
    return None
