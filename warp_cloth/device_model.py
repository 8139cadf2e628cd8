"""The model on the device: everything the passes read that does not change during a run, uploaded once
and owned here. What changes (positions, velocities, the clock, colliders' motion, contact state, the wind's
accelerations) is the state's (warp_cloth/state.py)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warp_cloth.kernels import motion, particle_collision
from warp_cloth.kernels.attachments import Attachments
from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.edge_collision import EdgeRules
from warp_cloth.kernels.forces import ExternalForces
from warp_cloth.kernels.limits import StrainLimits
from warp_cloth.kernels.particle_collision import Contacts, PairRules
from warp_cloth.kernels.bending import Bending
from warp_cloth.kernels.springs import Springs
from warp_cloth.kernels.wind import Wind

from . import surface_pairs
from .collider_kinds import KINDS, Meshes, upload
from .model import Model, Worlds
from .scene import Collision, Scene, WindKey

if TYPE_CHECKING:
    from .state import DeviceState


@dataclass(frozen=True)
class PinTarget:
    """Pinned particles that follow a mesh collider: each one's face, barycentric coordinates on it, and
    offset in the face's frame."""
    mesh: wp.Mesh
    index: wp.array
    face: wp.array
    bary: wp.array
    offset: wp.array
    soft: bool = False  # soft pins': where their springs pull is put there, not the particles


@dataclass(frozen=True)
class KeyedPins:
    """Pinned particles carried along sampled positions (see ``model.PinAnimation``)."""
    index: wp.array
    key_times: wp.array
    keys: wp.array  # (k, m) vec3
    soft: bool = False


@dataclass(frozen=True)
class SoftPins:
    """Soft pins' springs, per particle (zero where a particle has none: kernels/forces.py), and where they
    pull: their motion's passes put it there each substep before the step, a fixed soft pin's stays where
    it starts."""
    rate: wp.array  # (n,) stiffness / mass, 1/s^2
    damping: wp.array  # (n,) damping / mass, 1/s
    target_x: wp.array  # (n,) vec3
    target_v: wp.array  # (n,) vec3
    motion: PinMotion | None  # the oscillating ones'


@dataclass(frozen=True)
class PinMotion:
    """Pinned particles and their oscillations (zero amplitude for fixed pins)."""
    index: wp.array
    anchor: wp.array
    amplitude: wp.array
    frequency: wp.array
    phase: wp.array
    moving: bool


@dataclass(frozen=True)
class DeviceContactEdges:
    """Edge contacts' constants (kernels/edge_collision.py)."""
    ends: wp.array  # (m,) vec2i
    world: wp.array  # (m,) each edge's (its particles')
    incident_offsets: wp.array  # (n + 1,) each particle's edges (CSR)
    incident: wp.array
    rules: EdgeRules
    thickness: float  # how far apart edges are held: the scene's [collision] thickness
    longest: float  # the longest an edge may get (model.ContactEdges): a longer one widens the hash's cells


@dataclass(frozen=True)
class SeamClosing:
    """What the seams' pass writes the sewn pairs' allowed lengths from (model.SeamEntries)."""
    entry: wp.array
    start_length: wp.array
    close_time: wp.array
    closes_at: wp.array


@dataclass(frozen=True)
class ParticleContacts:
    """Particle collision's settings and per-particle constants."""
    settings: Collision
    radius: wp.array
    rules: PairRules
    max_radius: float
    min_radius: float
    surface_rules: EdgeRules  # which vertex-triangle and edge-edge pairs are contacts (surface_pairs.py)
    edges: DeviceContactEdges | None


