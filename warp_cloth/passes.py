"""The passes a substep is made of: each launches one kernel (the implicit step, its solve) with the
arguments it built once from the device model and the state. warp_cloth/plan.py puts them in order."""

from __future__ import annotations

from typing import Protocol

import warp as wp

from warp_cloth.kernels import colliders, gathering, motion, seams, wind
from warp_cloth.kernels.attachments import Attachments
from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.contact_velocities import ContactVelocitiesArgs, contact_velocities_kernel
from warp_cloth.kernels.edge_collision import EdgeContacts
from warp_cloth.kernels.edge_separation import EdgeSeparationPassArgs, edge_separation_pass_kernel
from warp_cloth.kernels.explicit_step import ContactStartArgs, contact_start
from warp_cloth.kernels.particle_collision import Contacts
from warp_cloth.kernels.projection_passes import (LimitAndSeparationPassArgs, LimitPassArgs, SeparationPassArgs,
                                                  limit_and_separation_pass_kernel, limit_pass_kernel,
                                                  separation_pass_kernel)

from .device_model import DeviceModel
from .state import EDGE_NEIGHBORS, DeviceState


class Pass(Protocol):
    name: str  # what it does, fused effects joined by '+'

    def run(self, state: DeviceState) -> None: ...


def launch(kernel, dim: int, state: DeviceState, inputs=(), outputs=()) -> None:
    wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=state.device)


def contact_start_args(model: DeviceModel, state: DeviceState, bundle: RigidColliders,
                       rebuild_distance: float) -> ContactStartArgs:
    args = ContactStartArgs()
    args.colliders, args.contacts, args.lists = bundle, contacts_args(model, state), state.contacts.lists()
    args.v_start, args.rebuild_distance = state.contacts.v_start, rebuild_distance
    args.inv_mass, args.h = model.inv_mass, model.h
    return args


def contacts_args(model: DeviceModel, state: DeviceState) -> Contacts:
    """Particle collision's constants and state as the kernels take them."""
    contacts, settings = Contacts(), model.contacts.settings
    contacts.radius, contacts.separation = model.contacts.radius, settings.separation
    contacts.neighbors, contacts.counts = state.contacts.neighbors, state.contacts.counts
    contacts.max_neighbors = settings.max_neighbors
    contacts.resting, contacts.pushed = state.contacts.resting, state.contacts.pushed
    contacts.friction = model.cloth_friction
    return contacts


def edge_contacts_args(model: DeviceModel, state: DeviceState) -> EdgeContacts:
    """Edge contacts' constants and lists as the kernels take them."""
    edges, constants = EdgeContacts(), model.contacts.edges
    edges.ends = constants.ends
    edges.incident_offsets, edges.incident = constants.incident_offsets, constants.incident
    edges.neighbors, edges.counts = state.edges.neighbors, state.edges.counts
    edges.max_neighbors = EDGE_NEIGHBORS
    edges.thickness = constants.thickness
    return edges


class GatheringPass:
    """A gathering kernel (kernels/gathering.py) over every particle, from the current positions and
    velocities to the next positions and, where ``new_velocities``, the next velocities (else it changes
    the current ones in place)."""

    def __init__(self, name: str, kernel: wp.Kernel, threads: int, args, device, new_positions: bool = True,
                 new_velocities: bool = False) -> None:
        self.name, self.kernel, self.threads, self.args = name, kernel, threads, args
        self.new_positions, self.new_velocities = new_positions, new_velocities
        gathering.load_gathering(kernel, threads, device)

    def run(self, state: DeviceState) -> None:
        x_out = state.x_next if self.new_positions else state.x
        v_out = state.v_next if self.new_velocities else state.v
        gathering.launch_gathering(self.kernel, self.threads, state.x.shape[0], state.x, state.v, x_out, v_out,
                                   self.args)
        if self.new_positions:
            state.swap_positions()
        if self.new_velocities:
            state.swap_velocities()


class ContactStart:
    """The contacts' start alone (see ``integrators.ExplicitIntegrator.step``), where the pass before cannot
    end with it."""

    name = "contact_start"

    def __init__(self, args: ContactStartArgs) -> None:
        self.args = args

    def run(self, state: DeviceState) -> None:
        launch(contact_start, state.x.shape[0], state, inputs=[state.x, state.v, self.args])


