"""The progress bar draws on a terminal and stays silent elsewhere (logs, CI)."""

import io

from warp_cloth.progress import Progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_draws_on_a_terminal_and_ends_its_line():
    stream = Terminal()
    bar = Progress(4, "hanging on cpu", stream=stream)
    for done in range(1, 5):
        bar.update(done)
    bar.close()
    text = stream.getvalue()
    assert text.startswith("\rhanging on cpu [") and "4/4" in text and text.endswith("\n")


def test_progress_is_silent_when_not_a_terminal():
    stream = io.StringIO()
    bar = Progress(4, "hanging on cpu", stream=stream)
    bar.update(4)
    bar.close()
    assert stream.getvalue() == ""
