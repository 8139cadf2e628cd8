"""A shot's clock is the run's: a USD shot keyed from time code 1001 is simulated and written at 1001 on,
``start`` and ``--start-frame`` move the run's first frame, ``preroll`` frames settle the cloth before it,
and a run stopped anywhere (in the preroll too) resumes to the frames of one that was not."""

import os
import signal
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli_in_process, with_simulation

FIRST, LAST, RISE = 1001, 1010, 0.3  # the shot's keys, and how far its box rises between them


def rising_box_shot(path: Path, start_code: bool = True) -> Path:
    """A 24 fps shot keyed as film pipelines key them: a 4 x 1 x 4 m box, its top at y = 0 at time code 1001,
    rising RISE metres by 1010 (keyed at both ends); the stage's start and end time codes are 1001 and 1010."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetTimeCodesPerSecond(24.0)
    if start_code:
        stage.SetStartTimeCode(FIRST)
        stage.SetEndTimeCode(LAST)
    translate = UsdGeom.Xform.Define(stage, "/World/Mover").AddTranslateOp()
    translate.Set((0.0, 0.0, 0.0), FIRST)
    translate.Set((0.0, RISE, 0.0), LAST)
    box = UsdGeom.Mesh.Define(stage, "/World/Mover/Box")
    box.CreatePointsAttr([(x, y, z) for z in (-2.0, 2.0) for y in (-1.0, 0.0) for x in (-2.0, 2.0)])
    box.CreateFaceVertexCountsAttr([4] * 6)
    box.CreateFaceVertexIndicesAttr([0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5])
    stage.Save()
    return path


def cloth_over_box(shot: Path, height: float = 0.01, **simulation) -> wc.Scene:
    cloth = wc.Cloth(resolution=(6, 6), size=(1.2, 1.2), orientation="horizontal", origin=(-0.6, height, 0.6),
                     density=0.2, limit=wc.Limit(0.1, 0.1), structural=wc.SpringKind(15.0, 0.02),
                     shear=wc.SpringKind(15.0, 0.02))
    box = wc.MeshCollider(name="box", mesh=wc.MeshSource(str(shot), "/World/Mover/Box"), thickness=0.01)
    settings = dict(fps=24, frames=LAST - FIRST, substeps=40, integrator="symplectic", limit_solve="converged")
    return wc.Scene(name="shot", cloths=(cloth,), colliders=(box,), simulation=wc.Simulation(**{**settings,
                                                                                               **simulation}))


def samples(stage: Usd.Stage, path: str) -> list[float]:
    return UsdGeom.Mesh(stage.GetPrimAtPath(path)).GetPointsAttr().GetTimeSamples()


def scene_file(folder: Path, shot: Path, simulation: str = "", height: float = 0.01) -> Path:
    path = folder / "shot.toml"
    path.write_text(f'[simulation]\nfps = 24\nframes = 3\n{simulation}\n'
                    f'[[collider]]\nname = "box"\nmesh = {{ file = "{shot.name}", prim = "/World/Mover/Box" }}\n'
                    f'[[cloth]]\nresolution = [6, 6]\nsize = [1.2, 1.2]\norientation = "horizontal"\n'
                    f'origin = [-0.6, {height}, 0.6]\ndensity = 0.2\nlimit = {{ stretch = 0.1, compression = 0.1 }}\n')
    return path


def test_a_shot_keyed_from_1001_is_simulated_and_written_on_its_clock(tmp_path):
    shot = rising_box_shot(tmp_path / "shot.usda")
    sim = wc.Simulator(cloth_over_box(shot), device="cpu")
    assert sim.frame == FIRST and sim.time == pytest.approx(FIRST / 24)
    writer = wc.UsdWriter(tmp_path / "out.usdc")
    sim.run(writers=[writer])
    # The box rose during the run and lifted the cloth resting on it (a thickness above its top).
    assert sim.positions()[:, 1].min() == pytest.approx(RISE + 0.01, abs=3e-3)
    stage = Usd.Stage.Open(str(tmp_path / "out.usdc"))
    codes = [float(f) for f in range(FIRST, LAST + 1)]
    assert samples(stage, "/World/cloth") == codes and samples(stage, "/World/Mover/Box") == codes
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (FIRST, LAST)
    layer = Usd.Stage.Open(str(tmp_path / "out.shot.usda"))
    assert (layer.GetStartTimeCode(), layer.GetEndTimeCode()) == (FIRST, LAST)


def test_a_shot_without_a_start_time_code_starts_at_0(tmp_path):
    scene = cloth_over_box(rising_box_shot(tmp_path / "shot.usda", start_code=False))
    assert wc.Simulator(scene, device="cpu").frame == 0


def test_start_overrides_the_shots_and_puts_the_colliders_where_the_shot_has_them_then(tmp_path):
    shot = rising_box_shot(tmp_path / "shot.usda")
    sim = wc.Simulator(cloth_over_box(shot, height=0.5, start=1005, frames=2), device="cpu")
    assert sim.frame == 1005
    # the box starts where the shot has it at 1005, four ninths of its way up
    assert sim.model.mesh_colliders.points[0][:, 1].max() == pytest.approx(RISE * 4 / 9, abs=1e-6)
    sim.run(writers=[wc.UsdWriter(tmp_path / "out.usdc")])
    stage = Usd.Stage.Open(str(tmp_path / "out.usdc"))
    assert samples(stage, "/World/cloth") == [1005.0, 1006.0, 1007.0]
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1005, 1007)


def test_start_frame_on_the_command_line_numbers_the_usd_and_poly_frames(tmp_path):
    scene = scene_file(tmp_path, rising_box_shot(tmp_path / "shot.usda"), height=0.5)
    code, out, err = run_cli_in_process("run", str(scene), "--start-frame", "1003", "--out", "out", "--quiet",
                                        "--device", "cpu", cwd=tmp_path)
    assert code == 0, err
    stage = Usd.Stage.Open(str(tmp_path / "out" / "shot.usdc"))
    assert samples(stage, "/World/cloth") == [1003.0, 1004.0, 1005.0, 1006.0]
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1003, 1006)
    assert sorted(p.name for p in (tmp_path / "out" / "shot" / "poly").iterdir()) == \
        [f"cloth.{f}.poly" for f in range(1003, 1007)]


def test_a_preroll_settles_the_cloth_before_the_first_written_frame_with_the_colliders_held(tmp_path):
    """A preroll of 3 frames before 1001 is a run from 998 whose frames before 1001 are not written; the
    box, keyed from 1001 only, is held at its first key meanwhile."""
    shot = rising_box_shot(tmp_path / "shot.usda")
    prerolled = wc.Simulator(cloth_over_box(shot, height=0.2, preroll=3, frames=3), device="cpu")
    assert prerolled.frame == 998
    initial = prerolled.positions()
    usd, poly = wc.UsdWriter(tmp_path / "out.usdc"), wc.PolyWriter(tmp_path / "poly")
    summary = prerolled.run(writers=[usd, poly])
    assert summary.frames == 6 and prerolled.frame == 1004
    stage = Usd.Stage.Open(str(tmp_path / "out.usdc"))
    assert samples(stage, "/World/cloth") == [1001.0, 1002.0, 1003.0, 1004.0]  # nothing before the start
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1001, 1004)
    assert sorted(p.name for p in (tmp_path / "poly").iterdir()) == [f"cloth.{f}.poly" for f in range(1001, 1005)]
    first_written = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth")).GetPointsAttr().Get(1001))

    alone = wc.Simulator(cloth_over_box(shot, height=0.2, start=998, frames=6), device="cpu")
    assert alone.frame == 998
    np.testing.assert_array_equal(alone.positions(), initial)
    np.testing.assert_allclose(alone.model.mesh_colliders.points[0][:, 1].max(), 0.0, atol=1e-7)  # held
    for _ in range(3):
        alone.step()
    np.testing.assert_array_equal(first_written, alone.positions())
    assert first_written[:, 1].max() < initial[:, 1].max() - 0.01  # the cloth fell in the preroll


@pytest.mark.parametrize("stop_at", [1000, 1002], ids=["in-the-preroll", "after-the-start"])
def test_a_run_with_a_preroll_stopped_anywhere_resumes_to_the_frames_of_one_that_was_not(tmp_path, monkeypatch,
                                                                                         stop_at):
    shot = rising_box_shot(tmp_path / "shot.usda")
    scene = scene_file(tmp_path, shot, simulation="preroll = 3", height=0.2)
    ran = ("run", str(scene), "--quiet", "--device", "cpu")
    code, _, err = run_cli_in_process(*ran, "--out", "reference", cwd=tmp_path)
    assert code == 0, err

    launch = wc.Simulator._launch_frame

    def stopping(self):
        frame = launch(self)
        if frame == stop_at:
            os.kill(os.getpid(), signal.SIGTERM)  # the run stops after this frame
        return frame

    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 0.0)  # a checkpoint after every frame
    monkeypatch.setattr(wc.Simulator, "_launch_frame", stopping)
    code, out, err = run_cli_in_process(*ran, "--out", "out", cwd=tmp_path)
    assert code == 128 + signal.SIGTERM and "--resume" in out + err, err
    monkeypatch.setattr(wc.Simulator, "_launch_frame", launch)
    code, out, err = run_cli_in_process(*ran, "--out", "out", "--resume", cwd=tmp_path)
    assert code == 0, err
    assert f"resumed at frame {stop_at}" in out
    expected = Usd.Stage.Open(str(tmp_path / "reference" / "shot.usdc"))
    got = Usd.Stage.Open(str(tmp_path / "out" / "shot.usdc"))
    assert samples(got, "/World/cloth") == samples(expected, "/World/cloth") == [1001.0, 1002.0, 1003.0, 1004.0]
    for code in range(1001, 1005):
        np.testing.assert_array_equal(
            np.asarray(UsdGeom.Mesh(got.GetPrimAtPath("/World/cloth")).GetPointsAttr().Get(code)),
            np.asarray(UsdGeom.Mesh(expected.GetPrimAtPath("/World/cloth")).GetPointsAttr().Get(code)))
    assert sorted(p.name for p in (tmp_path / "out" / "shot" / "poly").iterdir()) == \
        [f"cloth.{f}.poly" for f in range(1001, 1005)]
    assert not (tmp_path / "out" / "shot.checkpoint.npz").exists()


@pytest.mark.parametrize("simulation, options, expected", [
    ("start = 1.5", (), "simulation.start: expected a whole number, got 1.5"),
    ("preroll = -1", (), "simulation.preroll: expected a whole number in [0, 1000000], got -1"),
    ("start = 2000000", (), "simulation.start: expected a whole number in [-1000000, 1000000], got 2000000"),
    ("", ("--preroll", "-2"), "--preroll: expected a whole number in [0, 1000000], got -2"),
    ("", ("--start-frame", "-2000000"), "--start-frame: expected a whole number in [-1000000, 1000000], got -2000000"),
])
def test_bad_start_and_preroll_are_one_line_and_nothing_is_written(tmp_path, simulation, options, expected):
    scene = scene_file(tmp_path, rising_box_shot(tmp_path / "shot.usda"), simulation=simulation)
    code, _, err = run_cli_in_process("run", str(scene), *options, "--out", "out", "--device", "cpu", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
    assert not (tmp_path / "out").exists()


def test_a_scene_without_a_shot_keeps_frame_0_as_its_first(tmp_path):
    scene = with_simulation(wc.load_scene("hanging"), frames=2)
    sim = wc.Simulator(scene, device="cpu")
    assert sim.frame == 0
    sim.run(writers=[wc.UsdWriter(tmp_path / "out.usdc")])
    stage = Usd.Stage.Open(str(tmp_path / "out.usdc"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 2)


def test_a_batch_world_with_a_preroll_writes_the_frames_its_scene_alone_writes(tmp_path):
    scene = cloth_over_box(rising_box_shot(tmp_path / "shot.usda"), height=0.2, preroll=2, frames=2)
    wc.Simulator(scene, device="cpu").run(writers=[wc.UsdWriter(tmp_path / "alone.usdc")])
    wc.Batch([scene]).run(2, writers={0: [wc.UsdWriter(tmp_path / "world.usdc")]})
    alone, world = (Usd.Stage.Open(str(tmp_path / f"{name}.usdc")) for name in ("alone", "world"))
    assert samples(world, "/World/cloth") == samples(alone, "/World/cloth") == [1001.0, 1002.0, 1003.0]
    for code in (1001, 1003):
        np.testing.assert_array_equal(
            np.asarray(UsdGeom.Mesh(world.GetPrimAtPath("/World/cloth")).GetPointsAttr().Get(code)),
            np.asarray(UsdGeom.Mesh(alone.GetPrimAtPath("/World/cloth")).GetPointsAttr().Get(code)))
