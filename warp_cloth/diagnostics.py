"""Robustness diagnostics read off a simulator's state: intersecting triangle pairs, closest particles."""

from __future__ import annotations

import math

import warp as wp

from warp_cloth.kernels import intersections

from .seams import welded_ids
from .simulator import Simulator
from .strain import StrainMonitor


class TriangleIntersections:
    """Counts intersecting pairs among all cloth triangles of a simulator (self and cloth-cloth). Triangles
    that meet across a seam (one with a particle sewn to one of the other's) are neighbours, as those that
    share a vertex: shut, the seam is their common edge, whose two copies' rounding would count as crossings
    (and open, contacts leave them alone, seams.sewn_neighbourhood)."""

    def __init__(self, sim: Simulator) -> None:
        model = sim.model
        triangles = model.triangles
        self.device = sim.device
        self.points = wp.array(model.positions, dtype=wp.vec3, device=self.device)
        self.triangles = wp.array(triangles.ravel(), dtype=int, device=self.device)
        self.mesh = wp.Mesh(points=self.points, indices=self.triangles)
        self.welded = wp.array(welded_ids(model.sewn, len(model.positions)), dtype=int, device=self.device)
        self.count_buffer = wp.zeros(1, dtype=int, device=self.device)
        self.triangle_count = len(triangles)

    def count(self, positions: wp.array) -> int:
        wp.copy(self.points, positions)
        self.mesh.refit()
        self.count_buffer.zero_()
        wp.launch(intersections.count_intersecting_triangles, dim=self.triangle_count,
                  inputs=[self.mesh.id, self.points, self.triangles, self.welded], outputs=[self.count_buffer],
                  device=self.device)
        return int(self.count_buffer.numpy()[0])

    def __call__(self, sim: Simulator) -> int:
        return self.count(sim.state.x)


class ContactGaps:
    """The closest approach of two particles that may collide, as a fraction of their contact distance
    (1.0 or more: no pair overlaps; infinite where no pair is listed)."""

    def __init__(self, sim: Simulator) -> None:
        if sim.scene.collision is None:
            raise ValueError("the scene declares no [collision]")

    def __call__(self, sim: Simulator) -> float:
        return sim.closest_contact()


class CheckReport:
    """A frame writer that prints, after every frame, the intersecting triangle pairs, (with particle
    collision) the closest contact, and (given the run's ``StrainMonitor``, a writer before this one) the
    frame's worst edge stretch and compression; it keeps the worst intersections and contact for a
    summary."""

    def __init__(self, stream, strain: "StrainMonitor | None" = None) -> None:
        self.stream = stream
        self.strain = strain
        self.worst_intersections = (0, 0)  # (count, frame)
        self.last_intersections = 0  # of the last frame written
        self.closest_contact: tuple[float, int] | None = None

    def begin(self, sim: Simulator) -> None:
        self.intersections = TriangleIntersections(sim)
        self.gaps = ContactGaps(sim) if sim.scene.collision is not None else None

    def write_frame(self, sim: Simulator, frame: int) -> None:
        count = self.last_intersections = self.intersections(sim)
        line = f"frame {frame}: {count} intersecting triangle pairs"
        if count > self.worst_intersections[0]:
            self.worst_intersections = (count, frame)
        ratio = self.gaps(sim) if self.gaps is not None else math.inf
        if math.isfinite(ratio):
            line += f", closest contact {ratio:.3f} of contact distance"
            if self.closest_contact is None or ratio < self.closest_contact[0]:
                self.closest_contact = (ratio, frame)
        if self.strain is not None:
            stretch, compression = self.strain.frame_strain()
            line += f", worst edge +{100 * stretch:.1f}% / -{100 * compression:.1f}%"
        print(line, file=self.stream, flush=True)

    def finish(self, sim: Simulator, frames_written: int) -> None:
        pass

    @property
    def outputs(self) -> list:
        return []

    def summary(self) -> str:
        count, frame = self.worst_intersections
        text = f"most intersecting triangle pairs {count}" + (f" (frame {frame})" if count else "")
        if self.closest_contact is not None:
            text += f", closest contact {self.closest_contact[0]:.3f} (frame {self.closest_contact[1]})"
        return text
