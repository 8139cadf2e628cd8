"""Output safety: a run removes and replaces only what it made, a failed or stopped run keeps the previous
output and puts its own frames beside it, a full disk ends with a message, two runs cannot write the same
output, and a killed run can be resumed to the same frames an uninterrupted run makes."""

import contextlib
import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

import warp_cloth as wc
from conftest import (REPO, assert_restored_run_continues, lock_held_by_another_process, run_cli,
                      run_cli_in_process, with_simulation)
from warp_cloth.output import OutputError, OutputLock, first_free, labelled

FOLD_AROUND_A_MOVING_SPHERE = """
description = "a small cloth folding onto itself and the ground, pushed by a moving sphere"
[simulation]
fps = 24
frames = 60
dt = 0.0025
integrator = "symplectic"
[collision]
self = true
iterations = 4
[ground]
height = 0.0
friction = 0.5
[[sphere]]
name = "ball"
center = [0.0, 0.5, 1.5]
radius = 0.5
motion = { axis = [0.0, 0.0, 1.0], amplitude = 1.0, frequency = 0.5, phase = 0.0 }
[[cloth]]
name = "cloth"
resolution = [16, 16]
size = [4.0, 4.0]
orientation = "vertical"
rotation = [20.0, 0.0, 0.0]
origin = [-2.0, 0.3, 0.0]
density = 0.2
jitter = 0.05
limit = { stretch = 0.1, compression = 0.1 }
structural = { stiffness = 15.0, damping = 0.02 }
shear = { stiffness = 15.0, damping = 0.02 }
bend = { stiffness = 5.0, damping = 0.01, acts = "compression", damping_acts = "compression" }
"""


def usd_points(path: Path) -> list[np.ndarray]:
    stage = Usd.Stage.Open(str(path))
    attr = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth")).GetPointsAttr()
    return [np.array(attr.Get(t)) for t in attr.GetTimeSamples()]


