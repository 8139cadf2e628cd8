"""Starting Warp without the warning its C library prints on every machine without an NVIDIA driver:
running on the CPU is supported, and a run names the device it ran on. No Warp setting silences it
(it is an fprintf to standard error), so the standard error of ``wp.init()`` is read back and passed on
without that line."""

from __future__ import annotations

import os
import sys
import tempfile

import warp as wp

NO_CUDA_DRIVER_WARNING = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."

_started = False


def init_warp() -> None:
    """``wp.init()``, passing on what it writes to standard error except the no-driver warning."""
    global _started
    if _started:
        return
    with tempfile.TemporaryFile() as captured:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(captured.fileno(), 2)
        try:
            wp.init()
        finally:  # also where wp.init() fails: what it said about why is passed on
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            captured.seek(0)
            passed_on = b"".join(line for line in captured if not line.startswith(NO_CUDA_DRIVER_WARNING))
            if passed_on:
                os.write(2, passed_on)
    _started = True
