"""Edge strain over a run, measured honestly: every structural and shear edge of every cloth (springs or
not, limited or not), stretch and compression, in every frame a run writes, frame 0 included; with
percentiles over all edge-frames."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels import strain as strain_kernels

HISTOGRAM_LOW = -1.0  # strain of the first bin (a collapsed edge)
HISTOGRAM_HIGH = 4.0  # strain of the last (500% stretch); beyond either end counts in the end bins
BINS_PER_UNIT = 2000  # bins per unit of strain: percentiles to 0.05%
SLOTS = 256  # frames measured on the device before they are read back
BEYOND = 0.11  # the share of edge-frames stretched or compressed past 11% is reported: a 10% limit's bound


@dataclass(frozen=True)
class StrainReport:
    frames: int  # frames measured
    edges: int
    stretch: float  # worst over every edge and frame, as a fraction (0.1 = 10%)
    stretch_frame: int
    compression: float  # worst compression, as a positive fraction
    compression_frame: int
    percentiles: dict[float, float]  # of every edge-frame's |strain|, to 1 / BINS_PER_UNIT
    beyond: float  # fraction of edge-frames with |strain| > BEYOND
    per_frame: np.ndarray  # (frames, 3): frame, worst stretch, worst compression

    @property
    def worst(self) -> float:
        return max(self.stretch, self.compression)

    def describe(self) -> str:
        """One line: the worst stretch and compression with their frames, and the percentiles."""
        p = self.percentiles
        return (f"worst edge strain +{100 * self.stretch:.1f}% (frame {self.stretch_frame}) / "
                f"-{100 * self.compression:.1f}% (frame {self.compression_frame}) over {self.frames} frames; "
                f"|strain| p99 {100 * p[99.0]:.1f}%, p99.9 {100 * p[99.9]:.1f}%, "
                f"{100 * self.beyond:.2f}% of edge-frames past {100 * BEYOND:.0f}%")


def edges_on_device(model, device) -> tuple[wp.array, wp.array]:
    """Every cloth's structural and shear edges and their rest lengths, as the strain kernels read them."""
    return (wp.array(model.edges, dtype=wp.vec2i, device=device),
            wp.array(model.edge_rest, dtype=float, device=device))


class StrainMonitor:
    """A frame writer that measures edge strain in every frame it is given (``Simulator.run(writers=[...])``)
    on the device, reading back only every ``SLOTS`` frames and at the end; ``report()`` sums it up.
    ``earlier``: what the monitor of a run now resumed had measured (``measured_so_far``, as a checkpoint
    keeps it), so that the report covers the whole run."""

    def __init__(self, earlier: dict | None = None) -> None:
        self.earlier = earlier

    def load_kernels(self, sim) -> None:
        wp.load_module(strain_kernels, device=sim.device)

    def begin(self, sim) -> None:
        device = sim.device
        self.edges, self.rest = edges_on_device(sim.model, device)
        self.worst = wp.zeros((SLOTS, 2), dtype=float, device=device)
        bins = int(round((HISTOGRAM_HIGH - HISTOGRAM_LOW) * BINS_PER_UNIT))
        self.histogram = wp.zeros(bins, dtype=int, device=device)
        self.pending: list[int] = []  # frames measured in the slots, not yet read back
        self.measured: list[tuple[int, float, float]] = []
        if self.earlier is not None:
            self._take_earlier(self.earlier)

    def _take_earlier(self, earlier: dict) -> None:
        self.measured = [(int(f), float(s), float(c)) for f, s, c in earlier["per_frame"]]
        counts = np.zeros(self.histogram.shape[0], dtype=np.int32)
        bins, values = np.asarray(earlier["histogram"], dtype=np.int64).reshape(2, -1)
        counts[bins] = values
        self.histogram.assign(counts)

    def measured_so_far(self) -> dict:
        """What the monitor has measured, in plain lists (a checkpoint keeps it as JSON): each frame's worst
        stretch and compression, and the histogram's bins that count anything."""
        self._read_back()
        counts = self.histogram.numpy()
        bins = np.flatnonzero(counts)
        return {"per_frame": [list(m) for m in self.measured], "histogram": [bins.tolist(), counts[bins].tolist()]}

    def write_frame(self, sim, frame: int) -> None:
        if len(self.pending) == SLOTS:
            self._read_back()
        if self.edges.shape[0] > 0:
            wp.launch(strain_kernels.measure_edges, dim=self.edges.shape[0],
                      inputs=[sim.state.x, self.edges, self.rest, len(self.pending), HISTOGRAM_LOW,
                              float(BINS_PER_UNIT)], outputs=[self.worst, self.histogram], device=sim.device)
        self.pending.append(frame)

    def frame_strain(self) -> tuple[float, float]:
        """The last frame's worst stretch and compression (waits for the device)."""
        self._read_back()
        return self.measured[-1][1:]

    def _read_back(self) -> None:
        if not self.pending:
            return
        worst = self.worst.numpy()
        self.measured += [(f, float(worst[k, 0]), float(worst[k, 1])) for k, f in enumerate(self.pending)]
        self.worst.zero_()
        self.pending = []

    def finish(self, sim, frames_written: int) -> None:
        self._read_back()

    def abandon(self, sim, frames_written: int, outcome) -> None:
        self._read_back()

    def report(self) -> StrainReport | None:
        """What was measured (None before any frame)."""
        self._read_back()
        if not self.measured:
            return None
        per_frame = np.array(self.measured, dtype=np.float64)
        s, c = int(np.argmax(per_frame[:, 1])), int(np.argmax(per_frame[:, 2]))
        counts = self.histogram.numpy().astype(np.int64)
        return StrainReport(len(per_frame), int(self.edges.shape[0]), float(per_frame[s, 1]), int(per_frame[s, 0]),
                            float(per_frame[c, 2]), int(per_frame[c, 0]), magnitude_percentiles(counts, (99.0, 99.9)),
                            beyond_fraction(counts, BEYOND), per_frame)