def run_here(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``run_cli``'s answer from ``run_cli_in_process``: the same command without a Python to start."""
    code, out, err = run_cli_in_process(*args, cwd=cwd)
    return subprocess.CompletedProcess(args, code, out, err)


def one_error_line(result: subprocess.CompletedProcess, warned: bool = False) -> str:
    """The one line of a failed run's standard error (after the step warning, where ``warned``)."""
    lines = result.stderr.splitlines()
    if warned:
        assert lines.pop(0).startswith("warp-cloth: warning: command line: substeps = 1 gives a step of")
    assert "Traceback" not in result.stderr
    assert len([line for line in lines if line.strip()]) == 1, result.stderr
    return lines[0]


def files_under(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# Item 2: --poly DIR keeps what the run did not write


def test_poly_folder_keeps_the_users_files_and_the_usd_of_the_same_run(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "main.c").write_text("int main;")
    result = run_here("run", "hanging", "--frames", "3", "--out", str(tmp_path), "--poly", str(tmp_path), "--quiet",
                      cwd=REPO)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert (tmp_path / "src" / "main.c").read_text() == "int main;"
    assert len(usd_points(tmp_path / "hanging.usdc")) == 4
    assert sorted(p.name for p in tmp_path.glob("*.poly")) == [f"cloth.{f:04d}.poly" for f in range(4)]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["notes.txt", "src", "hanging.usdc"] + [f"cloth.{f:04d}.poly" for f in range(4)])


def test_poly_frames_replace_only_files_of_the_same_names(tmp_path):
    poly = tmp_path / "poly"
    poly.mkdir()
    (poly / "cloth.0001.poly").write_text("an older frame")
    (poly / "other.0001.poly").write_text("another cloth's frame")
    sim = wc.Simulator(with_simulation(wc.load_scene("hanging"), frames=2), device="cpu")
    sim.run(2, writers=[wc.PolyWriter(poly)])
    assert (poly / "other.0001.poly").read_text() == "another cloth's frame"
    assert (poly / "cloth.0001.poly").read_text().startswith("POINTS\n")
    assert not (tmp_path / "poly.incomplete").exists()


# Item 3: a failed run leaves the previous output in place and its own frames beside it


def test_unstable_run_keeps_the_previous_output_and_its_frames_beside_it(tmp_path):
    good = run_here("run", "hanging", "--frames", "4", "--out", str(tmp_path), "--quiet", cwd=REPO)
    assert good.returncode == 0, good.stderr
    before = files_under(tmp_path)
    bad = run_here("run", "hanging", "--frames", "40", "--substeps", "1", "--out", str(tmp_path), "--quiet", cwd=REPO)
    assert bad.returncode == 3
    line = one_error_line(bad, warned=True)
    failed_usd, failed_poly = tmp_path / "hanging.failed.usdc", tmp_path / "hanging" / "poly.failed"
    assert str(failed_usd) in line and str(failed_poly) in line
    assert {k: v for k, v in files_under(tmp_path).items() if k in before} == before
    last_good = int(line.split("Kept frames 0 to ")[1].split()[0])
    frames = usd_points(failed_usd)
    assert len(frames) == last_good + 1 and all(np.isfinite(p).all() for p in frames)
    assert len(list(failed_poly.glob("*.poly"))) == last_good + 1
    assert not list(tmp_path.rglob("*.incomplete*")) and not list(tmp_path.rglob("*.lock"))


def test_labelled_names_say_what_they_are_and_never_reuse_a_taken_one(tmp_path):
    assert labelled(Path("out/shot.usda"), "incomplete", ".usdc") == Path("out/shot.incomplete.usdc")
    assert labelled(Path("renders/shot.v2"), "failed") == Path("renders/shot.v2.failed")  # a folder keeps its dots
    (tmp_path / "hanging.failed.usdc").write_text("")
    (tmp_path / "hanging.failed.2.usdc").write_text("")
    assert first_free(tmp_path / "hanging.usdc", "failed", ".usdc") == tmp_path / "hanging.failed.3.usdc"


class RaiseAt:
    def __init__(self, frame: int, error: BaseException) -> None:
        self.frame, self.error = frame, error

    def begin(self, sim): pass

    def write_frame(self, sim, frame):
        if frame == self.frame:
            raise self.error

    def finish(self, sim, frames_written): pass


@pytest.mark.parametrize("error", [RuntimeError("a writer's bug"), OSError(errno.ENOSPC, "No space left on device")])
def test_a_writer_that_raises_keeps_the_previous_output(tmp_path, error):
    scene = with_simulation(wc.load_scene("hanging"), frames=3)
    usd, poly = tmp_path / "hanging.usdc", tmp_path / "poly"
    wc.Simulator(scene, device="cpu").run(3, writers=[wc.UsdWriter(usd), wc.PolyWriter(poly)])
    before = files_under(tmp_path)
    with pytest.raises(type(error)):
        wc.Simulator(scene, device="cpu").run(8, writers=[wc.UsdWriter(usd), wc.PolyWriter(poly), RaiseAt(5, error)])
    assert {k: v for k, v in files_under(tmp_path).items() if k in before} == before
    assert len(usd_points(tmp_path / "hanging.failed.usdc")) == 6  # frames 0 to 5: the stage keeps them
    assert sorted(p.name for p in (tmp_path / "poly.failed").iterdir()) == [f"cloth.{f:04d}.poly" for f in range(6)]


def test_a_second_failure_does_not_replace_the_first_ones_frames(tmp_path):
    # Without a checkpoint writer nothing holds a second run back (under the CLI, a failure that keeps its
    # checkpoint refuses a fresh run instead: see the checkpoint tests below).
    scene = with_simulation(wc.load_scene("hanging"), frames=3)
    usd = tmp_path / "hanging.usdc"
    for _ in range(2):
        with pytest.raises(RuntimeError):
            wc.Simulator(scene, device="cpu").run(3, writers=[wc.UsdWriter(usd), RaiseAt(2, RuntimeError())])
    assert (tmp_path / "hanging.failed.usdc").exists() and (tmp_path / "hanging.failed.2.usdc").exists()
    assert not usd.exists()


# Item 4: a full disk ends the run with a message, every saved frame readable


def test_usd_save_is_refused_before_the_disk_is_full(tmp_path, monkeypatch):
    import warp_cloth.output as output

    scene = with_simulation(wc.load_scene("hanging"), frames=6)
    path = tmp_path / "hanging.usdc"
    wc.Simulator(scene, device="cpu").run(2, writers=[wc.UsdWriter(path)])
    before = path.read_bytes()
    free = {"bytes": 10**12}

    class FillDiskAt(RaiseAt):
        def write_frame(self, sim, frame):
            if frame == self.frame:
                free["bytes"] = 1000

    monkeypatch.setattr(output, "free_bytes", lambda folder: free["bytes"])
    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 0.0)  # save as often as the run allows
    with pytest.raises(OutputError, match="not enough free space"):
        wc.Simulator(scene, device="cpu").run(6, writers=[FillDiskAt(3, None), wc.UsdWriter(path)])
    assert path.read_bytes() == before
    frames = usd_points(tmp_path / "hanging.failed.usdc")
    # the first sync (after frame 1) saved frames 0 and 1; frame 2 too if it was synced before frame 3 filled the disk
    assert 2 <= len(frames) <= 3 and all(np.isfinite(p).all() for p in frames)


