"""Particle collision's candidate lists, and the edge and face contacts' where the scene sets a thickness:
remade inside a substep where a particle has moved far enough since
they were made (or, with a thickness, where one may move past its allowance this substep: face_contacts.py),
or on demand outside one; and the closest contact they show."""

from __future__ import annotations

from typing import Protocol

import numpy as np
import warp as wp

from warp_cloth.kernels import edge_collision, particle_collision, spatial_hash
from warp_cloth.kernels.gathering import load_gathering
from warp_cloth.kernels.particle_collision import ListState
from warp_cloth.kernels.neighbour_search import (HashGrid, gather_edge_candidates, gather_neighbors_kernel,
                                                 launch_gather_neighbors)

from .counted_hash import CountedHash
from .device_model import DeviceModel
from .displacement_bounds import DisplacementBounds
from .passes import contacts_args, edge_contacts_args
from .state import (BUCKET_CAPACITY, DeviceState, edge_hash_table_size, hash_table_size,
                    uses_hash)

# The remake has more to gather (27 cells) than the other gathering passes: 16 threads a particle are
# fastest at 64^2, 4 at 256^2, one at 1024^2 (docs/results/list-probe-h200.json).
LIST_THREADS_BY_SIZE = ((8192, 16), (131072, 4))

# Tests and the bench set this to remake the lists in every substep: the same contacts as lists kept until
# a particle has moved far enough (a reference for them), at the broad phase's full cost.
REMAKE_EVERY_SUBSTEP = False


def rebuild_distance(model: DeviceModel) -> float:
    """How far a particle moves before the lists are remade: a pair left out of a list was farther apart
    than ``SEARCH_SCALE`` contact distances when it was made, so it cannot touch before then."""
    contacts = model.contacts
    return 0.5 * (contacts.rules.search_scale - 1.0) * contacts.settings.separation * contacts.min_radius


def widest_reach(lists: SurfaceLists | EdgeLists) -> float:
    """The largest reach of a pair in the lists' last remake, metres: the thickness plus twice the largest
    allowance (waits for the device)."""
    return lists.thickness + 2.0 * float(lists.widest.numpy()[0])


class SurfaceLists(Protocol):
    """Candidate lists remade with the particle lists where the substep started, within allowances
    (the face contacts, face_contacts.py)."""

    asking: list[wp.Kernel]
    allowing: list[wp.Kernel]
    kernels: list[wp.Kernel]
    thickness: float
    allowance: wp.array
    widest: wp.array
    dropped: wp.array

    def ask_if_moved(self, start: wp.array, x: wp.array, bounds: DisplacementBounds, lists: ListState) -> None: ...

    def allow(self, start: wp.array, x: wp.array, bounds: DisplacementBounds, lists: ListState) -> None: ...

    def remake_if_asked(self, x: wp.array, lists: ListState) -> None: ...


