"""Progress on stderr, and a notice for a slow step before it. On a terminal a bar redrawn in place; off one
(a log, CI, a pipe), where a bar would be a mess of carriage returns, a line every ``LINE_SECONDS`` once the
work has gone on that long, and a last one when it ends: a quick run adds nothing to a log, a long one is
never silent for more than a few seconds."""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

LINE_SECONDS = 5.0  # off a terminal: how often a line is written, and how long a step goes on before one


class Progress:
    """``update(done)`` after each of ``total`` steps; ``label`` says what is going on (``update`` may change
    it: "rendering hanging.preview.mp4, frame 12"). ``every``: seconds between lines off a terminal (default
    ``LINE_SECONDS``; 0: a line every update). The estimate of the time left counts from the end of the first step, which often carries a
    start-up of its own (Blender's, a first compile), and is shown from the second step on."""

    def __init__(self, total: int, label: str, stream: TextIO | None = None, every: float | None = None) -> None:
        self.total = max(1, total)
        self.label = label
        self.stream = stream or sys.stderr
        self.on_terminal = self.stream.isatty()
        self.every = LINE_SECONDS if every is None else every
        self.started = time.perf_counter()
        self._last_draw = 0.0
        self._last_line = self.started
        self._drawn_width = 0
        self._first_step: tuple[int, float] | None = None  # (done, when) at the first update
        self._lines_done = -1  # off a terminal: ``done`` at the last line written (-1: none yet)
        self.done = 0

    def update(self, done: int, label: str | None = None) -> None:
        self.done = done
        if label is not None:
            self.label = label
        now = time.perf_counter()
        if self._first_step is None and done > 0:
            self._first_step = (done, now)
        if self.on_terminal:
            if now - self._last_draw > 0.1 or done >= self.total:
                self._last_draw = now
                self._draw(now)
        elif now - self._last_line >= self.every:
            self._write_line(now)

    def eta(self, now: float) -> float | None:
        """Seconds left at the pace since the first step ended; None before a second step has ended."""
        if self._first_step is None:
            return None
        first_done, first_at = self._first_step
        if self.done <= first_done or now <= first_at:
            return None
        return (self.total - self.done) * (now - first_at) / (self.done - first_done)

    def _draw(self, now: float) -> None:
        fraction = min(1.0, self.done / self.total)
        width = 30
        filled = int(round(fraction * width))
        elapsed = now - self.started
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = self.eta(now)
        text = (f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {rate:6.1f}/s "
                f"eta {'--' if eta is None else f'{eta:.1f}s':>6} ")
        self.stream.write(f"\r{text}{' ' * max(0, self._drawn_width - len(text))}")  # over a longer label
        self._drawn_width = len(text)
        self.stream.flush()

    def _write_line(self, now: float) -> None:
        eta = self.eta(now) if self.done < self.total else None
        self._last_line = now
        self._lines_done = self.done
        self.stream.write(f"{self.label}: {self.done}/{self.total}, {now - self.started:.0f} s"
                          + ("" if eta is None else f", about {eta:.0f} s left") + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.on_terminal:
            self.stream.write("\n")
            self.stream.flush()
        elif self._lines_done >= 0 and self._lines_done != self.done:
            self._write_line(time.perf_counter())  # the last line of a log that had some


class SlowStepNotice:
    """Says what is going on (``"compiling kernels ..."``) once a step has taken ``after`` seconds on a
    terminal (``LINE_SECONDS`` off one), and how long it took when it ends; says nothing for a quick step."""

    def __init__(self, what: str, after: float = 0.5, stream: TextIO | None = None) -> None:
        self.what = what
        self.stream = stream or sys.stderr
        self.after = after if self.stream.isatty() else max(after, LINE_SECONDS)
        self.shown = False
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None

    def __enter__(self) -> "SlowStepNotice":
        self.started = time.perf_counter()
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
