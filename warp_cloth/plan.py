"""The plan of a substep: its passes in order, built once from the effects the scene declares. An effect
the scene does not declare has no pass, so it costs no launch and no memory. ``print(sim.plan)`` shows a
reader the substep; docs/architecture.md says where each kind of change goes."""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import groupby
from typing import Protocol, runtime_checkable

import warp as wp

from warp_cloth.kernels.colliders import RigidColliders

from .device_model import DeviceModel
from .displacement_bounds import BoundsFromLists, DisplacementBounds, MeasureAgain
from .face_contacts import FaceContacts
from .implicit import SolveStats
from .integrators import Integrator
from .limit_solve import ConvergedProjection, LimitSolveSettings
from .line_solve import HoldAndCollide, LineSolves
from .neighbour_lists import LIST_THREADS_BY_SIZE, NeighbourLists
from .passes import (AdvanceClock, CloseSeams, Collide, ContactStart, DrivePins, FollowKeys, FollowTargets, Pass, WindForces,
                     contact_start_args, contact_velocities, edge_contacts_args, edge_separation_pass,
                     limit_and_separation_pass, limit_pass, separation_pass)
from .start_projection import StartProjection
from .state import DeviceState
from .wording import counted

# Threads per particle of the gathering passes on a GPU by particle count (up to the first number), from
# the spring kernel's launch times on an H200 (docs/results/lanes-probe-h200.json): 16 are fastest at
# 64^2, 4 at 128^2, 2 at 256^2; from 1024^2 on, one thread per particle is.
THREADS_BY_SIZE = ((8192, 16), (32768, 4), (131072, 2))


def threads_per_particle(particles: int, device, table=THREADS_BY_SIZE) -> int:
    """How many threads gather each particle's springs, limits and contacts (see kernels/gathering.py)."""
    if not device.is_cuda:
        return 1
    return next((threads for most, threads in table if particles <= most), 1)


@runtime_checkable
class SolvingPass(Pass, Protocol):
    """A pass that solves (the implicit step), keeping the worst figures of its solves since last read."""

    def read_stats(self) -> SolveStats: ...

    def carried(self) -> dict[str, wp.array]: ...


@dataclass(frozen=True)
class Plan:
    passes: tuple[Pass, ...]
    h: float  # the substep's length, seconds
    threads: int  # threads per particle of the gathering passes
    solve: SolvingPass | None  # the integrator's pass where it solves, for its figures
    lists: NeighbourLists | None  # particle collision's candidate lists
    projection: ConvergedProjection | None  # the converged limit solve, for its figures
    start: StartProjection | None  # what the simulator projects a fresh run's start with, where cloths are limited
    bounds: DisplacementBounds | None = None  # the displacement bounds (a thickness's or the lab's), for their figures
    faces: FaceContacts | None = None  # the face contacts (a thickness's), whose lists a substep carries

    def carried(self) -> dict[str, wp.array]:
        """The plan's arrays that a substep reads before writing them (the converged solve's estimated
        spectral radius, which it carries from solve to solve; the implicit step's last dv, its next first
        guess; the face contacts' lists), by name."""
        projection = self.projection
        arrays = {"projection.omega": projection.omega} if projection is not None and projection.accelerated else {}
        arrays |= self.solve.carried() if self.solve is not None else {}
        return arrays | (self.faces.carried() if self.faces is not None else {})

    def run_substep(self, state: DeviceState) -> None:
        for step in self.passes:
            step.run(state)

    @property
    def pass_names(self) -> list[str]:
        return [p.name for p in self.passes]

    def __str__(self) -> str:
        threads = f"{counted(self.threads, 'thread')} a particle"
        lines = [f"substep of {self.h * 1000:.4g} ms, {threads} on the gathering passes:"]
        for number, (_, group) in enumerate(groupby(self.passes, key=lambda p: p.name), start=1):
            group = list(group)
            described = group[0].describe() if hasattr(group[0], "describe") else [group[0].name]
            repeats = f" x{len(group)}" if len(group) > 1 else ""
            lines += [f"  {number:>2}. {described[0]}{repeats}"] + [f"      {line}" for line in described[1:]]
        lines += ["not in the plan: after each substep of a frame (Simulator.step and run, not Simulator.substep)",
                  "the simulator checks the state for a blow-up (check_state)"]
        if self.start is not None:
            lines += self.start.describe()
        return "\n".join(lines)


