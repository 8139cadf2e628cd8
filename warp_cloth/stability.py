"""The largest stable time step of the explicit integrators on a scene's own springs and masses, and the
step a run takes: the scene's own (``substeps`` or ``dt``) or, under ``substeps = "auto"`` (where it sets
neither), the stable floor the run starts at (``warp_cloth.auto_substeps`` chooses from frame to frame).

The derivation (docs/stability.md has it at length). Linearised about a state, a cloth is
``M x'' = -K x - C v``. A spring i-j of rest length L0, stiffness k and damping b, direction n, adds
``k/L0 (n n^T)`` to K (its force is linear in its length: dF/dl = k/L0; the tension's transverse term
``T/l (I - n n^T)`` is smaller than that at any strain above -50%) and ``b (n n^T)`` to C, in the pattern
``[[1, -1], [-1, 1]]``. With ``y = M^1/2 u``, ``(n.(ui - uj))^2 = (n.yi/sqrt(mi) - n.yj/sqrt(mj))^2 <=
(1/mi + 1/sqrt(mi mj)) (n.yi)^2 + (1/mj + 1/sqrt(mi mj)) (n.yj)^2`` (Young; a held particle has 1/m = 0), so
every mode has ``w^2 <= W^2 = max_i lambda_max(S_i)``, S_i the sum over i's springs ij of
``k/L0 (1/mi + 1/sqrt(mi mj)) n n^T`` (2 k/(L0 m) a spring for equal masses: exact on a chain, 4 k/(L0 m),
and on a square grid of structural springs); likewise its damping rate ``c <= C = max_i lambda_max(D_i) + drag``, D_i the same sum of b.
One mode ``x'' = -w^2 x - c x'`` stepped with h:

- symplectic Euler: amplification ``[[1 - hc, -h w^2], [h (1 - hc), 1 - h^2 w^2]]``, determinant
  ``1 - hc``, trace ``2 - hc - h^2 w^2``; its roots are inside the unit circle iff
  ``h^2 w^2 + 2 h c < 4``, so ``h < 4 / (C + sqrt(C^2 + 4 W^2))`` (2/W undamped, 2/C without springs).
- forward Euler: roots ``1 + h s`` with s the mode's continuous roots. Underdamped, ``|1 + hs|^2 =
  1 - hc + h^2 w^2``: stable iff ``h < c / w^2``, and since a spring's c / w^2 is its ``b L0 / k``, a mode's
  (a ratio of two sums over its springs, exact where K and C share their modes) is at least the smallest,
  ``rho``; undamped springs are never stable (their modes grow by
  ``sqrt(1 + h^2 w^2)`` a step). Overdamped, ``h < 4 / (c + sqrt(c^2 - 4 w^2))``, which ``h < 2 / C``
  guarantees. So ``h < min(rho, 2 / C)``; with an undamped spring, the step at which the fastest mode grows
  at most 2x over the run, ``2 ln 2 / (T W^2)``.

A material's bending stencil (kernels/bending.py) adds ``k w w^T`` to K (and ``c w w^T`` to C) in every
direction; with ``a_r = |w_r| / sqrt(m_r)``, ``(sum_r w_r u_r)^2 <= (sum_r a_r) (sum_r a_r y_r^2)``
(Cauchy-Schwarz), so it adds ``k a_r sum_s a_s`` to the diagonal of particle r's S_r (and ``c`` times that
to D_r); its damping time c / k is the material's ``damping``.

A soft pin counts as a spring of zero length to a held point (``k`` where a spring has ``k/L0``). Every
enabled spring counts, in whatever regime it acts (a bend spring acts only when compressed, but a
compressed cloth has them all). Strain limits and collisions are projections: they add no stiffness.
The implicit integrator (backward Euler) is stable at any step on these linear springs: it has no bound.
This module finds W, C and rho; each integrator's bound from them is its own (``stable_step`` in
warp_cloth/integrators.py).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .errors import SceneError
from .integrators import LIMITED_BY_DAMPING, integrator_for
from .cloth_mesh import BendStencils
from .model import (FLAG_DAMPING_COMPRESSION, FLAG_DAMPING_TENSION, FLAG_ELASTIC_COMPRESSION,
                    FLAG_ELASTIC_TENSION, Model, build_model)
from .scene import Scene, Simulation
from .wording import counted

# Passes over the particles in one frame (substeps x the passes of a substep). Ctrl-C stops a run only
# between frames, and a captured frame holds every launch (about 0.4 kB and 50 us of capture each on the
# CPU; a pass of a tiny cloth runs in about 80 us), so a frame past this is refused rather than left to
# seem hung: at the bound a 2x2 cloth's frame takes seconds on this project's CPU. The study's finest
# references (10000 substeps a frame of 4 limit passes) fit.
MAX_PASSES_PER_FRAME = 50_000
# A converged limit solve's passes a substep at most, where the scene sets none (or fewer where its
# substeps would not fit a frame, ``cap_that_fits``): 200 stopped seed_default's solves 4 tolerances out
# (+12%), and the built-in scenes' hardest solves take up to 600 (docs/notebook/strain-solve.md, issue 32).
DEFAULT_LIMIT_MAX_PASSES = 1000

SAFETY = 0.8  # the automatic step is this fraction of the bound: the bound is of the linearised cloth
# ... and this where a spring has no damping: switching springs (tension only, limits, contacts) pump energy
# into an undamped cloth at 0.8 (an undamped cloth on the ground: 22 m/s at 0.8, 7 m/s at 0.4 and at 0.2)
SAFETY_UNDAMPED = 0.4
# ... and this where the bound is the damping's (``LIMITED_BY_DAMPING``: about h < 2 / C, where a damped
# velocity's factor a step, 1 - hC, stays above -1): at half of it the factor stays at or above 0, so a damped
# velocity decays without changing sign each step, which contacts and limits switching on and off pumped at
# 0.8 (seed_default's explicit step: 495 m/s by frame 25 on the CPU, a blow-up at frame 27 on an H200)
SAFETY_DAMPING = 0.5
AUTOMATIC_MIN_SUBSTEPS = 10  # never coarser than the old default: stability is not accuracy
AUTOMATIC_MAX_SUBSTEPS = 10000  # past this a scene is refused: the implicit integrator suits it better


# How a step choice of ``substeps = "auto"`` is said: its count is where the run starts and the least it takes.
AUTO_START = "to start, substeps auto (the stable floor; more where a frame's solves miss)"


class UnstableStepWarning(UserWarning):
    """A step set by the user (``substeps`` or ``dt``) that is past the scene's stable bound: the run may
    blow up. Given when the simulator is built, before the first frame."""


@dataclass(frozen=True)
class StabilityBound:
    """The largest stable step of an explicit integrator on a scene (``inf`` where nothing bounds it) and
    the scene's figures it comes from: the fastest angular frequency (rad/s), the fastest damping rate
    (1/s) and the smallest spring damping time ``b L0 / k`` (s, inf without stiff springs)."""

    integrator: str
    step: float
    omega_max: float
    damping_rate_max: float
    damping_time_min: float
    limited_by: str

    def describe(self) -> str:
        return (f"{self.integrator} Euler is stable below {_ms(self.step)} here (limited by {self.limited_by}: "
                f"fastest spring mode {self.omega_max:.3g} rad/s, damping rate up to {self.damping_rate_max:.3g} 1/s)")


@dataclass(frozen=True)
class StepChoice:
    """The step a run takes and where it comes from. ``bound`` is None for an integrator stable at any step.
    ``automatic``: ``substeps = "auto"``, where ``substeps`` is the stable floor a run starts at (and never
    goes below)."""

    substeps: int
    step: float
    automatic: bool
    bound: StabilityBound | None
    integrator: str

    @property
    def beyond_bound(self) -> bool:
        return self.bound is not None and self.step > self.bound.step

    def describe(self) -> str:
        """One line: the step, and why it is what it is."""
        head = f"step {_ms(self.step)} ({counted(self.substeps, 'substep')}/frame)"
        if self.bound is None:
            return head + (f" {AUTO_START}, the {self.integrator} integrator's default (no stability bound on its "
                           "step)" if self.automatic else
                           f", as set (the {self.integrator} integrator has no stability bound on its step)")
        if not self.automatic:
            return head + f", as set; {self.bound.describe()}"
        if self.substeps == AUTOMATIC_MIN_SUBSTEPS and self.step < safety(self.bound) * self.bound.step:
            return head + f" {AUTO_START}, the fewest chosen (within the stable bound: {self.bound.describe()})"
        return head + (f" {AUTO_START}, chosen for stability: {safety(self.bound):g} x the bound; "
                       f"{self.bound.describe()}")


def _ms(seconds: float) -> str:
    return "any step" if math.isinf(seconds) else f"{seconds * 1e3:.3g} ms"


def stable_step(positions: np.ndarray, inv_mass: np.ndarray, pairs: np.ndarray, rest: np.ndarray,
                stiffness: np.ndarray, damping: np.ndarray, flags: np.ndarray, integrator: str, drag: float = 0.0,
                duration: float = 10.0, bending: BendStencils | None = None) -> StabilityBound:
    """The largest stable step of ``integrator`` (named as a scene names it: one with a bound, as
    "explicit" or "symplectic") on springs ``pairs`` between particles at ``positions`` of inverse mass
    ``inv_mass`` (0: held), springs with the model's regime ``flags``, and the ``bending`` stencils;
    ``duration`` (s) is the run's length, used only by forward Euler with undamped springs. See the module's
    docstring for the derivation."""
    bound = integrator_for(integrator).stable_step
    if bound is None:
        raise ValueError(f"no stability bound for integrator {integrator!r}")
    free = inv_mass > 0
    pairs = np.asarray(pairs).reshape(-1, 2)
    elastic = (flags & (FLAG_ELASTIC_TENSION | FLAG_ELASTIC_COMPRESSION)) != 0
    damped = (flags & (FLAG_DAMPING_TENSION | FLAG_DAMPING_COMPRESSION)) != 0
    moving = free[pairs[:, 0]] | free[pairs[:, 1]]
    axial = np.where(elastic, stiffness.astype(np.float64) / rest, 0.0)
    dashpot = np.where(damped, damping.astype(np.float64), 0.0)
    stencil_k, stencil_c = _stencil_rates(bending, inv_mass)
    w2 = _largest_rate(positions, pairs, axial, inv_mass, stencil_k)
    c = _largest_rate(positions, pairs, dashpot, inv_mass, stencil_c) + drag
    # A spring's damping time b L0 / k counts where its dashpot acts in its elastic regime.
    both = (((flags & FLAG_ELASTIC_TENSION) != 0) & ((flags & FLAG_DAMPING_TENSION) != 0)) | \
           (((flags & FLAG_ELASTIC_COMPRESSION) != 0) & ((flags & FLAG_DAMPING_COMPRESSION) != 0))
    stiff = elastic & moving & (axial > 0)  # a knit's sides may carry nothing (materials.py)
    rho = np.where(both, dashpot, 0.0)[stiff] / axial[stiff] if stiff.any() else np.array([math.inf])
    if bending is not None and stencil_k.any():
        rho = np.append(rho, float((bending.damping / bending.stiffness).min()))
    rho_min = float(rho.min())
    step, limited_by = bound(w2, c, rho_min, duration)
    return StabilityBound(integrator, step, math.sqrt(w2), c, rho_min, limited_by)


def _stencil_rates(bending: BendStencils | None, inv_mass: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per particle, what the bending stencils add to the diagonal of S_r and of D_r (the module's
    docstring)."""
    k_rate, c_rate = np.zeros(len(inv_mass)), np.zeros(len(inv_mass))
    if bending is None:
        return k_rate, c_rate
    owner = bending.owners()
    a = np.abs(bending.weights) * np.sqrt(inv_mass.astype(np.float64)[bending.particles])
    share = a * bending.sums(a)[owner]
    k_rate += np.bincount(bending.particles, share * bending.stiffness[owner], len(inv_mass))
    c_rate += np.bincount(bending.particles, share * bending.damping[owner], len(inv_mass))
    return k_rate, c_rate


