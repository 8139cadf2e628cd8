"""Houdini .poly (the PRISMS ASCII polygon format Houdini reads and writes): one file per cloth per frame.

Layout, as the seed wrote it: ``POINTS`` then one ``label: x y z`` line per point (labels from 1),
``POLYS`` then one ``label: p1 p2 p3 p4 <`` line per quad (point labels; the trailing ``<`` closes the
polygon, without it Houdini reads an open polyline), then ``END``. Files are named
``<cloth>.<frame:04d>.poly`` by the frame they show on the shot's clock (``warp_cloth.shot_clock``: from 0,
or from a shot's start such as 1001), so a File SOP reads them with ``$F4``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..output import (INCOMPLETE, RunOutcome, StagedOutput, check_folder_output, check_writable_place,
                      copy_tree_files, first_free, fsync_path, labelled, move_files_into)


def format_points(points: np.ndarray) -> str:
    """The POINTS section: ``label: x y z`` lines, labels from 1."""
    n = len(points)
    columns = (np.arange(1, n + 1).tolist(), *np.asarray(points).T.tolist())
    return "POINTS\n" + ("%d: %.7g %.7g %.7g\n" * n) % tuple(v for row in zip(*columns) for v in row)


def format_polys(face_counts: np.ndarray, face_indices: np.ndarray) -> str:
    """The POLYS section and the end: ``label: p1 p2 p3 [p4] <`` lines (the same every frame)."""
    counts, vertices = np.asarray(face_counts), np.asarray(face_indices) + 1
    m = len(counts)
    if m and (counts == counts[0]).all():  # one face size, one format: fast for a large grid
        table = np.column_stack((np.arange(1, m + 1), vertices.reshape(m, counts[0])))
        return "POLYS\n" + (("%d:" + " %d" * counts[0] + " <\n") * m) % tuple(table.ravel().tolist()) + "END\n"
    faces = np.split(vertices, np.cumsum(counts)[:-1])
    return "POLYS\n" + "".join(f"{k}: {' '.join(map(str, face.tolist()))} <\n"
                               for k, face in enumerate(faces, start=1)) + "END\n"


def format_poly(points: np.ndarray, face_counts: np.ndarray, face_indices: np.ndarray) -> str:
    return format_points(points) + format_polys(face_counts, face_indices)


def frame_file_name(cloth: str, frame: int) -> str:
    return f"{cloth}.{frame:04d}.poly"


class PolyWriter(StagedOutput):
    """Writes ``<cloth>.<frame:04d>.poly`` files into ``directory``. They are written into a staging folder
    beside it and moved in when the run completes, replacing only files of the same names (see
    ``warp_cloth.output``). ``resume``: go on with the frames of an earlier run found in the staging folder,
    from the simulator's frame."""

    key = "poly"
    kind = "folder"

    def __init__(self, directory: str | Path, resume: bool = False) -> None:
        self.directory = Path(directory)
        if self.directory.name in ("", ".", ".."):
            self.directory = self.directory.resolve()  # a name to put the staging folder's beside
        if not self.directory.name:
            raise SceneError("poly", "a folder inside another one, where its frames can be staged beside it (not "
                                     "the root folder)", str(directory))
        check_folder_output(self.directory, "poly")
        super().__init__(self.directory, labelled(self.directory, INCOMPLETE), resume)
        check_writable_place(self.staging, "poly")
        self.saved_through = -1  # the last frame whose files are all written
        self.start = 0  # the first frame the run writes (its clock's start)
        self.names: list[str] = []  # the files this run wrote, in the staging folder
        self.older_frames_left = 0  # files of other frames of these cloths found in the folder on completion
        self._unsynced: list[str] = []
        self._polys: list[str] = []  # each cloth's POLYS section

    def take_back(self, location: Path, frame: int, cloths: list[str], start: int = 0) -> None:
        """Before resuming: the frames ``start`` to ``frame`` an earlier run left at ``location`` go back into
        the staging folder (copied where they are in place: those files stay until the resumed run completes)."""
        if location.absolute() == self.staging.absolute():
            return
        if location.absolute() == self.directory.absolute():
            names = [frame_file_name(c, f) for c in cloths for f in range(start, frame + 1)]
            missing = next((n for n in names if not (location / n).is_file()), None)
            if missing:
                raise SceneError("poly", f"frames up to the checkpoint's frame {frame} in {location}", f"no {missing}")
            copy_tree_files(location, self.staging, names)
        else:
            os.replace(location, self.staging)

    def begin(self, sim) -> None:
        self.prepare()
        self._polys = [format_polys(mesh.face_counts, mesh.face_indices) for mesh in sim.model.cloths]
        self.start = sim.clock.start
        self.saved_through = self.start - 1
        if not self.resume:
            self.staging.mkdir(parents=True)
            return
        if not self.staging.is_dir():
            raise SceneError("poly", f"the frames of the run to resume in {self.staging}", has_got=False)
        cloths = [c.name for c in sim.scene.cloths]
        for frame in range(self.start, sim.frame + 1):  # none where the checkpoint is in the preroll
            names = [frame_file_name(c, frame) for c in cloths]
            missing = [n for n in names if not (self.staging / n).is_file()]
            if missing:
                raise SceneError("poly", f"frames up to the checkpoint's frame {sim.frame} in {self.staging}",
                                 f"no {missing[0]}")
            self.names += names
        kept = set(self.names)
        for name in self._frame_files(self.staging, cloths):
            if name not in kept:
                (self.staging / name).unlink()  # a later frame this run's earlier part wrote
        self.saved_through = max(sim.frame, self.saved_through)

    @staticmethod
    def _frame_files(folder: Path, cloths: list[str]) -> list[str]:
        pattern = re.compile("(" + "|".join(re.escape(c) for c in cloths) + r")\.\d{4,}\.poly")
        return [p.name for p in folder.iterdir() if pattern.fullmatch(p.name)] if folder.is_dir() else []

    def write_frame(self, sim, frame: int) -> None:
        positions = sim.positions()
        for c, cloth in enumerate(sim.scene.cloths):
            name = frame_file_name(cloth.name, frame)
            text = format_points(sim.cloth_positions(c, positions)) + self._polys[c]
            try:
                (self.staging / name).write_text(text)
            except BaseException:
                (self.staging / name).unlink(missing_ok=True)  # no half-written frame stays
                raise
            self.names.append(name)
            self._unsynced.append(name)
        self.saved_through = frame

    def sync(self, sim) -> None:
        """Ask the disk to keep the files written since the last sync (the checkpoint saved with them
        counts on them)."""
        for name in self._unsynced:
            fsync_path(self.staging / name)
        fsync_path(self.staging)
        self._unsynced = []

    def finish(self, sim, frames_written: int) -> None:
        self.sync(sim)
        move_files_into(self.staging, self.directory, self.names)
        mine = set(self.names)
        self.older_frames_left = sum(name not in mine for name in
                                     self._frame_files(self.directory, [c.name for c in sim.scene.cloths]))
        self._end(self.directory)

    def abandon(self, sim, frames_written: int, outcome: RunOutcome) -> None:
        """Keep the frames so far: in place if the run was stopped and none of its files would replace one
        there, else beside the folder as ``<folder>.interrupted`` or ``<folder>.failed``."""
        if not self.staging.exists():
            self.lock.release()
            return
        # A frame whose cloths were not all written is not kept.
        complete = {frame_file_name(c.name, f) for c in sim.scene.cloths
                    for f in range(self.start, self.saved_through + 1)}
        for name in self.names:
            if name not in complete:
                (self.staging / name).unlink(missing_ok=True)
        self.names = [n for n in self.names if n in complete]
        if outcome.interrupted and not any((self.directory / n).exists() for n in self.names):
            self.finish(sim, frames_written)
            return
        target = first_free(self.directory, outcome.label)
        os.replace(self.staging, target)
        self._end(target)
