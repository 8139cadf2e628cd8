"""The simulation state on the device: positions and velocities (double buffered), the clock, the order the
next round of line solves takes the families in, where the colliders are, what particle collision carries
from one substep to the next, and what a pass hands a later one within a substep (the wind's accelerations)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels.particle_collision import ListState

from .collider_kinds import Spheres
from .device_model import DeviceModel


@dataclass
class ContactState:
    """Particle collision's arrays: each particle's candidate list and where it was made, the spatial
    hash (its buckets, their stamps' epoch), the remake request, what did not fit, how far this substep's
    passes pushed each particle, the velocities the contacts start from, and the particles the rigid
    colliders hold up (``resting``, empty without colliders)."""

    neighbors: wp.array
    counts: wp.array
    x_built: wp.array
    rebuild: wp.array
    epoch: wp.array
    overflow: wp.array
    bucket_size: wp.array
    bucket_items: wp.array
    pushed: wp.array
    resting: wp.array
    v_start: wp.array

    CARRIED = ("neighbors", "counts", "x_built", "rebuild", "epoch", "overflow", "bucket_size", "bucket_items",
               "pushed", "resting")  # what the next substep reads before it writes

    def lists(self) -> ListState:
        lists = ListState()
        lists.x_built, lists.rebuild, lists.epoch, lists.overflow = self.x_built, self.rebuild, self.epoch, self.overflow
        return lists


@dataclass
class EdgeListState:
    """Edge contacts' candidate lists (kernels/edge_collision.py); warp_cloth/neighbour_lists.py's
    ``EdgeLists`` remakes them."""

    neighbors: wp.array
    counts: wp.array

    CARRIED = ("neighbors", "counts")  # what the next substep reads before it writes


# Candidates an edge's list holds (the nearest; overflow is counted with the particles'): twice the most that
# lay within reach of an edge in the stacked drape (14, read at every frame's end: 3 sheets of 24^2 over 30
# frames and of 32^2 over 60, 2 m, 4 mm radius, edge and face contacts and the bounds; docs/notebook/layers.md).
EDGE_NEIGHBORS = 32

BUCKET_CAPACITY = 16  # particles a spatial-hash bucket holds (overflow is counted, tests keep it 0)
# Particles up to which the lists are made by checking all pairs, which costs less there than the hash
# (docs/benchmarks.md). Tests and the bench set it to choose the broad phase they compare: 0 for the hash.
BRUTE_FORCE_UP_TO = 512


def uses_hash(particles: int) -> bool:
    return particles > BRUTE_FORCE_UP_TO


def hash_table_size(particles: int) -> int:
    """Buckets of the spatial hash: a power of two of at least twice the particles (and 64)."""
    table = 64
    while table < 2 * particles:
        table *= 2
    return table


def edge_hash_table_size(edges: int) -> int:
    """Buckets of the edges' spatial hash: a cell holds some 9 edges of a layer (it is over one and a half
    grid cells wide), so half as many buckets as edges leave most buckets to one cell."""
    return hash_table_size(edges // 4)


class DeviceState:
    """``x``/``v`` are the current state; ``x_next``/``v_next`` receive a pass's output, after which the
    pass swaps them. ``parity`` says which buffer of each pair is current: a captured graph replays fixed
    buffers, so it is only valid at the parity it was captured at."""

    def __init__(self, positions: np.ndarray, velocities: np.ndarray, model: DeviceModel, clock: int = 0) -> None:
        device = self.device = model.device
        x = wp.array(positions, dtype=wp.vec3, device=device)
        v = wp.array(velocities, dtype=wp.vec3, device=device)
        self._x = (x, wp.empty_like(x))
        self._v = (v, wp.empty_like(v))
        self.clock = wp.array([clock], dtype=int, device=device)  # substeps since time 0 (see shot_clock)
        self.lines_backwards = wp.zeros(1, dtype=int, device=device)  # 1: the next line round goes backwards
        self.parity = 0
        start = model.collider_kinds[Spheres].initial_center
        start = start if start is not None else np.zeros((0, 3), dtype=np.float32)
        self.sphere_center = wp.array(start, dtype=wp.vec3, device=device)
        self.sphere_velocity = wp.zeros(len(start), dtype=wp.vec3, device=device)
        # what each position's compensated sum has rounded away so far (empty where the moves add plainly)
        self.rounded_away = wp.zeros(len(positions) if model.compensated else 0, dtype=wp.vec3, device=device)
        # each particle's acceleration by the wind this substep: the wind pass writes it, the integration reads
        # it (empty without wind)
        self.wind = wp.zeros(len(positions) if model.wind is not None else 0, dtype=wp.vec3, device=device)
        self.contacts = None if model.contacts is None else self._contact_state(model)
        self.edges = None if model.contacts is None or model.contacts.edges is None else self._edge_state(model)

    def _contact_state(self, model: DeviceModel) -> ContactState:
        n, device = model.particle_count, model.device
        settings = model.contacts.settings
        per_list = n * settings.max_neighbors
        table = hash_table_size(n) if uses_hash(n) else 0
        zeros = lambda count, dtype=int: wp.zeros(count, dtype=dtype, device=device)  # noqa: E731
        far = wp.full(n, wp.vec3(1.0e30), dtype=wp.vec3, device=device)  # lists never made: remake at once
        return ContactState(neighbors=zeros(per_list), counts=zeros(n), x_built=far,
                            rebuild=zeros(1), epoch=zeros(1), overflow=zeros(1), bucket_size=zeros(table),
                            bucket_items=zeros(table * BUCKET_CAPACITY), pushed=zeros(n, float),
                            resting=zeros(n if model.has_colliders else 0), v_start=zeros(n, wp.vec3))

    def _edge_state(self, model: DeviceModel) -> EdgeListState:
        m, device = model.contacts.edges.ends.shape[0], model.device
        return EdgeListState(neighbors=wp.zeros(m * EDGE_NEIGHBORS, dtype=int, device=device),
                             counts=wp.zeros(m, dtype=int, device=device))

    @property
    def x(self) -> wp.array:
        return self._x[self.parity & 1]

    @property
    def x_next(self) -> wp.array:
        return self._x[1 - (self.parity & 1)]

    @property
    def v(self) -> wp.array:
        return self._v[(self.parity >> 1) & 1]

    @property
    def v_next(self) -> wp.array:
        return self._v[1 - ((self.parity >> 1) & 1)]

    def swap_positions(self) -> None:
        self.parity ^= 1

    def swap_velocities(self) -> None:
        self.parity ^= 2

    def carried(self) -> dict[str, wp.array]:
        """Every array a substep reads before writing it, by name: what a checkpoint keeps."""
        arrays = {"x": self.x, "v": self.v, "clock": self.clock, "lines_backwards": self.lines_backwards,
                  "sphere_center": self.sphere_center, "sphere_velocity": self.sphere_velocity}
        if self.rounded_away.shape[0] > 0:
            arrays["rounded_away"] = self.rounded_away
        if self.contacts is not None:
            arrays.update({f"contacts.{name}": getattr(self.contacts, name) for name in ContactState.CARRIED})
        if self.edges is not None:
            arrays.update({f"edges.{name}": getattr(self.edges, name) for name in EdgeListState.CARRIED})
        return arrays
