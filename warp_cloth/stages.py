"""The stages a substep is made of. ``build_stages`` turns a model into the list once; an effect the
scene does not declare has no stage, so it costs no launch and no memory."""

from __future__ import annotations

from typing import Protocol

import warp as wp

from warp_cloth.kernels import (colliders, integration, limits, motion, particle_collision, pins, projection,
                                spatial_hash)

from .implicit import BackwardEuler
from .model import Model
from .state import DeviceState


class Stage(Protocol):
    name: str

    def run(self, state: DeviceState) -> None: ...


def launch(kernel, dim: int, state: DeviceState, inputs=(), outputs=()) -> None:
    wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=state.device)


def _upload(array, dtype, device):
    return wp.array(array, dtype=dtype, device=device)


LANE_BLOCK = 128  # threads a block of a kernel with several threads per particle
# Threads per particle on a GPU by particle count (up to the first number), from the spring kernel's
# launch times on an H200 (docs/results/lanes-probe-h200.json): 16 are fastest at 64^2, 4 at 128^2, 2 at
# 256^2; from 1024^2 on, one thread per particle is.
LANES_BY_SIZE = ((8192, 16), (32768, 4), (131072, 2))
# The neighbour lists' remake has more to gather (27 cells): 16 threads are fastest at 64^2, 4 at 256^2, one
# at 1024^2 (docs/results/list-probe-h200.json).
LIST_LANES_BY_SIZE = ((8192, 16), (131072, 4))


def threads_per_particle(particles: int, device, table=LANES_BY_SIZE) -> int:
    """How many threads gather each particle's springs, limits and contacts (see kernels/lanes.py)."""
    if not device.is_cuda:
        return 1
    return next((lanes for most, lanes in table if particles <= most), 1)


