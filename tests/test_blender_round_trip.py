"""A round trip through a real DCC tool: Blender (the ``bpy`` module) builds a shot, a subdivided plane above
a table that turns a quarter turn in a second, and exports it as USD; ``warp-cloth run`` simulates the plane
as cloth on the table as an animated mesh collider; Blender imports the result, the shot with the simulation
layered over it (``<output>.shot.usda``), and sees the cloth where our USD has it at every frame checked,
resting on the table and turned with it, and the table where its own animation has it. Blender runs in its own
process (it carries its own USD libraries). The built-in garment scene's shot opens there too. Skipped where bpy cannot be installed (it is in the test extra
for the Python versions its wheels exist for)."""

import importlib.util
import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli_in_process

pytestmark = pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="bpy (Blender) is not installed")

MAKE_SHOT = textwrap.dedent("""
    import math, sys
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 24
    scene.frame_start, scene.frame_end = 0, 24
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
    table = bpy.context.active_object
    table.name = "Table"
    table.scale = (2.0, 2.0, 1.0)
    for frame, angle in ((0, 0.0), (24, 90.0)):
        table.rotation_euler = (0.0, 0.0, math.radians(angle))
        table.keyframe_insert("rotation_euler", frame=frame)
    bpy.ops.mesh.primitive_plane_add(size=1.2, location=(0.0, 0.0, 1.1))
    sheet = bpy.context.active_object
    sheet.name = "Sheet"
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.subdivide(number_cuts=11)
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.ops.wm.usd_export(filepath=sys.argv[-1], export_animation=True)
""")

READ_RESULT = textwrap.dedent("""
    import json, sys
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=sys.argv[-3])
    scene = bpy.context.scene
    result = {"objects": sorted(o.name for o in scene.objects), "frames": {}}
    for frame in [int(f) for f in sys.argv[-2].split(",")]:
        scene.frame_set(frame)
        result["frames"][frame] = {}
        for name in sys.argv[-1].split(","):  # the objects whose meshes are read, world-space
            evaluated = scene.objects[name].evaluated_get(bpy.context.evaluated_depsgraph_get())
            mesh = evaluated.to_mesh()
            result["frames"][frame][name] = [list(evaluated.matrix_world @ v.co) for v in mesh.vertices]
            evaluated.to_mesh_clear()
    print("RESULT " + json.dumps(result))
""")

SCENE = """
[simulation]
fps = 24
frames = 24
integrator = "symplectic"
limit_solve = "converged"

[[collider]]
name = "Table"
mesh = { file = "shot.usda", prim = "/root/Table/Cube" }
thickness = 0.01
friction = 0.6

[[cloth]]
name = "Sheet"
mesh = { file = "shot.usda", prim = "/root/Sheet/Plane" }
density = 0.2
limit = { stretch = 0.1, compression = 0.1 }
structural = { stiffness = 15.0, damping = 0.02 }
shear = { stiffness = 15.0, damping = 0.02 }
bend = { stiffness = 5.0, damping = 0.01, acts = "compression", damping_acts = "compression" }
"""

FRAMES = (0, 6, 12, 24)


def blender(script: str, *args: str) -> str:
    result = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


def corner_angle(points: np.ndarray) -> float:
    """The direction of the first vertex from the cloth's centre, about the vertical, in degrees."""
    d = points[0] - points.mean(axis=0)
    return math.degrees(math.atan2(d[1], d[0]))  # Blender: Z up