def test_a_full_disk_under_the_cli_ends_with_exit_4_and_one_line(tmp_path, monkeypatch, capsys):
    from warp_cloth.cli import main
    from warp_cloth.writers.poly import PolyWriter

    write_frame = PolyWriter.write_frame

    def fill_at_frame_3(self, sim, frame):
        if frame == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        write_frame(self, sim, frame)

    monkeypatch.setattr(PolyWriter, "write_frame", fill_at_frame_3)
    assert main(["run", "hanging", "--frames", "6", "--out", str(tmp_path), "--quiet"]) == 4
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "No space left on device" in err
    # it failed before its first sync: there is no checkpoint, so --resume is not offered
    assert "--resume" not in err and not (tmp_path / "hanging.checkpoint.npz").exists()
    assert len(usd_points(tmp_path / "hanging.failed.usdc")) == 4  # the USD writer had frame 3 already
    assert len(list((tmp_path / "hanging" / "poly.failed").iterdir())) == 3
    assert not (tmp_path / "hanging.usdc").exists() and not (tmp_path / "hanging" / "poly").exists()


@contextlib.contextmanager
def small_disk(folder: Path, size: str):
    folder.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


@pytest.mark.parametrize("poly", [False, True])
def test_full_disk_ends_the_run_with_a_message_and_readable_frames(tmp_path, poly):
    with small_disk(tmp_path / "disk", "600k") as disk:
        result = run_cli("run", "hanging", "--frames", "2000", "--out", str(disk), "--quiet",
                         *([] if poly else ["--no-poly"]), cwd=REPO)
        assert result.returncode == 4, result.stderr
        line = one_error_line(result)
        assert "could not write the output" in line
        # --resume is offered exactly where the run left a checkpoint to go on from
        assert ("--resume" in line) == (disk / "hanging.checkpoint.npz").exists()
        frames = usd_points(disk / "hanging.failed.usdc")
        assert len(frames) >= 2 and all(np.isfinite(p).all() for p in frames)
        if poly:
            written = sorted((disk / "hanging" / "poly.failed").iterdir())
            assert written and all(p.read_text().endswith("END\n") for p in written)
        assert not list(disk.rglob("*.incomplete*")) and not list(disk.rglob("*.lock"))


# Item 5: two runs cannot write the same output


def test_a_second_run_on_the_same_output_is_refused_at_once(tmp_path):
    lock = OutputLock(tmp_path / "hanging.usdc")
    lock.acquire("usd")
    try:
        started = time.monotonic()
        result = run_cli("run", "hanging", "--frames", "3", "--out", str(tmp_path), "--quiet", cwd=REPO)
        assert result.returncode == 2
        line = one_error_line(result)
        assert f"process id {os.getpid()}" in line and "hanging.usdc" in line
        assert sorted(p.name for p in tmp_path.iterdir()) == ["hanging.lock"]
        assert time.monotonic() - started < 60
    finally:
        lock.release()


def test_a_lock_left_by_a_dead_run_is_taken_over(tmp_path):
    (tmp_path / "hanging.lock").write_text("999999\n")
    result = run_here("run", "hanging", "--frames", "3", "--out", str(tmp_path), "--no-poly", "--quiet", cwd=REPO)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hanging.usdc"]


# Item 6: SIGTERM and SIGHUP stop like Ctrl-C; a killed run resumes to the same frames