class DeviceModel:
    """A model and its scene's settings on a device; an effect the scene does not declare is None here and
    costs no memory. ``h`` is the substep's length in seconds; ``masses``: upload the masses, not only their
    inverses (for an integrator that asks for them)."""

    def __init__(self, model: Model, scene: Scene, h: float, device, masses: bool = False) -> None:
        self.device = device
        self.particle_count = n = model.particle_count
        self.h = h
        simulation = scene.simulation
        self.inv_mass = upload(model.inv_mass, float, device)
        self.mass = upload(model.masses, float, device) if masses else None
        worlds = model.worlds if model.worlds is not None else Worlds.of_scene(scene)
        self.world_count = worlds.count
        world = model.particle_world
        self.particle_world = upload(world, int, device)
        self.world_start = upload(model.world_start, int, device)
        self.free_particles = upload(np.maximum(np.bincount(world[model.inv_mass != 0], minlength=worlds.count), 1),
                                     float, device)  # each world's, for RMS residuals
        self._gravity = upload(worlds.gravity, wp.vec3, device)
        self._drag = simulation.drag
        self.wind = self._wind(model, scene.wind)
        self.compensated = simulation.compensated
        self.springs = self._springs(model, n)
        self.bending = self._bending(model, n)
        self.limits = self._limits(model)
        self.seams = self._seams(model)  # None: no seam
        self.attachments = self._attachments(model)  # None: no cloth has attachments to its pins
        hard = None if model.pins is None else ~model.pins.soft
        self.pins = None if hard is None or not hard.any() else self._pin_motion(model, hard)  # the hard pins
        self.soft_pins = self._soft_pins(model)
        self.pin_targets: tuple[PinTarget, ...] = ()
        self.keyed_pins = tuple(KeyedPins(upload(a.index, int, device), upload(a.key_times, float, device),
                                          upload(a.key_points, wp.vec3, device), a.soft)
                                for a in model.pin_animations)
        # the rigid colliders, by kind (collider_kinds.KINDS), and the passes that move them
        self.collider_kinds = {kind: kind(model, scene, worlds, device, h) for kind in KINDS}
        self.has_colliders = any(kind.present for kind in self.collider_kinds.values())
        self.collider_motion = tuple(kind.motion for kind in self.collider_kinds.values() if kind.motion is not None)
        if model.pins is not None and (model.pins.target >= 0).any():
            self.pin_targets = self._pin_targets(model)
        self.contacts = None if model.contacts is None else self._contacts(model, scene.collision)
        self.cloth_friction = upload(model.friction if model.friction is not None else np.zeros(0), float, device)
        self.no_marks = wp.zeros(0, dtype=int, device=device)  # for passes whose colliders mark no one
        self._no_colliders = no_colliders(device)

    def set_step(self, h: float) -> None:
        """A substep of ``h`` seconds from now on (between frames, where the simulator chooses the substeps):
        the passes that move the colliders take it at once; a plan built before keeps its own, so the
        simulator builds its plan again."""
        self.h = h
        for moving in self.collider_motion:
            moving.h = h

    def _springs(self, model: Model, n: int) -> Springs:
        """The spring adjacency and parameters (offsets all zero and the rest empty without springs)."""
        device, springs = self.device, Springs()
        if model.springs is None:
            springs.offsets = wp.zeros(n + 1, dtype=int, device=device)
            springs.other = springs.spring = springs.flags = wp.zeros(0, dtype=int, device=device)
            springs.rest = springs.stiffness = springs.damping = wp.zeros(0, dtype=float, device=device)
            return springs
        adjacency = model.springs.adjacency
        springs.offsets = upload(adjacency.offsets, int, device)
        springs.other = upload(adjacency.other, int, device)
        springs.spring = upload(adjacency.spring, int, device)
        springs.rest = upload(model.springs.rest, float, device)
        springs.stiffness = upload(model.springs.stiffness, float, device)
        springs.damping = upload(model.springs.damping, float, device)
        springs.flags = upload(model.springs.flags, int, device)
        return springs

    def _bending(self, model: Model, n: int) -> Bending:
        """The bending stencils and their incidences (offsets all zero and the rest empty without them)."""
        device, bending = self.device, Bending()
        stencils = model.bending
        if stencils is None:
            bending.offsets = wp.zeros(n + 1, dtype=int, device=device)
            bending.stencil = bending.entry = bending.particles = wp.zeros(0, dtype=int, device=device)
            bending.starts = wp.zeros(1, dtype=int, device=device)
            bending.weights = bending.stiffness = bending.damping = wp.zeros(0, dtype=float, device=device)
            return bending
        offsets, stencil, entry = stencils.incidences(n)
        bending.offsets = upload(offsets, int, device)
        bending.stencil = upload(stencil, int, device)
        bending.entry = upload(entry, int, device)
        bending.starts = upload(stencils.starts, int, device)
        bending.particles = upload(stencils.particles, int, device)
        bending.weights = upload(stencils.weights, float, device)
        bending.stiffness = upload(stencils.stiffness, float, device)
        bending.damping = upload(stencils.damping, float, device)
        return bending

    def _limits(self, model: Model) -> StrainLimits | None:
        if model.limits is None:
            return None
        device, lim, limits = self.device, model.limits, StrainLimits()
        limits.offsets = upload(lim.offsets, int, device)
        limits.other = upload(lim.other, int, device)
        limits.min_length = upload(lim.min_length, float, device)
        limits.max_length = upload(lim.max_length, float, device)
        limits.residual_length = upload(lim.seams.residual_length if lim.seams is not None else np.zeros(0), float,
                                        device)
        return limits

    def _seams(self, model: Model) -> SeamClosing | None:
        seams = model.limits.seams if model.limits is not None else None
        if seams is None:
            return None
        device = self.device
        return SeamClosing(upload(seams.entry, int, device), upload(seams.start_length, float, device),
                           upload(seams.close_time, float, device), upload(seams.closes_at, float, device))

    def _attachments(self, model: Model) -> Attachments | None:
        if model.limits is None or len(model.limits.attachment_pin) == 0:
            return None
        attachments, lim = Attachments(), model.limits
        attachments.pin = upload(lim.attachment_pin, int, self.device)
        attachments.length = upload(lim.attachment_length, float, self.device)
        springs = lim.max_length if lim.seams is None else np.delete(lim.max_length, lim.seams.entry)
        attachments.chord_half = 0.5 * float(springs.max(initial=0.0))
        return attachments

    def _contacts(self, model: Model, settings: Collision) -> ParticleContacts:
        device, contacts, rules = self.device, model.contacts, PairRules()
        rules.world = self.particle_world
        rules.cloth_id = upload(model.cloth_id, int, device)
        rules.self_collision = int(settings.self_collision)
        rules.between_cloths = int(settings.between_cloths)
        if contacts.exclude_adjacent is None:
            rules.adjacent_offsets = rules.adjacent_other = rules.exclude_adjacent = wp.zeros(0, dtype=int,
                                                                                              device=device)
        else:
            rules.adjacent_offsets = upload(contacts.rest_adjacent.offsets, int, device)
            rules.adjacent_other = upload(contacts.rest_adjacent.other, int, device)
            rules.exclude_adjacent = upload(contacts.exclude_adjacent, int, device)
        if contacts.sewn is None:
            rules.sewn_offsets = rules.sewn_other = wp.zeros(0, dtype=int, device=device)
        else:
            rules.sewn_offsets = upload(contacts.sewn.offsets, int, device)
            rules.sewn_other = upload(contacts.sewn.other, int, device)
        rules.search_scale = particle_collision.SEARCH_SCALE
        surface = surface_pairs.surface_rules(model, rules, device)
        return ParticleContacts(settings, upload(contacts.radius, float, device), rules, contacts.max_radius,
                                float(contacts.radius.min()), surface,
                                self._contact_edges(model, surface, settings.thickness))

    def surface_rules(self, model: Model) -> EdgeRules:
        """Which vertex-triangle and edge-edge pairs are contacts (surface_pairs.py): particle collision's, or
        every pair of a world where the scene has none."""
        if self.contacts is not None:
            return self.contacts.surface_rules
        return surface_pairs.surface_rules(model, None, self.device)

    def _contact_edges(self, model: Model, rules: EdgeRules, thickness: float | None) -> DeviceContactEdges | None:
        contacts, device = model.contacts, self.device
        edges = contacts.edges
        if edges is None:
            return None
        return DeviceContactEdges(upload(edges.ends, wp.vec2i, device),
                                  upload(model.particle_world[edges.ends[:, 0]], int, device),
                                  upload(edges.incidence.offsets, int, device),
                                  upload(edges.incidence.spring, int, device), rules, thickness, edges.longest)

    def forces(self, wind: wp.array) -> ExternalForces:
        """The external forces as the kernels take them, each particle's wind acceleration in ``wind`` (the
        state's, which the wind pass rewrites every substep)."""
        forces = ExternalForces()
        forces.gravity, forces.world, forces.drag, forces.wind = self._gravity, self.particle_world, self._drag, wind
        soft = self.soft_pins
        if soft is None:
            forces.pin_rate = forces.pin_damping = wp.zeros(0, dtype=float, device=self.device)
            forces.pin_x = forces.pin_v = wp.zeros(0, dtype=wp.vec3, device=self.device)
        else:
            forces.pin_rate, forces.pin_damping, forces.pin_x, forces.pin_v = (soft.rate, soft.damping, soft.target_x,
                                                                               soft.target_v)
        return forces

    def _pin_motion(self, model: Model, rows: np.ndarray) -> PinMotion:
        pins, device = model.pins, self.device
        return PinMotion(upload(pins.index[rows], int, device), upload(pins.anchor[rows], wp.vec3, device),
                         upload(pins.amplitude[rows], wp.vec3, device), upload(pins.frequency[rows], float, device),
                         upload(pins.phase[rows], float, device), bool(np.any(pins.amplitude[rows] != 0.0)))

    def _soft_pins(self, model: Model) -> SoftPins | None:
        """The soft pins' springs, pulling toward where their particles start (the model's start: where
        their motion puts them then) until a pass moves that."""
        pins = model.pins
        if pins is None or not pins.soft.any():
            return None
        soft, n, device = pins.soft, model.particle_count, self.device
        index = pins.index[soft]
        rate, damping = np.zeros(n, dtype=np.float32), np.zeros(n, dtype=np.float32)
        rate[index] = pins.stiffness[soft] / model.masses[index]
        damping[index] = pins.damping[soft] / model.masses[index]
        moving = np.any(pins.amplitude != 0.0, axis=1) & soft
        return SoftPins(upload(rate, float, device), upload(damping, float, device),
                        upload(model.positions, wp.vec3, device), upload(model.velocities, wp.vec3, device),
                        self._pin_motion(model, moving) if moving.any() else None)

    def no_limits(self) -> StrainLimits:
        """No limited spring: for checks of scenes without strain limits."""
        limits, empty_int, empty_float = StrainLimits(), wp.zeros(0, dtype=int, device=self.device), \
            wp.zeros(0, dtype=float, device=self.device)
        limits.offsets = wp.zeros(self.particle_count + 1, dtype=int, device=self.device)
        limits.other = empty_int
        limits.min_length = limits.max_length = limits.residual_length = empty_float
        return limits

    def no_attachments(self) -> Attachments:
        """No attachments to pins: for passes and checks of scenes without them."""
        attachments = Attachments()
        attachments.pin = wp.zeros(0, dtype=int, device=self.device)
        attachments.length = wp.zeros(0, dtype=float, device=self.device)
        attachments.chord_half = 0.0
        return attachments

    def no_contacts(self) -> Contacts:
        """No particle collision: for checks of scenes without it (never read)."""
        contacts, empty_int, empty_float = Contacts(), wp.zeros(0, dtype=int, device=self.device), \
            wp.zeros(0, dtype=float, device=self.device)
        contacts.radius = contacts.pushed = contacts.friction = empty_float
        contacts.neighbors = contacts.counts = contacts.resting = empty_int
        contacts.separation, contacts.max_neighbors = 1.0, 1
        return contacts

    def _wind(self, model: Model, settings) -> Wind | None:
        if settings is None:
            return None
        wind, device, faces = Wind(), self.device, model.wind_faces
        keys = settings.keys or (WindKey(0.0, settings.velocity),)
        wind.key_time = upload(np.asarray([k.time for k in keys]), float, device)
        wind.key_velocity = upload(np.asarray([k.velocity for k in keys]), wp.vec3, device)
        wind.turbulence, wind.scale, wind.air_density = settings.turbulence, settings.scale, settings.air_density
        wind.drag, wind.lift = settings.drag, settings.lift
        wind.faces = upload(faces.faces, wp.vec4i, device)
        wind.offsets, wind.incident = upload(faces.offsets, int, device), upload(faces.incident, int, device)
        return wind

    def _pin_targets(self, model: Model) -> tuple[PinTarget, ...]:
        """Each targeted collider's pinned particles, attached to its nearest faces where they start."""
        positions, device = upload(model.positions, wp.vec3, self.device), self.device
        targets = []
        pins = model.pins
        groups = [(k, soft) for k in np.unique(pins.target[pins.target >= 0]).tolist() for soft in (False, True)]
        for k, soft in groups:
            rows = (pins.target == k) & (pins.soft == soft)
            if not rows.any():
                continue
            index = upload(pins.index[rows], int, device)
            count = index.shape[0]
            target = PinTarget(self.collider_kinds[Meshes].meshes[k], index, wp.zeros(count, dtype=int, device=device),
                               wp.zeros(count, dtype=wp.vec2, device=device),
                               wp.zeros(count, dtype=wp.vec3, device=device), soft)
            wp.launch(motion.attach_to_mesh, dim=count, inputs=[target.mesh.id, index, positions],
                      outputs=[target.face, target.bary, target.offset], device=device)
            targets.append(target)
        return tuple(targets)

    def colliders(self, state: DeviceState) -> RigidColliders:
        """The scene's rigid colliders as the kernels take them, moving ones where the state has them."""
        colliders = RigidColliders()
        colliders.world, colliders.cloth_friction = self.particle_world, self.cloth_friction
        for kind in self.collider_kinds.values():
            kind.fill(colliders, state)
        return colliders

    def no_colliders(self) -> RigidColliders:
        return self._no_colliders


def no_colliders(device) -> RigidColliders:
    """No collider: for the passes that do not end with them."""
    colliders = RigidColliders()
    colliders.world = wp.zeros(0, dtype=int, device=device)
    colliders.cloth_friction = wp.zeros(0, dtype=float, device=device)
    for kind in KINDS:
        kind.fill_none(colliders, device)
    return colliders
