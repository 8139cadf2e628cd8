"""The kernels that combine effects: one pass over the particles that does several things, and the implicit
solve's products, which combine the springs' Jacobians with the external forces.

This is the only kernel module that imports others. Each fused pass is named for what it fuses, and its
``args`` struct holds what it reads besides the state (see gathering.py for the form of a gathering
kernel). warp_cloth/plan.py says which of them a substep runs, in which order.
"""

import functools
from typing import Any

import warp as wp

from .attachments import Attachments, attachment_violation, hold_to_pin
from .colliders import RigidColliders, collide_and_mark, collide_particle
from .edge_collision import EdgeContacts, EdgeRules, edge_pushes, may_touch, pair_gap
from .forces import ExternalForces, external_acceleration, external_damping
from .gathering import BLOCK, FAST_MATH, gathering_kernel, sum_over_threads, thread_layout
from .integration import compensated_sum, explicit_move
from .limits import StrainLimits, limit_corrections, limit_violation, mean_of
from .particle_collision import (Contacts, ListState, PairRules, add_candidate, begin_contact, deepest_overlap,
                                 end_remake, is_candidate, mean_push, pushes, sort_and_drop_repeats, velocity_changes)
from .solve_loop import chebyshev_extrapolation
from .spatial_hash import cell_of, count_in, first_visit, neighbour_bucket, stamp_of
from .springs import Springs, add_system_diagonal, add_system_times, spring_forces, stiffness_times_motion

wp.set_module_options(FAST_MATH)

vec8 = wp.types.vector(length=8, dtype=float)


@wp.func
def gathers(args: Any, i: int) -> bool:
    """Whether a thread gathers for particle i: one that exists (i >= 0: not past the last) and is free
    (a pinned particle's incidences move nothing)."""
    if i < 0:
        return False
    return args.inv_mass[i] != 0.0


# --- explicit step: spring forces, external forces, one explicit or symplectic Euler step -------------------

@wp.struct
class ExplicitStepArgs:
    springs: Springs
    forces: ExternalForces
    inv_mass: wp.array(dtype=float)
    h: float
    semi_implicit: int  # 1: symplectic Euler
    rounded_away: wp.array(dtype=wp.vec3)  # (n,): positions summed with compensation; empty: plainly


@wp.struct
class ContactStartArgs:
    """The contacts' start: rigid colliders first, then what particle_collision.begin_contact records."""
    colliders: RigidColliders
    contacts: Contacts
    lists: ListState
    v_start: wp.array(dtype=wp.vec3)
    rebuild_distance: float
    inv_mass: wp.array(dtype=float)
    h: float


@wp.struct
class ExplicitStepAndContactStartArgs:
    step: ExplicitStepArgs
    start: ContactStartArgs


