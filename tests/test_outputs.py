"""USD and .poly output, opened and checked; an interrupted run keeps every finished frame."""

import dataclasses
import re
import signal
import subprocess
import sys
import time

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdValidation

import warp_cloth as wc
from conftest import REPO, with_simulation
from warp_cloth.writers.poly import format_poly


def validation_errors(stage: Usd.Stage) -> list[str]:
    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    return [e.GetMessage() for e in context.Validate(stage)
            if e.GetType() == UsdValidation.ValidationErrorType.Error]


def simulate_to_usd(scene: wc.Scene, path, frames: int) -> list[np.ndarray]:
    """Runs the scene with a USD writer and returns the positions of every frame, read independently."""
    sim = wc.Simulator(scene, device="cpu")
    recorded = []

    class Recorder:
        def begin(self, sim): pass
        def write_frame(self, sim, frame): recorded.append(sim.positions())
        def finish(self, sim, frames_written): pass

    sim.run(frames, writers=[wc.UsdWriter(path, scene.output.subdivision), Recorder()])
    return recorded


def test_usd_stage_has_metadata_topology_and_one_sample_per_frame(tmp_path):
    scene = with_simulation(wc.load_scene("sphere_push"), frames=12)
    path = tmp_path / "push.usdc"
    recorded = simulate_to_usd(scene, path, 12)
    stage = Usd.Stage.Open(str(path))
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path("/World")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 24 and stage.GetFramesPerSecond() == 24
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 12)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    assert mesh.GetPointsAttr().GetTimeSamples() == list(range(13))
    assert mesh.GetExtentAttr().GetTimeSamples() == list(range(13))
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    counts, indices = mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get()
    assert len(counts) == 100 and set(counts) == {4}
    assert UsdGeom.Mesh.ValidateTopology(indices, counts, 121)[0]
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.vertex and len(st.Get()) == 121
    for frame in (0, 5, 12):
        points = np.array(mesh.GetPointsAttr().Get(frame))
        np.testing.assert_array_equal(points, recorded[frame])
        extent = np.array(mesh.GetExtentAttr().Get(frame))
        np.testing.assert_array_equal(extent, [points.min(axis=0), points.max(axis=0)])
    sphere = UsdGeom.Sphere(stage.GetPrimAtPath("/World/ball"))
    translate = sphere.GetOrderedXformOps()[0].GetAttr()
    assert translate.GetTimeSamples() == list(range(13))
    motion = scene.spheres[0].motion
    for frame in (0, 7):
        expected = np.add(scene.spheres[0].center, motion.offset(frame / 24))
        np.testing.assert_allclose(np.array(translate.Get(frame)), expected, atol=1e-5)
    assert validation_errors(stage) == []


def test_validator_reports_a_broken_stage(tmp_path):
    """The check above would see a problem: a stage without a default prim or up axis is reported."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "bad.usda"))
    UsdGeom.Mesh.Define(stage, "/m")
    assert validation_errors(stage)


def test_usd_has_ground_static_sphere_and_catmull_clark_when_asked(tmp_path):
    scene = with_simulation(wc.load_scene("drape"), frames=2)
    scene = dataclasses.replace(scene, output=wc.Output(subdivision="catmullClark"))
    path = tmp_path / "drape.usdc"
    simulate_to_usd(scene, path, 2)
    stage = Usd.Stage.Open(str(path))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.catmullClark
    ground = UsdGeom.Mesh(stage.GetPrimAtPath("/World/ground"))
    assert np.allclose(np.array(ground.GetPointsAttr().Get())[:, 1], 0.0)
    ball = UsdGeom.Sphere(stage.GetPrimAtPath("/World/ball"))
    assert ball.GetRadiusAttr().Get() == 1.5
    assert ball.GetOrderedXformOps()[0].GetAttr().GetTimeSamples() == []
    assert validation_errors(stage) == []


def test_poly_format_is_points_polys_end_with_one_based_labels():
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.5]], dtype=np.float32)
    text = format_poly(points, np.array([4]), np.array([0, 1, 2, 3]))
    assert text == "POINTS\n1: 0 0 0\n2: 1 0 0\n3: 1 1 0\n4: 0 1 0.5\nPOLYS\n1: 1 2 3 4 <\nEND\n"


def test_poly_writer_writes_one_file_per_cloth_per_frame(tmp_path):
    scene = with_simulation(wc.load_scene("hanging"), frames=3)
    sim = wc.Simulator(scene, device="cpu")
    sim.run(3, writers=[wc.PolyWriter(tmp_path / "poly")])
    files = sorted(p.name for p in (tmp_path / "poly").iterdir())
    assert files == [f"cloth.{f:04d}.poly" for f in range(4)]
    text = (tmp_path / "poly" / "cloth.0003.poly").read_text()
    sections = re.split(r"^(POINTS|POLYS|END)$", text, flags=re.M)
    assert [s for s in sections if s in ("POINTS", "POLYS", "END")] == ["POINTS", "POLYS", "END"]
    point_lines = sections[2].strip().splitlines()
    assert len(point_lines) == 121
    xyz = np.array([[float(v) for v in line.split(":")[1].split()] for line in point_lines])
    np.testing.assert_allclose(xyz, sim.positions(), rtol=1e-6, atol=1e-6)
    assert len(sections[4].strip().splitlines()) == 100
    assert not (tmp_path / "poly.partial").exists()


def test_interrupted_run_leaves_a_valid_usd_with_every_finished_frame(tmp_path):
    command = [sys.executable, "-m", "warp_cloth", "run", "hanging", "--frames", "100000", "--no-poly",
               "--out", str(tmp_path), "--quiet"]
    process = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = tmp_path / "hanging.incomplete.usdc"
    deadline = time.monotonic() + 120
    while not partial.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.5)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "Traceback" not in err
    assert "interrupted after" in out
    stage = Usd.Stage.Open(str(tmp_path / "hanging.usdc"))
    end = int(stage.GetEndTimeCode())
    assert end >= 1
    written = int(re.search(r"interrupted after (\d+) of", out).group(1))
    assert end == written
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    assert mesh.GetPointsAttr().GetTimeSamples() == list(range(end + 1))
    assert np.isfinite(np.array(mesh.GetPointsAttr().Get(end))).all()
    assert validation_errors(stage) == []
    assert not partial.exists()