def build_plan(model: DeviceModel, state: DeviceState, integrator: Integrator, solve: LimitSolveSettings,
               threads: int | None = None, lines: LineSolves | None = None,
               bounds: DisplacementBounds | None = None, control: dict[str, list[Pass]] | None = None,
               faces: FaceContacts | None = None) -> Plan:
    """The substep, in order: moving spheres and animated mesh colliders to the substep's end (nothing before
    the colliders reads them); the seams' allowed lengths; the wind's forces; the integrator's pass; driven pins (oscillating, on
    colliders, on keys); then, with particle collision, the contacts' start (in the integrator's pass where it
    can end with it and nothing comes between), the candidate lists, the projection passes (where the scene
    has a thickness, the edge and face contacts' passes before each separating pass of the converged solve,
    so that its check follows a projection) and the contact velocities; without
    it, the strain limit's passes or the colliders alone; the clock last, where something moves with it.
    ``solve``: how the limits and contacts are solved; ``threads``: per particle on the gathering passes
    (None: by size); ``lines``: the line solves of the cloths' lines where ``solve.line_rounds`` and a cloth
    is limited (with particle collision, where ``solve.choices.line_contacts`` too), made once for every plan a
    simulator builds (line_solve.LineSolves); ``bounds``: the displacement bounds
    (displacement_bounds.py, made once per simulator), the substep's start recorded first, the bounds measured
    there and the step clamped to them after the solves (before the contact velocities), or, in a converged
    solve of particle collision (not the lab's line rounds with contacts), measured there before the lists,
    held after each of its separating passes and the step clamped to the same bounds after it (wherever
    ``faces`` is given, their query radius chosen before the lists and the bounds read off the lists after
    them, and after the solve, in place of the clamp, the bounds measured again where the solve held particles
    at them and the solve run again within them, ``MeasureAgain``); ``control``: the
    passes that put what a script sent from Python (control.py's ``Control.passes``) after the colliders'
    motion (``"colliders"``), with the soft pins' motion before the step (``"soft pins"``: where their springs
    pull, which the step reads) and after the hard pins' motion (``"pins"``); ``faces``: the face contacts
    (face_contacts.py, made once per simulator, used only with particle collision, always with ``bounds``),
    their lists and the edge contacts' remade with the particle lists where the substep started (the bounds'
    record) within the allowances the bounds' query radius gives (kernels/surface_reach.py), their pass
    beside the edge contacts' pass, and the converged solve's check reading both kinds' pairs."""
    chosen = threads_per_particle(model.particle_count, model.device) if threads is None else threads
    rigid = model.colliders(state) if model.has_colliders else None
    control = control or {}
    oscillating_pins = model.pins is not None and model.pins.moving
    hard_motion = [p for p in (FollowTargets(model), FollowKeys(model)) if p.present]
    soft_motion = [p for p in (FollowTargets(model, soft=True), FollowKeys(model, soft=True)) if p.present]
    if model.soft_pins is not None and model.soft_pins.motion is not None:
        soft_motion.insert(0, DrivePins(model, soft=True))
    driven_pins = oscillating_pins or bool(hard_motion) or "pins" in control
    converged = solve.converged
    passes: list[Pass] = [bounds.record_start] if bounds is not None else []
    passes.extend(model.collider_motion)
    passes.extend(control.get("colliders", []))
    if model.seams is not None:
        passes.append(CloseSeams(model))
    lists = start = projection = None
    if model.contacts is not None:
        list_threads = threads_per_particle(model.particle_count, model.device, LIST_THREADS_BY_SIZE) \
            if threads is None else threads
        lists = NeighbourLists(model, state, list_threads, faces, bounds)
        start = contact_start_args(model, state, rigid or model.no_colliders(), lists.rebuild_distance)
    if model.wind is not None:
        passes.append(WindForces(model))
    passes.extend(soft_motion)
    passes.extend(control.get("soft pins", []))
    start_in_step = start is not None and integrator.ends_with_contact_start and not driven_pins
    step = integrator.step(model, state, chosen, start if start_in_step else None)
    passes.append(step)
    if oscillating_pins:
        passes.append(DrivePins(model))
    passes.extend(hard_motion)
    passes.extend(control.get("pins", []))
    if start is not None:
        if not start_in_step:
            passes.append(ContactStart(start))
        line_rounds = converged and model.limits is not None and lines is not None
        held = bounds is not None and converged and not line_rounds
        measured_before = bounds is not None and (held or faces is not None)
        from_lists = BoundsFromLists(bounds, faces.args, edge_contacts_args(model, state)) if faces is not None else None
        if from_lists is not None:
            passes += [bounds.choose, lists, from_lists]
        else:
            passes += [bounds.measure, lists] if measured_before else [lists]
        # a thickness brings both surface kinds, and the converged solve (Scene requires it)
        surface_passes = [] if faces is None else [edge_separation_pass(model, state, chosen, rigid),
                                                   faces.separation_pass(model, chosen, rigid)]
        if line_rounds:
            projection = line_contact_projection(model, state, solve, chosen, rigid, surface_passes, lines, faces)
            passes.append(projection)
        elif converged:
            projection = converged_projection(model, state, solve, chosen, rigid, surface_passes, faces,
                                              [bounds.hold] if held else [])
            passes.append(projection)
        else:
            passes.extend(projection_passes(model, state, solve, chosen, rigid))
        if from_lists is not None and held and bounds.settings.again > 0:
            passes.append(MeasureAgain(bounds, lists, from_lists, projection))  # its last hold is the clamp
        elif bounds is not None:
            passes.append(bounds.clamp_held if measured_before else bounds.clamp)
        friction = faces.friction_pass(model, state, chosen) if faces is not None else None
        if friction is not None:
            passes.append(friction)
        passes.append(contact_velocities(model, state, chosen))
    elif model.limits is not None and converged and lines is not None:
        projection = line_projection(model, state, solve, chosen, rigid, lines)
        passes.append(projection)
    elif model.limits is not None and converged:
        projection = ConvergedProjection(model, state, solve, [limit_pass(model, chosen, rigid, None, 1)] * 2, rigid)
        passes.append(projection)
    elif model.limits is not None:
        last = solve.iterations - 1
        passes.extend(limit_pass(model, chosen, rigid if k == last else None, None, 1)
                      for k in range(solve.iterations))
    elif rigid is not None:
        passes.append(Collide(model, rigid))
    if bounds is not None and start is None:
        passes.append(bounds.clamp)
    if driven_pins or soft_motion or control or model.collider_motion or model.seams is not None or \
            (model.wind is not None and (model.wind.turbulence > 0 or model.wind.key_time.shape[0] > 1)):
        passes.append(AdvanceClock())
    start_projection = StartProjection(model, state, solve, chosen, rigid) if model.limits is not None else None
    return Plan(tuple(passes), model.h, chosen, step if isinstance(step, SolvingPass) else None, lists, projection,
                start_projection, bounds, faces)