def bin_strains(bins: int) -> np.ndarray:
    """The strain at each bin's upper edge."""
    return HISTOGRAM_LOW + np.arange(1, bins + 1) / BINS_PER_UNIT


def magnitude_percentiles(counts: np.ndarray, levels: tuple[float, ...]) -> dict[float, float]:
    """Percentiles of |strain| from the histogram (each bin at its edge farther from zero)."""
    edges = bin_strains(len(counts))
    magnitude = np.maximum(np.abs(edges), np.abs(edges - 1.0 / BINS_PER_UNIT))
    order = np.argsort(magnitude, kind="stable")
    cumulative = np.cumsum(counts[order])
    total = cumulative[-1] if len(cumulative) else 0
    if total == 0:
        return {level: 0.0 for level in levels}
    return {level: float(magnitude[order][np.searchsorted(cumulative, level / 100.0 * total)]) for level in levels}


def beyond_fraction(counts: np.ndarray, bound: float) -> float:
    """The share of edge-frames whose bin lies wholly past ``bound`` of stretch or compression."""
    upper = bin_strains(len(counts))
    lower = upper - 1.0 / BINS_PER_UNIT
    total = counts.sum()
    return float(counts[(lower >= bound) | (upper <= -bound)].sum() / total) if total else 0.0


class WorldStrain:
    """A frame writer that keeps each world's worst edge stretch and compression over every frame it is
    given, on the device (for a batch's worlds, see warp_cloth/batch.py; a scene alone is one world);
    ``worst()`` reads them back, (worlds, 2)."""

    def load_kernels(self, sim) -> None:
        wp.load_module(strain_kernels, device=sim.device)

    def begin(self, sim) -> None:
        model, device = sim.model, sim.device
        self.edges, self.rest = edges_on_device(model, device)
        self.edge_world = wp.array(model.particle_world[model.edges[:, 0]] if len(model.edges) else
                                   np.zeros(0, dtype=np.int32), dtype=int, device=device)
        self.worst_strain = wp.zeros((sim.device_model.world_count, 2), dtype=float, device=device)

    def write_frame(self, sim, frame: int) -> None:
        if self.edges.shape[0] > 0:
            wp.launch(strain_kernels.worst_by_world, dim=self.edges.shape[0],
                      inputs=[sim.state.x, self.edges, self.rest, self.edge_world], outputs=[self.worst_strain],
                      device=sim.device)

    def finish(self, sim, frames_written: int) -> None:
        pass

    def abandon(self, sim, frames_written: int, outcome) -> None:
        pass

    def worst(self) -> np.ndarray:
        return self.worst_strain.numpy()
