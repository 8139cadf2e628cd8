"""The checkpoint as a frame writer: saved whenever the simulator syncs its writers, so that it always
matches frames the other outputs hold on disk; removed when the run completes or goes unstable (resuming it
would blow up again), kept when it was stopped or failed otherwise (a fresh run is then refused, see
``warp_cloth.output.StagedOutput.prepare``, until it is resumed or moved away). It keeps the strain measured
so far too, so that a resumed run reports the strain of the whole run. It comes after the writers whose
frames it points at."""

from __future__ import annotations

from pathlib import Path

from ..checkpoint import load_checkpoint, rewrite_extra, save_checkpoint
from ..errors import UnstableSimulation
from ..output import RunOutcome


class CheckpointWriter:
    """Keeps ``path`` with the state of the last synced frame and, for each of ``outputs`` (writers with a
    ``target`` and a ``location``), where that output's frames are (see ``frames_at``), and what the
    ``strain`` monitor (a ``StrainMonitor``, optional) has measured up to that frame (see ``strain_at``)."""

    def __init__(self, path: str | Path, outputs: list, strain=None) -> None:
        self.path = Path(path)
        self.outputs = outputs
        self.strain = strain

    @property
    def saved(self) -> bool:
        """Whether there is a checkpoint of this run to continue from (with ``--resume``)."""
        return self.path.exists()

    def _where(self) -> dict:
        return {"outputs": {str(w.target.absolute()): str((w.location or w.staging).absolute())
                            for w in self.outputs}}

    def begin(self, sim) -> None:
        pass

    def write_frame(self, sim, frame: int) -> None:
        pass

    def _extra(self) -> dict:
        extra = self._where()
        if self.strain is not None:
            extra["strain"] = self.strain.measured_so_far()
        return extra

    def sync(self, sim) -> None:
        save_checkpoint(sim, self.path, self._extra())

    def finish(self, sim, frames_written: int) -> None:
        self.path.unlink(missing_ok=True)

    def abandon(self, sim, frames_written: int, outcome: RunOutcome) -> None:
        """A stopped run is checkpointed at its last frame; a failed one keeps its last synced checkpoint,
        told where the outputs have put their frames, unless it went unstable: resumed at the same settings it
        would blow up again, and with others it cannot be resumed."""
        if outcome.interrupted:
            save_checkpoint(sim, self.path, self._extra())
        elif isinstance(outcome.error, UnstableSimulation):
            self.path.unlink(missing_ok=True)
        elif self.path.exists():  # the strain it keeps is that of its own frame
            rewrite_extra(self.path, {**load_checkpoint(self.path).extra, **self._where()})


def frames_at(checkpoint_extra: dict, target: Path) -> Path | None:
    """Where the checkpointed run left the frames of the output ``target``."""
    location = checkpoint_extra.get("outputs", {}).get(str(target.absolute()))
    return Path(location) if location else None


def strain_at(checkpoint_extra: dict) -> dict | None:
    """What the checkpointed run had measured of its strain (``StrainMonitor.measured_so_far``), if kept."""
    return checkpoint_extra.get("strain")