def test_blender_shot_simulated_and_read_back_by_blender(tmp_path: Path):
    blender(MAKE_SHOT, str(tmp_path / "shot.usda"))
    (tmp_path / "shot.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("run", "shot.toml", "--out", "out", cwd=tmp_path)
    assert code == 0, err
    assert "Z-up stage turned Y-up" in err  # Blender's stage is Z-up; the run said what it converted
    seen = json.loads(blender(READ_RESULT, str(tmp_path / "out" / "shot.shot.usda"), ",".join(map(str, FRAMES)),
                              "Plane,Cube").split("RESULT ", 1)[1])  # the sheet's and the table's, as Blender named them
    assert {"Sheet", "Table"} <= set(seen["objects"])  # the shot's own objects

    stage = Usd.Stage.Open(str(tmp_path / "out" / "shot.usdc"))
    ours = UsdGeom.Mesh(stage.GetPrimAtPath("/root/Sheet/Plane")).GetPointsAttr()  # the input's prim path
    shot = Usd.Stage.Open(str(tmp_path / "shot.usda"))
    table = UsdGeom.Mesh(shot.GetPrimAtPath("/root/Table/Cube"))
    blender_frames = {}
    for frame in FRAMES:
        y_up = np.asarray(ours.Get(frame), dtype=np.float64)
        expected = np.stack([y_up[:, 0], -y_up[:, 2], y_up[:, 1]], axis=1)  # our Y-up, as Blender's Z-up
        blender_frames[frame] = np.array(seen["frames"][str(frame)]["Plane"])
        np.testing.assert_allclose(blender_frames[frame], expected, atol=1e-5)
        to_world = np.asarray(table.ComputeLocalToWorldTransform(frame), dtype=np.float64)
        table_points = np.asarray(table.GetPointsAttr().Get(frame), dtype=np.float64)
        np.testing.assert_allclose(seen["frames"][str(frame)]["Cube"], table_points @ to_world[:3, :3] + to_world[3, :3],
                                   atol=1e-5)

    # What Blender sees is the simulation: the cloth fell onto the table (its top at 1 m, 1 cm thickness) ...
    assert blender_frames[0][:, 2].min() == pytest.approx(1.1, abs=1e-5)
    assert blender_frames[24][:, 2].min() == pytest.approx(1.01, abs=1e-3)
    # ... and turned with it by friction: as far as the table from frame 6 (landed) to 24, within 10%.
    table_turn = shot.GetPrimAtPath("/root/Table").GetAttribute("xformOp:rotateXYZ")
    turned_table = table_turn.Get(24)[2] - table_turn.Get(6)[2]
    turned_cloth = corner_angle(blender_frames[24]) - corner_angle(blender_frames[6])
    assert turned_cloth == pytest.approx(turned_table, rel=0.1)


GARMENT_FRAMES = (0, 7, 14)  # the seams pulled shut over the first 12 (close_time 0.5 s at 24 fps)


def test_the_garment_shot_opens_in_blender_with_the_skirt_sewn_round_the_body(tmp_path: Path):
    """``warp-cloth run garment`` writes the shot (scenes/garment.usda) with the simulated skirt layered over it;
    Blender imports it and sees both panels where our USD has them, the body where the shot animates it, and
    the panels' seams shut by frame 14, as the simulation left them."""
    code, out, err = run_cli_in_process("run", "garment", "--frames", str(GARMENT_FRAMES[-1]), "--out", "out",
                                        "--device", "cpu", cwd=tmp_path)
    assert code == 0, err
    seen = json.loads(blender(READ_RESULT, str(tmp_path / "out" / "garment.shot.usda"),
                              ",".join(map(str, GARMENT_FRAMES)), "Front,Back,Body").split("RESULT ", 1)[1])
    assert {"Front", "Back", "Body"} <= set(seen["objects"])

    def z_up(points) -> np.ndarray:  # the stage is Y-up; Blender turns it Z-up on import
        y_up = np.asarray(points, dtype=np.float64)
        return np.stack([y_up[:, 0], -y_up[:, 2], y_up[:, 1]], axis=1)

    ours = Usd.Stage.Open(str(tmp_path / "out" / "garment.usdc"))
    shot = Usd.Stage.Open(str(tmp_path / "out" / "garment.shot.usda"))
    body = UsdGeom.Mesh(shot.GetPrimAtPath("/World/Character/Body"))
    for frame in GARMENT_FRAMES:
        for panel in ("Front", "Back"):
            points = UsdGeom.Mesh(ours.GetPrimAtPath(f"/World/{panel}")).GetPointsAttr().Get(frame)
            np.testing.assert_allclose(seen["frames"][str(frame)][panel], z_up(points), atol=1e-5)
        to_world = np.asarray(body.ComputeLocalToWorldTransform(frame), dtype=np.float64)
        body_points = np.asarray(body.GetPointsAttr().Get(frame), dtype=np.float64) @ to_world[:3, :3] + to_world[3, :3]
        np.testing.assert_allclose(seen["frames"][str(frame)]["Body"], z_up(body_points), atol=1e-5)

    # the seams as Blender sees them: open at the start, shut (within a micrometre) once closed
    sewn = wc.Simulator(wc.load_scene("garment"), device="cpu").model.sewn.pairs
    front = len(seen["frames"]["0"]["Front"])

    def seam_gap(frame: int) -> float:
        points = np.array(seen["frames"][str(frame)]["Front"] + seen["frames"][str(frame)]["Back"])
        assert len(points) > front
        return float(np.linalg.norm(points[sewn[:, 0]] - points[sewn[:, 1]], axis=1).max())
    assert seam_gap(0) > 0.02 and seam_gap(GARMENT_FRAMES[-1]) < 1e-5