def projection_pass(name: str, kernel: wp.Kernel, args, model: DeviceModel, threads: int,
                    bundle: RigidColliders | None, read_bit: int) -> GatheringPass:
    """A Jacobi pass that moves particles and ends with the rigid colliders in ``bundle`` (None: none),
    which mark the particles they hold up for the next pass, which reads ``read_bit``."""
    args.inv_mass, args.h, args.read_bit = model.inv_mass, model.h, read_bit
    args.colliders = bundle if bundle is not None else model.no_colliders()
    return GatheringPass(name + ("+colliders" if bundle is not None else ""), kernel, threads, args, model.device)


def limit_pass(model: DeviceModel, threads: int, bundle: RigidColliders | None, resting: wp.array | None,
               read_bit: int) -> GatheringPass:
    """One Jacobi pass of the strain limits; its colliders mark in ``resting`` (None: no marks)."""
    args = LimitPassArgs()
    args.limits, args.attachments = model.limits, attachments_of(model)
    args.resting = resting if resting is not None else model.no_marks
    return projection_pass(limits_name(model), limit_pass_kernel(threads), args, model, threads, bundle,
                           read_bit)


def separation_pass(model: DeviceModel, state: DeviceState, threads: int, bundle: RigidColliders | None,
                    read_bit: int) -> GatheringPass:
    """One Jacobi pass pushing overlapping particles apart."""
    args = SeparationPassArgs()
    args.contacts = contacts_args(model, state)
    return projection_pass("separation", separation_pass_kernel(threads), args, model, threads, bundle,
                           read_bit)


def limit_and_separation_pass(model: DeviceModel, state: DeviceState, threads: int, bundle: RigidColliders | None,
                              read_bit: int) -> GatheringPass:
    """The limit's and the separation's Jacobi pass in one (see kernels/projection_passes.py)."""
    args = LimitAndSeparationPassArgs()
    args.limits, args.attachments, args.contacts = model.limits, attachments_of(model), contacts_args(model, state)
    return projection_pass(limits_name(model) + "+separation", limit_and_separation_pass_kernel(threads), args,
                           model, threads, bundle, read_bit)


def attachments_of(model: DeviceModel) -> Attachments:
    """What a limit pass holds to the pins: the model's attachments, or none (kernels/attachments.py)."""
    return model.attachments if model.attachments is not None else model.no_attachments()


def limits_name(model: DeviceModel) -> str:
    return "limits+attachments" if model.attachments is not None else "limits"


def edge_separation_pass(model: DeviceModel, state: DeviceState, threads: int,
                         bundle: RigidColliders | None) -> GatheringPass:
    """One Jacobi pass moving contact edges a thickness apart (kernels/edge_collision.py), then the
    colliders in ``bundle`` (None: none)."""
    args = EdgeSeparationPassArgs()
    args.edges, args.inv_mass, args.h = edge_contacts_args(model, state), model.inv_mass, model.h
    args.colliders = bundle if bundle is not None else model.no_colliders()
    return GatheringPass("edge_separation" + ("+colliders" if bundle is not None else ""),
                         edge_separation_pass_kernel(threads), threads, args, model.device)


CONTACT_SLACK = 1.01  # pairs within 1% of contact count as touching in the velocity pass


def contact_velocities(model: DeviceModel, state: DeviceState, threads: int) -> GatheringPass:
    """Inelastic contacts with friction, then the end of the substep's list remake (see
    kernels/particle_collision.py): the last pass that reads the remake's request clears it."""
    args = ContactVelocitiesArgs()
    args.contacts, args.lists, args.v_start = contacts_args(model, state), state.contacts.lists(), state.contacts.v_start
    args.inv_mass, args.contact_slack = model.inv_mass, CONTACT_SLACK
    args.friction, args.h = model.contacts.settings.friction, model.h
    return GatheringPass("contact_velocities+end_remake", contact_velocities_kernel(threads), threads, args,
                         model.device, new_positions=False, new_velocities=True)


class Collide:
    """The rigid colliders alone, where no other pass moves particles after integration."""

    name = "colliders"

    def __init__(self, model: DeviceModel, bundle: RigidColliders) -> None:
        self.model, self.bundle = model, bundle

    def run(self, state: DeviceState) -> None:
        launch(colliders.collide, state.x.shape[0], state, inputs=[self.bundle, self.model.h, self.model.inv_mass],
               outputs=[state.x, state.v])


