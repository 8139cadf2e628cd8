"""The stages a substep is made of. ``build_stages`` turns a model into the list once; an effect the
scene does not declare has no stage, so it costs no launch and no memory."""

from __future__ import annotations

from typing import Protocol

import warp as wp

from warp_cloth.kernels import colliders, integration, limits, motion, particle_collision, pins, spatial_hash

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


class ExplicitIntegration:
    """Spring forces and gravity, then one explicit or symplectic Euler step."""

    def __init__(self, model: Model, inv_mass: wp.array, springs: tuple, integrator: str, h: float) -> None:
        self.name = f"integrate:{integrator}"
        self.h = h
        self.semi_implicit = 1 if integrator == "symplectic" else 0
        self.gravity = wp.vec3(*model.scene.simulation.gravity)
        self.drag = model.scene.simulation.drag
        self.n = model.particle_count
        self.inv_mass = inv_mass
        self.springs = springs

    def run(self, state: DeviceState) -> None:
        launch(integration.euler_step, self.n, state,
               inputs=[state.x, state.v, self.inv_mass, self.gravity, self.drag, self.h, self.semi_implicit,
                       *self.springs],
                  outputs=[state.x_next, state.v_next])
        state.swap_positions()
        state.swap_velocities()


class HoldPins:
    def __init__(self, model: Model, device) -> None:
        self.name = "pins:fixed"
        self.index = _upload(model.pins.index, int, device)
        self.anchor = _upload(model.pins.anchor, wp.vec3, device)

    def run(self, state: DeviceState) -> None:
        launch(pins.hold_pins, self.index.shape[0], state, inputs=[self.index, self.anchor],
                  outputs=[state.x, state.v])


class DrivePins:
    """Pins moving along their oscillation (fixed pins are the ones with zero amplitude)."""

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


class StrainLimit:
    def __init__(self, model: Model, inv_mass: wp.array, iterations: int, h: float, device) -> None:
        self.name = f"limits:{iterations}"
        lim = model.limits
        self.iterations = iterations
        self.h = h
        self.inv_mass = inv_mass
        self.arrays = (_upload(lim.offsets, int, device), _upload(lim.other, int, device),
                       _upload(lim.min_length, float, device), _upload(lim.max_length, float, device))

    def run(self, state: DeviceState) -> None:
        for _ in range(self.iterations):
            self.run_pass(state)

    def run_pass(self, state: DeviceState) -> None:
        launch(limits.project_strain_limits, state.x.shape[0], state,
               inputs=[state.x, self.inv_mass, *self.arrays, self.h], outputs=[state.x_next, state.v])
        state.swap_positions()


class SphereColliders:
    """All spheres in one launch, at the centres and velocities in ``center`` / ``velocity``."""

    def __init__(self, model: Model, inv_mass: wp.array, h: float, device) -> None:
        s = model.spheres
        self.inv_mass = inv_mass
        self.h = h
        self.center = _upload(s.initial_center, wp.vec3, device)
        self.velocity = wp.zeros(len(s.center), dtype=wp.vec3, device=device)
        self.radius = _upload(s.radius, float, device)
        self.friction = _upload(s.friction, float, device)
        self.resting = wp.zeros(0, dtype=int, device=device)  # the collision stage's, when there is one
        self.name = "spheres"

    def run(self, state: DeviceState) -> None:
        launch(colliders.collide_spheres, state.x.shape[0], state,
               inputs=[self.center, self.velocity, self.radius, self.friction, self.h, self.inv_mass],
               outputs=[state.x, state.v, self.resting])


class MoveSpheres:
    """Puts moving spheres where their motion has them at the end of the substep, with its velocity."""

    def __init__(self, model: Model, target: SphereColliders, h: float, device) -> None:
        s = model.spheres
        self.name = "spheres:move"
        self.h = h
        self.target = target
        self.motion = (_upload(s.center, wp.vec3, device), _upload(s.amplitude, wp.vec3, device),
                       _upload(s.frequency, float, device), _upload(s.phase, float, device))

    def run(self, state: DeviceState) -> None:
        launch(motion.move_spheres, self.target.center.shape[0], state, inputs=[state.clock, self.h, *self.motion],
               outputs=[self.target.center, self.target.velocity])


