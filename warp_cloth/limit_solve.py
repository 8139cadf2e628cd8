"""The strain limit's solve: its settings (``LimitSolveSettings``, from the scene's ``[simulation]``) and the
converged projection, Jacobi passes of the strain limits (with particle collision, limits and separation
together), every pass ending with the rigid colliders, run in pairs inside a device-side loop (with an
edge contacts' pass before each where the scene has them, which the cap does not count) until the limits
and contacts hold to their tolerances or the cap on passes is reached; each pair accelerated by
Chebyshev's semi-iterative method with a spectral radius the solver estimates
(docs/notebook/strain-solve.md measures it against plain passes and fixed radii)."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator

import numpy as np
import warp as wp

from warp_cloth.kernels import converged_projection, solve_loop
from warp_cloth.kernels.colliders import RigidColliders
from warp_cloth.kernels.edge_collision import EdgeContacts
from warp_cloth.kernels.face_collision import FaceContacts as FaceContactsArgs

from .device_model import DeviceModel
from .face_contacts import FaceContacts
from .passes import Pass, attachments_of, contacts_args, edge_contacts_args
from .scene import Simulation
from .state import DeviceState


@dataclass(frozen=True)
class SolveChoices:
    """What the converged solve chooses for itself, not scene keys: the lab and the tests fix others with
    ``lab_hooks`` (tools/strain_solve_probe.py, tools/line_solve_probe.py) to measure against the choice.

    ``chebyshev_rho``: a fixed spectral radius for the Chebyshev acceleration, 0 for plain passes (None: the
    solver estimates it). ``joint_passes``: with strain limits and particle collision, the passes projected
    jointly before the rest are projected sequentially (0: sequential throughout; at least the cap: joint
    throughout). 200 was the cap's default before issue 32, within which every built-in scene but
    seed_default converged: the joint pass takes from each limit correction the part that pulls into a
    contact, so a chain of springs pulled taut over a contact cannot shorten, and seed_default's solves
    stalled at the cap there 2 to 4 tolerances out, where the sequential ones converge
    (docs/notebook/strain-solve.md).

    ``line_solve``: the converged solve of cloths without particle collision is a Jacobi pair, then, where it
    leaves a limit out, rounds of line solves (warp_cloth/line_solve.py, the lines from
    warp_cloth/cloth_lines.py; plan.line_projection): the default, which the lab turns off to measure the
    Jacobi passes alone. With particle collision the Jacobi passes stay unless the lab asks for line rounds
    there too (``line_contacts``: each round followed by the contacts' separating passes; slower than the
    joint passes on pile). The springs are held within ``line_hold_margin`` of a limit (1: every spring),
    ``line_newton_steps`` linearised steps a line a round (kernels/line_solve.py), a thread a segment of
    ``line_segment`` springs (at least the longest line: whole lines), the per-slot arrays stored interleaved
    where ``line_interleaved``, else contiguous; None leaves either to the device where the simulator builds
    the solves (line_solve.LineSolves.of: CUDA segments of a 64th of the longest line, interleaved; the CPU
    whole lines, contiguous)."""
    chebyshev_rho: float | None = None
    joint_passes: int = 200
    line_solve: bool = True
    line_contacts: bool = False
    line_hold_margin: float = 0.02
    line_newton_steps: int = 2
    line_segment: int | None = None
    line_interleaved: bool | None = None


# The choices simulators are built with: the solver's own, or the lab's while ``lab_hooks`` holds others.
CHOICES = SolveChoices()


@contextmanager
def lab_hooks(choices: SolveChoices) -> Iterator[None]:
    """Simulators built inside take ``choices`` (the lab's and tests', never a scene's)."""
    global CHOICES
    before, CHOICES = CHOICES, choices
    try:
        yield
    finally:
        CHOICES = before


@dataclass(frozen=True)
class LimitSolveSettings:
    """How the plan solves the strain limits (and, with particle collision, the contacts with them):
    ``converged`` repeats its passes until within ``tolerance`` (a fraction of an allowed length), at most
    ``max_passes`` a substep; else ``iterations`` fixed passes a substep. ``choices``: the solver's own
    (``SolveChoices``), or the lab's, as they were when the settings were made; the line rounds are the
    converged solve's alone (``line_rounds``)."""
    converged: bool
    iterations: int
    tolerance: float
    max_passes: int
    choices: SolveChoices

    @property
    def line_rounds(self) -> bool:
        """Whether the converged solve takes rounds of line solves (the simulator builds them for a scene with
        particle collision only where ``choices.line_contacts`` too)."""
        return self.converged and self.choices.line_solve

    @classmethod
    def of(cls, simulation: Simulation) -> LimitSolveSettings:
        """The settings of a scene's ``[simulation]`` as the simulator resolved it (its cap chosen)."""
        return cls(simulation.limit_solve == "converged", simulation.limit_iterations, simulation.limit_tolerance,
                   simulation.limit_max_passes, CHOICES)


def residual_args(model: DeviceModel, state: DeviceState, settings: LimitSolveSettings, colliders: RigidColliders,
                  contacts: bool = True, faces: FaceContacts | None = None) -> converged_projection.ResidualArgs:
    """What the solve's check reads: the limits and attachments, and where ``contacts`` the particle
    contacts, with their tolerances; where ``faces`` (a surface thickness's face contacts) also their pairs and
    the edge contacts' (where the scene has them), to the contacts' tolerance of the thickness both hold."""
    args = converged_projection.ResidualArgs()
    args.check_limits = int(model.limits is not None)
    args.limits = model.limits if model.limits is not None else model.no_limits()
    args.attachments = attachments_of(model)
    args.limit_tolerance = settings.tolerance
    args.check_contacts = int(contacts and model.contacts is not None)
    args.contacts = contacts_args(model, state) if model.contacts is not None else model.no_contacts()
    args.contact_tolerance = model.contacts.settings.tolerance if model.contacts is not None else 1.0
    surfaces = contacts and faces is not None
    args.check_edges = int(surfaces)  # a thickness brings the edge contacts with the face contacts
    args.edges = edge_contacts_args(model, state) if args.check_edges else EdgeContacts()  # unread where 0
    args.check_faces = int(surfaces)
    args.faces = faces.args if surfaces else FaceContactsArgs()
    args.inv_mass = model.inv_mass
    args.colliders = colliders
    return args


class ConvergedProjection:
    """Runs ``body`` (passes that leave the positions' buffer parity as they found it) until the check after
    it finds every limit and contact within tolerance, or ``settings.max_passes`` passes have run. Where
    ``later_body`` is given, a solve that has run ``switch_at`` counted passes runs that body instead for the
    rest of it. Without ``contacts`` it checks the limits alone (for a body that does not separate); with
    ``faces`` (a surface thickness's face contacts) the edge and face pairs too (``residual_args``).

    Each iteration is accelerated by Chebyshev's method (``kernels/solve_loop.py``) with a spectral radius
    the solver adjusts from solve to solve (lowered where the residual grows, raised where an accelerated
    solve converges), or the choices' fixed ``chebyshev_rho`` (0: plain)."""

    def __init__(self, model: DeviceModel, state: DeviceState, settings: LimitSolveSettings, body: list[Pass],
                 colliders: RigidColliders | None, counted: int | None = None,
                 later_body: list[Pass] | None = None, later_counted: int | None = None,
                 switch_at: int | None = None, contacts: bool = True, faces: FaceContacts | None = None) -> None:
        assert len(body) % 2 == 0, "a loop's body must leave the positions where it found them"
        assert later_body is None or len(later_body) % 2 == 0
        self.body, self.later_body = body, later_body
        self.counted = len(body) if counted is None else counted  # the body's passes that count to the cap
        self.later_counted = later_counted
        self.name = "converged solve"
        self.colliders = colliders if colliders is not None else model.no_colliders()
        self.max_passes = settings.max_passes
        self.switch_at = switch_at if later_body is not None else settings.max_passes + 1
        self.h = model.h
        device = model.device
        self.args = residual_args(model, state, settings, self.colliders, contacts, faces)
        self.active = wp.zeros(1, dtype=int, device=device)
        self.switched = wp.zeros(1, dtype=int, device=device)
        self.counts = wp.zeros(3, dtype=int, device=device)
        self.residual = wp.zeros(1, dtype=float, device=device)
        self.stats = wp.zeros(4, dtype=float, device=device)  # see kernels/solve_loop.py
        rho = settings.choices.chebyshev_rho
        self.accelerated = rho != 0.0
        if self.accelerated:
            estimated = rho is None
            rho = solve_loop.RHO_MOST if estimated else rho
            omega = np.zeros(solve_loop.CHEBYSHEV_SLOTS, dtype=np.float32)
            omega[1], omega[4], omega[5] = rho * rho, rho, float(estimated)
            self.omega = wp.array(omega, dtype=float, device=device)  # see solve_loop.start_chebyshev
            self.iterates = [wp.zeros(model.particle_count, dtype=wp.vec3, device=device)
                             for _ in range(2)]  # start, before
        # the loop's own launches, which ``run`` makes and ``describe`` names
        self.start_kernels = [solve_loop.start_solve] + ([solve_loop.start_chebyshev] if self.accelerated else [])
        self.step_kernels = [converged_projection.chebyshev_step_and_colliders] if self.accelerated else []
        self.continue_kernel = solve_loop.continue_chebyshev_solve if self.accelerated else solve_loop.continue_solve

    def describe(self) -> list[str]:
        """The solve's launches in order, one a line, those of an iteration indented under the loop."""
        lines = [f"{self.name}, until within tolerance or at {self.max_passes} passes:",
                 "    " + ", ".join([k.key for k in self.start_kernels]
                                    + (["a copy of the positions"] if self.accelerated else [])),
                 "  each iteration:"]

        def iteration(body: list[Pass]) -> list[str]:
            return ([f"    {p.name}" for p in body] + [f"    {k.key}" for k in self.step_kernels]
                    + [f"    {converged_projection.projection_residual.key}",
                       f"    {self.continue_kernel.key} (the loop's bookkeeping)"])

        lines += iteration(self.body)
        if self.later_body is not None:
            lines += [f"  after {self.switch_at} passes, each iteration instead:"] + iteration(self.later_body)
        return lines

    def run(self, state: DeviceState) -> None:
        device = state.device
        wp.launch(self.start_kernels[0], dim=1, inputs=[self.max_passes, self.switch_at],
                  outputs=[self.active, self.counts, self.residual, self.switched], device=device)
        if self.accelerated:
            wp.launch(self.start_kernels[1], dim=1, outputs=[self.omega], device=device)
            wp.copy(self.iterates[0], state.x)
        omega = [self.omega] if self.accelerated else []

        def iteration(body: list[Pass], counted: int) -> None:
            for step in body:
                step.run(state)
            for kernel in self.step_kernels:
                wp.launch(kernel, dim=state.x.shape[0], inputs=[state.x, state.v, self.args.inv_mass, self.omega,
                                                                self.h, self.colliders, *self.iterates],
                          device=device)
            wp.launch(converged_projection.projection_residual, dim=state.x.shape[0],
                      inputs=[state.x, self.args], outputs=[self.residual], device=device)
            wp.launch(self.continue_kernel, dim=1, inputs=[1.0, counted],
                      outputs=[self.active, self.counts, self.residual, self.stats, self.switched, *omega],
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