def start_run(*args: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "warp_cloth", "run", *args], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(path: Path, process: subprocess.Popen, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.05)


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_after_a_frame_like_ctrl_c(tmp_path, stop):
    previous = run_here("run", "hanging", "--frames", "2", "--out", str(tmp_path), "--quiet", cwd=REPO)
    assert previous.returncode == 0
    before = files_under(tmp_path)
    process = start_run("hanging", "--frames", "100000", "--out", str(tmp_path), "--quiet")
    wait_for(tmp_path / "hanging.checkpoint.npz", process)
    process.send_signal(stop)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 128 + stop, err
    assert "Traceback" not in err
    assert f"by {signal.Signals(stop).name}" in out and "--resume" in out
    assert {k: v for k, v in files_under(tmp_path).items() if k in before} == before  # a complete result stays
    frames = usd_points(tmp_path / "hanging.interrupted.usdc")
    assert len(frames) > 2 and all(np.isfinite(p).all() for p in frames)
    assert len(list((tmp_path / "hanging" / "poly.interrupted").iterdir())) == len(frames)
    assert not list(tmp_path.rglob("*.incomplete*")) and not list(tmp_path.rglob("*.lock"))


def scene_file(tmp_path: Path) -> Path:
    path = tmp_path / "fold_push.toml"
    path.write_text(FOLD_AROUND_A_MOVING_SPHERE)
    return path


@pytest.mark.parametrize("make_scene", [
    lambda tmp: wc.load_scene(scene_file(tmp)),
    lambda tmp: wc.load_scene("oscillating_pins"),
    lambda tmp: with_simulation(wc.load_scene("hanging"), integrator="implicit", dt=1 / 96),
    lambda tmp: with_simulation(wc.load_scene("hanging"), compensated=True),
    lambda tmp: wc.load_scene("seed_default"),
], ids=["collision-and-moving-sphere", "oscillating-pins", "implicit", "compensated", "edge-contacts"])
def test_a_restored_simulator_makes_the_same_frames(tmp_path, make_scene):
    scene = make_scene(tmp_path)
    sim = wc.Simulator(scene, device="cpu")
    for _ in range(6):
        sim.step()
    restored = wc.Simulator(scene, device="cpu")
    assert_restored_run_continues(sim, restored, tmp_path / "state.npz")
    assert (restored.frame, restored.time) == (12, 12 * scene.simulation.substeps_per_frame * scene.simulation.time_step)


def test_restore_refuses_a_checkpoint_of_another_scene(tmp_path):
    scene = with_simulation(wc.load_scene("hanging"), frames=3)
    sim = wc.Simulator(scene, device="cpu")
    sim.step()
    sim.save_checkpoint(tmp_path / "state.npz")
    other = wc.Simulator(with_simulation(scene, substeps=30, dt=None), device="cpu")
    with pytest.raises(wc.SceneError, match="changed since"):
        other.restore(tmp_path / "state.npz")


def test_a_checkpoint_taken_where_the_next_line_round_goes_backwards_continues_the_same_frames(tmp_path):
    """The line rounds take the families forwards and backwards in turn, carried across substeps and frames:
    a checkpoint keeps the order, so a run restored at a frame where an odd number of rounds has gone makes
    the frames the run it was taken from makes."""
    scene = with_simulation(wc.load_scene("hanging"), frames=60)
    sim = wc.Simulator(scene, device="cpu")
    backwards = lambda: sim.state.lines_backwards.numpy()[0]  # noqa: E731
    while backwards() == 0:
        sim.step()
        assert sim.frame < 40, "no frame of hanging ended with an odd number of line rounds"
    sim.save_checkpoint(tmp_path / "state.npz")
    expected = []
    while backwards() == 1:  # until the next round has gone, backwards
        sim.step()
        expected.append(sim.positions())
        assert sim.frame < 60, "no line round after the checkpoint"
    restored = wc.Simulator(scene, device="cpu")
    restored.restore(tmp_path / "state.npz")
    for x in expected:
        restored.step()
        np.testing.assert_array_equal(restored.positions(), x)


def test_a_scene_read_again_matches_its_checkpoint_where_the_simulator_chose_its_step_and_cap():
    from warp_cloth.checkpoint import scene_fingerprint

    # no step and no limit cap set: the simulator chooses both, and its scene holds them
    scene = with_simulation(wc.load_scene("hanging"), dt=None, substeps=None, limit_max_passes=None)
    sim = wc.Simulator(scene, device="cpu")
    assert sim.scene != scene and sim.scene.simulation.limit_max_passes is not None
    assert scene_fingerprint(scene) == scene_fingerprint(sim.scene)
    assert scene_fingerprint(with_simulation(scene, limit_max_passes=50)) != scene_fingerprint(sim.scene)