def converged_projection(model: DeviceModel, state: DeviceState, solve: LimitSolveSettings, threads: int,
                         rigid: RigidColliders | None, surface_passes: list[Pass],
                         faces: FaceContacts | None = None,
                         after_passes: list[Pass] | None = None) -> ConvergedProjection:
    """The converged solve of particle collision (with the strain limits where the scene has them: projected
    jointly for ``solve.choices.joint_passes`` passes, then sequentially; see limit_solve.SolveChoices); with
    ``faces`` (a surface thickness's), its check reads the edge and face pairs too; ``after_passes`` (the
    displacement bounds' hold, or none) follow each separating pass."""
    after = after_passes or []
    joint_first = model.limits is None or solve.choices.joint_passes > 0
    first = projection_pair(model, state, threads, rigid, surface_passes, "joint" if joint_first else "sequential",
                            after)
    counted = lambda body: sum(p not in surface_passes and p not in after for p in body)  # noqa: E731
    if model.limits is None or not joint_first:
        return ConvergedProjection(model, state, solve, first, rigid, counted=counted(first), faces=faces)
    later = projection_pair(model, state, threads, rigid, surface_passes, "sequential", after)
    return ConvergedProjection(model, state, solve, first, rigid, counted=counted(first), later_body=later,
                               later_counted=counted(later), switch_at=solve.choices.joint_passes, faces=faces)


def line_round(model: DeviceModel, lines: LineSolves, rigid: RigidColliders | None) -> list[Pass]:
    """A round of the line solve (line_solve.py): the families of ``lines``, then the attachments and the
    colliders, each in place."""
    return [lines, HoldAndCollide(model, rigid)]


def line_projection(model: DeviceModel, state: DeviceState, solve: LimitSolveSettings, threads: int,
                    rigid: RigidColliders | None, lines: LineSolves) -> ConvergedProjection:
    """The converged solve of the strain limits by line solves (``solve.line_rounds``, the default): a Jacobi pair
    first, and where it leaves a limit out of tolerance, rounds to the end, each a line round and a Jacobi pair
    (counted together as one pass toward the cap), plain unless the lab fixes a Chebyshev radius. The first pair
    ends every solve of a cloth at rest: rounds alone, exact along their lines, kept the hanging cloth swinging
    at 0.1 m/s after 480 frames, where the pair first lets it settle as Jacobi passes alone do. The pair in each
    round handles what couples the families where they meet, one Jacobi pass moving a particle by all its
    springs at once: on an H200 the 1024^2 sphere cloth's swing (24 frames) took 6.6 rounds a substep, not
    11.8, and 193 ms a frame, not 311; Chebyshev's estimated radius over the rounds took 14.4 rounds and 385 ms
    (docs/notebook/strain-solve.md, "A Jacobi pair before the lines", "A Jacobi pair in every round")."""
    pair = [limit_pass(model, threads, rigid, None, 1)] * 2
    choices = solve.choices
    plain = solve if choices.chebyshev_rho is not None else replace(solve, choices=replace(choices, chebyshev_rho=0.0))
    return ConvergedProjection(model, state, plain, pair, rigid, later_body=line_round(model, lines, rigid) + pair,
                               later_counted=1, switch_at=2)


