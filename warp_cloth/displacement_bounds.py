"""Displacement bounds (issue 34): a step that never creates a crossing, as in Offset Geometric Contact
(Chen et al. 2025). A substep records where it starts; after the integrator and the solves every vertex's
bound is measured there (the nearest vertex-triangle and edge-edge pairs that are contacts, surface_pairs.py,
within the query radius), each
particle's displacement from the start is clamped to its bound and its velocity made the clamped displacement
over the substep, before the contact velocities where the scene has them (kernels/displacement_bounds.py,
whose docstring proves that no pair of triangles apart at the start then crosses). With ``rounds`` above 1,
the bounds are measured again where a clamp left the particles and the rest of each step clamped to them, so
that a step may go farther than the start's bounds allow and still never cross.

Inside the converged solve of particle collision the bounds are held too: measured where the substep started
before the solve (within a radius wide enough for the step's motion so far), every particle is put back
within its bound after each separating pass, so that the solve converges to limits and contacts that hold
within the bounds, and the clamp after it, to the same bounds, has little left to do. The
clamp after the solve alone undid the limits: the fold at 4 mm landed at +15.3% / -19.6% with surfaces 0.62 of
the thickness apart, against +10.4% / -10.4% and 0.95 with the bounds held inside (docs/notebook/layers.md,
"Sides where the substep started, and the bounds inside the solve").

With a thickness, the bounds are measured again where the solve held particles at them (``MeasureAgain``, as
OGC detects collisions again in its iterations): each round moves the bounds' anchor to where the solve left
every particle, sends the held ones on to where the step would take them and solves again within bounds
measured at the new anchor, so the substep's path is a chain of moves each within bounds measured where it
starts, and crosses nothing. Measured once a substep, the bounds capped a layer's sliding over another at
0.45 gap / h (a sheet thrown at 4 m/s over another 5 mm below kept 1.35 m/s at 10 substeps of 60 fps; it
keeps 4 m/s with two rounds a substep); seed_default at 4 mm, its cloth sliding at some 25 m/s, ended at
+286%, and holds +10.5% measured again (docs/notebook/layers.md, "The bounds measured again inside the
substep"). The last round's hold, every particle put back within its bound, is the substep's clamp.

The query radius is the settings' or, where the step's longest motion asks for more, motion / gamma: OGC
bounds a vertex with nothing within the radius at gamma times the radius, which at a fixed radius caps the
speed of a cloth falling through empty air (0.56 thicknesses a substep at 1.25 thicknesses); measured after
the step (before a converged solve that holds them, else after the solves), the radius follows it, and a
particle with nothing near takes its whole step. One radius for all gives every particle room for the solve's
corrections beyond its own step: each particle's own radius held the slow ones short of their limits'
corrections (seed_default at 4 mm and its 17 substeps: +16.0% in 18 frames against +10.5%), and, given room for
them and the rounds to catch the rest, measured no faster on an H200 (docs/notebook/layers.md, "Each particle's
own query radius, with the rounds").

A scene with a surface thickness (``[collision] thickness``) has them at ``for_thickness``'s settings, and
reads them off the surface contacts' lists, which hold every pair they need (kernels/listed_distances.py),
instead of searching for them. The lab's ``lab_hooks`` set other settings (more clamp rounds, fewer
measures again), or put them on a
scene without one (particle contacts alone), where the bounds' own search (kernels/primitive_distances.py)
measures them. The simulator makes one ``DisplacementBounds`` where either asks, and hands it to every plan
it builds (warp_cloth/plan.py: its ``record_start`` pass first; with a thickness, its ``choose`` pass (the
query radii) before the candidate lists, whose face and edge pairs reach as far as the bounds may let
particles move (kernels/surface_reach.py), and ``BoundsFromLists`` after them; else, where a converged solve
follows, its ``measure`` pass before the lists; its ``hold`` pass inside a converged solve and its
``clamp_held`` after the solves (with a thickness, ``MeasureAgain`` instead); elsewhere its ``clamp`` pass
after the solves)"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator, NamedTuple

import numpy as np
import warp as wp

from warp_cloth.kernels import displacement_bounds, listed_distances, primitive_distances
from warp_cloth.kernels.edge_collision import EdgeContacts
from warp_cloth.kernels.face_collision import FaceContacts as FaceContactsArgs
from warp_cloth.kernels.primitive_distances import Primitives

from .adjacency import Adjacency
from .counted_hash import CountedHash
from .device_model import DeviceModel
from .mesh_io import triangle_sides
from .model import Model
from .state import DeviceState, hash_table_size

if TYPE_CHECKING:
    from .limit_solve import ConvergedProjection
    from .neighbour_lists import NeighbourLists


@dataclass(frozen=True)
class BoundSettings:
    """``radius``: the least query radius r in metres (a step's longest motion / gamma widens it); ``gamma``:
    below 1/2; ``rounds``: clamps a substep, each after bounds measured where the last left the particles (1:
    the start's alone); ``again``: with a thickness, the most rounds a substep in which the bounds are measured
    again where the solve held particles at them and the solve is run again (``MeasureAgain``)."""
    radius: float = 0.01
    gamma: float = 0.45
    rounds: int = 1
    again: int = 32

    def __post_init__(self) -> None:
        if not (0.0 < self.gamma < 0.5 and self.radius > 0.0 and self.rounds >= 1 and self.again >= 0):
            raise ValueError(f"displacement bounds need 0 < gamma < 1/2, a radius above 0 and a round, got {self}")

    @classmethod
    def parse(cls, spec: str) -> BoundSettings | None:
        """A tool's spec: ``off`` (None), ``on`` (the defaults) or comma-separated ``radius=``, ``gamma=``,
        ``rounds=``."""
        if spec == "off":
            return None
        values = {} if spec == "on" else dict(item.split("=") for item in spec.split(","))
        return cls(**{k: (int if k in ("rounds", "again") else float)(v) for k, v in values.items()})

    @classmethod
    def for_thickness(cls, thickness: float) -> BoundSettings:
        """The bounds of surfaces held ``thickness`` metres apart: the query radius ``RADIUS_THICKNESSES``
        thicknesses, the rest the defaults (the stacked drape's measured setting, docs/notebook/layers.md)."""
        return cls(radius=RADIUS_THICKNESSES * thickness)


# The query radius, in thicknesses: above 1, so that pairs held at the thickness are measured at their
# distance (a bound of gamma times it); the least radius: a step that moves a particle farther than gamma
# times it widens it (``widen_to_motion``), so no particle is held short for want of radius. 2.5 measured
# the same quality at 1.3 to 1.45 times the time on a stack of fine cells (3 x 32^2 at 0.5 m, 4 mm, CPU):
# its reach filled the edge lists with the sheets' own neighbouring edges (docs/notebook/layers.md).
RADIUS_THICKNESSES = 1.25


# The lab's hook: simulators built while it is set clamp their steps to these bounds, with or without a
# surface thickness.
BOUNDS: BoundSettings | None = None


@contextmanager
def lab_hooks(bounds: BoundSettings | None = None) -> Iterator[None]:
    """Simulators built inside take these bounds (None: the scene's, those of its thickness or none; the
    lab's and tests', never a scene's)."""
    global BOUNDS
    before = BOUNDS
    BOUNDS = bounds
    try:
        yield
    finally:
        BOUNDS = before


def mesh_primitives(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """Every cloth's triangles, (t, 3), and their edges once each, (m, 2), in the model's particle numbers."""
    triangles = model.triangles
    return triangles, triangle_sides(triangles, model.particle_count).astype(np.int32)


class DisplacementBounds:
    """The bounds' arrays and their passes (``record_start``, ``measure``, ``hold``, ``clamp`` and
    ``clamp_held``), made once per simulator."""

    def __init__(self, model: Model, device_model: DeviceModel, settings: BoundSettings) -> None:
        self.settings = settings
        self.device_model = device_model
        device = self.device = device_model.device
        n = self.n = model.particle_count
        triangles, ends = mesh_primitives(model)
        self.edge_count = len(ends)
        order = np.argsort(triangles[:, 0], kind="stable")
        owned_offsets = np.zeros(n + 1, dtype=np.int32)
        np.cumsum(np.bincount(triangles[:, 0], minlength=n), out=owned_offsets[1:])
        edges_at = Adjacency.of(ends, n)
        mesh = self.mesh = Primitives()
        mesh.triangles = wp.array(triangles, dtype=wp.vec3i, device=device)
        mesh.owned_offsets = wp.array(owned_offsets, dtype=int, device=device)
        mesh.owned = wp.array(order.astype(np.int32), dtype=int, device=device)
        mesh.ends = wp.array(ends, dtype=wp.vec2i, device=device)
        mesh.edge_offsets = wp.array(edges_at.offsets, dtype=int, device=device)
        mesh.edges_at = wp.array(edges_at.spring, dtype=int, device=device)
        mesh.rules = device_model.surface_rules(model)
        self.hash = CountedHash(n, hash_table_size(n), device)
        self.insert_always = wp.ones(1, dtype=int, device=device)  # the hash's request to fill: every table
        self.longest = wp.zeros(1, dtype=float, device=device)
        self.query = wp.zeros(1, dtype=float, device=device)  # the query radius last chosen
        self.nearest = wp.zeros(n, dtype=float, device=device)
        # where the bounds were last measured: where the substep started, until MeasureAgain moves it (a plan
        # that clamps after its solves never does, so there it is the start the clamp takes the velocity from)
        self.anchor = wp.zeros(n, dtype=wp.vec3, device=device)
        self.predicted = wp.zeros(n, dtype=wp.vec3, device=device)  # where the step would take the particles
        self.position = wp.zeros(n, dtype=wp.vec3, device=device)
        self.clamped = wp.zeros(settings.rounds, dtype=int, device=device)  # particles held short, by round
        self.held_back = wp.zeros(1, dtype=float, device=device)
        self.measured_again = wp.zeros(1, dtype=int, device=device)  # rounds of MeasureAgain
        self.left_held = wp.zeros(1, dtype=int, device=device)  # particles MeasureAgain left held, its rounds spent
        self.record_start = RecordStart(self)
        self.clamp = ClampToBounds(self, measured_before=False)
        self.measure = MeasureBounds(self)
        self.choose = ChooseQuery(self)
        self.hold = HoldWithinBounds(self)
        self.clamp_held = ClampToBounds(self, measured_before=True)  # after a solve that held ``measure``'s bounds

    @classmethod
    def of(cls, model: Model, device_model: DeviceModel) -> DisplacementBounds | None:
        """The bounds the lab's hook asks for now, else those of the scene's surface thickness (None: neither)."""
        contacts = device_model.contacts
        thickness = None if contacts is None else contacts.settings.thickness
        settings = BOUNDS if BOUNDS is not None or thickness is None else BoundSettings.for_thickness(thickness)
        return None if settings is None else cls(model, device_model, settings)

    def choose_query(self, x: wp.array, target: wp.array | None = None) -> None:
        """The query radius (``query``): the settings' radius, or, with the positions the step would take the
        particles from ``x`` to (``target``), wider where gamma times it would hold a free particle short of
        its step."""
        self.query.fill_(self.settings.radius)
        if target is not None:
            wp.launch(primitive_distances.widen_to_motion, dim=self.n,
                      inputs=[x, target, self.device_model.inv_mass, self.settings.gamma], outputs=[self.query],
                      device=self.device)

    def measure_at(self, x: wp.array, target: wp.array | None = None) -> None:
        """Each particle's nearest pair distance at positions ``x``, into ``nearest``, within the query radius
        (``choose_query``'s), found through the bounds' own spatial hash."""
        device, grid = self.device, self.hash.buckets
        self.choose_query(x, target)
        self.longest.zero_()
        wp.launch(primitive_distances.longest_edge, dim=self.edge_count, inputs=[x, self.mesh.ends],
                  outputs=[self.longest], device=device)
        wp.launch(primitive_distances.choose_cells, dim=1, inputs=[self.query, self.longest], outputs=[grid.inv_width],
                  device=device)
        self.hash.fill(x, self.mesh.rules.world, self.insert_always)
        wp.launch(primitive_distances.fill_with_radius, dim=self.n, inputs=[self.query], outputs=[self.nearest],
                  device=device)
        wp.launch(primitive_distances.nearest_to_triangles, dim=self.n,
                  inputs=[x, self.mesh, grid, self.query, self.longest], outputs=[self.nearest], device=device)
        wp.launch(primitive_distances.nearest_between_edges, dim=self.edge_count,
                  inputs=[x, self.mesh, grid, self.query, self.longest], outputs=[self.nearest], device=device)

    QUERY_LAUNCHES = ["the query radius filled with the settings'", "widen_to_motion"]  # choose_query's
    MEASURE_LAUNCHES = [*QUERY_LAUNCHES, "a zeroed longest edge",
                        "longest_edge", "choose_cells", *(k.key for k in CountedHash.kernels), "fill_with_radius",
                        "nearest_to_triangles", "nearest_between_edges"]

    def read_stats(self) -> BoundStats:
        """What the bounds held back since the last reading (waits for the device)."""
        stats = BoundStats(self.clamped.numpy().tolist(), float(self.held_back.numpy()[0]),
                           int(self.measured_again.numpy()[0]), int(self.left_held.numpy()[0]))
        for counter in (self.clamped, self.held_back, self.measured_again, self.left_held):
            counter.zero_()
        return stats


class BoundStats(NamedTuple):
    held_short: list[int]  # particles the clamp after the solve held short, by clamp round
    held_back: float  # the distance they gave up, metres, summed
    measured_again: int  # the rounds in which the bounds were measured again inside a substep (MeasureAgain)
    left_held: int  # the particles it left held at their bounds, predicted beyond, its rounds spent (summed)


class RecordStart:
    """The substep's first pass: where it starts, from which the clamp measures the bounds and each step."""

    name = "bounds:start"

    def __init__(self, bounds: DisplacementBounds) -> None:
        self.bounds = bounds

    def describe(self) -> list[str]:
        return [f"{self.name}:", "    a copy of the positions (the bounds' anchor)"]

    def run(self, state: DeviceState) -> None:
        wp.copy(self.bounds.anchor, state.x)


class MeasureBounds:
    """Before the solves: the bounds measured where the substep started, within a query radius wide enough
    for the step's motion so far, for ``HoldWithinBounds`` in the solve."""

    name = "bounds:measure"

    def __init__(self, bounds: DisplacementBounds) -> None:
        self.bounds = bounds

    def describe(self) -> list[str]:
        return [f"{self.name}:"] + [f"    {launch}" for launch in DisplacementBounds.MEASURE_LAUNCHES]

    def run(self, state: DeviceState) -> None:
        self.bounds.measure_at(self.bounds.anchor, state.x)


class ChooseQuery:
    """Before the surface contacts' lists (with a thickness): the query radius, wide enough for the step's
    motion so far from where the substep started; gamma times it is every free particle's reach in the lists
    (kernels/surface_reach.py), from which ``BoundsFromLists`` reads the bounds."""

    name = "bounds:query"

    def __init__(self, bounds: DisplacementBounds) -> None:
        self.bounds = bounds

    def describe(self) -> list[str]:
        return [f"{self.name}:", "    a copy of the positions (where the step would take the particles)"] + \
            [f"    {launch}" for launch in DisplacementBounds.QUERY_LAUNCHES]

    def run(self, state: DeviceState) -> None:
        wp.copy(self.bounds.predicted, state.x)
        self.bounds.choose_query(self.bounds.anchor, state.x)


class BoundsFromLists:
    """After the surface contacts' lists (with a thickness): the bounds read off them where the substep
    started (kernels/listed_distances.py; the lists hold every pair the substep's bounds need), for
    ``HoldWithinBounds`` in the solve. A search of the bounds' own (``MeasureBounds``) cost the stacked drape
    a third of a substep's time on an H200 (docs/notebook/layers.md)."""

    name = "bounds:from-lists"
    kernels = [listed_distances.nearest_listed_triangles, listed_distances.nearest_listed_vertices,
               listed_distances.nearest_listed_edges]

    def __init__(self, bounds: DisplacementBounds, faces: FaceContactsArgs, edges: EdgeContacts) -> None:
        self.bounds, self.faces, self.edges = bounds, faces, edges

    def describe(self) -> list[str]:
        return [f"{self.name}:"] + [f"    {kernel.key}" for kernel in self.kernels]

    def run(self, state: DeviceState) -> None:
        bounds, device = self.bounds, state.device
        start, nearest = bounds.anchor, bounds.nearest
        wp.launch(listed_distances.nearest_listed_triangles, dim=bounds.n, inputs=[start, self.faces, bounds.query],
                  outputs=[nearest], device=device)
        wp.launch(listed_distances.nearest_listed_vertices, dim=self.faces.triangles.shape[0],
                  inputs=[start, self.faces], outputs=[nearest], device=device)
        wp.launch(listed_distances.nearest_listed_edges, dim=self.edges.ends.shape[0], inputs=[start, self.edges],
                  outputs=[nearest], device=device)


class HoldWithinBounds:
    """Inside the solve, after each separating pass: every particle held within the bounds ``MeasureBounds``
    or ``BoundsFromLists`` measured, in place, so that the solve converges to positions the clamp after it
    leaves as they are."""

    name = "bounds:hold"

    def __init__(self, bounds: DisplacementBounds) -> None:
        self.bounds = bounds

    def describe(self) -> list[str]:
        return [f"{self.name}:", f"    {displacement_bounds.hold_within_bounds.key}"]

    def run(self, state: DeviceState) -> None:
        bounds = self.bounds
        model = bounds.device_model
        wp.launch(displacement_bounds.hold_within_bounds, dim=bounds.n,
                  inputs=[bounds.anchor, bounds.nearest, bounds.settings.gamma, model.inv_mass, 1.0 / model.h],
                  outputs=[state.x, state.v], device=state.device)


class ClampToBounds:
    """After the solves: the bounds measured where the substep started, within a query radius wide enough for
    the step's longest motion (or, ``measured_before``, those ``MeasureBounds`` measured before a solve that
    held them), and each particle's step from the start clamped to its bound (in rounds, the bounds measured
    again where the last clamp left the particles, for the rest of the step), then the particles held short
    moved there, with the velocity of their clamped step.

    Bounds measured at the start within any radius keep the guarantee (kernels/displacement_bounds.py: a pair
    within the radius bounds its vertices by gamma times its distance, one beyond it by gamma times the
    radius); the radius only decides how far a particle with nothing near may go. After a solve that held
    the bounds measured before it, only its acceleration's last extrapolation can have moved a particle past
    them, and the same bounds clamp it."""

    name = "bounds:clamp"

    def __init__(self, bounds: DisplacementBounds, measured_before: bool) -> None:
        self.bounds = bounds
        self.measured_before = measured_before

    def describe(self) -> list[str]:
        rounds = self.bounds.settings.rounds
        measure_and_clamp = DisplacementBounds.MEASURE_LAUNCHES + [displacement_bounds.clamp_to_bounds.key]
        first = [displacement_bounds.clamp_to_bounds.key] if self.measured_before else measure_and_clamp
        lines = [f"{self.name}:", "    a copy of the start"] + [f"    {launch}" for launch in first]
        if rounds > 1:
            lines += [f"    then {rounds - 1} more rounds of:"] + [f"      {launch}" for launch in measure_and_clamp]
        return lines + [f"    {displacement_bounds.take_bounded_step.key}"]

    def run(self, state: DeviceState) -> None:
        bounds, device = self.bounds, state.device
        model = bounds.device_model
        wp.copy(bounds.position, bounds.anchor)
        for slot in range(bounds.settings.rounds):
            if slot > 0 or not self.measured_before:
                bounds.measure_at(bounds.position, state.x)
            wp.launch(displacement_bounds.clamp_to_bounds, dim=bounds.n,
                      inputs=[state.x, bounds.nearest, bounds.settings.gamma, model.inv_mass, bounds.position,
                              bounds.clamped, slot], device=device)
        wp.launch(displacement_bounds.take_bounded_step, dim=bounds.n,
                  inputs=[bounds.anchor, bounds.position, 1.0 / model.h],
                  outputs=[state.x, state.v, bounds.held_back], device=device)


class MeasureAgain:
    """After the converged solve (with a thickness), in place of the clamp: where it left particles held at
    their bounds with their predicted positions beyond, the bounds measured again there and the solve run
    again within them, up to ``settings.again`` times a substep. Each round moves every particle's anchor to where the solve left it,
    sends the held ones on to their predicted positions, and makes the query radius, the lists
    (``lists``, from the new anchors) and the bounds (``from_lists``) anew before the solve
    (``projection``). Each move of the path stays within bounds measured where it starts, so the substep
    still crosses nothing, and a layer sliding over another goes 0.45 of their gap farther each round."""

    name = "bounds:again"

    def __init__(self, bounds: DisplacementBounds, lists: NeighbourLists, from_lists: BoundsFromLists,
                 projection: ConvergedProjection) -> None:
        self.bounds, self.lists, self.from_lists, self.projection = bounds, lists, from_lists, projection
        device = bounds.device
        self.rounds = wp.zeros(1, dtype=int, device=device)  # rounds left in this substep
        self.again = wp.zeros(1, dtype=int, device=device)  # whether to run another

    def describe(self) -> list[str]:
        kernels = displacement_bounds
        return [f"{self.name}, up to {self.bounds.settings.again} times while a particle is held at its bound:",
                f"    {kernels.hold_within_bounds.key}, {kernels.start_round.key}, {kernels.find_held.key} "
                "(whether to go on)",
                "  each round:", f"    {kernels.send_on.key}", "    end_remake_once",
                *(f"    {launch}" for launch in DisplacementBounds.QUERY_LAUNCHES),
                f"    {self.lists.name}", f"    {self.from_lists.name}",
                f"    {self.projection.name}",
                f"    {kernels.hold_within_bounds.key}, {kernels.start_round.key}, {kernels.find_held.key}"]

    def run(self, state: DeviceState) -> None:
        self.rounds.fill_(self.bounds.settings.again)
        self._find_held(state)
        wp.capture_while(self.again, lambda: self._round(state))

    def _find_held(self, state: DeviceState) -> None:
        """Every particle put back within its bound first (the solve's last acceleration may have moved it past:
        an anchor must be where a move within the bounds ended), then whether to measure again."""
        bounds = self.bounds
        bounds.hold.run(state)
        wp.launch(displacement_bounds.start_round, dim=1, outputs=[self.rounds, self.again], device=state.device)
        wp.launch(displacement_bounds.find_held, dim=bounds.n,
                  inputs=[bounds.anchor, bounds.nearest, bounds.settings.gamma, bounds.device_model.inv_mass,
                          state.x, bounds.predicted, self.rounds],
                  outputs=[self.again, bounds.measured_again, bounds.left_held], device=state.device)

    def _round(self, state: DeviceState) -> None:
        bounds = self.bounds
        model = bounds.device_model
        wp.launch(displacement_bounds.send_on, dim=bounds.n,
                  inputs=[bounds.nearest, bounds.settings.gamma, model.inv_mass, bounds.predicted, 1.0 / model.h],
                  outputs=[bounds.anchor, state.x, state.v], device=state.device)
        self.lists.end_remake()
        bounds.choose_query(bounds.anchor, state.x)
        self.lists.run(state)
        self.from_lists.run(state)
        self.projection.run(state)
        self._find_held(state)
