"""The output layered over the user's shot: cloths and colliders from USD prims keep their prim paths, and
``<output>.shot.usda`` puts the result over the shot in the shot's own up axis, units and time codes."""

from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli_in_process
from warp_cloth.writers.shot_layer import prim_paths

CM = 0.01


def z_up_centimetre_shot(path: Path) -> Path:
    """A Z-up stage in centimetres at 48 time codes a second: a 1 m sheet with normals under rotated and
    raised Xforms, and a 2 m table box keyed to rise 20 cm over one second."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, CM)
    stage.SetTimeCodesPerSecond(48.0)
    stage.SetFramesPerSecond(48.0)
    shot = UsdGeom.Xform.Define(stage, "/Shot")
    shot.AddTranslateOp().Set(Gf.Vec3d(10.0, -20.0, 250.0))
    stage.SetDefaultPrim(shot.GetPrim())
    UsdGeom.Xform.Define(stage, "/Shot/Cloth").AddRotateZOp().Set(30.0)
    sheet = UsdGeom.Mesh.Define(stage, "/Shot/Cloth/Sheet")
    n = 4
    sheet.CreatePointsAttr([(100.0 * i / (n - 1), 100.0 * j / (n - 1), 0.0) for j in range(n) for i in range(n)])
    sheet.CreateFaceVertexCountsAttr([4] * (n - 1) ** 2)
    sheet.CreateFaceVertexIndicesAttr([k for j in range(n - 1) for i in range(n - 1)
                                       for k in (j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)])
    sheet.CreateNormalsAttr([(0.0, 0.0, 1.0)] * n * n)
    table = UsdGeom.Mesh.Define(stage, "/Shot/Table")
    table.CreatePointsAttr([(x, y, z) for z in (-300.0, -250.0) for y in (-100.0, 100.0) for x in (-100.0, 100.0)])
    table.CreateFaceVertexCountsAttr([4] * 6)
    table.CreateFaceVertexIndicesAttr([0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5])
    rise = table.AddTranslateOp()
    rise.Set(Gf.Vec3d(0.0, 0.0, 0.0), 0.0)
    rise.Set(Gf.Vec3d(0.0, 0.0, 20.0), 48.0)
    stage.Save()
    return path


SCENE = """
[simulation]
fps = 24
frames = 6
integrator = "symplectic"

[[collider]]
name = "table"
mesh = { file = "shot.usda", prim = "/Shot/Table" }

[[cloth]]
name = "sheet"
mesh = { file = "shot.usda", prim = "/Shot/Cloth/Sheet" }
density = 0.2
limit = { stretch = 0.1, compression = 0.1 }
"""


def world_points(stage: Usd.Stage, path: str, code: float) -> np.ndarray:
    """A mesh prim's points in its stage's world, at time code ``code``."""
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(path))
    points = np.asarray(mesh.GetPointsAttr().Get(code), dtype=np.float64)
    matrix = np.asarray(mesh.ComputeLocalToWorldTransform(code), dtype=np.float64)
    return points @ matrix[:3, :3] + matrix[3, :3]


def as_y_up_metres(points: np.ndarray) -> np.ndarray:
    return np.stack([points[:, 0], points[:, 2], -points[:, 1]], axis=1) * CM


def test_the_shot_layer_puts_the_simulated_cloth_over_the_shot_in_its_units_axes_and_time_codes(tmp_path):
    z_up_centimetre_shot(tmp_path / "shot.usda")
    (tmp_path / "scene.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("run", "scene.toml", "--out", "out", cwd=tmp_path)
    assert code == 0, err
    assert "wrote out/scene.usdc, out/scene.shot.usda" in out

    ours = Usd.Stage.Open(str(tmp_path / "out" / "scene.usdc"))  # Y up, metres, at the input's paths
    assert UsdGeom.GetStageUpAxis(ours) == UsdGeom.Tokens.y and ours.GetTimeCodesPerSecond() == 24
    simulated = UsdGeom.Mesh(ours.GetPrimAtPath("/Shot/Cloth/Sheet")).GetPointsAttr()
    assert ours.GetPrimAtPath("/Shot/Table").IsA(UsdGeom.Mesh)
    # Their parents are transforms: Blender's importer takes a prim under a parent of no type out of the
    # hierarchy, and with it out of the Y-up turn its root gives.
    assert ours.GetPrimAtPath("/Shot").IsA(UsdGeom.Xform) and ours.GetPrimAtPath("/Shot/Cloth").IsA(UsdGeom.Xform)

    layered = Usd.Stage.Open(str(tmp_path / "out" / "scene.shot.usda"))
    shot = Usd.Stage.Open(str(tmp_path / "shot.usda"))
    assert UsdGeom.GetStageUpAxis(layered) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(layered) == CM
    assert layered.GetTimeCodesPerSecond() == 48 and layered.GetEndTimeCode() == 12
    assert layered.GetDefaultPrim().GetPath() == "/Shot"
    for frame in (0, 3, 6):
        # The cloth, composed in the shot, is where the simulation put it (frame f is the shot's time code 2f).
        cloth = world_points(layered, "/Shot/Cloth/Sheet", 2 * frame)
        np.testing.assert_allclose(as_y_up_metres(cloth), simulated.Get(frame), atol=1e-5)
        # The table is where the shot's own animation has it.
        np.testing.assert_allclose(world_points(layered, "/Shot/Table", 2 * frame),
                                   world_points(shot, "/Shot/Table", 2 * frame), atol=1e-3)
    fallen = as_y_up_metres(world_points(layered, "/Shot/Cloth/Sheet", 12) - world_points(shot, "/Shot/Cloth/Sheet", 0))
    assert fallen[:, 1].mean() == pytest.approx(-0.5 * 9.81 * 0.25 ** 2, rel=0.05)  # it fell 0.25 s from rest
    # The shot's normals belong to the sheet's rest shape: blocked on the simulated cloth.
    assert UsdGeom.Mesh(layered.GetPrimAtPath("/Shot/Cloth/Sheet")).GetNormalsAttr().Get(0) is None


def test_meshes_keep_their_prim_paths_unless_taken(tmp_path):
    shot = z_up_centimetre_shot(tmp_path / "shot.usda")
    sheet = wc.MeshSource(str(shot), "/Shot/Cloth/Sheet")
    scene = wc.Scene(cloths=(wc.Cloth(name="a", mesh=sheet), wc.Cloth(name="b", mesh=sheet),
                             wc.Cloth(name="grid", origin=(0.0, 5.0, 0.0))),
                     colliders=(wc.MeshCollider(name="table", mesh=wc.MeshSource(str(shot), "/Shot/Table")),),
                     spheres=(wc.Sphere(name="ball", center=(0.0, -9.0, 0.0)),))
    paths = prim_paths(scene)
    assert paths.cloths == ["/Shot/Cloth/Sheet", "/World/b", "/World/grid"]  # b's prim is a's: b under /World
    assert paths.colliders == ["/Shot/Table"] and paths.spheres == ["/World/ball"]
