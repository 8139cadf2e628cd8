"""The backward Euler pass: Newton steps, each solved by a block-Jacobi preconditioned conjugate gradient
whose loop runs on the device, so a captured frame never waits for the host: a conditional loop
(``wp.capture_while``), or a fixed number of iterations that do nothing once converged. The kernels are in
``kernels/implicit.py`` (the cloth's system, the step's end, Newton's bookkeeping) and ``kernels/cg.py``
(the solver).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels import cg, implicit, motion

from .device_model import DeviceModel
from .scene import ImplicitSolver
from .state import DeviceState

PARTIALS = 16384  # one world: partial sums of every dot product, then totalled by one block


@dataclass(frozen=True)
class SolveStats:
    """The worst over the substeps since the last reading: of the implicit step's solve (None with the
    explicit integrators) and of a converged limit solve (None with ``limit_solve = "fixed"``)."""

    cg_iterations: int | None = None
    cg_relative_residual: float | None = None  # sqrt(r.z / b.Pb): the preconditioned residual, of the rhs's
    newton_iterations: int | None = None
    newton_residual: float | None = None  # RMS over free particles of |M (v - v0) - h f| / m, in m/s
    limit_passes: int | None = None  # the most projection passes a substep
    limit_mean_passes: float | None = None  # projection passes a substep, on average
    limit_residual: float | None = None  # where a solve ended, in its tolerances (at most 1: within them)
    limit_solves: int | None = None  # the substeps' solves these figures are over

    def merged(self, later: "SolveStats") -> "SolveStats":
        """These figures and ``later``'s as one reading over the substeps of both."""
        worst = lambda a, b: b if a is None else a if b is None else max(a, b)  # noqa: E731
        mean, earlier = self.limit_mean_passes, self.limit_solves or 0
        if later.limit_solves:
            total = (mean or 0.0) * earlier + later.limit_mean_passes * later.limit_solves
            mean = total / (earlier + later.limit_solves)
        solves = None if self.limit_solves is None and later.limit_solves is None else \
            earlier + (later.limit_solves or 0)
        return SolveStats(worst(self.cg_iterations, later.cg_iterations),
                          worst(self.cg_relative_residual, later.cg_relative_residual),
                          worst(self.newton_iterations, later.newton_iterations),
                          worst(self.newton_residual, later.newton_residual),
                          worst(self.limit_passes, later.limit_passes), mean,
                          worst(self.limit_residual, later.limit_residual), solves)