class NeighbourLists:
    """The pass that remakes every particle's candidate list where ``rebuild`` is set (by the contacts'
    start, or at every substep with ``REMAKE_EVERY_SUBSTEP``), from the spatial hash or, up to
    ``BRUTE_FORCE_UP_TO`` particles, by checking all pairs; its kernels launch every substep and return at
    once otherwise.

    A pair left out of a list was farther apart than ``SEARCH_SCALE`` contact distances when it was made,
    so it cannot touch before some particle has moved ``rebuild_distance``. With ``faces`` (a thickness's,
    which brings ``bounds``), the face and edge lists are made where the substep started (the bounds' record),
    after the bounds were measured there, and a particle that may move past its allowance this substep asks
    for the remake too (kernels/surface_reach.py)."""

    def __init__(self, model: DeviceModel, state: DeviceState, threads: int, faces: SurfaceLists | None = None,
                 bounds: DisplacementBounds | None = None) -> None:
        settings = model.contacts.settings
        n = model.particle_count
        self.every_substep = REMAKE_EVERY_SUBSTEP
        self.name = "lists:remake" + ("" if self.every_substep else "-if-moved")
        self.contacts = contacts_args(model, state)
        self.rules = model.contacts.rules
        self.lists = state.contacts.lists()
        self.rebuild = state.contacts.rebuild
        self.state = state.contacts
        self.n = n
        self.rebuild_distance = rebuild_distance(model)
        self.use_hash = uses_hash(n)
        self.threads = threads if self.use_hash else 1
        self.grid = HashGrid()
        self.grid.inv_cell = 1.0 / (self.rules.search_scale * settings.separation * model.contacts.max_radius)
        self.grid.mask = (hash_table_size(n) if self.use_hash else 1) - 1
        self.grid.capacity = BUCKET_CAPACITY
        self.grid.bucket_size, self.grid.bucket_items = state.contacts.bucket_size, state.contacts.bucket_items
        # several threads a particle gather each list in two steps: the lists before their sort, and their lengths
        several = self.use_hash and self.threads > 1
        self.unsorted = wp.zeros(n * settings.max_neighbors if several else 0, dtype=int, device=model.device)
        self.appended = wp.zeros(n if several else 0, dtype=int, device=model.device)
        if self.use_hash:
            load_gathering(gather_neighbors_kernel(self.threads), self.threads, model.device)
        self.edges = EdgeLists(model, state, faces) if faces is not None else None  # a thickness brings both
        if self.edges is not None:
            self.name += "+edges"
        self.faces = faces
        if faces is not None:
            self.name += "+faces"
        self.bounds = bounds

    def run(self, state: DeviceState) -> None:
        if self.every_substep:
            self.rebuild.fill_(1)
        self._remake_if_asked(state.x, self.bounds.anchor if self.faces is not None else state.x)

    @property
    def kernels(self) -> list[wp.Kernel]:
        """What a substep launches, in order (each returns at once where no list is to be remade)."""
        particles = [spatial_hash.insert_points, gather_neighbors_kernel(self.threads)] if self.use_hash \
            else [particle_collision.gather_neighbors_brute_force]
        faces = self.faces
        return (faces.asking if faces is not None else []) + particles + \
            (faces.allowing if faces is not None else []) + (self.edges.kernels if self.edges is not None else []) + \
            (faces.kernels if faces is not None else [])

    def describe(self) -> list[str]:
        """For the printed plan: the pass and its launches."""
        return [f"{self.name}:"] + [f"    {kernel.key}" for kernel in self.kernels]

    def _remake_if_asked(self, x: wp.array, surface_x: wp.array) -> None:
        """The lists where asked: the particles' from ``x``, the surfaces' from ``surface_x``."""
        faces = self.faces
        if faces is not None:
            faces.ask_if_moved(surface_x, x, self.bounds, self.lists)
        if self.use_hash:
            wp.launch(spatial_hash.insert_points, dim=self.n,
                      inputs=[x, self.rules.world, self.grid.inv_cell, self.grid.mask, self.grid.capacity,
                              self.lists.epoch, self.rebuild],
                      outputs=[self.grid.bucket_size, self.grid.bucket_items, self.lists.overflow], device=x.device)
            launch_gather_neighbors(self.threads, x, [self.contacts, self.rules, self.lists, self.grid, self.unsorted,
                                                      self.appended])
        else:
            wp.launch(particle_collision.gather_neighbors_brute_force, dim=self.n,
                      inputs=[x, self.contacts, self.rules, self.lists], device=x.device)
        if faces is not None:
            faces.allow(surface_x, x, self.bounds, self.lists)
        if self.edges is not None:
            self.edges.remake_if_asked(surface_x, self.lists)
        if faces is not None:
            faces.remake_if_asked(surface_x, self.lists)

    def remake_now(self, x: wp.array) -> None:
        """Remake every particle's list from positions ``x`` now, outside a substep."""
        self.rebuild.fill_(1)
        self._remake_if_asked(x, x)
        self.end_remake()

    def end_remake(self) -> None:
        """Ends a remake (or none) before the lists are asked for again in the same substep (its end does the
        same in the contact velocities' pass): the request cleared and, where lists were remade, the particle
        hash's next epoch started, so that a second fill does not add to the first."""
        wp.launch(particle_collision.end_remake_once, dim=1, inputs=[self.lists], device=self.rebuild.device)

    def closest_contacts(self, x: wp.array, worlds: int, remake: bool = True) -> np.ndarray:
        """Each world's closest approach of two particles that may collide, as a fraction of their contact
        distance (infinite where none is listed; a diagnostic: it waits for the device). With ``remake`` it
        remakes the lists from ``x`` first, which the simulation may then go on using: they are as valid as
        any it makes itself."""
        if remake:
            self.remake_now(x)
        ratio = wp.full(worlds, 1.0e30, dtype=float, device=x.device)
        wp.launch(particle_collision.closest_contact_ratio, dim=self.n, inputs=[x, self.contacts, self.rules.world],
                  outputs=[ratio], device=x.device)
        ratios = ratio.numpy()
        return np.where(ratios >= 1.0e29, np.inf, ratios)  # the kernels' 1e30: nothing listed

    def closest_pair(self, x: wp.array) -> tuple[float, int, int, float] | None:
        """The closest approach of two particles that may collide, as a fraction of their contact distance,
        the two particles and that distance in metres (None where no pair is listed); the lists remade from
        ``x`` first (a diagnostic: it waits for the device)."""
        self.remake_now(x)
        ratio = wp.empty(self.n, dtype=float, device=x.device)
        partner = wp.empty(self.n, dtype=int, device=x.device)
        wp.launch(particle_collision.closest_contact_partner, dim=self.n, inputs=[x, self.contacts],
                  outputs=[ratio, partner], device=x.device)
        ratios, partners = ratio.numpy(), partner.numpy()
        i = int(np.argmin(ratios))
        if partners[i] < 0:
            return None
        j = int(partners[i])
        radius = self.contacts.radius.numpy()
        return float(ratios[i]), i, j, float(0.5 * self.contacts.separation * (radius[i] + radius[j]))

    @property
    def overflow(self) -> int:
        """Particle candidates (and contact edges', without a thickness) dropped so far, from a full list
        (which keeps the nearest) or a full hash bucket, at most ``spatial_hash.DROPPED_MOST`` (the count
        stops there; waits for the device)."""
        return int(self.lists.overflow.numpy()[0])

    @property
    def surface_dropped(self) -> int:
        """With a thickness, the surface pairs within reach left out of full lists so far (the farthest;
        waits for the device), as ``overflow`` counts; 0 without one."""
        return int(self.faces.dropped.numpy()[0]) if self.faces is not None else 0

    def candidates(self) -> list[np.ndarray]:
        """Each particle's candidate list as last made, in index order (waits for the device)."""
        counts = self.state.counts.numpy()
        table = self.state.neighbors.numpy().reshape(len(counts), -1)
        return [table[i, :count] for i, count in enumerate(counts)]


