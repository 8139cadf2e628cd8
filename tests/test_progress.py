"""Progress: a bar on a terminal; off one (logs, CI, pipes) a line every few seconds once the work has gone on
that long, and nothing for quick work."""

import io
import types

import pytest

import warp_cloth.progress
from warp_cloth.progress import LINE_SECONDS, Progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def clock(monkeypatch):
    """Progress's clock, moved on by hand."""
    now = types.SimpleNamespace(value=100.0)
    monkeypatch.setattr(warp_cloth.progress, "time", types.SimpleNamespace(perf_counter=lambda: now.value))
    return now


def test_progress_draws_on_a_terminal_and_ends_its_line():
    stream = Terminal()
    bar = Progress(4, "hanging on cpu", stream=stream)
    for done in range(1, 5):
        bar.update(done)
    bar.close()
    text = stream.getvalue()
    assert text.startswith("\rhanging on cpu [") and "4/4" in text and text.endswith("\n")


def test_progress_off_a_terminal_is_a_line_every_few_seconds_and_a_last_one(clock):
    stream = io.StringIO()
    bar = Progress(100, "drape on cpu", stream=stream)
    for done in range(1, 101):
        clock.value += 0.25  # 25 s in all: a line every 5 s
        bar.update(done)
    bar.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 25 / LINE_SECONDS
    assert lines[0] == "drape on cpu: 20/100, 5 s, about 20 s left"
    assert lines[-1].startswith("drape on cpu: 100/100, 25 s")


def test_progress_off_a_terminal_adds_nothing_for_quick_work(clock):
    stream = io.StringIO()
    bar = Progress(4, "hanging on cpu", stream=stream)
    for done in range(1, 5):
        clock.value += 0.5
        bar.update(done)
    bar.close()
    assert stream.getvalue() == ""


def test_progress_estimates_the_time_left_from_the_steps_after_the_first(clock):
    """The first step carries a start-up (Blender's, a compile): 80 s, then 1 s a step. No estimate after
    it (rather than 80 s x the rest), then the pace of the steps that followed."""
    stream = Terminal()
    bar = Progress(99, "rendering", stream=stream)
    clock.value += 80.0
    bar.update(1, "rendering hanging.preview.png")
    assert bar.eta(clock.value) is None and "eta     --" in stream.getvalue()
    clock.value += 1.0
    bar.update(2, "rendering hanging.preview.mp4, frame 1")
    assert bar.eta(clock.value) == pytest.approx(97.0)
    assert stream.getvalue().rsplit("\r", 1)[1].startswith("rendering hanging.preview.mp4, frame 1 [")
