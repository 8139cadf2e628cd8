"""How the command line ends where the user cuts it short or asks for what is not there: a closed pipe,
Ctrl-C while it is still loading, a signal before the first frame, a GPU on a machine without one, outputs
and options that cannot work."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import warp as wp

import warp_cloth as wc
from conftest import REPO, run_cli, run_cli_in_process

# Sends the process a real Ctrl-C (SIGINT) the moment something first imports Warp, the slow import a
# user is most likely to interrupt; then runs the command line as its console script or as -m does. (A
# process started in the background inherits SIGINT ignored, where Ctrl-C could not reach it: the child
# restores Python's handler first.)
CTRL_C_DURING_WARP_IMPORT = """
import builtins, os, signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal, even where the tests run in the background
real_import = builtins.__import__
def import_with_ctrl_c(name, *args, **kwargs):
    if name == "warp" and not getattr(builtins, "ctrl_c_sent", False):
        builtins.ctrl_c_sent = True
        os.kill(os.getpid(), signal.SIGINT)
    return real_import(name, *args, **kwargs)
builtins.__import__ = import_with_ctrl_c
"""
ENTRY_POINTS = {
    "console script": "from warp_cloth.cli import main\nsys.exit(main())",
    "python -m": "import runpy\nrunpy.run_module('warp_cloth', run_name='__main__', alter_sys=True)",
}


@pytest.mark.parametrize("entry", sorted(ENTRY_POINTS))
def test_ctrl_c_while_importing_gives_one_line_and_exit_130(tmp_path, entry):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    result = subprocess.run([sys.executable, "-c", CTRL_C_DURING_WARP_IMPORT + ENTRY_POINTS[entry],
                             "run", "hanging", "--frames", "2", "--device", "cpu"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 130, result.stderr
    assert result.stderr.strip() == "warp-cloth: interrupted", result.stderr
    assert result.stdout == "" and list(tmp_path.iterdir()) == []


def test_output_into_a_closed_pipe_ends_quietly(tmp_path):
    """``warp-cloth scenes | head -1``: the reader has gone when the listing is written."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        result = subprocess.run([sys.executable, "-m", "warp_cloth", "scenes"], cwd=tmp_path, stdout=write_end,
                                stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert result.stderr == ""
    assert result.returncode == 141  # 128 + SIGPIPE, as a shell reports a command the closed pipe stopped