def test_a_killed_run_resumes_to_the_frames_of_an_uninterrupted_run(tmp_path):
    scene = scene_file(tmp_path)
    frames = "1200"
    reference = run_here("run", str(scene), "--frames", frames, "--device", "cpu", "--out", str(tmp_path / "ref"),
                         "--quiet", cwd=REPO)
    assert reference.returncode == 0, reference.stderr
    out = tmp_path / "killed"
    process = start_run(str(scene), "--frames", frames, "--device", "cpu", "--out", str(out), "--quiet")
    wait_for(out / "fold_push.checkpoint.npz", process)
    time.sleep(0.5)
    process.kill()
    process.wait(timeout=60)
    assert (out / "fold_push.incomplete.usdc").exists() and (out / "fold_push.checkpoint.npz").exists()
    frames_left = {k: v for k, v in files_under(out).items() if not k.endswith(".lock")}  # dead runs' locks go
    fresh = run_here("run", str(scene), "--frames", frames, "--device", "cpu", "--out", str(out), "--quiet", cwd=REPO)
    assert fresh.returncode == 2 and "--resume" in one_error_line(fresh)
    assert {k: v for k, v in files_under(out).items() if not k.endswith(".lock")} == frames_left
    resumed = run_here("run", str(scene), "--frames", frames, "--device", "cpu", "--out", str(out), "--quiet",
                       "--resume", cwd=REPO)
    assert resumed.returncode == 0, resumed.stderr
    assert "resumed at frame" in resumed.stdout
    expected, got = usd_points(tmp_path / "ref" / "fold_push.usdc"), usd_points(out / "fold_push.usdc")
    assert len(got) == len(expected) == int(frames) + 1
    for frame, (a, b) in enumerate(zip(expected, got)):
        np.testing.assert_array_equal(a, b, err_msg=f"frame {frame}")
    assert files_under(tmp_path / "ref" / "fold_push" / "poly") == files_under(out / "fold_push" / "poly")
    assert sorted(p.name for p in out.iterdir()) == ["fold_push", "fold_push.usdc"]


@pytest.mark.parametrize("previous", [False, True], ids=["frames-put-in-place", "frames-put-beside"])
def test_a_stopped_run_resumes_from_where_its_frames_went(tmp_path, previous):
    out = tmp_path / "out"
    if previous:
        assert run_here("run", "hanging", "--frames", "2", "--out", str(out), "--quiet", cwd=REPO).returncode == 0
    process = start_run("hanging", "--frames", "100000", "--out", str(out), "--quiet")
    wait_for(out / "hanging.checkpoint.npz", process)
    process.send_signal(signal.SIGINT)
    stopped, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    kept = int(stopped.split("interrupted after ")[1].split()[0])
    total = str(kept + 12)
    resumed = run_here("run", "hanging", "--frames", total, "--out", str(out), "--quiet", "--resume", cwd=REPO)
    assert resumed.returncode == 0, resumed.stderr
    reference = tmp_path / "reference.usdc"
    wc.Simulator(wc.load_scene("hanging"), device="cpu").run(int(total), writers=[wc.UsdWriter(reference)])
    expected, got = usd_points(reference), usd_points(out / "hanging.usdc")
    assert len(got) == len(expected) == int(total) + 1
    for a, b in zip(expected, got):
        np.testing.assert_array_equal(a, b)
    assert len(list((out / "hanging" / "poly").iterdir())) == int(total) + 1
    assert sorted(p.name for p in out.iterdir()) == ["hanging", "hanging.usdc"]
    assert sorted(p.name for p in (out / "hanging").iterdir()) == ["poly"]