def pin_outputs(model: DeviceModel, state: DeviceState, soft: bool) -> list[wp.array]:
    """Where a pin's motion puts its particles: the particles themselves (a hard pin), or where the soft pins'
    springs pull them (kernels/forces.py)."""
    return [model.soft_pins.target_x, model.soft_pins.target_v] if soft else [state.x, state.v]


class DrivePins:
    """Pins moving along their oscillation. Fixed pins need no pass: a hard-pinned particle has inverse mass
    0, starts at its anchor at rest, and no pass moves it (nor a fixed soft pin's target)."""

    def __init__(self, model: DeviceModel, soft: bool = False) -> None:
        self.model, self.soft = model, soft
        self.pins = model.soft_pins.motion if soft else model.pins
        self.name = "soft pins:oscillating" if soft else "pins:oscillating"

    def run(self, state: DeviceState) -> None:
        p = self.pins
        launch(motion.drive_pins, p.index.shape[0], state,
               inputs=[p.index, p.anchor, p.amplitude, p.frequency, p.phase, state.clock, self.model.h],
               outputs=pin_outputs(self.model, state, self.soft))


class FollowTargets:
    """Pins that follow mesh colliders put where their attachments are now (hard ones after the integration,
    as every driven pin; soft ones' targets before it)."""

    def __init__(self, model: DeviceModel, soft: bool = False) -> None:
        self.model, self.soft = model, soft
        self.targets = [t for t in model.pin_targets if t.soft == soft]
        self.name = "soft pins:follow colliders" if soft else "pins:follow colliders"
        self.present = bool(self.targets)

    def run(self, state: DeviceState) -> None:
        for t in self.targets:
            launch(motion.follow_mesh, t.index.shape[0], state,
                   inputs=[t.mesh.id, t.index, t.face, t.bary, t.offset],
                   outputs=pin_outputs(self.model, state, t.soft))


class FollowKeys:
    """Puts pinned particles carried along keys (or a USD prim's transform) where they are at the end of
    the substep, with their velocity (a soft pin's: where its springs pull)."""

    def __init__(self, model: DeviceModel, soft: bool = False) -> None:
        self.model, self.soft = model, soft
        self.keyed = [k for k in model.keyed_pins if k.soft == soft]
        self.name = "soft pins:follow keys" if soft else "pins:follow keys"
        self.present = bool(self.keyed)

    def run(self, state: DeviceState) -> None:
        for pins in self.keyed:
            launch(motion.place_keyed_particles, pins.index.shape[0], state,
                   inputs=[state.clock, self.model.h, pins.key_times, pins.keys, pins.index],
                   outputs=pin_outputs(self.model, state, pins.soft))


class WindForces:
    """Each particle's acceleration by the wind on its faces (into the state's ``wind``), from the positions
    and velocities the substep starts from: the integration after it reads them as an external force."""

    name = "wind"

    def __init__(self, model: DeviceModel) -> None:
        self.model = model
        self.shares = wp.zeros(model.wind.faces.shape[0], dtype=wp.vec3, device=model.device)

    kernels = [wind.face_forces, wind.wind_accelerations]  # as run launches them

    def describe(self) -> list[str]:
        """For the printed plan: the pass and its launches."""
        return [f"{self.name}:"] + [f"    {kernel.key}" for kernel in self.kernels]

    def run(self, state: DeviceState) -> None:
        model = self.model
        launch(wind.face_forces, self.shares.shape[0], state,
               inputs=[model.wind, state.clock, model.h, state.x, state.v], outputs=[self.shares])
        launch(wind.wind_accelerations, model.particle_count, state, inputs=[model.wind, self.shares, model.inv_mass],
               outputs=[state.wind])


class CloseSeams:
    """The sewn pairs' allowed lengths at the substep's end (kernels/seams.py), before any pass holds them."""

    name = "seams:close"

    def __init__(self, model: DeviceModel) -> None:
        self.model = model

    def run(self, state: DeviceState) -> None:
        s = self.model.seams
        launch(seams.close_seams, s.entry.shape[0], state,
               inputs=[state.clock, self.model.h, s.entry, s.start_length, s.close_time, s.closes_at],
               outputs=[self.model.limits.max_length])


class AdvanceClock:
    name = "clock"

    def run(self, state: DeviceState) -> None:
        launch(motion.advance_clock, 1, state, outputs=[state.clock])
