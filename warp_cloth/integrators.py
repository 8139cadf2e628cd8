"""The integrators, one object each: what a scene's choice of integrator decides wherever it matters (its
pass in the plan, its stable step, the device memory it needs, the passes its solve may take, what to try
when a run blows up), so that nothing else compares its name. ``integrator_for`` is the one place a name
(a scene's ``simulation.integrator``) becomes one."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Protocol

from warp_cloth.kernels import explicit_step

from .device_model import DeviceModel
from .implicit import BackwardEuler
from .passes import GatheringPass, Pass
from .scene import ImplicitSolver
from .state import DeviceState

EXPLICIT_RUN_GROWTH = 2.0  # forward Euler with undamped springs: the fastest mode's growth over the run
LIMITED_BY_DAMPING = "damping"  # a stable step's limit where the damping rate C sets it (about h < 2 / C)


class Integrator(Protocol):
    name: str  # as a scene names it
    device_bytes_per_particle: int  # beyond the state's and the springs': its own arrays (a rough bound)
    needs_masses: bool  # the device model uploads the masses, not only their inverses
    ends_with_contact_start: bool  # its pass can end with particle collision's contacts' start
    unstable_advice: str  # what to try, besides a smaller step, when a run blows up (a clause)
    # Its largest stable step on a cloth of fastest squared frequency (rad^2/s^2), fastest damping rate (1/s)
    # and smallest spring damping time (s), run for a duration (s), and what limits it (see stability.py);
    # None where it is stable at any step.
    stable_step: Callable[[float, float, float, float], tuple[float, str]] | None

    def solve_passes(self) -> dict[str, int]:
        """The most passes its solve may take a substep, by the scene key that sets them (none: empty)."""
        ...

    def step(self, model: DeviceModel, state: DeviceState, threads: int,
             start: explicit_step.ContactStartArgs | None) -> Pass:
        """Its pass of the substep; where ``start`` is given (only if ``ends_with_contact_start``), the
        contacts' start too."""
        ...


@dataclass(frozen=True)
class ExplicitIntegrator:
    """Forward Euler (the seed's: x += h v, then v += h a) or, where ``symplectic``, symplectic Euler
    (v += h a, then x += h v'): one gathering pass of the springs' and external forces
    (kernels/integration.py), stable below a bound."""

    name: str
    symplectic: bool

    device_bytes_per_particle = 0
    needs_masses = False
    ends_with_contact_start = True
    unstable_advice = " or the implicit integrator (--integrator implicit)"

    def stable_step(self, omega_sq: float, damping_rate: float, damping_time: float,
                    duration: float) -> tuple[float, str]:
        """The bound stability.py's docstring derives for one mode ``x'' = -w^2 x - c x'``."""
        w2, c = omega_sq, damping_rate
        if self.symplectic:
            root = math.sqrt(c * c + 4.0 * w2)
            step = 4.0 / (c + root) if c + root > 0 else math.inf
            return step, "stiffness" if w2 * step >= 2.0 * c else LIMITED_BY_DAMPING
        candidates = {LIMITED_BY_DAMPING: 2.0 / c if c > 0 else math.inf}
        if damping_time > 0:
            candidates["damping time b L0/k"] = damping_time
        else:
            candidates[f"undamped springs, {EXPLICIT_RUN_GROWTH:g}x growth over the run"] = \
                2.0 * math.log(EXPLICIT_RUN_GROWTH) / (duration * w2)
        limited_by = min(candidates, key=candidates.get)
        return candidates[limited_by], limited_by

    def solve_passes(self) -> dict[str, int]:
        return {}

    def step(self, model: DeviceModel, state: DeviceState, threads: int,
             start: explicit_step.ContactStartArgs | None) -> GatheringPass:
        """Spring and external forces and one Euler step; where ``start`` is given, the particle collision's
        contact start too (the colliders, the velocities the contacts start from, the lists' remake check),
        which saves a pass over the particles."""
        name = f"integrate:{self.name}"
        if start is None:
            return GatheringPass(name, explicit_step.explicit_step_kernel(threads), threads,
                                 self.step_args(model, state), model.device, new_velocities=True)
        args = explicit_step.ExplicitStepAndContactStartArgs()
        args.step, args.start = self.step_args(model, state), start
        return GatheringPass(f"{name}+contact_start", explicit_step.explicit_step_and_contact_start_kernel(threads),
                             threads, args, model.device, new_velocities=True)

    def step_args(self, model: DeviceModel, state: DeviceState) -> explicit_step.ExplicitStepArgs:
        args = explicit_step.ExplicitStepArgs()
        args.springs, args.bending, args.forces = model.springs, model.bending, model.forces(state.wind)
        args.inv_mass, args.h = model.inv_mass, model.h
        args.semi_implicit = int(self.symplectic)
        args.rounded_away = state.rounded_away
        return args


@dataclass(frozen=True)
class ImplicitIntegrator:
    """Backward Euler (implicit.py's ``BackwardEuler``), with its Newton and conjugate gradient settings:
    stable at any step on the cloth's linear springs."""

    settings: ImplicitSolver

    name = "implicit"
    device_bytes_per_particle = 100  # CG vectors and the preconditioner's blocks
    needs_masses = True
    ends_with_contact_start = False
    unstable_advice = ", or raise implicit.cg_max_iterations"
    stable_step = None

    def solve_passes(self) -> dict[str, int]:
        return {"implicit.cg_max_iterations": self.settings.newton_iterations * self.settings.cg_max_iterations}

    def step(self, model: DeviceModel, state: DeviceState, threads: int,
             start: explicit_step.ContactStartArgs | None) -> BackwardEuler:
        return BackwardEuler(model, state, self.settings)


BY_NAME: dict[str, Callable[[ImplicitSolver], Integrator]] = {
    "explicit": lambda _: ExplicitIntegrator("explicit", symplectic=False),
    "symplectic": lambda _: ExplicitIntegrator("symplectic", symplectic=True),
    "implicit": ImplicitIntegrator,
}


def integrator_for(name: str, implicit: ImplicitSolver = ImplicitSolver()) -> Integrator:
    """The integrator a scene names (``simulation.integrator``, one of ``scene.INTEGRATORS``), with the
    implicit solve's settings (the scene's ``implicit``) where it is the implicit one."""
    return BY_NAME[name](implicit)
