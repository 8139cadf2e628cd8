"""Per-frame metrics of a run, as a CSV with named columns and a PNG of them over time.

``MetricsWriter(path)`` is a frame writer (``Simulator.run(writers=[...])``, ``warp-cloth run --metrics``).
Each frame's row: its number and time; the worst stretch and compression of the structural and of the shear
edges (every edge, springs or not, as fractions: 0.1 is 10%); the closest contact (with particle collision:
the closest pair the simulation has listed, as a fraction of its contact distance; measuring it changes
nothing in the run); the crossing triangle pairs (where the run's ``--check`` counts them); kinetic energy,
potential energy (gravity's, from y = 0 along the gravity of the cloth's world, plus the elastic energy:
1/2 k L (l/L - 1)^2 for each spring in the regime it acts in, and 1/2 k |d|^2 for each of a material's
bending stencils, kernels/bending.py) and the elastic part of it, in joules; the substeps' solves since the frame before (the converged strain limit solve's mean and most
passes a substep, the implicit step's most CG iterations); the frame's substeps (with substeps auto, those
it was kept at); and the frame's wall time, from the end of the frame before (simulation and the writers
before this one).

The CSV is an output like the USD (``warp_cloth.output.StagedOutput``): locked while the run writes it, so
that a second run naming the same file is refused; written under a staging name and put in place when the
run completes (a failed or stopped run leaves its rows beside it, as the other outputs do); kept by a
checkpoint, so that a resumed run's CSV has every frame of the run. The plot is made from it then, beside
it; a PNG of that name that is not a plot of warp-cloth's is never written over (the run is refused before
it starts).
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import time
from pathlib import Path

import numpy as np

from warp_cloth.kernels.springs import ELASTIC_COMPRESSION, ELASTIC_TENSION

from .cloth_mesh import SHEAR, STRUCTURAL
from .model import Worlds
from .errors import SceneError
from .output import StagedOutput, check_file_output, first_free, labelled, png_mark, refuse_replacing_unmarked_png

COLUMNS = ("frame", "time", "structural_stretch", "structural_compression", "shear_stretch", "shear_compression",
           "closest_contact", "crossing_pairs", "kinetic_energy", "potential_energy", "spring_energy",
           "limit_passes_mean", "limit_passes_most", "cg_iterations", "substeps", "wall_seconds")
PLOT = "metrics plot"  # what the PNG is, in its mark and in messages
PLOTS = (  # (title, columns, unit) of each panel of the PNG
    ("worst edge strain", ("structural_stretch", "structural_compression", "shear_stretch", "shear_compression"),
     "%"),
    ("energy", ("kinetic_energy", "potential_energy", "spring_energy"), "J"),
    ("closest contact", ("closest_contact",), "of contact distance"),
    ("solver", ("limit_passes_mean", "limit_passes_most", "cg_iterations"), "a substep"),
    ("substeps", ("substeps",), "a frame"),
    ("wall time", ("wall_seconds",), "s a frame"),
)


class MetricsWriter(StagedOutput):
    """Writes a run's per-frame metrics to ``path`` (CSV) and plots them to ``path`` with ``.png``. Give it
    the run's ``CheckReport`` (a writer before it) to have the crossing pairs it counts. ``resume``: go on
    with the rows of an earlier run of the same scene (see ``take_back``), from the simulator's frame."""

    key = "metrics"
    kind = "file"
    suffix = ".csv"

    def __init__(self, path: str | Path, check=None, plot: bool = True, resume: bool = False) -> None:
        self.path = Path(path)
        check_file_output(self.path, (".csv",), self.key)
        self.plot = plot
        super().__init__(self.path, labelled(self.path, "incomplete", self.suffix), resume)
        if plot:
            self.lock.claims |= {self.plot_path.absolute(), labelled(self.plot_path, "incomplete", ".png").absolute()}
        self.check = check
        self._file = None

    def _names_made(self) -> list[str]:
        return [*super()._names_made(), labelled(self.plot_path, "incomplete", ".png").name]

    @property
    def outputs(self) -> list[Path]:
        return [*super().outputs, self.plot_path] if self.plot and self.location == self.path else super().outputs

    @property
    def plot_path(self) -> Path:
        return self.path.with_suffix(".png")

    def prepare(self) -> None:
        super().prepare()
        if self.plot:
            try:
                refuse_replacing_unmarked_png(self.plot_path, PLOT, self.key, self.path)
            except SceneError:
                self.lock.release()
                raise

    def _copy_to_staging(self, location: Path) -> None:
        shutil.copyfile(location, self.staging)

    def begin(self, sim) -> None:
        self.prepare()
        model = sim.model
        self.path.parent.mkdir(parents=True, exist_ok=True)
        kept = self._rows_through(sim.frame) if self.resume else []
        self._file = open(self.staging, "w", newline="")
        self._csv = csv.DictWriter(self._file, COLUMNS)
        self._csv.writeheader()
        self._csv.writerows(kept)
        self._kinds = {kind: model.edge_kind == kind for kind in (STRUCTURAL, SHEAR)}
        worlds = model.worlds if model.worlds is not None else Worlds.of_scene(sim.scene)
        self._gravity = worlds.gravity[model.particle_world].astype(np.float64)
        self._masses = model.masses.astype(np.float64)
        self._last: float | None = None
        self._frame = sim.frame

    def write_frame(self, sim, frame: int) -> None:
        model = sim.model
        x = sim.positions().astype(np.float64)
        v = sim.velocities().astype(np.float64)
        row: dict = {"frame": frame, "time": frame / sim.scene.simulation.fps}
        strain = np.linalg.norm(x[model.edges[:, 0]] - x[model.edges[:, 1]], axis=1) / model.edge_rest - 1.0
        for kind, name in ((STRUCTURAL, "structural"), (SHEAR, "shear")):
            chosen = strain[self._kinds[kind]]
            row[f"{name}_stretch"] = max(0.0, float(chosen.max())) if len(chosen) else ""
            row[f"{name}_compression"] = max(0.0, float(-chosen.min())) if len(chosen) else ""
        contacts = sim.closest_contacts(remake=False)
        row["closest_contact"] = "" if contacts is None or not np.isfinite(contacts.min()) else float(contacts.min())
        row["crossing_pairs"] = "" if self.check is None else self.check.last_intersections
        row["kinetic_energy"] = 0.5 * float(np.sum(self._masses * np.sum(v * v, axis=1)))
        spring_energy = _spring_energy(model.springs, x) + _bending_energy(model.bending, x)
        row["potential_energy"] = -float(np.sum(self._masses * np.sum(self._gravity * x, axis=1))) + spring_energy
        row["spring_energy"] = spring_energy
        stats = sim.solver_stats()
        stepped = stats is not None and sim.frame > self._frame  # none before the first frame's
        self._frame = sim.frame
        row["limit_passes_mean"] = stats.limit_mean_passes if stepped and stats.limit_solves else ""
        row["limit_passes_most"] = stats.limit_passes if stepped and stats.limit_solves else ""
        row["cg_iterations"] = stats.cg_iterations if stepped and stats.cg_iterations is not None else ""
        row["substeps"] = sim.frame_substeps if sim.frame > sim.clock.first else ""
        now = time.perf_counter()
        row["wall_seconds"] = "" if self._last is None else now - self._last  # none for the first frame written
        self._last = now
        self._csv.writerow(row)

    def _rows_through(self, frame: int) -> list[dict]:
        """The rows of the run being resumed, up to ``frame`` (those after it are simulated again)."""
        if not self.staging.exists():
            raise SceneError(self.key, f"the rows of the run to resume in {self.staging}", has_got=False)
        with open(self.staging, newline="") as handle:
            return [row for row in csv.DictReader(handle) if int(row["frame"]) <= frame]

    def sync(self, sim) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    def finish(self, sim, frames_written: int) -> None:
        self._file.close()
        os.replace(self.staging, self.path)
        if self.plot:
            plot_metrics(self.path, self.plot_path)
        self._end(self.path)

    def abandon(self, sim, frames_written: int, outcome) -> None:
        if self._file is None:
            self.lock.release()
            return
        self._file.close()
        location = first_free(self.path, outcome.label, self.suffix)
        os.replace(self.staging, location)
        self._end(location)