class GroundCollider:
    def __init__(self, model: Model, inv_mass: wp.array, h: float, device) -> None:
        self.name = "ground"
        ground = model.scene.ground
        self.height = ground.height
        self.friction = ground.friction
        self.h = h
        self.inv_mass = inv_mass
        self.resting = wp.zeros(0, dtype=int, device=device)  # the collision stage's, when there is one

    def run(self, state: DeviceState) -> None:
        launch(colliders.collide_ground, state.x.shape[0], state,
               inputs=[self.height, self.friction, self.h, self.inv_mass], outputs=[state.x, state.v, self.resting])


class ParticleCollision:
    """Self and cloth-cloth collision: hash grid, neighbour lists, Jacobi separation, velocity projection.

    Collisions, strain limits and rigid colliders fight over the same particles (a layer pressed onto a
    sphere by the layers above can only give way sideways), so with collision they are projected together
    in ``passes`` passes, the larger of the limit's and the collision's iteration counts: every pass ends
    with the colliders, and the limit and the separation each run in the last of the passes as many
    times as their own count says, so that the last pass runs all of them.
    """

    SEARCH_SCALE = 1.5  # candidates within 1.5 contact distances, so passes that move particles miss none
    CONTACT_SLACK = 1.01  # pairs within 1% of contact count as touching in the velocity pass
    BUCKET_CAPACITY = 16  # particles a spatial-hash bucket holds (overflow is counted, tests keep it 0)
    BRUTE_FORCE_UP_TO = 512  # particles; below, checking all pairs costs less than the hash

    def __init__(self, model: Model, inv_mass: wp.array, cloth_id: wp.array, limit: StrainLimit | None,
                 colliders: list[Stage], h: float, device) -> None:
        settings = model.scene.collision
        contacts = model.contacts
        n = model.particle_count
        self.passes = max(settings.iterations, limit.iterations if limit else 0)
        self.name = "+".join([f"collision:{self.passes}", *(["limits"] if limit else []),
                              *(c.name for c in colliders)])
        self.limit = limit
        self.colliders = colliders
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
        self.resting = wp.zeros(n if colliders else 0, dtype=int, device=device)
        for collider in colliders:
            collider.resting = self.resting
        self.overflow = wp.zeros(1, dtype=int, device=device)
        # Neighbour lists are remade only when some particle has moved more than this since they were made:
        # a pair left out was farther than SEARCH_SCALE contact distances apart, so it cannot touch before.
        self.rebuild_distance = 0.5 * (self.SEARCH_SCALE - 1.0) * settings.separation * float(contacts.radius.min())
        self.remake_every_substep = False  # for benchmarks of the broad phase
        self.x_built = wp.full(n, wp.vec3(1.0e30), dtype=wp.vec3, device=device)
        self.rebuild = wp.zeros(1, dtype=int, device=device)
        self.use_hash = settings.broad_phase == "hash_grid" or (
            settings.broad_phase == "auto" and n > self.BRUTE_FORCE_UP_TO)
        table = 64
        while table < 2 * n:
            table *= 2
        self.table_mask = table - 1
        self.bucket_size = wp.zeros(table if self.use_hash else 0, dtype=int, device=device)
        self.bucket_items = wp.zeros(table * self.BUCKET_CAPACITY if self.use_hash else 0, dtype=int, device=device)

    def make_lists(self, x: wp.array) -> None:
        """Remake every particle's candidate list from positions ``x`` (and remember them)."""
        s = self.settings
        pair_rules = [self.cloth_id, int(s.self_collision), int(s.between_cloths), *self.exclusion, s.max_neighbors]
        lists = [self.neighbors, self.counts, self.overflow]
        if self.use_hash:
            inv_cell = 1.0 / self.search_radius
            self.bucket_size.zero_()
            wp.launch(spatial_hash.insert_points, dim=self.n,
                      inputs=[x, inv_cell, self.table_mask, self.BUCKET_CAPACITY],
                      outputs=[self.bucket_size, self.bucket_items, self.overflow], device=x.device)
            wp.launch(particle_collision.gather_neighbors, dim=self.n,
                      inputs=[x, self.radius, inv_cell, self.table_mask, self.BUCKET_CAPACITY, self.bucket_size,
                              self.bucket_items, s.separation, self.SEARCH_SCALE, *pair_rules],
                      outputs=lists, device=x.device)
        else:
            wp.launch(particle_collision.gather_neighbors_brute_force, dim=self.n,
                      inputs=[x, self.radius, s.separation, self.SEARCH_SCALE, *pair_rules], outputs=lists,
                      device=x.device)
        wp.copy(self.x_built, x)

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

    def run(self, state: DeviceState) -> None:
        s = self.settings
        wp.copy(self.v_start, state.v)
        if self.colliders:
            self.resting.zero_()
            for collider in self.colliders:
                collider.run(state)
        if self.remake_every_substep:
            self.make_lists(state.x)
        else:
            self.rebuild.zero_()
            launch(particle_collision.displacement_exceeds, self.n, state,
                   inputs=[state.x, self.x_built, self.rebuild_distance], outputs=[self.rebuild])
            positions = state.x
            wp.capture_if(self.rebuild, on_true=lambda: self.make_lists(positions))
        for remaining in range(self.passes, 0, -1):
            if self.limit is not None and remaining <= self.limit.iterations:
                self.limit.run_pass(state)
            if remaining <= s.iterations:
                launch(particle_collision.separate_particles, self.n, state,
                       inputs=[state.x, self.inv_mass, self.radius, s.separation, self.h, self.neighbors,
                               self.counts, s.max_neighbors, self.resting],
                       outputs=[state.x_next, state.v, self.pushed])
                state.swap_positions()
            for collider in self.colliders:
                collider.run(state)
        launch(particle_collision.resolve_contact_velocities, self.n, state,
               inputs=[state.x, state.v, self.v_start, self.inv_mass, self.radius, s.separation, self.CONTACT_SLACK,
                       s.friction, self.h, self.pushed, self.neighbors, self.counts, s.max_neighbors],
               outputs=[state.v_next])
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


