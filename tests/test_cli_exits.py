"""How the command line ends where the user cuts it short or asks for what is not there: a closed pipe,
Ctrl-C while it is still loading, a GPU on a machine without one."""

import os
import subprocess
import sys

import pytest
import warp as wp

from conftest import REPO, run_cli

# Sends the process a real Ctrl-C (SIGINT) the moment something first imports Warp, the slow import a
# user is most likely to interrupt; then runs the command line as its console script or as -m does.
CTRL_C_DURING_WARP_IMPORT = """
import builtins, os, signal, sys
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
