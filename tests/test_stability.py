"""Hard cases stay numerically stable, and the blow-up guard reports the ones that do not."""

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli, with_simulation
from warp_cloth.errors import UnstableSimulation


def test_guard_names_frame_and_substep_and_suggests_a_fix():
    scene = with_simulation(wc.load_scene("hanging"), dt=0.0104)
    sim = wc.Simulator(scene, device="cpu")
    with pytest.raises(UnstableSimulation) as info:
        for _ in range(240):
            sim.step()
    error = info.value
    assert 1 <= error.frame <= 24 and 1 <= error.substep <= sim.substeps_per_frame
    assert f"frame {error.frame}, substep {error.substep}" in str(error)
    assert "--integrator implicit" in str(error) and "smaller step" in str(error)


def test_unstable_run_keeps_every_written_frame_valid_and_writes_no_nan(tmp_path):
    result = run_cli("run", "hanging", "--dt", "0.0104", "--out", str(tmp_path), "--quiet", cwd=tmp_path)
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr and "unstable at frame" in result.stderr
    stage = Usd.Stage.Open(str(tmp_path / "hanging.usdc"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
    samples = mesh.GetPointsAttr().GetTimeSamples()
    assert samples == list(range(int(stage.GetEndTimeCode()) + 1)) and len(samples) >= 2
    for t in samples:
        assert np.isfinite(np.array(mesh.GetPointsAttr().Get(t))).all()
    polys = sorted((tmp_path / "hanging" / "poly").iterdir())
    assert len(polys) == len(samples)
    assert all("nan" not in p.read_text().lower() for p in polys)