def test_a_resumed_run_measures_and_reports_the_whole_run(tmp_path):
    """The strain summary and the metrics CSV of a stopped run resumed are those of the run that never
    stopped: every frame from 0, not only the resumed ones."""
    from warp_cloth.metrics import read_metrics

    out, metrics = tmp_path / "out", tmp_path / "m.csv"
    process = start_run("hanging", "--frames", "100000", "--out", str(out), "--quiet", "--metrics", str(metrics))
    wait_for(out / "hanging.checkpoint.npz", process)
    process.send_signal(signal.SIGINT)
    stopped, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    total = int(stopped.split("interrupted after ")[1].split()[0]) + 12
    resumed = run_here("run", "hanging", "--frames", str(total), "--out", str(out), "--quiet", "--resume",
                       "--metrics", str(metrics), cwd=REPO)
    assert resumed.returncode == 0, resumed.stderr
    strain = wc.StrainMonitor()
    reference = tmp_path / "reference.csv"
    wc.Simulator(wc.load_scene("hanging"), device="cpu").run(total, writers=[
        strain, wc.MetricsWriter(reference, plot=False)])
    assert f"over {total + 1} frames" in strain.report().describe()
    assert strain.report().describe() in resumed.stdout
    got, expected = read_metrics(metrics), read_metrics(reference)
    assert list(got["frame"]) == list(range(total + 1))
    for column in ("structural_stretch", "shear_compression", "kinetic_energy", "potential_energy"):
        np.testing.assert_array_equal(got[column], expected[column], err_msg=column)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv", "m.png", "out", "reference.csv"]


def test_resume_refuses_a_changed_scene_and_a_missing_checkpoint(tmp_path):
    missing = run_here("run", "hanging", "--frames", "3", "--out", str(tmp_path), "--resume", "--quiet", cwd=REPO)
    assert missing.returncode == 2 and "checkpoint" in one_error_line(missing)
    process = start_run("hanging", "--frames", "100000", "--out", str(tmp_path), "--quiet")
    wait_for(tmp_path / "hanging.checkpoint.npz", process)
    process.send_signal(signal.SIGINT)
    process.communicate(timeout=120)
    changed = run_here("run", "hanging", "--substeps", "30", "--out", str(tmp_path), "--resume", "--quiet", cwd=REPO)
    assert changed.returncode == 2
    assert "changed since" in one_error_line(changed)


# Item 10: output paths checked before the simulation starts


@pytest.mark.parametrize("option, value, expected", [
    ("--out", "a_file", "a folder"),
    ("--usd", "a_folder", "a file name"),
    ("--usd", "shot.obj", "ending in"),
    ("--usd", "shot.txt", "ending in"),
    ("--poly", "a_file", "a folder"),
])
def test_output_paths_that_cannot_work_are_refused_with_one_line(tmp_path, option, value, expected):
    (tmp_path / "a_file").write_text("mine")
    (tmp_path / "a_folder").mkdir()
    result = run_here("run", "hanging", "--frames", "2", "--out", str(tmp_path / "out"), option,
                      str(tmp_path / value), "--quiet", cwd=REPO)
    assert result.returncode == 2
    line = one_error_line(result)
    assert line.startswith("warp-cloth: error: command line: " + option) and expected in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "a_folder"]


@pytest.mark.parametrize("suffix", [".usd", ".usda", ".usdc"])
def test_every_usd_suffix_is_written_in_its_format(tmp_path, suffix):
    path = tmp_path / f"shot{suffix}"
    result = run_here("run", "hanging", "--frames", "3", "--usd", str(path), "--no-poly", "--quiet", cwd=REPO)
    assert result.returncode == 0, result.stderr
    assert (path.read_bytes()[:8] == b"PXR-USDC") == (suffix != ".usda")
    assert len(usd_points(path)) == 4
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_a_read_only_output_folder_is_refused_before_simulating(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    if os.geteuid() == 0:
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(folder)],
                          capture_output=True).returncode != 0:
            pytest.skip("root ignores folder permissions and cannot mount a read-only tmpfs here")
    else:
        folder.chmod(0o555)
    try:
        result = run_here("run", "hanging", "--frames", "2", "--out", str(folder), "--quiet", cwd=REPO)
        assert result.returncode == 2
        assert "read-only" in one_error_line(result)
        assert list(folder.iterdir()) == []
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", str(folder)], check=True)
        else:
            folder.chmod(0o755)


# Item 13: the USD is saved every few seconds, not every frame, and compacted at the end


def test_usd_is_as_small_as_its_data(tmp_path):
    path = tmp_path / "hanging.usdc"
    sim = wc.Simulator(with_simulation(wc.load_scene("hanging"), frames=120), device="cpu")
    sim.run(120, writers=[wc.UsdWriter(path)])
    compact = tmp_path / "compact.usdc"
    Sdf.Layer.FindOrOpen(str(path)).Export(str(compact))
    assert os.path.getsize(path) <= 1.05 * os.path.getsize(compact)
    assert len(usd_points(path)) == 121