def line_contact_projection(model: DeviceModel, state: DeviceState, solve: LimitSolveSettings, threads: int,
                            rigid: RigidColliders | None, surface_passes: list[Pass], lines: LineSolves,
                            faces: FaceContacts | None = None) -> ConvergedProjection:
    """The converged solve of particle collision with the strain limits by rounds of line solves (the lab's,
    ``solve.choices.line_contacts``): a round, counted as one pass toward the cap, is a line round and then the two
    separating passes of the contacts' own converged solve (``surface_passes`` before each), reading the resting
    marks' first bit, then the other, as ``projection_pair`` does; with ``faces`` (a surface thickness's), the
    check reads the edge and face pairs too. (Two line rounds an iteration, each
    followed by one separating pass, held the speed matrix's self cloth as well at 2.0 rounds a substep
    against 1.0-1.1 and took 14% longer at 64^2 on the CPU.)"""
    body = line_round(model, lines, rigid) + [
        p for bit in (1, 2) for p in surface_passes + [separation_pass(model, state, threads, rigid, bit)]]
    return ConvergedProjection(model, state, solve, body, rigid, counted=1, faces=faces)


def projection_pair(model: DeviceModel, state: DeviceState, threads: int, rigid: RigidColliders | None,
                    surface_passes: list[Pass], order: str, after: list[Pass] | None = None) -> list[Pass]:
    """Two projection passes of particle collision (with the strain limits where the scene has them, in
    the ``order`` "joint" or "sequential"), for a converged solve to repeat: each ends with the colliders,
    the first reading the resting marks' first bit, the second the other (see ``projection_passes``);
    ``surface_passes`` (a thickness's edge and face contacts' passes, or none) come before each pass that
    separates, so that the solve's check follows a projection, and ``after`` (in place) after it."""
    after = after or []
    if model.limits is None:
        return [p for bit in (1, 2)
                for p in surface_passes + [separation_pass(model, state, threads, rigid, bit)] + after]
    if order == "joint":
        return [p for bit in (1, 2)
                for p in surface_passes + [limit_and_separation_pass(model, state, threads, rigid, bit)] + after]
    return [p for bit in (1, 2) for p in [limit_pass(model, threads, None, None, 1)] + surface_passes
            + [separation_pass(model, state, threads, rigid, bit)] + after]


def projection_passes(model: DeviceModel, state: DeviceState, solve: LimitSolveSettings, threads: int,
                      rigid: RigidColliders | None) -> list[Pass]:
    """Collisions, strain limits and rigid colliders fight over the same particles (a layer pressed onto a
    sphere by the layers above can only give way sideways), so with particle collision they are projected
    together: the larger of the limit's and the collision's iteration counts of passes, every one ending
    with the colliders; the limit and the separation each run in the last of the passes as many times as
    their own count says, so that the last pass runs all of them. A pass that runs both runs them as one
    Jacobi pass among the first ``solve.choices.joint_passes``, else the limit's pass and then the separation's
    (as the converged solve does). The particles the colliders hold up (``resting``, marked at the contacts' start
    and by each pass) do not give way to others in the passes that follow; passes alternate the bit they
    read and the one they write (see kernels/colliders.py)."""
    settings = model.contacts.settings
    limit_iterations = solve.iterations if model.limits is not None else 0
    total = max(settings.iterations, limit_iterations)
    resting = state.contacts.resting
    passes: list[Pass] = []
    for remaining in range(total, 0, -1):
        joint = total - remaining < solve.choices.joint_passes
        read_bit = 1 if (total - remaining) % 2 == 0 else 2
        separates = remaining <= settings.iterations
        limits_too = remaining <= limit_iterations
        if not separates:
            passes.append(limit_pass(model, threads, rigid, resting, read_bit))
        elif limits_too and joint:
            passes.append(limit_and_separation_pass(model, state, threads, rigid, read_bit))
        else:
            if limits_too:
                passes.append(limit_pass(model, threads, None, None, 1))
            passes.append(separation_pass(model, state, threads, rigid, read_bit))
    return passes