def _largest_rate(positions: np.ndarray, pairs: np.ndarray, weight: np.ndarray, inv_mass: np.ndarray,
                  isotropic: np.ndarray) -> float:
    """An upper bound of the largest eigenvalue of M^-1 A, A the springs' ``weight`` (n n^T) pattern over
    the free particles and ``isotropic`` (each particle's, times I) on its diagonal: max over them of
    lambda_max(sum over their springs ij of weight (w_i + sqrt(w_i w_j)) n n^T) + isotropic, w the inverse
    masses (a held particle, w = 0, does not move)."""
    free = inv_mass > 0
    if not free.any() or not (weight.any() or isotropic.any()):
        return 0.0
    n = len(inv_mass)
    d = positions[pairs[:, 1]].astype(np.float64) - positions[pairs[:, 0]]
    length = np.linalg.norm(d, axis=1)
    unit = d / np.where(length > 0, length, 1.0)[:, None]
    w = inv_mass.astype(np.float64)
    i, j = pairs[:, 0], pairs[:, 1]
    across = weight * np.sqrt(w[i] * w[j])
    end_i, end_j = weight * w[i] + across, weight * w[j] + across
    block = np.zeros((n, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            # a zero-length spring pushes in any direction: count it whole on the diagonal
            direction = np.where(length > 0, unit[:, a] * unit[:, b], 1.0 if a == b else 0.0)
            summed = np.bincount(i, end_i * direction, n) + np.bincount(j, end_j * direction, n)
            block[:, a, b] = block[:, b, a] = summed
    return float((np.linalg.eigvalsh(block[free])[:, -1] + isotropic[free]).max())


def model_bound(model: Model, sim: Simulation) -> StabilityBound | None:
    """The stable bound of the simulation's integrator on a model (None for one stable at any step)."""
    if integrator_for(sim.integrator).stable_step is None:
        return None
    springs = model.springs
    duration = (sim.preroll + sim.frames) / sim.fps
    if springs is None:
        arrays = (model.positions, model.inv_mass, np.zeros((0, 2), dtype=np.int64), *(np.zeros(0),) * 3,
                  np.zeros(0, dtype=np.int32))
    else:
        arrays = (model.positions, model.inv_mass, springs.pairs, springs.rest, springs.stiffness, springs.damping,
                  springs.flags)
    if model.pins is not None and model.pins.soft.any():
        arrays = _with_soft_pins(model, *arrays)
    return stable_step(*arrays, sim.integrator, sim.drag, duration, model.bending)


def _with_soft_pins(model: Model, positions, inv_mass, pairs, rest, stiffness, damping, flags) -> tuple:
    """The springs with each soft pin's as one more, to a held particle where its own is (of zero length: it
    counts whole in every direction) with rest length 1, so that its k / L0 is its stiffness k."""
    pins = model.pins
    index = pins.index[pins.soft]
    count, n = len(index), len(positions)
    both = FLAG_ELASTIC_TENSION | FLAG_ELASTIC_COMPRESSION | FLAG_DAMPING_TENSION | FLAG_DAMPING_COMPRESSION
    return (np.concatenate([positions, positions[index]]), np.concatenate([inv_mass, np.zeros(count, inv_mass.dtype)]),
            np.concatenate([pairs, np.stack([index, n + np.arange(count)], axis=1)]),
            np.concatenate([rest, np.ones(count)]), np.concatenate([stiffness, pins.stiffness[pins.soft]]),
            np.concatenate([damping, pins.damping[pins.soft]]),
            np.concatenate([flags, np.full(count, both, dtype=flags.dtype)]))


def automatic_substeps(fps: float, bound: StabilityBound | None) -> int:
    """Substeps a frame for a step ``safety(bound)`` times the bound, at least ``AUTOMATIC_MIN_SUBSTEPS``."""
    if bound is None or math.isinf(bound.step):
        return AUTOMATIC_MIN_SUBSTEPS
    return max(AUTOMATIC_MIN_SUBSTEPS, math.ceil(1.0 / (fps * safety(bound) * bound.step)))


def safety(bound: StabilityBound) -> float:
    """The fraction of the bound the automatic step takes: ``SAFETY``, ``SAFETY_DAMPING`` where the bound is
    the damping's, or ``SAFETY_UNDAMPED`` where some spring has no damping in its elastic regime."""
    if bound.damping_time_min <= 0:
        return SAFETY_UNDAMPED
    return SAFETY_DAMPING if bound.limited_by == LIMITED_BY_DAMPING else SAFETY


def choose_step(model: Model, sim: Simulation) -> StepChoice:
    """The simulation's own step if it sets one, else the largest within ``safety(bound)`` times the bound
    and no coarser than ``AUTOMATIC_MIN_SUBSTEPS`` a frame. A SceneError if that needs more than
    ``AUTOMATIC_MAX_SUBSTEPS`` a frame."""
    bound = model_bound(model, sim)
    if sim.substeps_per_frame is not None:
        return StepChoice(sim.substeps_per_frame, sim.time_step, False, bound, sim.integrator)
    substeps = automatic_substeps(sim.fps, bound)
    if substeps > AUTOMATIC_MAX_SUBSTEPS:
        raise SceneError("simulation.substeps", f"a scene whose stable step needs at most {AUTOMATIC_MAX_SUBSTEPS} "
                                                f"substeps a frame: this one needs {substeps} ({bound.describe()}); "
                                                "use the implicit integrator, or softer or heavier cloth",
                         has_got=False)
    return StepChoice(substeps, 1.0 / (sim.fps * substeps), True, bound, sim.integrator)


def cap_that_fits(cap: int, substeps: int) -> int:
    """``cap`` passes a substep, or fewer where that many would not keep a frame of ``substeps`` within
    ``MAX_PASSES_PER_FRAME`` (a step included; at least 2)."""
    return max(2, min(cap, MAX_PASSES_PER_FRAME // substeps - 1))


def with_passes_cap(scene: Scene, substeps: int | None) -> Scene:
    """The scene with its converged limit solve's cap chosen where it sets none: ``DEFAULT_LIMIT_MAX_PASSES``
    a substep, or fewer where that many would not fit a frame of ``substeps`` (``cap_that_fits``; None:
    substeps chosen frame by frame, which fit the cap to each count, ``at_substeps``)."""
    simulation = scene.simulation
    if simulation.limit_max_passes is not None:
        return scene
    cap = DEFAULT_LIMIT_MAX_PASSES if substeps is None else cap_that_fits(DEFAULT_LIMIT_MAX_PASSES, substeps)
    return dataclasses.replace(scene, simulation=dataclasses.replace(simulation, limit_max_passes=cap))


def at_substeps(scene: Scene, substeps: int) -> Scene:
    """A scene of ``substeps = "auto"`` (as ``resolve_step`` leaves it) as it runs at ``substeps`` a frame:
    that count, and its limit solve's cap fitted to it (``cap_that_fits``)."""
    simulation = scene.simulation
    return dataclasses.replace(scene, simulation=dataclasses.replace(
        simulation, substeps=substeps, limit_max_passes=cap_that_fits(simulation.limit_max_passes, substeps)))


def resolve_step(scene: Scene, model: Model) -> tuple[Scene, StepChoice]:
    """The scene as a simulator runs it, and the step choice made: its limit solve's cap chosen where it
    sets none (``with_passes_cap``), and ``substeps = "auto"`` written out where it sets neither substeps
    nor dt (the choice's substeps are then the floor the run starts at)."""
    choice = choose_step(model, scene.simulation)
    if not choice.automatic:
        return with_passes_cap(scene, choice.substeps), choice
    scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, substeps="auto"))
    return with_passes_cap(scene, None), choice


def scene_with_step(scene: Scene) -> Scene:
    """The scene as a simulator runs it (``resolve_step``), without building its model where it sets a step
    (with substeps auto it builds it, to refuse a floor past ``AUTOMATIC_MAX_SUBSTEPS`` here)."""
    substeps = scene.simulation.substeps_per_frame
    if substeps is not None:
        return with_passes_cap(scene, substeps)
    return resolve_step(scene, build_model(scene))[0]


def beyond_bound_message(choice: StepChoice, simulation: Simulation) -> str:
    """What the warning for a set step past the bound says (one line)."""
    bound = choice.bound
    assert bound is not None
    setting = f"substeps = {simulation.substeps}" if simulation.substeps is not None else f"dt = {simulation.dt:g}"
    chosen = automatic_substeps(simulation.fps, bound)
    return (f"{setting} gives a step of {_ms(choice.step)}, past the stable bound: {bound.describe()}; it may "
            f"blow up: leave substeps and dt out (substeps auto) to have the simulator choose them (from "
            f"{chosen} a frame)")