def _spring_energy(springs, x: np.ndarray) -> float:
    """1/2 k L (l/L - 1)^2 over the springs, each in the regime its elastic part acts in."""
    if springs is None:
        return 0.0
    strain = np.linalg.norm(x[springs.pairs[:, 0]] - x[springs.pairs[:, 1]], axis=1) / springs.rest - 1.0
    acts = np.where(strain > 0, springs.flags & int(ELASTIC_TENSION), springs.flags & int(ELASTIC_COMPRESSION))
    return float(np.sum(np.where(acts != 0, 0.5 * springs.stiffness * springs.rest * strain * strain, 0.0)))


def _bending_energy(bending, x: np.ndarray) -> float:
    """1/2 k |d|^2 over the bending stencils, d = sum_r w_r x_r."""
    if bending is None:
        return 0.0
    curvature = bending.curvatures(x.astype(np.float64))
    return float(np.sum(0.5 * bending.stiffness * np.einsum("sk,sk->s", curvature, curvature)))


def read_metrics(path: str | Path) -> dict[str, np.ndarray]:
    """A metrics CSV's columns as arrays (nan where a row has no value)."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {c: np.array([float(r[c]) if r.get(c) not in (None, "") else math.nan for r in rows]) for c in COLUMNS}


def plot_metrics(csv_path: str | Path, png_path: str | Path) -> Path:
    """The metrics over time, a panel for each of ``PLOTS`` that has values, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = read_metrics(csv_path)
    panels = [(title, [c for c in columns if np.isfinite(data[c]).any()], unit)
              for title, columns, unit in PLOTS]
    panels = [p for p in panels if p[1]]
    figure, axes = plt.subplots(len(panels), 1, figsize=(8, 2.2 * len(panels)), sharex=True, squeeze=False)
    for axis, (title, columns, unit) in zip(axes[:, 0], panels):
        for column in columns:
            values = data[column] * (100.0 if unit == "%" else 1.0)
            axis.plot(data["time"], values, label=column.replace("_", " "))
        axis.set_title(title, fontsize=10)
        axis.set_ylabel(unit)
        axis.grid(alpha=0.3)
        if len(columns) > 1:
            axis.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("time (s)")
    figure.tight_layout()
    png_path = Path(png_path)
    staging = labelled(png_path, "incomplete", png_path.suffix)
    figure.savefig(staging, dpi=100, metadata=png_mark(PLOT))
    plt.close(figure)
    os.replace(staging, png_path)
    return png_path