@pytest.mark.skipif(wp.is_cuda_available(), reason="checks a machine without a CUDA GPU")
@pytest.mark.parametrize("command", [["bench", "--suite", "core"], ["study", "hanging"], ["run", "hanging"]])
def test_cuda_without_a_gpu_is_one_line_naming_the_option(tmp_path, command):
    result = run_cli(*command, "--device", "cuda", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1, result.stderr
    assert "command line: --device: expected 'cpu' (no CUDA device is available here), got 'cuda'" in result.stderr
    assert result.stdout == "" and list(tmp_path.iterdir()) == []


# Sends the process a signal as its kernels are about to compile: after the outputs' locks are taken and
# before the first frame, where the run's own stop-after-a-frame handlers are not yet in place.
SIGNAL_BEFORE_THE_FRAMES = """
import os, signal, sys
import warp_cloth.simulator as simulator
real_prepare = simulator.Simulator.prepare
def prepare_after_a_signal(self):
    os.kill(os.getpid(), signal.{name})
    return real_prepare(self)
simulator.Simulator.prepare = prepare_after_a_signal
from warp_cloth.cli import main
sys.exit(main())
"""


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_a_signal_before_the_first_frame_ends_with_one_line_and_leaves_nothing(tmp_path, name):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    result = subprocess.run([sys.executable, "-c", SIGNAL_BEFORE_THE_FRAMES.format(name=name),
                             "run", "hanging", "--frames", "2", "--device", "cpu"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 128 + getattr(signal, name), result.stderr
    assert result.stderr.strip() == f"warp-cloth: stopped by {name}", result.stderr
    assert list(tmp_path.iterdir()) == []  # no lock, no folder made for one


def test_resume_with_no_frames_left_to_run_is_refused(tmp_path):
    scene = wc.load_scene("hanging")
    sim = wc.Simulator(scene, device="cpu")
    sim.run(3)
    sim.save_checkpoint(tmp_path / "hanging.checkpoint.npz")
    before = sorted(tmp_path.iterdir())
    code, out, err = run_cli_in_process("run", "hanging", "--resume", "--frames", "3", "--out", str(tmp_path),
                                        "--device", "cpu", cwd=tmp_path)
    assert (code, out) == (2, "")
    assert err.strip() == ("warp-cloth: error: command line: --frames: expected more frames than the "
                           "checkpoint's 3 to resume, got 3"), err
    assert sorted(tmp_path.iterdir()) == before


def test_an_output_refused_is_named_as_the_user_gave_it(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    scene = (REPO / "scenes" / "hanging.toml").read_text() + '\n[output]\ndir = "notes.txt/renders"\n'
    (tmp_path / "shot.toml").write_text(scene)
    code, _, err = run_cli_in_process("run", "shot.toml", "--frames", "1", "--device", "cpu", cwd=tmp_path)
    assert code == 2 and err.startswith("warp-cloth: error: shot.toml: output.dir: expected "), err
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "1", "--out", "notes.txt/renders",
                                      "--device", "cpu", cwd=tmp_path)
    assert code == 2 and err.startswith("warp-cloth: error: command line: --out: expected "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "shot.toml"]


def test_an_empty_scene_name_is_one_line(tmp_path):
    code, out, err = run_cli_in_process("run", "", "--device", "cpu", cwd=tmp_path)
    assert (code, out) == (2, "")
    assert err.strip() == "warp-cloth: error: scene: expected a built-in scene name or a path to a .toml file, got ''"


def test_bench_refuses_a_repeat_count_below_one(tmp_path):
    result = run_cli("bench", "--suite", "core", "--device", "cpu", "--repeats", "-1", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip() == ("warp-cloth bench: error: command line: --repeats: expected a whole number "
                                     ">= 1, got -1")
    assert list(tmp_path.iterdir()) == []


def test_an_out_folder_name_too_long_for_the_file_system_is_one_line(tmp_path):
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "1", "--out", "o" * 300, "--device", "cpu",
                                        cwd=tmp_path)
    assert (code, out) == (2, "")
    assert err.startswith("warp-cloth: error: command line: --out: expected a path the file system can hold"), err
    assert len(err.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []


def _checkpoint_of_three_frames(folder) -> Path:
    sim = wc.Simulator(wc.load_scene("hanging"), device="cpu")
    sim.run(3)
    path = folder / "hanging.checkpoint.npz"
    sim.save_checkpoint(path)
    return path


def test_resume_from_a_truncated_checkpoint_is_one_line_naming_it(tmp_path):
    checkpoint = _checkpoint_of_three_frames(tmp_path)
    checkpoint.write_bytes(checkpoint.read_bytes()[:2000])  # cut short, as by a full disk
    before = sorted(tmp_path.iterdir())
    code, out, err = run_cli_in_process("run", "hanging", "--resume", "--frames", "6", "--out", str(tmp_path),
                                        "--device", "cpu", cwd=tmp_path)
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"warp-cloth: error: {checkpoint}: checkpoint: expected a whole checkpoint written by "
                          "warp-cloth (an .npz file; this one is cut short or is not one: "), err
    assert sorted(tmp_path.iterdir()) == before


def test_resume_from_a_checkpoint_without_its_frame_is_one_line_naming_it(tmp_path):
    import json

    import numpy as np

    checkpoint = _checkpoint_of_three_frames(tmp_path)
    with np.load(checkpoint) as data:
        arrays = {name: data[name] for name in data.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["frame"]
    arrays["meta"] = np.array(json.dumps(meta))
    with open(checkpoint, "wb") as f:
        np.savez(f, **arrays)
    code, out, err = run_cli_in_process("run", "hanging", "--resume", "--frames", "6", "--out", str(tmp_path),
                                        "--device", "cpu", cwd=tmp_path)
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
    assert err.strip() == (f"warp-cloth: error: {checkpoint}: checkpoint.meta: expected the fields format, frame, "
                           "substeps and scene (frame is missing)"), err