# A checkpoint a run did not complete stays until it is resumed or moved away; an unstable run's goes


def test_an_unstable_run_removes_its_own_checkpoint_and_a_fresh_run_may_start(tmp_path, monkeypatch):
    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 0.0)  # a checkpoint after every frame
    for failed_usd in ("hanging.failed.usdc", "hanging.failed.2.usdc"):  # a second failure is not refused either
        code, _, err = run_cli_in_process("run", "hanging", "--frames", "40", "--substeps", "1", "--out",
                                          str(tmp_path), "--quiet", cwd=tmp_path)
        assert code == 3 and "--resume" not in err and failed_usd in err
        assert int(err.split("Kept frames 0 to ")[1].split()[0]) >= 1  # it was checkpointed before it blew up
        assert not (tmp_path / "hanging.checkpoint.npz").exists()
    failed = files_under(tmp_path)
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", str(tmp_path), "--quiet",
                                      cwd=tmp_path)
    assert code == 0, err
    assert {k: v for k, v in files_under(tmp_path).items() if k in failed} == failed
    assert len(usd_points(tmp_path / "hanging.usdc")) == 3


def stop_at_frame_3_with_sigterm(self, sim, frame):
    if frame == 3:
        os.kill(os.getpid(), signal.SIGTERM)  # the run stops after this frame, as it would for a real signal


def fail_at_frame_3_with_a_full_disk(self, sim, frame):
    if frame == 3:
        raise OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.parametrize("end, code", [(fail_at_frame_3_with_a_full_disk, 4), (stop_at_frame_3_with_sigterm, 143)],
                         ids=["write-failure", "signal"])
def test_a_fresh_run_is_refused_while_a_run_that_did_not_complete_keeps_its_checkpoint(tmp_path, monkeypatch, end,
                                                                                        code):
    from warp_cloth.writers.poly import PolyWriter

    write_frame = PolyWriter.write_frame

    def ending_at_frame_3(self, sim, frame):
        end(self, sim, frame)
        write_frame(self, sim, frame)

    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 0.0)  # a checkpoint after every frame
    monkeypatch.setattr(PolyWriter, "write_frame", ending_at_frame_3)
    run = ("run", "hanging", "--out", str(tmp_path), "--quiet")
    ended, out, err = run_cli_in_process(*run, "--frames", "6", cwd=tmp_path)
    assert ended == code and "--resume" in out + err
    monkeypatch.setattr(PolyWriter, "write_frame", write_frame)
    left = files_under(tmp_path)
    assert "hanging.checkpoint.npz" in left
    fresh, _, err = run_cli_in_process(*run, "--frames", "2", cwd=tmp_path)
    assert fresh == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "hanging.checkpoint.npz" in err and "--resume" in err
    assert files_under(tmp_path) == left
    resumed, out, err = run_cli_in_process(*run, "--frames", "6", "--resume", cwd=tmp_path)
    assert resumed == 0, err
    assert "resumed at frame" in out and len(usd_points(tmp_path / "hanging.usdc")) == 7
    assert not (tmp_path / "hanging.checkpoint.npz").exists()


def test_saved_says_whether_the_run_has_a_checkpoint_to_resume(tmp_path, monkeypatch):
    scene = with_simulation(wc.load_scene("hanging"), frames=3)
    usd = wc.UsdWriter(tmp_path / "hanging.usdc")
    checkpoint = wc.CheckpointWriter(tmp_path / "hanging.checkpoint.npz", [usd])
    assert not checkpoint.saved
    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 1e9)  # no save before the failure at frame 1
    with pytest.raises(RuntimeError):
        wc.Simulator(scene, device="cpu").run(3, writers=[usd, checkpoint, RaiseAt(1, RuntimeError())])
    assert not checkpoint.saved and not checkpoint.path.exists()
    monkeypatch.setattr(wc.Simulator, "SYNC_SECONDS", 0.0)
    usd = wc.UsdWriter(tmp_path / "hanging.usdc")
    checkpoint = wc.CheckpointWriter(tmp_path / "hanging.checkpoint.npz", [usd])
    with pytest.raises(RuntimeError):
        wc.Simulator(scene, device="cpu").run(3, writers=[usd, checkpoint, RaiseAt(2, RuntimeError())])
    assert checkpoint.saved and checkpoint.path.exists()


