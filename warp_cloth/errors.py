"""Errors a user can act on: bad scene input, an unstable run; and the exit codes the commands end with."""

from __future__ import annotations

EXIT_BAD_INPUT = 2  # a SceneError: bad input, one line naming the file or the command line
EXIT_UNSTABLE = 3
EXIT_INTERRUPTED = 130
EXIT_OUTPUT_FAILED = 4  # a writer failed (a full disk, ...): the run's frames are kept beside the output
EXIT_SIGNAL_BASE = 128  # a run stopped by a signal exits with 128 + the signal's number (130 for Ctrl-C)
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, what a shell reports for a command stopped by a closed pipe


class SceneError(ValueError):
    """A scene (file or object) that cannot be simulated.

    ``key`` is the dotted path of the offending value (``cloth[0].resolution``), ``expected`` says what
    would have been accepted, ``source`` names the file when there is one.
    """

    def __init__(self, key: str, expected: str, got: object = None, source: str | None = None,
                 has_got: bool = True) -> None:
        self.key = key
        self.expected = expected
        self.got = got
        self.has_got = has_got
        self.source = source
        super().__init__(self._message())

    def _message(self) -> str:
        where = f"{self.source}: " if self.source else ""
        key = f"{self.key}: " if self.key else ""
        got = f", got {_shortened(repr(self.got))}" if self.has_got else ""
        return f"{where}{key}expected {self.expected}{got}"

    def within(self, prefix: str) -> "SceneError":
        """The same error with ``prefix`` put in front of its key path."""
        if not self.key:
            key = prefix
        else:
            key = f"{prefix}{self.key}" if self.key.startswith("[") else f"{prefix}.{self.key}"
        return SceneError(key, self.expected, self.got, self.source, self.has_got)

    def in_file(self, source: str) -> "SceneError":
        return SceneError(self.key, self.expected, self.got, source, self.has_got)


MAX_SHOWN = 80  # characters of a rejected value shown in a message


def _shortened(text: str) -> str:
    """``text`` whole, or its start and its end (where a path names its file) around "..."."""
    if len(text) <= MAX_SHOWN:
        return text
    start = (MAX_SHOWN - 3) // 2
    return text[:start] + "..." + text[-(MAX_SHOWN - 3 - start):]


class UnstableSimulation(RuntimeError):
    """A run that went unstable: non-finite values, or energy or strain exploding. Raised by
    ``Simulator.step`` at the end of the frame where the blow-up guard saw it; frames written before it stay
    valid."""

    def __init__(self, frame: int, substep: int, reason: str, advice: str) -> None:
        self.frame = frame
        self.substep = substep
        self.reason = reason
        self.advice = advice
        super().__init__(f"unstable at frame {frame}, substep {substep}: {reason}. {advice}")
