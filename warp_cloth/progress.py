"""A progress bar on the terminal (stderr), and a notice for a slow step before it; both silent when
stderr is not a terminal."""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO


class Progress:
    def __init__(self, total: int, label: str, stream: TextIO | None = None) -> None:
        self.total = max(1, total)
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.started = time.perf_counter()
        self._last_draw = 0.0
        self.done = 0

    def update(self, done: int) -> None:
        self.done = done
        now = time.perf_counter()
        if self.enabled and (now - self._last_draw > 0.1 or done >= self.total):
            self._last_draw = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        fraction = min(1.0, self.done / self.total)
        width = 30
        filled = int(round(fraction * width))
        elapsed = now - self.started
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else 0.0
        self.stream.write(f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
                          f"{rate:6.1f}/s eta {eta:5.1f}s ")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


class SlowStepNotice:
    """Says what is going on (``"compiling kernels ..."``) once a step has taken ``after`` seconds, and
    how long it took when it ends; says nothing for a quick step."""

    def __init__(self, what: str, after: float = 0.5, stream: TextIO | None = None) -> None:
        self.what = what
        self.after = after
        self.stream = stream or sys.stderr
        self.shown = False
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None

    def __enter__(self) -> "SlowStepNotice":
        self.started = time.perf_counter()
        if self.stream.isatty():
            self._timer = threading.Timer(self.after, self._show)
            self._timer.daemon = True
            self._timer.start()
        return self

    def _show(self) -> None:
        with self._lock:
            if self._timer is not None:
                self.shown = True
                self.stream.write(f"{self.what} ...")
                self.stream.flush()

    def __exit__(self, *exc) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            if self.shown:
                self.stream.write(f" {time.perf_counter() - self.started:.1f} s\n")
                self.stream.flush()
