"""The lab's trial of a global limit solve (issue 33; kernels/multilevel_solve.py): a round is one step of the
stiff-spring projection over every limited spring of the cloths' lines, solved by a few conjugate-gradient
iterations preconditioned by a V-cycle over aggregates, in place of the line solves (``SolveChoices.multilevel``).
The aggregates are the particles binned by their rest positions into cells of ``AGGREGATE`` x ``AGGREGATE``
spacings (a grid's blocks of 4 x 4), then those cells' in turn, down to one node."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels.multilevel_solve import (P_AP, RZ, RZ_NEXT, Aggregation, BlockLevel, coarse_diagonal,
                                                 coarse_edges, dot, invert_diagonal, move_particles, multiply,
                                                 next_scalars, particle_rows, prolong, residual, restrict, smooth,
                                                 smooth_from_zero, spring_blocks, start_directions, step_direction,
                                                 step_solution)

from .cloth_lines import Family
from .device_model import DeviceModel
from .state import DeviceState

AGGREGATE = 4  # spacings a cell's side, level to level
STIFFNESS = 1000.0  # k w: the springs' stiffness times a particle's inverse mass
ITERATIONS = 12  # conjugate-gradient iterations a round
WEIGHT = 0.6  # the smoothing's damping
DOT_THREADS = 4096


def springs_of(lines: list[Family]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every spring of the families' lines: its first and second particle and its allowed range."""
    first, second, low, high = [], [], [], []
    for starts, particles, lo, hi in lines:
        last = np.zeros(len(particles), dtype=bool)
        last[starts[1:] - 1] = True  # a line's last slot starts no spring
        slots = np.flatnonzero(~last)
        first.append(particles[slots])
        second.append(particles[slots + 1])
        low.append(lo[slots])
        high.append(hi[slots])
    return tuple(np.concatenate(values) for values in (first, second, low, high))


@dataclass
class HostLevel:
    """A level's graph on the host: its node count and edges (first, second)."""
    count: int
    first: np.ndarray
    second: np.ndarray


def incidence(level: HostLevel) -> dict[str, np.ndarray]:
    """Each node's incident edges, the other node and whether the node is the edge's first."""
    edges = np.arange(len(level.first))
    node = np.concatenate([level.first, level.second])
    order = np.argsort(node, kind="stable")
    edge = np.concatenate([edges, edges])[order]
    other = np.concatenate([level.second, level.first])[order]
    is_first = np.concatenate([np.ones(len(edges)), np.zeros(len(edges))])[order]
    start = np.concatenate([[0], np.cumsum(np.bincount(node, minlength=level.count))])
    return dict(start=start, edge=edge, other=other, is_first=is_first)