def world_lanes(world_start: np.ndarray) -> int:
    """Partial sums a world's dot products: one world's a particle each below ``cg.SUM_TILE`` particles, else
    up to ``PARTIALS``, a multiple of the tile (its block totals them a tile at a time); a batch's about 32
    particles a lane in its largest world, as a power of two from 32 to 1024."""
    sizes = np.diff(world_start)
    if len(sizes) == 1:
        n = max(1, int(sizes[0]))
        return n if n < cg.SUM_TILE else min(PARTIALS, cg.SUM_TILE * (n // cg.SUM_TILE))
    largest = int(sizes.max())
    return int(min(1024, max(32, 1 << max(0, math.ceil(math.log2(max(1, largest) / 32))))))


class BackwardEuler:
    name = "integrate:implicit"

    def __init__(self, model: DeviceModel, state: DeviceState, settings: ImplicitSolver) -> None:
        self.settings = settings
        self.h = model.h
        self.n = n = model.particle_count
        self.device = device = model.device
        self.inv_mass = model.inv_mass
        self.free_particles = model.free_particles
        self.worlds = worlds = model.world_count
        self.world = model.particle_world
        self.world_start = model.world_start
        self.pins = model.pins
        self.system = implicit.SpringSystemArgs()
        self.system.springs, self.system.bending = model.springs, model.bending
        self.system.forces = model.forces(state.wind)
        self.system.mass, self.system.inv_mass, self.system.h = model.mass, model.inv_mass, model.h
        vec = lambda: wp.zeros(n, dtype=wp.vec3, device=device)  # noqa: E731
        self.dv, self.r, self.z, self.p, self.ap = vec(), vec(), vec(), vec(), vec()
        self.inverse = wp.zeros(n, dtype=wp.mat33, device=device)
        self.lanes = world_lanes(model.world_start.numpy())
        self.partial = wp.zeros(worlds * self.lanes, dtype=float, device=device)
        self.scalars = wp.zeros((worlds, cg.CG_SLOTS), dtype=float, device=device)
        self.cg_active = wp.zeros(worlds, dtype=int, device=device)
        self.cg_iterating = wp.zeros(1, dtype=int, device=device)  # the device loop's condition
        self.cg_iterations = wp.zeros(worlds, dtype=int, device=device)
        self.newton = wp.ones((worlds, 2), dtype=int, device=device)  # [on (0 once converged), steps this substep]
        self.stats = wp.zeros(4, dtype=float, device=device)  # worst since read, see implicit.record_*
        self.always = wp.ones(worlds, dtype=int, device=device)

    def run(self, state: DeviceState) -> None:
        x0, v0 = state.x, state.v
        x1, v1 = state.x_next, state.v_next
        launch = self._launch
        launch(implicit.start_newton, self.worlds, outputs=[self.newton])
        # Baraff & Witkin's step, linearised at the start of the step.
        launch(implicit.newton_rhs, self.n, inputs=[x0, v0, v0, self.system, 1], outputs=[self.r])
        self._solve(x0, v0, state.clock, warm=self.settings.newton_iterations == 1)
        finish = [self.h, self.world, self.newton]
        launch(implicit.finish_step, self.n, inputs=[x0, v0, self.dv, *finish], outputs=[x1, v1])
        # Further Newton steps on M (v - v0) = h f(x0 + h v, v), at y = x0 + h v = x1, until the residual
        # is below the tolerance.
        for _ in range(self.settings.newton_iterations - 1):
            self._newton_residual(x1, v1, v0)
            self._total(implicit.continue_newton, inputs=[self.partial, self.lanes, self.free_particles,
                                                           self.settings.newton_tolerance], outputs=[self.newton])
            self._solve(x1, v1, state.clock, warm=False)
            launch(implicit.finish_step, self.n, inputs=[x0, v1, self.dv, *finish], outputs=[x1, v1])
        if self.settings.newton_iterations > 1:
            self._newton_residual(x1, v1, v0)
            self._total(implicit.record_newton, inputs=[self.partial, self.lanes, self.free_particles, self.newton],
                        outputs=[self.stats])
        state.swap_positions()
        state.swap_velocities()

    def _launch(self, kernel, dim: int, inputs=(), outputs=()) -> None:
        wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=self.device)

    def _total(self, kernel, inputs=(), outputs=()) -> None:
        """A kernel that totals each world's partial sums, launched a block a world (cg.world_total)."""
        wp.launch_tiled(kernel, dim=[self.worlds], inputs=inputs, outputs=outputs, block_dim=cg.SUM_BLOCK,
                        device=self.device)

    def _dot(self, a: wp.array, b: wp.array, active: wp.array) -> None:
        """Leaves each world's a . b (where ``active``) in ``partial``, as the ``lanes`` partial sums a world
        that the next totalling kernel adds up."""
        self._launch(cg.world_dot_partials, self.partial.shape[0],
                     inputs=[a, b, self.world_start, self.lanes, active], outputs=[self.partial])

    def _solve(self, y: wp.array, v: wp.array, clock: wp.array, warm: bool) -> None:
        """dv from A dv = r (r holds the right-hand side), with pinned particles' dv prescribed; from the last
        solve's dv where ``warm`` (a step's, not a Newton correction's), else from zero. The tolerance is
        relative to the right-hand side's size, so a solve from a first guess stops where one from zero
        would."""
        launch = self._launch
        s = self.settings
        total = self._total
        lanes, partials = self.lanes, self.partial.shape[0]
        launch(implicit.block_jacobi_inverse, self.n, inputs=[y, self.system], outputs=[self.inverse])
        launch(cg.precondition_and_dot, partials, inputs=[self.inverse, self.r, self.world_start, lanes, self.always],
               outputs=[self.z, self.partial])
        total(cg.reference, inputs=[self.partial, lanes], outputs=[self.scalars])
        if warm:
            launch(implicit.warm_start, self.n, inputs=[self.inv_mass], outputs=[self.dv])
        else:
            self.dv.zero_()
        if self.pins is not None:
            p = self.pins
            launch(motion.pinned_velocity_change, p.index.shape[0],
                   inputs=[p.index, p.amplitude, p.frequency, p.phase, clock, self.h, v], outputs=[self.dv])
        launch(implicit.system_times, self.n, inputs=[y, self.dv, self.always, self.system], outputs=[self.ap])
        launch(cg.subtract, self.n, inputs=[self.r, self.ap], outputs=[self.r])
        launch(cg.precondition_and_dot, partials, inputs=[self.inverse, self.r, self.world_start, lanes, self.always],
               outputs=[self.z, self.partial])
        wp.copy(self.p, self.z)
        self.cg_iterating.zero_()
        total(cg.start, inputs=[self.partial, lanes, s.cg_tolerance, s.cg_max_iterations, self.newton],
              outputs=[self.scalars, self.cg_active, self.cg_iterating, self.cg_iterations])

        active, world = self.cg_active, self.world

        def iteration() -> None:
            launch(implicit.system_times, self.n, inputs=[y, self.p, active, self.system], outputs=[self.ap])
            self._dot(self.p, self.ap, active)
            total(cg.step_length, inputs=[self.partial, lanes, active], outputs=[self.scalars, self.cg_iterating])
            launch(cg.advance_and_precondition, partials,
                   inputs=[self.p, self.ap, self.inverse, self.world_start, lanes, self.scalars, active],
                   outputs=[self.dv, self.r, self.z, self.partial])
            total(cg.next_direction_scale, inputs=[self.partial, lanes, s.cg_max_iterations],
                  outputs=[self.scalars, active, self.cg_iterating, self.cg_iterations])
            launch(cg.update_direction, self.n, inputs=[self.z, world, self.scalars, active], outputs=[self.p])

        wp.capture_while(self.cg_iterating, iteration)
        launch(cg.record_solve, self.worlds, inputs=[self.scalars, self.cg_iterations, self.newton],
               outputs=[self.stats])

    def _newton_residual(self, y: wp.array, v: wp.array, v0: wp.array) -> None:
        """r = h f(y, v) - M (v - v0), and (in the partial sums) the square of its size per unit mass."""
        self._launch(implicit.newton_rhs, self.n, inputs=[y, v, v0, self.system, 0], outputs=[self.r])
        self._launch(implicit.per_unit_mass, self.n, inputs=[self.r, self.inv_mass], outputs=[self.z])
        self._dot(self.z, self.z, self.always)

    def carried(self) -> dict[str, wp.array]:
        """The last step's dv, the next step's first guess (where a step is one solve), by name."""
        return {"implicit.dv": self.dv} if self.settings.newton_iterations == 1 else {}

    def read_stats(self) -> SolveStats:
        values = self.stats.numpy().copy()
        self.stats.zero_()
        newton = self.settings.newton_iterations > 1
        return SolveStats(int(values[0]), math.sqrt(max(0.0, float(values[1]))), int(values[2]) if newton else 1,
                          float(values[3]) if newton else None)