class PerParticle:
    """A kernel that gathers over each particle's springs, limits or contacts, launched with a thread per
    particle or, where ``lanes`` > 1, with that many (its ``lanes_factory`` builds that form); ``lanes``
    None: as ``table`` has it for this many particles."""

    def __init__(self, kernel, lanes_factory, lanes: int | None, particles: int, device,
                 table=LANES_BY_SIZE) -> None:
        self.lanes = lanes = threads_per_particle(particles, device, table) if lanes is None else lanes
        if lanes == 1:
            self.kernel = kernel
        else:
            # built and loaded now: a graph capture cannot compile it
            self.kernel = lanes_factory(lanes, LANE_BLOCK)
            self.kernel.module.load(device, block_dim=LANE_BLOCK)

    def launch(self, n: int, device, inputs, outputs) -> None:
        if self.lanes == 1:
            wp.launch(self.kernel, dim=n, inputs=inputs, outputs=outputs, device=device)
        else:
            per_block = LANE_BLOCK // self.lanes
            wp.launch_tiled(self.kernel, dim=[(n + per_block - 1) // per_block], inputs=inputs, outputs=outputs,
                            block_dim=LANE_BLOCK, device=device)


class ExplicitIntegration:
    """Spring forces and gravity, then one explicit or symplectic Euler step; and the start of the
    particle collision's ``contacts`` where that stage follows directly (see integration.py)."""

    def __init__(self, model: Model, inv_mass: wp.array, springs: tuple, integrator: str, h: float,
                 lanes: int | None, device, contacts: "ParticleCollision | None" = None) -> None:
        self.name = f"integrate:{integrator}" + ("+contacts" if contacts is not None else "")
        self.kernel = PerParticle(integration.euler_step, integration.euler_step_lanes, lanes,
                                  model.particle_count, device)
        self.h = h
        self.semi_implicit = 1 if integrator == "symplectic" else 0
        self.gravity = wp.vec3(*model.scene.simulation.gravity)
        self.drag = model.scene.simulation.drag
        self.n = model.particle_count
        self.inv_mass = inv_mass
        self.springs = springs
        if contacts is None:
            self.contact_start = no_contact_start(device)
        else:
            self.contact_start = contacts.hand_start_to_integration()

    def run(self, state: DeviceState) -> None:
        start_inputs, start_outputs = self.contact_start
        self.kernel.launch(self.n, state.device,
                           inputs=[state.x, state.v, self.inv_mass, self.gravity, self.drag, self.h,
                                   self.semi_implicit, *self.springs, *start_inputs],
                           outputs=[state.x_next, state.v_next, *start_outputs])
        state.swap_positions()
        state.swap_velocities()


def no_contact_start(device) -> tuple[list, list]:
    """The contacts' start arguments of an integration step that begins no contacts."""
    empty_vec3 = wp.zeros(0, dtype=wp.vec3, device=device)
    empty_int = wp.zeros(0, dtype=int, device=device)
    return [rigid_colliders(None, device), empty_vec3, 0.0], [empty_vec3, empty_int, empty_int]


class DrivePins:
    """Pins moving along their oscillation. Fixed pins need no stage: a pinned particle has inverse mass 0,
    starts at its anchor at rest, and no stage moves it."""

    def __init__(self, model: Model, h: float, device) -> None:
        self.name = "pins:oscillating"
        p = model.pins
        self.h = h
        self.arrays = (_upload(p.index, int, device), _upload(p.anchor, wp.vec3, device),
                       _upload(p.amplitude, wp.vec3, device), _upload(p.frequency, float, device),
                       _upload(p.phase, float, device))

    def run(self, state: DeviceState) -> None:
        launch(pins.drive_pins, self.arrays[0].shape[0], state, inputs=[*self.arrays, state.clock, self.h],
                  outputs=[state.x, state.v])


def rigid_colliders(model: Model | None, device) -> colliders.RigidColliders:
    """The scene's ground and spheres as the kernels take them (``None``: no collider, for passes that
    end without them); spheres at their initial centres, at rest."""
    bundle = colliders.RigidColliders()
    ground = model.scene.ground if model is not None else None
    bundle.ground = int(ground is not None)
    bundle.ground_height = ground.height if ground is not None else 0.0
    bundle.ground_friction = ground.friction if ground is not None else 0.0
    spheres = model.spheres if model is not None else None
    if spheres is None:
        bundle.center = wp.zeros(0, dtype=wp.vec3, device=device)
        bundle.velocity = wp.zeros(0, dtype=wp.vec3, device=device)
        bundle.radius = wp.zeros(0, dtype=float, device=device)
        bundle.friction = wp.zeros(0, dtype=float, device=device)
    else:
        bundle.center = _upload(spheres.initial_center, wp.vec3, device)
        bundle.velocity = wp.zeros(len(spheres.center), dtype=wp.vec3, device=device)
        bundle.radius = _upload(spheres.radius, float, device)
        bundle.friction = _upload(spheres.friction, float, device)
    return bundle


class RigidCollision:
    """The ground and all spheres in one launch. Kernels that move particles end with them instead where
    they run last (``bundle``), so this stage runs alone only where nothing else moves particles after
    integration."""

    def __init__(self, model: Model, inv_mass: wp.array, h: float, device) -> None:
        self.name = "+".join((["ground"] if model.scene.ground is not None else [])
                             + (["spheres"] if model.spheres is not None else []))
        self.inv_mass = inv_mass
        self.h = h
        self.bundle = rigid_colliders(model, device)

    def run(self, state: DeviceState) -> None:
        launch(colliders.collide, state.x.shape[0], state, inputs=[self.bundle, self.h, self.inv_mass],
               outputs=[state.x, state.v])


class StrainLimit:
    """Provot's limit in ``iterations`` Jacobi passes; the last one ends with the ``rigid`` colliders, if
    given (the collision stage instead chooses per pass)."""

    def __init__(self, model: Model, inv_mass: wp.array, iterations: int, h: float,
                 rigid: RigidCollision | None, lanes: int | None, device) -> None:
        self.name = f"limits:{iterations}" + (f"+{rigid.name}" if rigid is not None else "")
        self.kernel = PerParticle(limits.project_strain_limits, limits.project_strain_limits_lanes, lanes,
                                  model.particle_count, device)
        lim = model.limits
        self.iterations = iterations
        self.h = h
        self.inv_mass = inv_mass
        self.colliders = rigid
        self.no_colliders = rigid_colliders(None, device)
        self.no_resting = wp.zeros(0, dtype=int, device=device)
        self.arrays = (_upload(lim.offsets, int, device), _upload(lim.other, int, device),
                       _upload(lim.min_length, float, device), _upload(lim.max_length, float, device),
                       _upload(lim.attachment_pin, int, device), _upload(lim.attachment_length, float, device))

    def run(self, state: DeviceState) -> None:
        for k in range(self.iterations):
            last = k == self.iterations - 1
            self.run_pass(state, self.colliders.bundle if last and self.colliders else self.no_colliders)

    def run_pass(self, state: DeviceState, bundle: colliders.RigidColliders, resting: wp.array | None = None,
                 read_bit: int = 1) -> None:
        """One pass, ending with the colliders in ``bundle``, which mark ``resting`` (see colliders.py)."""
        self.kernel.launch(state.x.shape[0], state.device,
                           inputs=[state.x, self.inv_mass, *self.arrays, self.h, bundle,
                                   self.no_resting if resting is None else resting, read_bit],
                           outputs=[state.x_next, state.v])
        state.swap_positions()


class MoveSpheres:
    """Puts moving spheres where their motion has them at the end of the substep, with its velocity."""

    def __init__(self, model: Model, target: RigidCollision, h: float, device) -> None:
        s = model.spheres
        self.name = "spheres:move"
        self.h = h
        self.target = target.bundle
        self.motion = (_upload(s.center, wp.vec3, device), _upload(s.amplitude, wp.vec3, device),
                       _upload(s.frequency, float, device), _upload(s.phase, float, device))

    def carried_arrays(self) -> dict[str, wp.array]:
        """Where the spheres are, which the next substep's colliders read before this stage moves them."""
        return {"center": self.target.center, "velocity": self.target.velocity}

    def run(self, state: DeviceState) -> None:
        launch(motion.move_spheres, self.target.center.shape[0], state, inputs=[state.clock, self.h, *self.motion],
               outputs=[self.target.center, self.target.velocity])


class ParticleCollision:
    """Self and cloth-cloth collision: hash grid, neighbour lists, Jacobi separation, velocity projection.

    Collisions, strain limits and rigid colliders fight over the same particles (a layer pressed onto a
    sphere by the layers above can only give way sideways), so with collision they are projected together
    in ``passes`` passes, the larger of the limit's and the collision's iteration counts: every pass ends
    with the colliders, and the limit and the separation each run in the last of the passes as many
    times as their own count says, so that the last pass runs all of them. A pass that runs both runs them
    as one Jacobi pass, in one kernel (kernels/projection.py), or, with ``projection = "sequential"``, the
    limit's kernel and then the separation's. The colliders run at the end of each pass, and once before
    the passes, in the kernel that starts the stage; the particles they hold up (``resting``) do not give
    way to others in the passes that follow.
    """

    SEARCH_SCALE = 1.5  # candidates within 1.5 contact distances, so passes that move particles miss none
    CONTACT_SLACK = 1.01  # pairs within 1% of contact count as touching in the velocity pass
    BUCKET_CAPACITY = 16  # particles a spatial-hash bucket holds (overflow is counted, tests keep it 0)
    BRUTE_FORCE_UP_TO = 512  # particles; below, checking all pairs costs less than the hash

    def __init__(self, model: Model, inv_mass: wp.array, cloth_id: wp.array, limit: StrainLimit | None,
                 rigid: RigidCollision | None, h: float, lanes: int | None, device) -> None:
        settings = model.scene.collision
        n = model.particle_count
        self.separate = PerParticle(particle_collision.separate_particles, particle_collision.separate_particles_lanes,
                                    lanes, n, device)
        self.resolve = PerParticle(particle_collision.resolve_contact_velocities,
                                   particle_collision.resolve_contact_velocities_lanes, lanes, n, device)
        self.joint = None if limit is None or settings.projection != "joint" else PerParticle(
            projection.project_limits_and_separation, projection.project_limits_and_separation_lanes, lanes, n,
            device)
        contacts = model.contacts
        self.passes = max(settings.iterations, limit.iterations if limit else 0)
        self.name = "+".join([f"collision:{self.passes}", *(["limits"] if limit else []),
                              *([rigid.name] if rigid else [])])
        self.limit = limit
        self.colliders = rigid
        self.no_colliders = rigid_colliders(None, device)
        self.bundle = rigid.bundle if rigid is not None else self.no_colliders
        self.settings = settings
        self.h = h
        self.n = n
        self.inv_mass = inv_mass
        self.cloth_id = cloth_id
        self.radius = _upload(contacts.radius, float, device)
        self.search_radius = self.SEARCH_SCALE * settings.separation * contacts.max_radius
        if contacts.exclude_adjacent is None:
            self.exclusion = (wp.zeros(0, dtype=int, device=device), wp.zeros(0, dtype=int, device=device))
        else:
            self.exclusion = (_upload(contacts.grid_xy, int, device), _upload(contacts.exclude_adjacent, int, device))
        self.neighbors = wp.zeros(n * settings.max_neighbors, dtype=int, device=device)
        self.counts = wp.zeros(n, dtype=int, device=device)
        self.pushed = wp.zeros(n, dtype=float, device=device)
        self.v_start = wp.zeros(n, dtype=wp.vec3, device=device)
        self.resting = wp.zeros(n if rigid else 0, dtype=int, device=device)
        self.overflow = wp.zeros(1, dtype=int, device=device)
        # Neighbour lists are remade only when some particle has moved more than this since they were made:
        # a pair left out was farther than SEARCH_SCALE contact distances apart, so it cannot touch before.
        self.rebuild_distance = 0.5 * (self.SEARCH_SCALE - 1.0) * settings.separation * float(contacts.radius.min())
        self.remake_every_substep = False  # for benchmarks of the broad phase
        self.x_built = wp.full(n, wp.vec3(1.0e30), dtype=wp.vec3, device=device)
        self.rebuild = wp.zeros(1, dtype=int, device=device)
        self.started_by_integration = False  # see hand_start_to_integration
        self.use_hash = settings.broad_phase == "hash_grid" or (
            settings.broad_phase == "auto" and n > self.BRUTE_FORCE_UP_TO)
        table = 64
        while table < 2 * n:
            table *= 2
        self.table_mask = table - 1
        self.bucket_size = wp.zeros(table if self.use_hash else 0, dtype=int, device=device)
        self.epoch = wp.zeros(1, dtype=int, device=device)  # the hash table's: see spatial_hash.py
        self.bucket_items = wp.zeros(table * self.BUCKET_CAPACITY if self.use_hash else 0, dtype=int, device=device)
        self.gather = PerParticle(particle_collision.gather_neighbors, particle_collision.gather_neighbors_lanes,
                                  lanes if self.use_hash else 1, n, device, LIST_LANES_BY_SIZE)
        # where several threads a particle make the lists: the lists before their sort, and their lengths
        several = self.gather.lanes > 1
        self.unsorted = wp.zeros(n * settings.max_neighbors if several else 0, dtype=int, device=device)
        self.appended = wp.zeros(n if several else 0, dtype=int, device=device)

    def remake_lists_if_asked(self, x: wp.array) -> None:
        """Launches the remake of every particle's candidate list from positions ``x``; its kernels do it
        where ``rebuild`` is set, and leave it set (the substep's last kernel clears it)."""
        s = self.settings
        pair_rules = [self.cloth_id, int(s.self_collision), int(s.between_cloths), *self.exclusion, s.max_neighbors,
                      self.rebuild]
        lists = [self.neighbors, self.counts, self.overflow, self.x_built]
        if self.use_hash:
            inv_cell = 1.0 / self.search_radius
            wp.launch(spatial_hash.insert_points, dim=self.n,
                      inputs=[x, inv_cell, self.table_mask, self.BUCKET_CAPACITY, self.epoch, self.rebuild],
                      outputs=[self.bucket_size, self.bucket_items, self.overflow], device=x.device)
            grid = [x, self.radius, inv_cell, self.table_mask, self.BUCKET_CAPACITY, self.bucket_size,
                    self.bucket_items, self.epoch, s.separation, self.SEARCH_SCALE, *pair_rules]
            scratch = [self.unsorted, self.appended] if self.gather.lanes > 1 else []
            self.gather.launch(self.n, x.device, inputs=[*grid, *scratch], outputs=lists)
        else:
            wp.launch(particle_collision.gather_neighbors_brute_force, dim=self.n,
                      inputs=[x, self.radius, s.separation, self.SEARCH_SCALE, *pair_rules], outputs=lists,
                      device=x.device)

    def make_lists(self, x: wp.array) -> None:
        """Remake every particle's candidate list from positions ``x`` now, outside a substep."""
        self.rebuild.fill_(1)
        self.remake_lists_if_asked(x)
        wp.launch(particle_collision.end_remake_once, dim=1, outputs=[self.rebuild, self.epoch], device=x.device)

    def closest_contact(self, x: wp.array) -> float:
        """The closest approach of two particles that may collide, as a fraction of their contact distance
        (a diagnostic: it waits for the device). It remakes the lists from ``x``, which the simulation may
        then go on using: they are as valid as any it makes itself."""
        self.make_lists(x)
        ratio = wp.full(1, 1.0e30, dtype=float, device=x.device)
        wp.launch(particle_collision.closest_contact_ratio, dim=self.n,
                  inputs=[x, self.radius, self.settings.separation, self.neighbors, self.counts,
                          self.settings.max_neighbors], outputs=[ratio], device=x.device)
        return float(ratio.numpy()[0])

    def carried_arrays(self) -> dict[str, wp.array]:
        """What one substep leaves for the next: the neighbour lists and where they were made, the hash
        table and its epoch, the remake flag, the collider contact flags, the overflow count."""
        return {"neighbors": self.neighbors, "counts": self.counts, "x_built": self.x_built, "rebuild": self.rebuild,
                "epoch": self.epoch, "bucket_size": self.bucket_size, "bucket_items": self.bucket_items,
                "resting": self.resting, "overflow": self.overflow, "pushed": self.pushed}

    def start_arguments(self) -> tuple[list, list]:
        """What ``begin_contact`` takes besides the state, as (inputs, outputs)."""
        return [self.bundle, self.x_built, self.rebuild_distance], [self.v_start, self.resting, self.rebuild]

    def hand_start_to_integration(self) -> tuple[list, list]:
        """From now on the integration step begins the contacts, and this stage launches no kernel for
        that; returns what the step's kernel takes for it (``start_arguments``)."""
        self.started_by_integration = True
        return self.start_arguments()

    def run(self, state: DeviceState) -> None:
        s = self.settings
        if not self.started_by_integration:
            start_inputs, start_outputs = self.start_arguments()
            launch(particle_collision.begin_contacts, self.n, state, inputs=[self.inv_mass, self.h, *start_inputs],
                   outputs=[state.x, state.v, *start_outputs])
        if self.remake_every_substep:
            self.rebuild.fill_(1)
        self.remake_lists_if_asked(state.x)
        for remaining in range(self.passes, 0, -1):
            separates = remaining <= s.iterations
            limits_too = self.limit is not None and remaining <= self.limit.iterations
            read_bit = 1 if (self.passes - remaining) % 2 == 0 else 2  # resting flags: see colliders.py
            if not separates:
                self.limit.run_pass(state, self.bundle, self.resting, read_bit)
                continue
            contacts = [self.radius, s.separation, self.h, self.neighbors, self.counts, s.max_neighbors,
                        self.resting, read_bit, self.bundle]
            if limits_too and self.joint is not None:
                self.joint.launch(self.n, state.device, inputs=[state.x, self.inv_mass, *self.limit.arrays, *contacts],
                                  outputs=[state.x_next, state.v, self.pushed])
            else:
                if limits_too:
                    self.limit.run_pass(state, self.no_colliders)
                self.separate.launch(self.n, state.device, inputs=[state.x, self.inv_mass, *contacts],
                                     outputs=[state.x_next, state.v, self.pushed])
            state.swap_positions()
        self.resolve.launch(self.n, state.device,
                            inputs=[state.x, state.v, self.v_start, self.inv_mass, self.radius, s.separation,
                                    self.CONTACT_SLACK, s.friction, self.h, self.pushed, self.neighbors, self.counts,
                                    s.max_neighbors],
                            outputs=[state.v_next, self.rebuild, self.epoch])
        state.swap_velocities()


class AdvanceClock:
    name = "clock"

    def run(self, state: DeviceState) -> None:
        launch(motion.advance_clock, 1, state, outputs=[state.clock])


def upload_springs(model: Model, device) -> tuple:
    """The spring adjacency and parameters as the kernels take them: offsets, other, spring, rest,
    stiffness, damping, flags (offsets all zero and the rest empty for a cloth without springs)."""
    springs = model.springs
    if springs is None:
        empty_i, empty_f = wp.zeros(0, dtype=int, device=device), wp.zeros(0, dtype=float, device=device)
        return (wp.zeros(model.particle_count + 1, dtype=int, device=device), empty_i, empty_i, empty_f, empty_f,
                empty_f, empty_i)
    adj = springs.adjacency
    return (_upload(adj.offsets, int, device), _upload(adj.other, int, device), _upload(adj.spring, int, device),
            _upload(springs.rest, float, device), _upload(springs.stiffness, float, device),
            _upload(springs.damping, float, device), _upload(springs.flags, int, device))


def build_stages(model: Model, device, lanes: int | None = None) -> list[Stage]:
    """The substep, in order: moving spheres to the substep's end (nothing before the colliders reads
    them), integrate, driven pins, then strain limits and colliders, or, with particle collision, those
    projected together with it, then the clock. Where particle collision follows an explicit step
    directly, the step begins its contacts. ``lanes``: threads per particle of the gathering kernels
    (None: each chooses by size; see ``PerParticle``)."""
    sim = model.scene.simulation
    h = sim.step
    inv_mass = _upload(model.inv_mass, float, device)
    springs = upload_springs(model, device)
    driven_pins = model.pins is not None and model.pins.moving
    moving_spheres = model.spheres is not None and model.spheres.moving
    rigid = None
    if model.scene.ground is not None or model.spheres is not None:
        rigid = RigidCollision(model, inv_mass, h, device)
    limit = collision = None
    if model.contacts is not None:
        limit = (StrainLimit(model, inv_mass, sim.limit_iterations, h, None, lanes, device)
                 if model.limits is not None else None)
        collision = ParticleCollision(model, inv_mass, _upload(model.cloth_id, int, device), limit, rigid, h,
                                      lanes, device)
    stages: list[Stage] = [MoveSpheres(model, rigid, h, device)] if moving_spheres else []
    if sim.integrator == "implicit":
        stages.append(BackwardEuler(model, inv_mass, springs, h, device))
    else:
        stages.append(ExplicitIntegration(model, inv_mass, springs, sim.integrator, h, lanes, device,
                                          contacts=None if driven_pins else collision))
    if driven_pins:
        stages.append(DrivePins(model, h, device))
    if collision is not None:
        stages.append(collision)
    elif model.limits is not None:
        stages.append(StrainLimit(model, inv_mass, sim.limit_iterations, h, rigid, lanes, device))
    elif rigid is not None:
        stages.append(rigid)
    if driven_pins or moving_spheres:
        stages.append(AdvanceClock())
    return stages
