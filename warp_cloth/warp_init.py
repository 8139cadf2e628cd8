"""Starting Warp without the warning its C library prints on every machine without an NVIDIA driver:
running on the CPU is supported, and a run names the device it ran on. No Warp setting silences it
(it is an fprintf to standard error), so the standard error of ``wp.init()`` is read back and passed on
without that line.

Warp's banner at start and its line for every kernel module it loads are for Warp's developers, not a
script's output: off unless ``set_verbose(True)`` asks for them (or the user set Warp's log level)."""

from __future__ import annotations

import os
import sys
import tempfile

import warp as wp

NO_CUDA_DRIVER_WARNING = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."

_started = False
_verbose: bool | None = None  # None: not asked, Warp's messages quiet unless the user set its level


def set_verbose(verbose: bool = True) -> None:
    """Let Warp print its banner (at its start, if it has not started yet) and a line for every kernel module
    it loads, or (``False``) only its warnings and errors."""
    global _verbose
    _verbose = verbose
    _set_warp_level(verbose)


def _set_warp_level(verbose: bool) -> None:
    if hasattr(wp, "LOG_INFO"):
        wp.config.log_level = wp.LOG_INFO if verbose else wp.LOG_WARNING
    else:  # Warp before its log levels: one switch for the banner and the module lines
        wp.config.quiet = not verbose


def _at_warps_default() -> bool:
    """Whether Warp's messages are as it starts them (banner and module lines on): a level the user set is theirs."""
    if hasattr(wp, "LOG_INFO"):
        return wp.config.log_level == wp.LOG_INFO
    return not wp.config.quiet


def init_warp() -> None:
    """``wp.init()``, passing on what it writes to standard error except the no-driver warning."""
    global _started
    if _started:
        return
    if _verbose is None and _at_warps_default():
        _set_warp_level(False)
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
