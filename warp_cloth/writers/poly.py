"""Houdini .poly (the PRISMS ASCII polygon format Houdini reads and writes): one file per cloth per frame.

Layout, as the seed wrote it: ``POINTS`` then one ``label: x y z`` line per point (labels from 1),
``POLYS`` then one ``label: p1 p2 p3 p4 <`` line per quad (point labels; the trailing ``<`` closes the
polygon, without it Houdini reads an open polyline), then ``END``. Files are named
``<cloth>.<frame:04d>.poly`` so a File SOP reads them with ``$F4``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np


def format_poly(points: np.ndarray, quads: np.ndarray) -> str:
    labels = np.arange(1, len(points) + 1)
    point_lines = "".join(f"{i}: {x:.7g} {y:.7g} {z:.7g}\n" for i, (x, y, z) in zip(labels, points.tolist()))
    q = (quads + 1).tolist()
    poly_lines = "".join(f"{k}: {a} {b} {c} {d} <\n" for k, (a, b, c, d) in enumerate(q, start=1))
    return f"POINTS\n{point_lines}POLYS\n{poly_lines}END\n"


class PolyWriter:
    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        self.partial = self.directory.with_name(self.directory.name + ".partial")

    def begin(self, sim) -> None:
        shutil.rmtree(self.partial, ignore_errors=True)
        self.partial.mkdir(parents=True)

    def write_frame(self, sim, frame: int) -> None:
        positions = sim.positions()
        for c, cloth in enumerate(sim.scene.cloths):
            text = format_poly(sim.cloth_positions(c, positions), sim.model.grids[c].quads)
            (self.partial / f"{cloth.name}.{frame:04d}.poly").write_text(text)

    def finish(self, sim, frames_written: int) -> None:
        if self.directory.exists():
            shutil.rmtree(self.directory)
        self.partial.rename(self.directory)

    @property
    def outputs(self) -> list[Path]:
        return [self.directory]
