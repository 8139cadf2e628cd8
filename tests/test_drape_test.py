"""The Cusick drape test: the drape coefficient of known projections (a flat specimen: 1; a cone: its
closed form), the specimen's mesh, ``warp-cloth drape-test``'s JSON and refusals, and that a stiffer
fabric drapes less."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from conftest import run_cli_in_process
from warp_cloth import drape_geometry as geometry
from warp_cloth.drape_test import run_drape_test
from warp_cloth.materials import Material

REQUIRED = {"material", "drape_coefficient", "published_range", "source", "resolution", "seconds"}


@pytest.mark.parametrize("resolution", [8, 30, 61])
def test_the_specimen_is_a_disc_of_quads_inside_and_triangles_round_its_rim(resolution):
    specimen = geometry.specimen(resolution)
    triangles = specimen.triangles()
    p = specimen.points
    normals = np.cross(p[triangles[:, 1]] - p[triangles[:, 0]], p[triangles[:, 2]] - p[triangles[:, 0]])
    assert (normals[:, 1] > 0).all()  # every face faces +Y, none folded over
    rim = geometry.SPECIMEN_DIAMETER / 2
    count = math.ceil(2 * math.pi * rim / (geometry.SPECIMEN_DIAMETER / resolution))
    polygon = count / 2 * rim ** 2 * math.sin(2 * math.pi / count)
    assert specimen.area == pytest.approx(polygon, rel=1e-12)  # the faces tile the rim's polygon exactly
    assert np.hypot(p[:, 0], p[:, 2]).max() == pytest.approx(rim, rel=1e-12)
    # every point within sqrt(2) cells of the kept corners' circle lies in a kept cell: a quad
    from warp_cloth.mesh_io import face_areas

    quads = face_areas(p, specimen.face_counts, specimen.face_indices)[specimen.face_counts == 4].sum()
    cell = geometry.SPECIMEN_DIAMETER / resolution
    assert quads >= math.pi * (rim - (geometry.BORDER + math.sqrt(2)) * cell) ** 2


def test_a_flat_specimen_has_a_drape_coefficient_of_one():
    specimen = geometry.specimen(30)
    projection = geometry.projected_area(specimen.points, specimen.triangles())
    coefficient = geometry.drape_coefficient(projection.area, specimen.area)
    bound = projection.error / (specimen.area - geometry.SUPPORT_AREA)
    assert bound < 0.01
    assert abs(coefficient - 1.0) <= bound


@pytest.mark.parametrize("angle", [30.0, 60.0, 85.0])
def test_a_cone_hanging_off_the_support_has_its_closed_form_coefficient(angle):
    """The overhang turned down at ``angle`` about the support's edge, each point moved along its radius:
    the shadow is the rim's polygon scaled by f(R) / R, f(r) = r_d + (r - r_d) cos(angle)."""
    specimen = geometry.specimen(30)
    points = specimen.points.copy()
    r = np.hypot(points[:, 0], points[:, 2])
    r_d = geometry.SUPPORT_DIAMETER / 2
    over = np.maximum(r - r_d, 0.0)
    scale = np.where(r > 0, (r - over + over * math.cos(math.radians(angle))) / np.maximum(r, 1e-30), 1.0)
    points[:, 0] *= scale
    points[:, 2] *= scale
    points[:, 1] = -over * math.sin(math.radians(angle))
    projection = geometry.projected_area(points, specimen.triangles())
    rim = geometry.SPECIMEN_DIAMETER / 2
    shadow = specimen.area * ((r_d + (rim - r_d) * math.cos(math.radians(angle))) / rim) ** 2
    expected = geometry.drape_coefficient(shadow, specimen.area)
    measured = geometry.drape_coefficient(projection.area, specimen.area)
    assert abs(measured - expected) <= projection.error / (specimen.area - geometry.SUPPORT_AREA)
    assert abs(measured - expected) < 0.005


def test_the_command_writes_the_result_and_a_picture(tmp_path):
    code, out, err = run_cli_in_process("drape-test", "cotton", "--device", "cpu", "--resolution", "8",
                                        "--frames", "4", "--json", "out.json", "--picture", "top.png",
                                        "--quiet", cwd=tmp_path)
    assert code == 0, err
    document = json.loads((tmp_path / "out.json").read_text())
    assert REQUIRED <= set(document)
    assert document["material"] == "cotton" and document["resolution"] == 8 and document["frames"] == 4
    assert 0.0 < document["drape_coefficient"] <= 1.0 + document["coefficient_error"]
    assert document["settled"] is False  # 4 frames: still falling
    assert (tmp_path / "top.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.count("\n") == 1 and out.startswith("cotton: drape coefficient")


@pytest.mark.parametrize("args, key", [
    (["velvet"], "MATERIAL"),
    (["no-such-file.toml"], "MATERIAL"),
    (["cotton", "--resolution", "2"], "--resolution"),
    (["cotton", "--frames", "0"], "--frames"),
    (["cotton", "--device", "tpu"], "--device"),
    (["cotton", "--picture", "top.jpg"], "--picture"),
])
def test_bad_input_is_refused_in_one_line_and_nothing_is_written(tmp_path, args, key):
    code, out, err = run_cli_in_process("drape-test", *args, "--json", "out.json", cwd=tmp_path)
    assert code == 2
    assert err.count("\n") == 1 and key in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, key", [(["cotton", "--resolution", "ten"], "--resolution"), (["cotton"], "--json")])
def test_malformed_arguments_are_refused_in_one_line(tmp_path, args, key):
    result = subprocess.run([sys.executable, "-m", "warp_cloth", "drape-test", *args], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and key in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_material_file_is_read_and_its_errors_name_the_key(tmp_path):
    (tmp_path / "stiff.toml").write_text('preset = "cotton"\nbending = 1e-3\n')
    (tmp_path / "bad.toml").write_text('preset = "cotton"\nbending = -1.0\n')
    code, out, err = run_cli_in_process("drape-test", "bad.toml", "--json", "out.json", cwd=tmp_path)
    assert code == 2 and "bending" in err and "bad.toml" in err
    code, out, err = run_cli_in_process("drape-test", "stiff.toml", "--device", "cpu", "--resolution", "8",
                                        "--frames", "2", "--json", "out.json", "--quiet", cwd=tmp_path)
    assert code == 0, err
    document = json.loads((tmp_path / "out.json").read_text())
    assert document["material"] == "stiff" and document["published_range"] is None  # not the preset as measured


def test_a_stiffer_fabric_drapes_less():
    """Cotton against cotton ten times as stiff in bending, at 12 cells across after 1 s: the stiffer's
    overhang stands further out (0.87 against 0.22 with the bending stencils; 0.54 against 0.13 with the bend
    springs before them). Both coefficients lie inside (0, 1)."""
    soft = run_drape_test(Material(preset="cotton"), "cotton", 12, "cpu", frames=24)
    stiff_bending = tuple(10 * b for b in Material(preset="cotton").bending)
    stiff = run_drape_test(Material(preset="cotton", bending=stiff_bending), "stiff", 12, "cpu", frames=24)
    assert 0.0 < soft.drape_coefficient < stiff.drape_coefficient < 1.0
    assert stiff.drape_coefficient - soft.drape_coefficient > 5 * (soft.coefficient_error + stiff.coefficient_error)
