"""The converged projection: Jacobi passes of the strain limits (with particle collision, limits and
separation together), every pass ending with the rigid colliders, run in pairs inside a device-side loop
(with an edge contacts' pass before each where the scene has them, which the cap does not count) until
the limits and contacts hold to their tolerances or the cap on passes is reached; each pair optionally
accelerated by Chebyshev's semi-iterative method (``limit_chebyshev_rho``, the pair's spectral radius as
estimated for it; docs/notebook/strain-solve.md measures both)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_cloth.kernels import converged_projection, solve_loop
from warp_cloth.kernels.colliders import RigidColliders

from .device_model import DeviceModel
from .passes import Pass, attachments_of, contacts_args
from .state import DeviceState


class ConvergedProjection:
    """Runs ``body`` (passes that leave the positions' buffer parity as they found it) until the check after
    it finds every limit and contact within tolerance, or ``limit_max_passes`` passes have run. Where ``later_body`` is given, a solve that
    has run ``switch_at`` counted passes runs that body instead for the rest of it.

    Each iteration is accelerated by Chebyshev's method (``kernels/solve_loop.py``) with the scene's
    ``limit_chebyshev_rho``, or where it sets none with a spectral radius the solver adjusts from solve to
    solve (lowered where the residual grows, raised where an accelerated solve converges); 0: plain."""

    def __init__(self, model: DeviceModel, state: DeviceState, body: list[Pass],
                 colliders: RigidColliders | None, counted: int | None = None,
                 later_body: list[Pass] | None = None, later_counted: int | None = None,
                 switch_at: int | None = None) -> None:
        assert len(body) % 2 == 0, "a loop's body must leave the positions where it found them"
        assert later_body is None or len(later_body) % 2 == 0
        self.body, self.later_body = body, later_body
        self.counted = len(body) if counted is None else counted  # the body's passes that count to the cap
        self.later_counted = later_counted
        self.name = f"until within tolerance, {len(body)} at a time: " + ", ".join(p.name for p in body)
        if later_body is not None:
            self.name += (f"; after {switch_at} passes, {len(later_body)} at a time: "
                          + ", ".join(p.name for p in later_body))
        self.colliders = colliders if colliders is not None else model.no_colliders()
        self.max_passes = model.limit_max_passes
        self.switch_at = switch_at if later_body is not None else model.limit_max_passes + 1
        self.h = model.h
        device = model.device
        args = converged_projection.ResidualArgs()
        args.check_limits = int(model.limits is not None)
        args.limits = model.limits if model.limits is not None else model.no_limits()
        args.attachments = attachments_of(model)
        args.limit_tolerance = model.limit_tolerance
        args.check_contacts = int(model.contacts is not None)
        args.contacts = contacts_args(model, state) if model.contacts is not None else model.no_contacts()
        args.contact_tolerance = model.contacts.settings.tolerance if model.contacts is not None else 1.0
        args.inv_mass = model.inv_mass
        args.colliders = self.colliders
        self.args = args
        self.active = wp.zeros(1, dtype=int, device=device)
        self.switched = wp.zeros(1, dtype=int, device=device)
        self.counts = wp.zeros(3, dtype=int, device=device)
        self.residual = wp.zeros(1, dtype=float, device=device)
        self.stats = wp.zeros(4, dtype=float, device=device)  # see kernels/solve_loop.py
        rho = model.limit_chebyshev_rho
        self.accelerated = rho != 0.0
        if self.accelerated:
            estimated = rho is None
            rho = solve_loop.RHO_MOST if estimated else rho
            omega = np.zeros(solve_loop.CHEBYSHEV_SLOTS, dtype=np.float32)
            omega[1], omega[4], omega[5] = rho * rho, rho, float(estimated)
            self.omega = wp.array(omega, dtype=float, device=device)  # see solve_loop.start_chebyshev
            self.iterates = [wp.zeros(model.particle_count, dtype=wp.vec3, device=device)
                             for _ in range(2)]  # start, before

    def run(self, state: DeviceState) -> None:
        device = state.device
        wp.launch(solve_loop.start_solve, dim=1, inputs=[self.max_passes, self.switch_at],
                  outputs=[self.active, self.counts, self.residual, self.switched], device=device)
        if self.accelerated:
            wp.launch(solve_loop.start_chebyshev, dim=1, outputs=[self.omega], device=device)
            wp.copy(self.iterates[0], state.x)

        def iteration(body: list[Pass], counted: int) -> None:
            for step in body:
                step.run(state)
            if self.accelerated:
                wp.launch(converged_projection.chebyshev_step_and_colliders, dim=state.x.shape[0],
                          inputs=[state.x, state.v, self.args.inv_mass, self.omega, self.h, self.colliders,
                                  *self.iterates], device=device)
            wp.launch(converged_projection.projection_residual, dim=state.x.shape[0],
                      inputs=[state.x, self.args], outputs=[self.residual], device=device)
            bookkeeping = [self.active, self.counts, self.residual, self.stats, self.switched]
            if self.accelerated:
                wp.launch(solve_loop.continue_chebyshev_solve, dim=1, inputs=[1.0, counted],
                          outputs=[*bookkeeping, self.omega], device=device)
            else:
                wp.launch(solve_loop.continue_solve, dim=1, inputs=[1.0, counted], outputs=bookkeeping,
                          device=device)

        if self.later_body is None:
            wp.capture_while(self.active, lambda: iteration(self.body, self.counted))
        else:
            wp.capture_while(self.active, lambda: wp.capture_if(
                self.switched, on_true=lambda: iteration(self.later_body, self.later_counted),
                on_false=lambda: iteration(self.body, self.counted)))

    def read_stats(self) -> tuple[int, float, float, int]:
        """The most passes a substep took, the largest residual a solve ended with (in tolerances: 1 or less
        within them), the mean passes a substep and the solves, since the last reading (waits for the device)."""
        most, residual, total, solves = self.stats.numpy()
        self.stats.zero_()
        return int(most), float(residual), float(total / solves) if solves else 0.0, int(solves)