@wp.func
def gather_spring_forces(step: ExplicitStepArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                         v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    if not gathers(step, i):
        return wp.vec3(0.0)
    return spring_forces(step.springs, i, first, stride, x, v)


@wp.func
def stepped(step: ExplicitStepArgs, i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    xi = x[i]
    vi = v[i]
    move, v_new = explicit_move(vi, step.inv_mass[i], f, external_acceleration(step.forces, i, xi, vi), step.h,
                                step.semi_implicit)
    if step.rounded_away.shape[0] == 0:
        return xi + move, v_new
    p, rounded = compensated_sum(xi, move, step.rounded_away[i])
    step.rounded_away[i] = rounded
    return p, v_new


@wp.func
def start_contacts(start: ContactStartArgs, i: int, p: wp.vec3, vel: wp.vec3):
    """Particle i's position and velocity after the rigid colliders, with the contacts' start recorded."""
    hit = int(0)
    v_before = vel
    if start.inv_mass[i] != 0.0:
        p, vel, hit = collide_particle(i, p, vel, start.colliders, start.h)
    begin_contact(i, p, v_before, hit, start.contacts, start.lists, start.v_start, start.rebuild_distance)
    return p, vel


@wp.func
def finish_explicit_step(args: ExplicitStepArgs, i: int, f: wp.vec3, x: wp.array(dtype=wp.vec3),
                         v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    p, vel = stepped(args, i, f, x, v)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_step_of(args: ExplicitStepAndContactStartArgs, i: int, first: int, stride: int,
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    return gather_spring_forces(args.step, i, first, stride, x, v)


@wp.func
def finish_explicit_step_and_contact_start(args: ExplicitStepAndContactStartArgs, i: int, f: wp.vec3,
                                           x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                           x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    p, vel = stepped(args.step, i, f, x, v)
    p, vel = start_contacts(args.start, i, p, vel)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def explicit_step_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("explicit_step", ExplicitStepArgs, gather_spring_forces, finish_explicit_step, threads)


@functools.cache
def explicit_step_and_contact_start_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("explicit_step_and_contact_start", ExplicitStepAndContactStartArgs, gather_step_of,
                            finish_explicit_step_and_contact_start, threads)


@wp.kernel
def contact_start(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), args: ContactStartArgs):
    """The contacts' start alone, in place, where the step before cannot end with it."""
    i = wp.tid()
    p, vel = start_contacts(args, i, x[i], v[i])
    x[i] = p
    v[i] = vel


# --- projection passes: strain limits, particle separation, each ending with the rigid colliders ------------

@wp.struct
class LimitPassArgs:
    limits: StrainLimits
    attachments: Attachments  # empty arrays: none
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders  # empty arrays and no ground: none
    resting: wp.array(dtype=int)  # empty: no marks
    read_bit: int


@wp.struct
class SeparationPassArgs:
    contacts: Contacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders
    read_bit: int


@wp.struct
class LimitAndSeparationPassArgs:
    limits: StrainLimits
    attachments: Attachments
    contacts: Contacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders
    read_bit: int


@wp.func
def held_and_collided(args: Any, i: int, p: wp.vec3, vel: wp.vec3, x: wp.array(dtype=wp.vec3),
                      resting: wp.array(dtype=int)):
    """The end of a pass that limits: the particle held to its pin, then put out of the colliders."""
    p, vel = hold_to_pin(args.attachments, args.colliders, i, p, vel, args.h, x)
    return collide_and_mark(i, p, vel, args.colliders, args.h, resting, args.read_bit)


@wp.func
def gather_limits(args: LimitPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return limit_corrections(args.limits, i, first, stride, x[i], args.inv_mass[i], x, args.inv_mass)


@wp.func
def finish_limit_pass(args: LimitPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                      v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its limit corrections (its velocity by that over h)."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    correction = mean_of(total)
    p, vel = held_and_collided(args, i, xi + correction, v[i] + correction / args.h, x, args.resting)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_pushes(args: SeparationPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return pushes(args.contacts, i, first, stride, x[i], args.inv_mass[i], x, args.inv_mass, args.read_bit)


@wp.func
def finish_separation_pass(args: SeparationPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                           v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                           v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its pushes out of overlapping pairs (its velocity by that over
    h), then out of the rigid colliders, which mark whom they hold up."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    push = mean_push(args.contacts, i, total)
    vel = v[i]
    if total[3] > 0.0:
        vel = vel + push / args.h
    p, vel = collide_and_mark(i, xi + push, vel, args.colliders, args.h, args.contacts.resting, args.read_bit)
    x_out[i] = p
    v_out[i] = vel


@wp.func
def gather_limits_and_pushes(args: LimitAndSeparationPassArgs, i: int, first: int, stride: int,
                             x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> vec8:
    if not gathers(args, i):
        return vec8(0.0)
    xi = x[i]
    wi = args.inv_mass[i]
    a = limit_corrections(args.limits, i, first, stride, xi, wi, x, args.inv_mass)
    b = pushes(args.contacts, i, first, stride, xi, wi, x, args.inv_mass, args.read_bit)
    return vec8(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])


@wp.func
def finish_limit_and_separation_pass(args: LimitAndSeparationPassArgs, i: int, total: vec8,
                                     x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                     x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its limits' corrections plus the mean of its pushes, both from
    the same positions, less the part of the limit's correction that would pull it into a contact; then
    holds it to its pin and puts it out of the colliders. Limit corrections lie mostly along the cloth and
    pushes across it, so this moves a particle about as far as the two passes one after the other did,
    in one launch instead of two."""
    xi = x[i]
    if args.inv_mass[i] == 0.0:
        x_out[i] = xi
        return
    correction = mean_of(wp.vec4(total[0], total[1], total[2], total[3]))
    pushed = wp.vec4(total[4], total[5], total[6], total[7])
    if pushed[3] > 0.0:
        push = mean_push(args.contacts, i, pushed)
        against = wp.dot(correction, push)
        if against < 0.0:
            correction = correction - (against / wp.length_sq(push)) * push
        correction = correction + push
    p, vel = held_and_collided(args, i, xi + correction, v[i] + correction / args.h, x, args.contacts.resting)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def limit_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("limit_pass", LimitPassArgs, gather_limits, finish_limit_pass, threads)


@functools.cache
def separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("separation_pass", SeparationPassArgs, gather_pushes, finish_separation_pass,
                            threads)


@functools.cache
def limit_and_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("limit_and_separation_pass", LimitAndSeparationPassArgs, gather_limits_and_pushes,
                            finish_limit_and_separation_pass, threads)


# --- edge separation: triangle edges moved a thickness apart (edge_collision.py), ending with the colliders ---

@wp.struct
class EdgeSeparationPassArgs:
    edges: EdgeContacts
    inv_mass: wp.array(dtype=float)
    h: float
    colliders: RigidColliders


@wp.func
def gather_edge_pushes(args: EdgeSeparationPassArgs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                       v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return edge_pushes(args.edges, i, first, stride, x, args.inv_mass)


@wp.func
def finish_edge_separation_pass(args: EdgeSeparationPassArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                                v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                                v_out: wp.array(dtype=wp.vec3)):
    """Moves free particle i by the mean of its edges' moves (its velocity by that over h), then out of the
    rigid colliders."""
    xi = x[i]
    if args.inv_mass[i] == 0.0 or total[3] == 0.0:
        x_out[i] = xi
        return
    move = mean_of(total)
    p, vel, unused_hit = collide_particle(i, xi + move, v[i] + move / args.h, args.colliders, args.h)
    x_out[i] = p
    v_out[i] = vel


@functools.cache
def edge_separation_pass_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("edge_separation_pass", EdgeSeparationPassArgs, gather_edge_pushes,
                            finish_edge_separation_pass, threads)


# --- Chebyshev's acceleration of a converged projection's iteration, ending with the colliders -------------

@wp.kernel
def chebyshev_step_and_colliders(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                 inv_mass: wp.array(dtype=float), omega: wp.array(dtype=float), h: float,
                                 colliders: RigidColliders, x_start: wp.array(dtype=wp.vec3),
                                 x_before: wp.array(dtype=wp.vec3)):
    """The extrapolated position (solve_loop.chebyshev_extrapolation), put out of the rigid colliders as
    every pass's move is; the velocity changed by both moves over h (extrapolating the velocities
    themselves blew the matrix's sphere cloth up). A solve's first iteration (and its second where it began
    close; see solve_loop.start_chebyshev), and the first after a restart, are plain ones: the iterates only shift, and the positions stay as the pass left them."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    xi = x[i]
    if omega[2] < 1.5:
        x_before[i] = x_start[i]
        x_start[i] = xi
        return
    xn = chebyshev_extrapolation(i, x, omega, x_start, x_before)
    p, vel, hit = collide_particle(i, xn, v[i] + (xn - xi) / h, colliders, h)
    x[i] = p
    v[i] = vel


# --- the check of a converged projection: how far limits and contacts are from holding ---------------------

@wp.struct
class ResidualArgs:
    limits: StrainLimits
    attachments: Attachments
    check_limits: int  # 0: the scene limits no strain (the limits' arrays are empty)
    limit_tolerance: float  # of an allowed length
    contacts: Contacts
    check_contacts: int  # 0: no particle collision
    contact_tolerance: float  # of a contact distance
    inv_mass: wp.array(dtype=float)
    colliders: RigidColliders  # the spheres that attachments run around


@wp.kernel
def projection_residual(x: wp.array(dtype=wp.vec3), args: ResidualArgs, residual: wp.array(dtype=float)):
    """residual[0] becomes the worst of each free particle's limit violation and contact overlap, each in
    its own tolerances (1: at the tolerance), where some exceed theirs (where none does it is left as is)."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        return
    worst = float(0.0)
    if args.check_limits != 0:
        worst = limit_violation(args.limits, i, x)
        if args.attachments.pin.shape[0] > 0:
            worst = wp.max(worst, attachment_violation(args.attachments, args.colliders, i, x))
        worst = worst / args.limit_tolerance
    if args.check_contacts != 0:
        worst = wp.max(worst, deepest_overlap(args.contacts, i, x) / args.contact_tolerance)
    if worst > 1.0:
        wp.atomic_max(residual, 0, worst)


# --- contact velocities, and the end of the substep's list remake -------------------------------------------

@wp.struct
class ContactVelocitiesArgs:
    contacts: Contacts
    lists: ListState
    v_start: wp.array(dtype=wp.vec3)
    inv_mass: wp.array(dtype=float)
    contact_slack: float
    friction: float
    h: float


@wp.func
def gather_velocity_changes(args: ContactVelocitiesArgs, i: int, first: int, stride: int,
                            x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)) -> wp.vec4:
    if not gathers(args, i):
        return wp.vec4(0.0)
    return velocity_changes(args.contacts, i, first, stride, x, v, args.v_start, args.inv_mass,
                            args.contact_slack, args.friction, args.h)


@wp.func
def finish_contact_velocities(args: ContactVelocitiesArgs, i: int, total: wp.vec4, x: wp.array(dtype=wp.vec3),
                              v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
                              v_out: wp.array(dtype=wp.vec3)):
    """Particle i's velocity changes by the mean of its contacts' changes; its pushes of this substep are
    forgotten; and (by one thread) the lists' remake ends."""
    v_out[i] = v[i] + mean_of(total)
    args.contacts.pushed[i] = 0.0
    if i == 0:
        end_remake(args.lists)


@functools.cache
def contact_velocities_kernel(threads: int) -> wp.Kernel:
    return gathering_kernel("contact_velocities_and_end_remake", ContactVelocitiesArgs, gather_velocity_changes,
                            finish_contact_velocities, threads)


# --- neighbour lists of particles and of contact edges, from spatial hashes (spatial_hash.py) ----------------

@wp.struct
class HashGrid:
    inv_cell: float  # 1 / cell width
    mask: int  # table size - 1
    capacity: int  # particles a bucket holds
    bucket_size: wp.array(dtype=int)
    bucket_items: wp.array(dtype=int)


@wp.func
def sorted_candidates(contacts: Contacts, rules: PairRules, lists: ListState, grid: HashGrid, i: int,
                      x: wp.array(dtype=wp.vec3)):
    """Particle i's list made by one thread: the candidates of the 27 cells around it appended as found
    (a bucket two cells share is visited twice), then sorted and the repeats dropped."""
    center = cell_of(x[i], grid.inv_cell)
    stamp = stamp_of(lists.epoch[0])
    count = int(0)
    for k in range(27):
        bucket = neighbour_bucket(center, rules.world[i], k, grid.mask)
        for s in range(wp.min(count_in(grid.bucket_size[bucket], stamp), grid.capacity)):
            count = add_candidate(contacts, rules, lists, i, grid.bucket_items[bucket * grid.capacity + s], x, count)
    contacts.counts[i] = sort_and_drop_repeats(contacts.neighbors, i * contacts.max_neighbors, count)
    lists.x_built[i] = x[i]


@functools.cache
def gather_neighbors_kernel(threads: int) -> wp.Kernel:
    """Each particle's candidates, from the spatial hash of this epoch, where ``rebuild`` is set (else
    nothing): pairs allowed to collide and closer than search_scale contact distances, in index order,
    and the positions they were made from.

    One thread a particle sorts its own list (``sorted_candidates``). With several, thread s visits cells
    s, s + threads, ... of the 27 (each bucket once: ranks below need distinct entries) and appends
    candidates to ``unsorted`` through the atomic count in ``appended`` (zero on entry, and left zero for
    the next gather); after the sum over threads, which is also the barrier after which every append is
    seen, each thread writes its entries at their rank (a list that overflows, one thread remakes as
    ``sorted_candidates`` makes it, keeping the nearest). Both make the same lists; one thread visiting
    every bucket once before its sort took 35% more of the 1024^2 self-collision frame on an H200."""
    per_block = BLOCK // threads
    total_over_threads = sum_over_threads(per_block, threads)

    def gather_neighbors(x: wp.array(dtype=wp.vec3), contacts: Contacts, rules: PairRules, lists: ListState,
                         grid: HashGrid, unsorted: wp.array(dtype=int), appended: wp.array(dtype=int)):
        if lists.rebuild[0] == 0:  # the same for the whole block, so its tile sum is not left waiting
            return
        block, lane = wp.tid()
        i, slot, owner = thread_layout(block, lane, wp.static(per_block), wp.static(threads), x.shape[0])
        if wp.static(threads == 1):
            if i >= 0:
                sorted_candidates(contacts, rules, lists, grid, i, x)
        else:
            most = contacts.max_neighbors
            found = int(0)
            if i >= 0:
                center = cell_of(x[i], grid.inv_cell)
                stamp = stamp_of(lists.epoch[0])
                for k in range(slot, 27, wp.static(threads)):
                    bucket = neighbour_bucket(center, rules.world[i], k, grid.mask)
                    if first_visit(center, rules.world[i], k, bucket, grid.mask):
                        for s in range(wp.min(count_in(grid.bucket_size[bucket], stamp), grid.capacity)):
                            j = grid.bucket_items[bucket * grid.capacity + s]
                            if is_candidate(contacts, rules, i, j, x):
                                at = wp.atomic_add(appended, i, 1)
                                found += 1
                                if at < most:
                                    unsorted[i * most + at] = j
            found = total_over_threads(found, lane)
            if i >= 0 and found > most:
                if owner:  # a full list keeps the nearest candidates (add_candidate), made as one thread makes it
                    sorted_candidates(contacts, rules, lists, grid, i, x)
                    appended[i] = 0
            elif i >= 0:
                count = found
                start = i * most
                for e in range(slot, count, wp.static(threads)):
                    j = unsorted[start + e]
                    rank = int(0)
                    for f in range(count):
                        if unsorted[start + f] < j:
                            rank += 1
                    contacts.neighbors[start + rank] = j
                if owner:
                    contacts.counts[i] = count
                    appended[i] = 0
                    lists.x_built[i] = x[i]

    gather_neighbors.__qualname__ = "gather_neighbors"
    return wp.kernel(gather_neighbors, module="unique", module_options=FAST_MATH)


def launch_gather_neighbors(threads: int, x: wp.array, inputs: list) -> None:
    kernel = gather_neighbors_kernel(threads)
    per_block = BLOCK // threads
    blocks = (x.shape[0] + per_block - 1) // per_block
    if threads == 1:
        wp.launch(kernel, dim=(blocks, BLOCK), inputs=[x, *inputs], device=x.device)
    else:
        wp.launch_tiled(kernel, dim=[blocks], inputs=[x, *inputs], block_dim=BLOCK, device=x.device)


@wp.kernel
def gather_edge_candidates(x: wp.array(dtype=wp.vec3), midpoint: wp.array(dtype=wp.vec3),
                           edge_world: wp.array(dtype=int), edges: EdgeContacts, rules: EdgeRules, lists: ListState,
                           reach: float, inv_cell: float, mask: int, capacity: int,
                           bucket_size: wp.array(dtype=int), bucket_items: wp.array(dtype=int)):
    """Each edge's candidates from the hash of its midpoint's 27 cells (each bucket once), where ``rebuild``
    is set: edges that may touch it whose segments lie within ``reach`` (``pair_gap``: each lists the other),
    in index order."""
    if lists.rebuild[0] == 0:
        return
    e = wp.tid()
    ends_e = edges.ends[e]
    center = cell_of(midpoint[e], inv_cell)
    world = edge_world[e]
    stamp = stamp_of(lists.epoch[0])
    start = e * edges.max_neighbors
    count = int(0)
    for k in range(27):
        bucket = neighbour_bucket(center, world, k, mask)
        if first_visit(center, world, k, bucket, mask):
            for s in range(wp.min(count_in(bucket_size[bucket], stamp), capacity)):
                f = bucket_items[bucket * capacity + s]
                ends_f = edges.ends[f]
                if f != e and may_touch(rules, ends_e, ends_f) and pair_gap(edges.ends, x, e, f) < reach:
                    if count < edges.max_neighbors:
                        edges.neighbors[start + count] = f
                        count += 1
                    else:
                        wp.atomic_add(lists.overflow, 0, 1)
    edges.counts[e] = sort_and_drop_repeats(edges.neighbors, start, count)


# --- the implicit step's system: the springs' Jacobians with the external forces' part ----------------------

@wp.struct
class SpringSystemArgs:
    springs: Springs
    forces: ExternalForces
    mass: wp.array(dtype=float)
    inv_mass: wp.array(dtype=float)
    h: float


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def newton_rhs(y: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v0: wp.array(dtype=wp.vec3),
               args: SpringSystemArgs, linearized_at_start: int, rhs: wp.array(dtype=wp.vec3)):
    """Right-hand side of one Newton step for v' with M (v' - v0) = h f(x0 + h v', v').

    With forces evaluated at y = x0 + h v, this is h f(y, v) - M (v - v0). Baraff & Witkin's single step
    linearises at the start of the step instead (y = x0, v = v0), which adds h^2 K v0 for the motion
    x0 -> x0 + h v0 that y leaves out: ``linearized_at_start`` = 1 selects that."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        rhs[i] = wp.vec3(0.0)
        return
    m = args.mass[i]
    f = spring_forces(args.springs, i, 0, 1, y, v)
    f = f + m * external_acceleration(args.forces, i, y[i], v[i])
    out = args.h * f - m * (v[i] - v0[i])
    if linearized_at_start != 0:
        out = out - (args.h * args.h) * stiffness_times_motion(args.springs, i, y, v0)
    rhs[i] = out


@wp.func
def mass_term(args: SpringSystemArgs, i: int) -> float:
    """The diagonal of M - h (d external force / dv) for particle i."""
    return args.mass[i] * (1.0 + args.h * external_damping(args.forces))


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def system_times(y: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3), active: wp.array(dtype=int),
                 args: SpringSystemArgs, out: wp.array(dtype=wp.vec3)):
    """out = A p on free particles, 0 on pinned ones (the filter). Does nothing in a world whose ``active``
    is 0."""
    i = wp.tid()
    if active[args.forces.world[i]] == 0:
        return
    if args.inv_mass[i] == 0.0:
        out[i] = wp.vec3(0.0)
        return
    out[i] = add_system_times(args.springs, i, y, p, args.h, mass_term(args, i) * p[i])


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def block_jacobi_inverse(y: wp.array(dtype=wp.vec3), args: SpringSystemArgs, inverse: wp.array(dtype=wp.mat33)):
    """The inverse of each particle's 3x3 diagonal block of A: the preconditioner (0 on pinned)."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        inverse[i] = wp.mat33(0.0)
        return
    block = add_system_diagonal(args.springs, i, y, args.h, mass_term(args, i) * wp.identity(n=3, dtype=float))
    inverse[i] = wp.inverse(block)
