"""The checkpoint as a frame writer: saved whenever the simulator syncs its writers, so that it always
matches frames the other outputs hold on disk; removed when the run completes, kept when it does not."""

from __future__ import annotations

from pathlib import Path

from ..checkpoint import rewrite_extra, save_checkpoint
from ..output import RunOutcome


class CheckpointWriter:
    """Keeps ``path`` with the state of the last synced frame and, for each of ``outputs`` (writers with a
    ``target`` and a ``location``), where that output's frames are (see ``frames_at``)."""

    def __init__(self, path: str | Path, outputs: list) -> None:
        self.path = Path(path)
        self.outputs = outputs
        self.kept = False

    def _where(self) -> dict:
        return {"outputs": {str(w.target.absolute()): str((w.location or w.staging).absolute())
                            for w in self.outputs}}

    def begin(self, sim) -> None:
        pass

    def write_frame(self, sim, frame: int) -> None:
        pass

    def sync(self, sim) -> None:
        save_checkpoint(sim, self.path, self._where())

    def finish(self, sim, frames_written: int) -> None:
        self.path.unlink(missing_ok=True)

    def abandon(self, sim, frames_written: int, outcome: RunOutcome) -> None:
        """A stopped run is checkpointed at its last frame; a failed one keeps its last synced checkpoint,
        told where the outputs have put their frames."""
        if outcome.interrupted:
            save_checkpoint(sim, self.path, self._where())
        elif self.path.exists():
            rewrite_extra(self.path, self._where())
        self.kept = self.path.exists()


def frames_at(checkpoint_extra: dict, target: Path) -> Path | None:
    """Where the checkpointed run left the frames of the output ``target``."""
    location = checkpoint_extra.get("outputs", {}).get(str(target.absolute()))
    return Path(location) if location else None