# One lock covers what outputs of one stem share (the staging file, the checkpoint)


@pytest.mark.parametrize("outputs", [["--usd", "shot.usd", "--no-poly"], ["--usd", "shot.usdc", "--no-poly"],
                                     ["--no-usd", "--poly", "shot"]], ids=["usd", "usdc", "poly"])
def test_outputs_that_share_a_staging_file_or_checkpoint_share_one_lock(tmp_path, outputs):
    (tmp_path / "out").mkdir()
    outputs = [str(tmp_path / "out" / o) if o.startswith("shot") else o for o in outputs]
    with lock_held_by_another_process(OutputLock(tmp_path / "out" / "shot.usda").path) as holder:
        code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", *outputs, cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and f"process id {holder}" in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["shot.lock"]


def test_two_outputs_of_one_run_with_one_lock_share_it(tmp_path):
    out = tmp_path / "out"
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", "--usd", str(out / "p.usdc"),
                                      "--poly", str(out / "p"), cwd=tmp_path)
    assert code == 0, err
    assert len(usd_points(out / "p.usdc")) == 3 and len(list((out / "p").glob("*.poly"))) == 3
    assert sorted(p.name for p in out.iterdir()) == ["p", "p.usdc"]


def test_a_usd_file_and_a_poly_folder_of_one_name_are_refused(tmp_path):
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", "--usd", str(tmp_path / "p.usdc"),
                                      "--poly", str(tmp_path / "p.usdc"), cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("warp-cloth: error: command line: --poly") and "another output of this run" in err
    assert list(tmp_path.iterdir()) == []


# Output paths the file system cannot hold


def test_a_poly_folder_with_no_parent_to_stage_beside_is_refused(tmp_path):
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", "--out", str(tmp_path / "out"),
                                      "--poly", "/", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("warp-cloth: error: command line: --poly")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option, name", [
    ("--poly", "p" * 250),  # fits, but its staging folder's name does not
    ("--poly", "p" * 300 + "/poly"),
    ("--usd", "u" * 300 + ".usdc"),
    ("--usd", "u" * 245 + ".usdc"),  # fits, but its staging file's name does not
])
def test_names_too_long_for_the_file_system_are_refused_with_one_line(tmp_path, option, name):
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", "--out", str(tmp_path / "out"),
                                      option, str(tmp_path / name), cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith(f"warp-cloth: error: command line: {option}") and "file system can hold" in err
    assert list(tmp_path.iterdir()) == []


def test_a_usd_whose_staging_path_is_too_long_is_refused_with_one_line(tmp_path):
    limit = os.pathconf(tmp_path, "PC_PATH_MAX")
    folder = tmp_path
    while len(os.fsencode(str(folder))) < limit - 300:
        folder = folder / ("d" * 200)
    folder.mkdir(parents=True)
    usd = folder / ("u" * (limit - 10 - len(os.fsencode(str(folder)))) + ".usdc")  # fits, its staging name not
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--quiet", "--usd", str(usd), "--no-poly",
                                      cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("warp-cloth: error: command line: --usd") and "file system can hold" in err
    assert list(folder.iterdir()) == []


# A full disk's message


def test_a_full_disk_message_says_how_much_more_is_needed(tmp_path, monkeypatch):
    import re

    import warp_cloth.output as output
    from warp_cloth.writers.usd import SAVE_MARGIN_BYTES

    free = {"bytes": 10**12}

    class FillDiskAt(RaiseAt):
        def write_frame(self, sim, frame):
            if frame == self.frame:
                free["bytes"] = SAVE_MARGIN_BYTES  # a few KiB short of what the next save needs

    monkeypatch.setattr(output, "free_bytes", lambda folder: free["bytes"])
    with pytest.raises(OutputError) as raised:
        wc.Simulator(wc.load_scene("hanging"), device="cpu").run(
            4, writers=[FillDiskAt(2, None), wc.UsdWriter(tmp_path / "hanging.usdc")])
    amount = re.search(r"about ([\d.]+) (bytes|KiB|MiB) more needed", str(raised.value))
    assert amount and float(amount.group(1)) > 0, str(raised.value)
