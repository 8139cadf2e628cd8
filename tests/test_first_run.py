"""A first run: Warp compiles the kernels before the frames are timed and says so on a terminal, and its
no-CUDA-driver warning does not reach the user."""

import io
import os
import pty
import re
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
import warp_cloth.progress
import warp_cloth.simulator
from conftest import REPO, run_cli, run_cli_in_process, with_simulation

# Prints Warp's own line for every kernel module it loads (from its cache or compiled), and a marker
# between prepare() and the frames of run().
MODULE_LOADS_AFTER_PREPARE = """
import sys
import warp_cloth as wc
from conftest import with_simulation
wc.set_verbose(True)
scene = wc.load_scene(sys.argv[1])
if sys.argv[2] != "-":
    scene = with_simulation(scene, integrator=sys.argv[2])
sim = wc.Simulator(scene, device="cpu", graph=sys.argv[3] == "graph")
sim.prepare()
print("prepared", flush=True)
sim.run(2)
"""


@pytest.mark.parametrize("scene, integrator, graph", [("hanging", "-", "graph"), ("hanging", "-", "no-graph"),
                                                      ("hanging", "implicit", "graph"), ("pile", "-", "graph")])
def test_prepare_loads_every_kernel_module_a_frame_launches(tmp_path, scene, integrator, graph):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), str(REPO / "tests")]))
    result = subprocess.run([sys.executable, "-c", MODULE_LOADS_AFTER_PREPARE, scene, integrator, graph],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    before, marker, after = result.stdout.partition("prepared\n")
    assert marker and "load on device 'cpu'" in before
    assert "load on device" not in after, after


@pytest.mark.parametrize("scene, integrator, graph", [("pile", None, True), ("pile", None, False),
                                                      ("hanging", "implicit", True)])
def test_prepare_changes_no_result(scene, integrator, graph):
    loaded = wc.load_scene(scene)
    loaded = with_simulation(loaded, integrator=integrator) if integrator else loaded
    prepared, plain = (wc.Simulator(loaded, device="cpu", graph=graph) for _ in range(2))
    for frame in range(3):
        prepared.prepare()
        prepared.step()
        plain.step()
    np.testing.assert_array_equal(prepared.positions(), plain.positions())
    np.testing.assert_array_equal(prepared.velocities(), plain.velocities())


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        self.now += 0.001
        return self.now


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_run_keeps_compiling_out_of_its_wall_time_and_eta(monkeypatch):
    """Preparing takes 100 s on a fake clock: neither the summary's wall time nor the bar's rate shows it."""
    clock = FakeClock()
    fake_time = types.SimpleNamespace(perf_counter=clock.perf_counter)
    monkeypatch.setattr(warp_cloth.simulator, "time", fake_time)
    monkeypatch.setattr(warp_cloth.progress, "time", fake_time)
    terminal = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    sim = wc.Simulator(wc.load_scene("hanging"), device="cpu")
    real_prepare = sim.prepare
    prepared = []

    def slow_prepare() -> None:
        real_prepare()
        clock.now += 100.0
        prepared.append(clock.now)

    monkeypatch.setattr(sim, "prepare", slow_prepare)
    summary = sim.run(3, progress=True)
    assert prepared and summary.frames == 3
    assert summary.wall_seconds < 1.0
    rate = float(terminal.getvalue().rsplit("3/3", 1)[1].split("/s")[0])
    assert rate > 3 / 1.0


def test_slow_step_notice_says_what_and_how_long_sooner_on_a_terminal(monkeypatch):
    terminal = FakeTerminal()
    with warp_cloth.progress.SlowStepNotice("compiling kernels", after=0.01, stream=terminal):
        time.sleep(0.3)
    assert terminal.getvalue().startswith("compiling kernels ... ") and terminal.getvalue().endswith(" s\n")
    quick = FakeTerminal()
    with warp_cloth.progress.SlowStepNotice("compiling kernels", after=5.0, stream=quick):
        pass
    piped = io.StringIO()
    with warp_cloth.progress.SlowStepNotice("compiling kernels", after=0.01, stream=piped):
        time.sleep(0.3)
    assert quick.getvalue() == "" and piped.getvalue() == ""  # off a terminal, only after LINE_SECONDS
    monkeypatch.setattr(warp_cloth.progress, "LINE_SECONDS", 0.05)
    with warp_cloth.progress.SlowStepNotice("compiling kernels", after=0.01, stream=piped):
        time.sleep(0.3)
    assert piped.getvalue().startswith("compiling kernels ... ") and piped.getvalue().endswith(" s\n")


def cache_lacking(module: str, folder: Path) -> Path:
    """A Warp cache (for WARP_CACHE_PATH) of links to every kernel module this process's cache holds but
    ``module``'s: a run finds the others compiled and compiles that one."""
    cache = Path(wp.config.kernel_cache_dir)
    made = folder / cache.name  # Warp keeps a cache for each of its versions, in a folder of that name
    made.mkdir(parents=True)
    for entry in cache.iterdir():
        if not entry.name.startswith(f"wp_{module}_"):
            (made / entry.name).symlink_to(entry)
    return folder


def test_first_run_on_a_terminal_says_kernels_are_compiling(tmp_path):
    """A kernel module not in the cache, as on a user's first run (where none is): the terminal shows the
    compile, then the run. One module, the solve loop a substep launches, takes seconds to compile; all of
    them again would take a minute on two cores."""
    cache = cache_lacking("warp_cloth.kernels.solve_loop", tmp_path / "kernel-cache")
    env = dict(os.environ, WARP_CACHE_PATH=str(cache), PYTHONUNBUFFERED="1")
    reader, terminal = pty.openpty()
    with open(reader, "rb", buffering=0) as screen:
        process = subprocess.Popen([sys.executable, "-m", "warp_cloth", "run", "hanging", "--frames", "2",
                                    "--device", "cpu", "--no-poly"], cwd=tmp_path, env=env,
                                   stdout=subprocess.PIPE, stderr=terminal, text=True)
        os.close(terminal)
        shown = b""
        while chunk := _read_until_closed(screen):
            shown += chunk
        stdout = process.communicate(timeout=300)[0]
    assert process.returncode == 0
    text = shown.decode()
    assert text.startswith("compiling kernels ... "), text
    assert "CUDA" not in text and "Traceback" not in text
    first, *_, summary = stdout.splitlines()
    assert first.startswith("hanging: step 2.45 ms") and summary.startswith("hanging: 2 frames")


def _read_until_closed(screen) -> bytes:
    try:
        return screen.read(4096)
    except OSError:  # the pty reports the other side's close as EIO
        return b""


def test_a_cpu_run_shows_no_cuda_driver_warning(tmp_path):
    result = run_cli("run", "hanging", "--frames", "1", "--device", "cpu", "--no-poly", cwd=tmp_path)
    assert result.returncode == 0 and result.stderr == "", result.stderr


def test_warp_start_passes_on_everything_but_the_no_driver_warning(tmp_path):
    script = """
import os
import warp as wp
from warp_cloth import warp_init
def init_that_writes_to_stderr():
    os.write(2, warp_init.NO_CUDA_DRIVER_WARNING + b" GPU execution will not be available.\\n")
    os.write(2, b"Warp: something else worth saying\\n")
wp.init = init_that_writes_to_stderr
warp_init.init_warp()
"""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    result = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0 and result.stderr == "Warp: something else worth saying\n"


PYTHON_RUN = """
import sys
import warp_cloth as wc
if sys.argv[1] == "verbose":
    wc.set_verbose(True)
sim = wc.Simulator(wc.load_scene("hanging"), device="cpu")
sim.run(1)
print(sim)
"""


@pytest.mark.parametrize("verbose", [False, True])
def test_from_python_warp_says_nothing_unless_asked(tmp_path, verbose):
    """A script's output is its own: Warp's banner and its line per kernel module loaded come only with
    ``set_verbose(True)``; ``print(sim)`` is one line with the step and why."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    result = subprocess.run([sys.executable, "-c", PYTHON_RUN, "verbose" if verbose else "quiet"], cwd=tmp_path,
                            env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    said = result.stdout + result.stderr
    if verbose:
        assert "initialized" in said and "load on device 'cpu'" in said, said
    else:
        assert "Warp " not in said and "Module " not in said, said
        assert result.stderr == "" and len(result.stdout.splitlines()) == 1, said
    sim = wc.Simulator(wc.load_scene("hanging"), device="cpu")
    sim.step()
    assert result.stdout.splitlines()[-1] == str(sim)


def test_run_off_a_terminal_shows_progress_lines_and_states_the_compile_apart(tmp_path, monkeypatch):
    """In a log (stderr not a terminal) a run's progress is lines (one per update here, where a line is due
    every 0 s); the summary's time is the frames', with the building and compiling before them stated apart."""
    monkeypatch.setattr(warp_cloth.progress, "LINE_SECONDS", 0.0)
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "3", "--no-usd", "--no-poly", "--device", "cpu",
                                        cwd=tmp_path)
    assert code == 0, err
    assert [line.split(",")[0] for line in err.splitlines() if line.startswith("hanging on cpu: ")] == \
        ["hanging on cpu: 1/3", "hanging on cpu: 2/3", "hanging on cpu: 3/3"], err
    summary = out.splitlines()[-1]
    assert re.search(r" on cpu in \d+\.\d\d s \(\+\d+\.\d s building and compiling; [\d.e+]+ particle-substeps/s\); ",
                     summary), summary
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "3", "--no-usd", "--no-poly", "--device", "cpu",
                                        "--quiet", cwd=tmp_path)
    assert code == 0 and err == "", err
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "3", "--no-usd", "--no-poly", "--device", "cpu",
                                        "--check", "--progress", cwd=tmp_path)
    assert code == 0 and "hanging on cpu: 3/3" in err, err
