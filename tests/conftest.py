import contextlib
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import warp as wp

wp.config.log_level = wp.LOG_ERROR
wp.init()

import warp_cloth as wc  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(config, items):
    if wp.is_cuda_available():
        return
    skip = pytest.mark.skip(reason="needs a CUDA GPU")
    for item in items:
        if "cuda" in item.keywords:
            item.add_marker(skip)


def with_simulation(scene: wc.Scene, **changes) -> wc.Scene:
    """The scene with some [simulation] settings changed."""
    return dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, **changes))


def spring_strains(sim: wc.Simulator, positions: np.ndarray | None = None) -> np.ndarray:
    x = sim.positions() if positions is None else positions
    springs = sim.model.springs
    lengths = np.linalg.norm(x[springs.pairs[:, 0]] - x[springs.pairs[:, 1]], axis=1)
    return lengths / springs.rest - 1.0


def run_cli(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.run([sys.executable, "-m", "warp_cloth", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def run_cli_in_process(*args: str, cwd: Path) -> tuple[int, str, str]:
    """``warp-cloth ARGS`` in this process, run in ``cwd``: (exit code, stdout, stderr). A subprocess costs
    seconds of imports; this costs none, for tests that only need the command's answer."""
    import contextlib
    import io

    from warp_cloth import cli

    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(list(args))
    return code, out.getvalue(), err.getvalue()


def assert_restored_run_continues(sim: wc.Simulator, restored: wc.Simulator, checkpoint: Path, frames: int = 6) -> None:
    """Saves ``sim``'s checkpoint, steps it ``frames`` more frames, restores ``restored`` from the checkpoint
    and checks that it makes the same frames: positions, velocities and sphere centres, bit for bit."""
    sim.save_checkpoint(checkpoint)
    expected = []
    for _ in range(frames):
        sim.step()
        expected.append((sim.positions(), sim.velocities(), sim.sphere_centers()))
    restored.restore(checkpoint)
    for x, v, centers in expected:
        restored.step()
        np.testing.assert_array_equal(restored.positions(), x)
        np.testing.assert_array_equal(restored.velocities(), v)
        np.testing.assert_array_equal(restored.sphere_centers(), centers)


@contextlib.contextmanager
def lock_held_by_another_process(path: Path):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import fcntl, os, sys\n"
                               "fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)\n"
                               "fcntl.flock(fd, fcntl.LOCK_EX)\n"
                               "os.write(fd, b'%d\\n' % os.getpid())\n"
                               "print('held', flush=True)\n"
                               "sys.stdin.read()\n", str(path)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        yield holder.pid
    finally:
        holder.stdin.close()
        holder.wait(timeout=30)
