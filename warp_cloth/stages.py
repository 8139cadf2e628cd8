"""The stages a substep is made of. ``build_stages`` turns a model into the list once; an effect the
scene does not declare has no stage, so it costs no launch and no memory."""

from __future__ import annotations

from typing import Protocol

import warp as wp

from warp_cloth.kernels import colliders, integration, limits, motion, pins

from .model import Model
from .state import DeviceState


class Stage(Protocol):
    name: str

    def run(self, state: DeviceState, launch: "Launcher") -> None: ...


class Launcher:
    """Launches kernels on one device, or records them as prepared launches (``wp.Launch``) to replay:
    on the CPU, where there are no CUDA graphs, replaying prepared launches skips most of the Python
    cost of ``wp.launch`` (about 19 us against 4 us a launch here)."""

    def __init__(self, device) -> None:
        self.device = device
        self.recording: list[wp.Launch] | None = None

    def __call__(self, kernel, dim: int, inputs=(), outputs=()) -> None:
        if self.recording is None:
            wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=self.device)
        else:
            self.recording.append(wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=self.device,
                                            record_cmd=True))


def _upload(array, dtype, device):
    return wp.array(array, dtype=dtype, device=device)


class ExplicitIntegration:
    """Spring forces and gravity, then one explicit or symplectic Euler step."""

    def __init__(self, model: Model, inv_mass: wp.array, integrator: str, h: float, device) -> None:
        self.name = f"integrate:{integrator}"
        self.h = h
        self.semi_implicit = 1 if integrator == "symplectic" else 0
        self.gravity = wp.vec3(*model.scene.simulation.gravity)
        self.drag = model.scene.simulation.drag
        self.n = model.particle_count
        self.inv_mass = inv_mass
        springs = model.springs
        if springs is None:
            self.offsets = wp.zeros(self.n + 1, dtype=int, device=device)
            empty_i, empty_f = wp.zeros(0, dtype=int, device=device), wp.zeros(0, dtype=float, device=device)
            self.spring_arrays = (empty_i, empty_i, empty_f, empty_f, empty_f, empty_i)
        else:
            adj = springs.adjacency
            self.offsets = _upload(adj.offsets, int, device)
            self.spring_arrays = (_upload(adj.other, int, device), _upload(adj.spring, int, device),
                                  _upload(springs.rest, float, device), _upload(springs.stiffness, float, device),
                                  _upload(springs.damping, float, device), _upload(springs.flags, int, device))

    def run(self, state: DeviceState, launch: Launcher) -> None:
        launch(integration.euler_step, self.n,
                  inputs=[state.x, state.v, self.inv_mass, self.gravity, self.drag, self.h, self.semi_implicit, self.offsets,
                          *self.spring_arrays],
                  outputs=[state.x_next, state.v_next])
        state.swap_positions()
        state.swap_velocities()


class HoldPins:
    def __init__(self, model: Model, device) -> None:
        self.name = "pins:fixed"
        self.index = _upload(model.pins.index, int, device)
        self.anchor = _upload(model.pins.anchor, wp.vec3, device)

    def run(self, state: DeviceState, launch: Launcher) -> None:
        launch(pins.hold_pins, self.index.shape[0], inputs=[self.index, self.anchor],
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

    def run(self, state: DeviceState, launch: Launcher) -> None:
        launch(pins.drive_pins, self.arrays[0].shape[0], inputs=[*self.arrays, state.clock, self.h],
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

    def run(self, state: DeviceState, launch: Launcher) -> None:
        for _ in range(self.iterations):
            launch(limits.project_strain_limits, state.x.shape[0],
                      inputs=[state.x, self.inv_mass, *self.arrays, self.h],
                      outputs=[state.x_next, state.v])
            state.swap_positions()


class SphereColliders:
    """All spheres in one launch; moving ones first get their centre and velocity at the substep's end."""

    def __init__(self, model: Model, inv_mass: wp.array, h: float, device) -> None:
        s = model.spheres
        self.inv_mass = inv_mass
        self.h = h
        self.center = _upload(s.initial_center, wp.vec3, device)
        self.velocity = wp.zeros(len(s.center), dtype=wp.vec3, device=device)
        self.radius = _upload(s.radius, float, device)
        self.friction = _upload(s.friction, float, device)
        self.motion = None
        if s.moving:
            self.motion = (_upload(s.center, wp.vec3, device), _upload(s.amplitude, wp.vec3, device),
                           _upload(s.frequency, float, device), _upload(s.phase, float, device))
        self.name = "spheres:moving" if s.moving else "spheres:static"

    def run(self, state: DeviceState, launch: Launcher) -> None:
        if self.motion is not None:
            launch(motion.move_spheres, self.center.shape[0], inputs=[state.clock, self.h, *self.motion],
                      outputs=[self.center, self.velocity])
        launch(colliders.collide_spheres, state.x.shape[0],
                  inputs=[self.center, self.velocity, self.radius, self.friction, self.inv_mass],
                  outputs=[state.x, state.v])


class GroundCollider:
    def __init__(self, model: Model, inv_mass: wp.array) -> None:
        self.name = "ground"
        ground = model.scene.ground
        self.height = ground.height
        self.friction = ground.friction
        self.inv_mass = inv_mass

    def run(self, state: DeviceState, launch: Launcher) -> None:
        launch(colliders.collide_ground, state.x.shape[0], inputs=[self.height, self.friction, self.inv_mass],
                  outputs=[state.x, state.v])


class AdvanceClock:
    name = "clock"

    def run(self, state: DeviceState, launch: Launcher) -> None:
        launch(motion.advance_clock, 1, outputs=[state.clock])


def build_stages(model: Model, device) -> list[Stage]:
    """The substep, in order: integrate, pins, strain limits, colliders, clock."""
    sim = model.scene.simulation
    h = sim.step
    inv_mass = _upload(model.inv_mass, float, device)
    stages: list[Stage] = [ExplicitIntegration(model, inv_mass, sim.integrator, h, device)]
    if model.pins is not None:
        stages.append(DrivePins(model, h, device) if model.pins.moving else HoldPins(model, device))
    if model.limits is not None:
        stages.append(StrainLimit(model, inv_mass, sim.limit_iterations, h, device))
    if model.scene.ground is not None:
        stages.append(GroundCollider(model, inv_mass))
    if model.spheres is not None:
        stages.append(SphereColliders(model, inv_mass, h, device))
    if (model.pins is not None and model.pins.moving) or (model.spheres is not None and model.spheres.moving):
        stages.append(AdvanceClock())
    return stages
