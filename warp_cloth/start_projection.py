"""A run's start projected onto the strain limits. A cloth that starts past them (a twisted grid whose rest
lengths are the flat grid's) would otherwise be projected by the first substep's solve, whose passes turn
the move into velocity (v += correction / h): the twisted hard case, 15.6% past its limit, gained 62 J
over the 21 J it held. Before the first substep of a run that starts fresh (not one restored from a
checkpoint), the simulator has the cloths that start past their limits, by more than the solve's
tolerance, projected onto them by the converged solve's limit passes (each ending with the colliders, as
every pass does), keeping the velocities the scene gives; the other cloths stay exactly as they start."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_cloth.kernels import converged_projection
from warp_cloth.kernels.colliders import RigidColliders

from .device_model import DeviceModel
from .limit_solve import ConvergedProjection, LimitSolveSettings, residual_args
from .passes import limit_pass, limits_name
from .state import DeviceState
from .wording import counted


@dataclass(frozen=True)
class StartedPast:
    """A cloth that started past its strain limits (by its index and name in the scene), and how far: its
    worst limited spring or attachment, as a fraction of the allowed length (0.156: 15.6% longer)."""
    cloth: int
    name: str
    past: float


@dataclass(frozen=True)
class StartReport:
    """What the start's projection did: the cloths it projected, the passes its solve took, and where the
    solve ended (in tolerances: 1 or less within them; more where it stopped at its cap of passes)."""
    cloths: tuple[StartedPast, ...]
    passes: int
    residual: float
    cap: int

    def describe(self) -> str:
        """One line, for the run's log."""
        if len(self.cloths) == 1:
            name, past = self.cloths[0].name, self.cloths[0].past
            started = f"cloth {name!r} starts {100 * past:.1f}% past its strain limit: its start was"
        else:
            each = ", ".join(f"{c.name!r} {100 * c.past:.1f}%" for c in self.cloths)
            started = f"cloths start past their strain limits ({each}): their starts were"
        ended = ("" if self.residual <= 1.0 else
                 f", to within {self.residual:.3g} tolerances (the cap of {self.cap} passes)")
        return (f"{started} projected onto it in {counted(self.passes, 'pass', 'passes')}{ended}, with the velocities "
                "the scene gives")


class StartProjection:
    """Projects the cloths that start past their strain limits onto them (see the module's docstring); its
    solve is built only when one does."""

    name = "start projection"

    def __init__(self, model: DeviceModel, state: DeviceState, settings: LimitSolveSettings, threads: int,
                 colliders: RigidColliders | None) -> None:
        self.model, self.state, self.settings = model, state, settings
        self.threads, self.colliders = threads, colliders

    def describe(self) -> list[str]:
        body = limits_name(self.model) + ("+colliders" if self.colliders is not None else "")
        return ["before the first substep of a run that starts fresh (not restored from a checkpoint), the",
                "simulator projects the cloths that start past their strain limits onto them (limit_violations,",
                f"then a converged solve of the {body} pass), keeping the velocities the scene gives"]

    def project(self, cloth_starts: np.ndarray, cloth_names: list[str]) -> StartReport | None:
        """Projects the cloths (particles ``cloth_starts[c]:cloth_starts[c + 1]``) that start past their limits;
        None where none does (then nothing is launched but the measure, and the state is untouched)."""
        model, state = self.model, self.state
        colliders = self.colliders if self.colliders is not None else model.no_colliders()
        violation = wp.zeros(model.particle_count, dtype=float, device=model.device)
        wp.launch(converged_projection.limit_violations, dim=model.particle_count,
                  inputs=[state.x, residual_args(model, state, self.settings, colliders, contacts=False)],
                  outputs=[violation], device=model.device)
        past = np.maximum.reduceat(violation.numpy(), cloth_starts[:-1])
        projected = np.nonzero(past > self.settings.tolerance)[0]
        if len(projected) == 0:
            return None
        solve = ConvergedProjection(model, state, self.settings,
                                    [limit_pass(model, self.threads, self.colliders, None, 1)] * 2, self.colliders,
                                    contacts=False)
        start, velocities = state.x.numpy().copy(), wp.clone(state.v)
        solve.run(state)
        wp.copy(state.v, velocities)
        keep = np.ones(model.particle_count, dtype=bool)
        for c in projected:
            keep[cloth_starts[c]:cloth_starts[c + 1]] = False
        if keep.any():
            x = state.x.numpy().copy()
            x[keep] = start[keep]
            state.x.assign(x)
        passes, residual, _, _ = solve.read_stats()
        return StartReport(tuple(StartedPast(int(c), cloth_names[c], float(past[c])) for c in projected), passes,
                           residual, self.settings.max_passes)
