"""The backward Euler stage: Newton steps, each solved by a block-Jacobi preconditioned conjugate
gradient whose loop runs on the device, so a captured frame never waits for the host: a conditional
loop (``wp.capture_while``), or a fixed number of iterations that do nothing once converged. The
kernels are in ``kernels/implicit.py`` (the cloth's system) and ``kernels/cg.py`` (the solver).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels import cg, implicit, pins

from .model import Model
from .state import DeviceState

PARTIALS = 16384  # first level of every dot product's reduction
PARTIALS_2 = 128  # second level, summed by one thread


@dataclass(frozen=True)
class SolveStats:
    """The worst over the substeps since the last reading."""

    cg_iterations: int
    cg_relative_residual: float  # sqrt(r.z / r0.z0) of the preconditioned residual
    newton_iterations: int
    newton_residual: float | None  # RMS over free particles of |M (v - v0) - h f| / m, in m/s


class BackwardEuler:
    name = "integrate:implicit"

    def __init__(self, model: Model, inv_mass: wp.array, springs: tuple, h: float, device) -> None:
        sim = model.scene.simulation
        self.settings = model.scene.implicit
        self.h = h
        self.gravity = wp.vec3(*sim.gravity)
        self.drag = sim.drag
        self.n = n = model.particle_count
        self.device = device
        self.inv_mass = inv_mass
        self.mass = wp.array(model.masses, dtype=float, device=device)
        self.springs = springs  # offsets, other, spring, rest, stiffness, damping, flags
        self.free_particles = max(1, int(np.count_nonzero(model.inv_mass)))
        self.pins = None
        if model.pins is not None:
            p = model.pins
            self.pins = tuple(wp.array(a, dtype=t, device=device) for a, t in
                              ((p.index, int), (p.amplitude, wp.vec3), (p.frequency, float), (p.phase, float)))
        vec = lambda: wp.zeros(n, dtype=wp.vec3, device=device)  # noqa: E731
        self.dv, self.r, self.z, self.p, self.ap = vec(), vec(), vec(), vec(), vec()
        self.inverse = wp.zeros(n, dtype=wp.mat33, device=device)
        self.partial = wp.zeros(min(n, PARTIALS), dtype=float, device=device)
        self.partial_2 = wp.zeros(min(n, PARTIALS_2), dtype=float, device=device)
        self.scalars = wp.zeros(cg.CG_SLOTS, dtype=float, device=device)
        self.cg_active = wp.zeros(1, dtype=int, device=device)  # the device loop's condition
        self.cg_counts = wp.zeros(2, dtype=int, device=device)
        self.newton = wp.ones(2, dtype=int, device=device)  # [on (0 once converged), steps this substep]
        self.stats = wp.zeros(4, dtype=float, device=device)  # worst since read, see implicit.record_*
        self.always = wp.ones(1, dtype=int, device=device)

    def run(self, state: DeviceState) -> None:
        x0, v0 = state.x, state.v
        x1, v1 = state.x_next, state.v_next
        launch = self._launch
        launch(implicit.start_newton, 1, outputs=[self.newton])
        # Baraff & Witkin's step, linearised at the start of the step.
        launch(implicit.newton_rhs, self.n, inputs=[x0, v0, v0, self.mass, self.inv_mass, self.gravity, self.drag,
                                                    self.h, 1, *self.springs], outputs=[self.r])
        self._solve(x0, v0, state.clock)
        launch(implicit.finish_step, self.n, inputs=[x0, v0, self.dv, self.h, self.newton], outputs=[x1, v1])
        # Further Newton steps on M (v - v0) = h f(x0 + h v, v), at y = x0 + h v = x1, until the residual
        # is below the tolerance.
        for _ in range(self.settings.newton_iterations - 1):
            self._newton_residual(x1, v1, v0)
            launch(implicit.continue_newton, 1, inputs=[self.partial_2, float(self.free_particles),
                                                        self.settings.newton_tolerance], outputs=[self.newton])
            self._solve(x1, v1, state.clock)
            launch(implicit.finish_step, self.n, inputs=[x0, v1, self.dv, self.h, self.newton], outputs=[x1, v1])
        if self.settings.newton_iterations > 1:
            self._newton_residual(x1, v1, v0)
            launch(implicit.record_newton, 1, inputs=[self.partial_2, float(self.free_particles), self.newton],
                   outputs=[self.stats])
        state.swap_positions()
        state.swap_velocities()

    def _launch(self, kernel, dim: int, inputs=(), outputs=()) -> None:
        wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=self.device)

    def _dot(self, a: wp.array, b: wp.array, active: wp.array) -> None:
        """Leaves a . b as the partial sums that the next scalar kernel totals (if ``active[0]``)."""
        self._launch(cg.dot_partials, self.partial.shape[0], inputs=[a, b, self.partial.shape[0], active],
                     outputs=[self.partial])
        self._launch(cg.sum_partials, self.partial_2.shape[0],
                     inputs=[self.partial, self.partial_2.shape[0], active], outputs=[self.partial_2])

    def _solve(self, y: wp.array, v: wp.array, clock: wp.array) -> None:
        """dv from A dv = r (r holds the right-hand side), with pinned particles' dv prescribed."""
        launch = self._launch
        s = self.settings
        self.dv.zero_()
        if self.pins is not None:
            index, amplitude, frequency, phase = self.pins
            launch(pins.pinned_velocity_change, index.shape[0],
                   inputs=[index, amplitude, frequency, phase, clock, self.h, v], outputs=[self.dv])
        system = [y, self.mass, self.inv_mass, self.drag, self.h, *self.springs]
        launch(implicit.system_times, self.n, inputs=[*system, self.dv, self.always], outputs=[self.ap])
        launch(cg.subtract, self.n, inputs=[self.r, self.ap], outputs=[self.r])
        launch(implicit.block_jacobi_inverse, self.n, inputs=system, outputs=[self.inverse])
        launch(cg.precondition, self.n, inputs=[self.inverse, self.r, self.always], outputs=[self.z])
        wp.copy(self.p, self.z)
        self._dot(self.r, self.z, self.always)
        launch(cg.start, 1, inputs=[self.partial_2, s.cg_tolerance, s.cg_max_iterations, self.newton],
               outputs=[self.scalars, self.cg_active, self.cg_counts])

        state = self.cg_active

        def iteration() -> None:
            launch(implicit.system_times, self.n, inputs=[*system, self.p, state], outputs=[self.ap])
            self._dot(self.p, self.ap, state)
            launch(cg.step_length, 1, inputs=[self.partial_2, state], outputs=[self.scalars])
            launch(cg.advance, self.n, inputs=[self.p, self.ap, self.scalars, state], outputs=[self.dv, self.r])
            launch(cg.precondition, self.n, inputs=[self.inverse, self.r, state], outputs=[self.z])
            self._dot(self.r, self.z, state)
            launch(cg.next_direction_scale, 1, inputs=[self.partial_2], outputs=[self.scalars, state, self.cg_counts])
            launch(cg.update_direction, self.n, inputs=[self.z, self.scalars, state], outputs=[self.p])

        if s.cg_loop == "device_while":
            wp.capture_while(state, iteration)
        else:
            for _ in range(s.cg_max_iterations):
                iteration()
        launch(implicit.record_solve, 1, inputs=[self.scalars, self.cg_counts], outputs=[self.stats])

    def _newton_residual(self, y: wp.array, v: wp.array, v0: wp.array) -> None:
        """r = h f(y, v) - M (v - v0), and (in the partial sums) the square of its size per unit mass."""
        self._launch(implicit.newton_rhs, self.n, inputs=[y, v, v0, self.mass, self.inv_mass, self.gravity,
                                                          self.drag, self.h, 0, *self.springs], outputs=[self.r])
        self._launch(implicit.per_unit_mass, self.n, inputs=[self.r, self.inv_mass], outputs=[self.z])
        self._dot(self.z, self.z, self.always)

    def read_stats(self) -> SolveStats:
        values = self.stats.numpy().copy()
        self.stats.zero_()
        newton = self.settings.newton_iterations > 1
        return SolveStats(int(values[0]), math.sqrt(max(0.0, float(values[1]))), int(values[2]) if newton else 1,
                          float(values[3]) if newton else None)