class EdgeLists:
    """Each contact edge's candidates (kernels/edge_collision.py), remade with the particle lists: from a
    spatial hash of the edges' midpoints whose buckets hold every edge (counted_hash.py), whose cells are as
    wide as the longest edge at the remake plus the reach (never narrower than the longest an edge may get,
    ``longest``, plus the reach: the cells of a remake without over-long edges), so that the 27 around an
    edge's midpoint hold every edge within reach.
    An edge's list holds the edges within the thickness plus both edges' allowances, the face contacts'
    (kernels/surface_reach.py)."""

    def __init__(self, model: DeviceModel, state: DeviceState, faces: SurfaceLists) -> None:
        constants = model.contacts.edges
        self.edges = edge_contacts_args(model, state)
        self.thickness = constants.thickness
        self.dropped = faces.dropped  # where a full list counts what it leaves out: the surface lists' count
        self.allowance, self.widest = faces.allowance, faces.widest
        self.rules = constants.rules
        self.m = constants.ends.shape[0]
        self.longest = constants.longest
        self.hash = CountedHash(self.m, edge_hash_table_size(self.m), model.device)
        self.midpoint = wp.zeros(self.m, dtype=wp.vec3, device=model.device)
        self.half_extent = wp.zeros(self.m, dtype=wp.vec3, device=model.device)
        self.placed_half_extents = wp.zeros(self.m, dtype=wp.vec3, device=model.device)  # in the buckets' order
        self.world = constants.world
        # the gather's scratch: the listed pairs' gaps while the lists are made, laid out as the lists
        self.gaps = wp.zeros(self.edges.neighbors.shape[0], dtype=float, device=model.device)

    kernels = [edge_collision.start_edge_cells, edge_collision.midpoints_and_cell_width, *CountedHash.kernels,
               spatial_hash.place_values, gather_edge_candidates]  # as remake_if_asked launches them

    def remake_if_asked(self, x: wp.array, lists: ListState) -> None:
        edges, buckets, device = self.edges, self.hash.buckets, x.device
        wp.launch(edge_collision.start_edge_cells, dim=1,
                  inputs=[lists.rebuild, self.longest, self.thickness, self.widest], outputs=[buckets.inv_width],
                  device=device)
        wp.launch(edge_collision.midpoints_and_cell_width, dim=self.m,
                  inputs=[x, edges.ends, lists.rebuild, self.longest, self.thickness, self.widest],
                  outputs=[self.midpoint, self.half_extent, buckets.inv_width], device=device)
        self.hash.fill(self.midpoint, self.world, lists.rebuild)
        wp.launch(spatial_hash.place_values, dim=self.m, inputs=[self.half_extent, lists.rebuild, buckets],
                  outputs=[self.placed_half_extents], device=device)
        wp.launch(gather_edge_candidates, dim=self.m,
                  inputs=[x, self.midpoint, self.world, edges, self.rules, lists, self.allowance, self.widest,
                          buckets, self.placed_half_extents, self.gaps, self.dropped],
                  device=device)