def lists(keys: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The indices of ``keys`` grouped by key (0 .. count - 1): starts and members."""
    order = np.argsort(keys, kind="stable")
    start = np.concatenate([[0], np.cumsum(np.bincount(keys, minlength=count))])
    return start, order


def coarsen(level: HostLevel, cells: np.ndarray) -> tuple[HostLevel, dict[str, np.ndarray]]:
    """The level whose nodes are the distinct ``cells`` (a fine node's) and its aggregation."""
    _, aggregate = np.unique(cells, axis=0, return_inverse=True)
    aggregate = aggregate.ravel()
    count = int(aggregate.max()) + 1
    a, b = aggregate[level.first], aggregate[level.second]
    inner = a == b
    crossing = np.flatnonzero(~inner)
    low, high = np.minimum(a[crossing], b[crossing]), np.maximum(a[crossing], b[crossing])
    pairs, edge_of = np.unique(np.stack([low, high], 1), axis=0, return_inverse=True)
    edge_of = edge_of.ravel()
    member_start, member = lists(aggregate, count)
    inner_edges = np.flatnonzero(inner)
    inner_start, inner_order = lists(a[inner_edges], count)
    source_start, source_order = lists(edge_of, len(pairs))
    source = crossing[source_order]
    flip = (a[source] != pairs[edge_of[source_order], 0]).astype(int)
    return HostLevel(count, pairs[:, 0], pairs[:, 1]), dict(
        member_start=member_start, member=member, inner_start=inner_start, inner=inner_edges[inner_order],
        source_start=source_start, source=source, source_flip=flip, aggregate=aggregate)


class MultilevelSolve:
    """A round of the stiff-spring projection: springs' blocks, the levels' Galerkin sums and inverses, then
    ``ITERATIONS`` preconditioned conjugate-gradient iterations, and the particles moved."""

    def __init__(self, model: DeviceModel, lines: list[Family], rest: np.ndarray, inv_mass: np.ndarray) -> None:
        self.model = model
        device = model.device
        first, second, low, high = springs_of(lines)
        free = inv_mass > 0
        self.stiffness = STIFFNESS / float(inv_mass[free].mean()) if free.any() else 0.0
        ints = lambda values: wp.array(np.asarray(values, dtype=np.int32), dtype=int, device=device)  # noqa: E731
        self.first, self.second = ints(first), ints(second)
        self.low = wp.array(low.astype(np.float32), dtype=float, device=device)
        self.high = wp.array(high.astype(np.float32), dtype=float, device=device)
        self.normal = wp.zeros(len(first), dtype=wp.vec3, device=device)
        self.excess = wp.zeros(len(first), dtype=float, device=device)
        grid = grid_coordinates(lines, rest)
        host = HostLevel(len(rest), first, second)
        self.levels, self.aggregations, self.counts, self.edge_counts = [], [], [], []
        self.aggregations_host: list[np.ndarray] = []
        node_free = free.astype(np.int32)
        scale = 1
        while True:
            self.levels.append(self._upload_level(host, node_free, device))
            self.counts.append(host.count)
            self.edge_counts.append(max(len(host.first), 0))
            if host.count == 1:
                break
            scale *= AGGREGATE
            cells = grid // scale
            # a fine node's cell: any of its particles' (the cells nest)
            coarse, aggregation = coarsen(host, cells_of_nodes(cells, self.aggregations_host, host.count))
            if coarse.count >= host.count:
                break
            self.aggregations.append(self._upload_aggregation(aggregation, device))
            self.aggregations_host.append(aggregation["aggregate"])
            host, node_free = coarse, np.ones(coarse.count, dtype=np.int32)
        self.x = [wp.zeros(count, dtype=wp.vec3, device=device) for count in self.counts]
        self.y = [wp.zeros(count, dtype=wp.vec3, device=device) for count in self.counts]
        self.right = [wp.zeros(count, dtype=wp.vec3, device=device) for count in self.counts]
        n = self.counts[0]
        self.b = wp.zeros(n, dtype=wp.vec3, device=device)
        self.dx, self.r, self.p, self.a_p = (wp.zeros(n, dtype=wp.vec3, device=device) for _ in range(4))
        self.scalars = wp.zeros(3, dtype=wp.float64, device=device)
        self.name = (f"stiff-spring projection ({len(first)} springs, {len(self.counts)} levels of "
                     f"{'/'.join(str(c) for c in self.counts)} nodes, {ITERATIONS} CG iterations)")

    def _upload_level(self, host: HostLevel, free: np.ndarray, device) -> BlockLevel:
        ints = lambda values: wp.array(np.asarray(values, dtype=np.int32), dtype=int, device=device)  # noqa: E731
        inc = incidence(host)
        level = BlockLevel()
        level.diagonal = wp.zeros(host.count, dtype=wp.mat33, device=device)
        level.inverse = wp.zeros(host.count, dtype=wp.mat33, device=device)
        level.edge_block = wp.zeros(max(len(host.first), 1), dtype=wp.mat33, device=device)
        level.incident_start = ints(inc["start"])
        level.incident_edge = ints(inc["edge"] if len(inc["edge"]) else [0])
        level.incident_node = ints(inc["other"] if len(inc["other"]) else [0])
        level.incident_first = ints(inc["is_first"] if len(inc["is_first"]) else [0])
        level.free = ints(free)
        return level

    @staticmethod
    def _upload_aggregation(values: dict[str, np.ndarray], device) -> Aggregation:
        aggregation = Aggregation()
        for name, array in values.items():
            setattr(aggregation, name, wp.array(np.asarray(array if len(array) else [0], dtype=np.int32),
                                                dtype=int, device=device))
        return aggregation

    def run(self, state: DeviceState) -> None:
        device = state.device
        levels, aggregations = self.levels, self.aggregations
        springs = self.first.shape[0]
        wp.launch(spring_blocks, dim=springs, inputs=[state.x, self.first, self.second, self.low, self.high,
                                                     self.model.inv_mass, self.stiffness],
                  outputs=[self.normal, self.excess, levels[0].edge_block], device=device)
        wp.launch(particle_rows, dim=self.counts[0], inputs=[levels[0], self.normal, self.excess,
                                                            self.model.inv_mass, self.stiffness],
                  outputs=[self.b], device=device)
        wp.launch(invert_diagonal, dim=self.counts[0], inputs=[levels[0]], device=device)
        for l, aggregation in enumerate(aggregations):
            wp.launch(coarse_diagonal, dim=self.counts[l + 1], inputs=[levels[l], aggregation, levels[l + 1]],
                      device=device)
            if self.edge_counts[l + 1]:
                wp.launch(coarse_edges, dim=self.edge_counts[l + 1], inputs=[levels[l], aggregation, levels[l + 1]],
                          device=device)
            wp.launch(invert_diagonal, dim=self.counts[l + 1], inputs=[levels[l + 1]], device=device)
        n = self.counts[0]
        wp.copy(self.r, self.b)
        z = self._cycle(0, self.r, device)
        wp.launch(start_directions, dim=n, inputs=[z], outputs=[self.dx, self.p], device=device)
        self.scalars.zero_()
        self._dot(self.r, z, RZ, device)
        for _ in range(ITERATIONS):
            wp.launch(multiply, dim=n, inputs=[levels[0], self.p], outputs=[self.a_p], device=device)
            self._dot(self.p, self.a_p, P_AP, device)
            wp.launch(step_solution, dim=n, inputs=[self.scalars, self.p, self.a_p], outputs=[self.dx, self.r],
                      device=device)
            z = self._cycle(0, self.r, device)
            self._dot(self.r, z, RZ_NEXT, device)
            wp.launch(step_direction, dim=n, inputs=[self.scalars, z], outputs=[self.p], device=device)
            wp.launch(next_scalars, dim=1, outputs=[self.scalars], device=device)
        wp.launch(move_particles, dim=n, inputs=[self.dx, self.model.inv_mass, self.model.h],
                  outputs=[state.x, state.v], device=device)

    def _dot(self, a: wp.array, b: wp.array, slot: int, device) -> None:
        count = a.shape[0]
        threads = min(DOT_THREADS, count)
        wp.launch(dot, dim=threads, inputs=[a, b, count, threads], outputs=[self.scalars, slot], device=device)

    def _cycle(self, l: int, right: wp.array, device) -> wp.array:
        """The V-cycle from level l for ``right``: its approximate solution's array."""
        level, count = self.levels[l], self.counts[l]
        if l == len(self.aggregations):
            wp.launch(smooth_from_zero, dim=count, inputs=[level, right, 1.0], outputs=[self.x[l]], device=device)
            return self.x[l]
        aggregation = self.aggregations[l]
        wp.launch(smooth_from_zero, dim=count, inputs=[level, right, WEIGHT], outputs=[self.x[l]], device=device)
        wp.launch(residual, dim=count, inputs=[level, right, self.x[l]], outputs=[self.y[l]], device=device)
        wp.launch(restrict, dim=self.counts[l + 1], inputs=[aggregation, self.y[l]], outputs=[self.right[l + 1]],
                  device=device)
        coarse = self._cycle(l + 1, self.right[l + 1], device)
        wp.launch(prolong, dim=count, inputs=[level, aggregation, coarse], outputs=[self.x[l]], device=device)
        wp.launch(smooth, dim=count, inputs=[level, right, self.x[l], WEIGHT], outputs=[self.y[l]], device=device)
        return self.y[l]


def grid_coordinates(lines: list[Family], rest: np.ndarray) -> np.ndarray:
    """Each particle's integer coordinates along the first two families' directions at rest (a grid's rows and
    columns), in spacings of their first springs."""
    axes = []
    for starts, particles, *_ in lines[:2]:
        d = rest[particles[1]] - rest[particles[0]]
        axes.append(d / float(np.dot(d, d)))
    return np.floor((rest - rest[lines[0][1][0]]) @ np.stack(axes, 1) + 0.5).astype(np.int64)


def cells_of_nodes(cells: np.ndarray, aggregates: list[np.ndarray], count: int) -> np.ndarray:
    """Each node's cell at the current level: a particle's cell carried up through the aggregations made so
    far (every particle of a node shares it)."""
    node = np.arange(len(cells))
    for aggregate in aggregates:
        node = aggregate[node]
    out = np.zeros((count, cells.shape[1]), dtype=cells.dtype)
    out[node] = cells
    return out