def build_stages(model: Model, device) -> list[Stage]:
    """The substep, in order: integrate, pins, then strain limits and colliders, or, with particle
    collision, those projected together with it, then the clock."""
    sim = model.scene.simulation
    h = sim.step
    inv_mass = _upload(model.inv_mass, float, device)
    springs = upload_springs(model, device)
    if sim.integrator == "implicit":
        stages: list[Stage] = [BackwardEuler(model, inv_mass, springs, h, device)]
    else:
        stages = [ExplicitIntegration(model, inv_mass, springs, sim.integrator, h)]
    if model.pins is not None:
        stages.append(DrivePins(model, h, device) if model.pins.moving else HoldPins(model, device))
    limit = StrainLimit(model, inv_mass, sim.limit_iterations, h, device) if model.limits is not None else None
    colliders: list[Stage] = []
    if model.scene.ground is not None:
        colliders.append(GroundCollider(model, inv_mass, h, device))
    if model.spheres is not None:
        spheres = SphereColliders(model, inv_mass, h, device)
        colliders.append(spheres)
        if model.spheres.moving:
            stages.append(MoveSpheres(model, spheres, h, device))
    if model.contacts is not None:
        stages.append(ParticleCollision(model, inv_mass, _upload(model.cloth_id, int, device), limit, colliders, h,
                                        device))
    else:
        stages.extend([limit] if limit is not None else [])
        stages.extend(colliders)
    if (model.pins is not None and model.pins.moving) or (model.spheres is not None and model.spheres.moving):
        stages.append(AdvanceClock())
    return stages
