"""Self and cloth-cloth collision between particles (spheres), in O(n) through a spatial hash.

One substep: if some particle has moved far enough since they were made, remake each particle's list of
candidate neighbours within a search radius (through ``spatial_hash.py``); then run Jacobi passes that
push overlapping pairs apart (each particle moves by the mean of its corrections, weighted by inverse
mass: no races, deterministic; its velocity changes by the same correction over h); then make each
contact inelastic (averaged the same way), with friction in proportion to the normal speed taken away.
Two particles i, j touch when closer than ``separation * (r_i + r_j) / 2``.

The remake is asked for by ``rebuild[0]``, which the kernel that begins the contacts sets and the
substep's last kernel clears (``end_remake``), once every kernel that reads it has run; the kernels that
remake run every substep and return at once where it is not set (two such launches cost a GPU graph less
than one conditional node: docs/benchmarks.md).
"""

import functools

import warp as wp

from . import spatial_hash
from .colliders import RigidColliders, collide_and_mark, collide_particle
from .lanes import FAST_MATH, lane_layout, lane_particle, lane_sum

wp.set_module_options(FAST_MATH)


@wp.func
def begin_contact(i: int, p: wp.vec3, vel: wp.vec3, w: float, colliders: RigidColliders, h: float,
                  x_built: wp.array(dtype=wp.vec3), rebuild_distance: float, v_start: wp.array(dtype=wp.vec3),
                  resting: wp.array(dtype=int), rebuild: wp.array(dtype=int)):
    """The collision stage's start for particle i at position p with velocity vel (inverse mass w):
    remembers the velocity the contacts start from, puts the particle out of the rigid colliders and marks
    it if they hold it up (``resting``, empty without colliders), and sets rebuild[0] if it has moved
    farther than ``rebuild_distance`` since the neighbour lists were made. Returns its new p and vel."""
    v_start[i] = vel
    hit = int(0)
    if w != 0.0:
        p, vel, hit = collide_particle(p, vel, colliders, h)
    if resting.shape[0] > 0:
        resting[i] = 3 * hit  # both bits: the first pass reads either
    if wp.length_sq(p - x_built[i]) > rebuild_distance * rebuild_distance:
        rebuild[0] = 1
    return p, vel


@wp.kernel
def begin_contacts(inv_mass: wp.array(dtype=float), h: float, colliders: RigidColliders,
                   x_built: wp.array(dtype=wp.vec3), rebuild_distance: float, x: wp.array(dtype=wp.vec3),
                   v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3), resting: wp.array(dtype=int),
                   rebuild: wp.array(dtype=int)):
    """``begin_contact`` for every particle, where the integration step cannot do it (see stages.py)."""
    i = wp.tid()
    p, vel = begin_contact(i, x[i], v[i], inv_mass[i], colliders, h, x_built, rebuild_distance, v_start, resting,
                           rebuild)
    x[i] = p
    v[i] = vel


@wp.func
def contact_distance(ri: float, rj: float, separation: float) -> float:
    return separation * 0.5 * (ri + rj)


@wp.func
def may_collide(i: int, j: int, cloth_id: wp.array(dtype=int), self_collision: int, between_cloths: int,
                grid_xy: wp.array(dtype=int), exclude_adjacent: wp.array(dtype=int)) -> bool:
    """Whether the pair i-j is one the scene asks to collide. Rest-adjacent particles of a cloth (grid
    neighbours, diagonals included) are skipped only where that cloth's strain limit cannot keep them
    apart by itself."""
    ci = cloth_id[i]
    if ci != cloth_id[j]:
        return between_cloths != 0
    if self_collision == 0:
        return False
    if exclude_adjacent.shape[0] > 0:
        if exclude_adjacent[ci] != 0:
            a = grid_xy[i]
            b = grid_xy[j]
            dx = wp.abs((a & 65535) - (b & 65535))
            dy = wp.abs((a >> 16) - (b >> 16))
            if dx <= 1 and dy <= 1:
                return False
    return True


@wp.func
def is_candidate(i: int, j: int, x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), separation: float,
                 search_scale: float, cloth_id: wp.array(dtype=int), self_collision: int, between_cloths: int,
                 grid_xy: wp.array(dtype=int), exclude_adjacent: wp.array(dtype=int)) -> bool:
    """Whether j belongs in i's list: a pair that may collide, within search_scale contact distances."""
    if j == i:
        return False
    reach = search_scale * contact_distance(radius[i], radius[j], separation)
    if wp.length_sq(x[i] - x[j]) >= reach * reach:
        return False
    return may_collide(i, j, cloth_id, self_collision, between_cloths, grid_xy, exclude_adjacent)


@wp.func
def add_candidate(i: int, j: int, x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), separation: float,
                  search_scale: float, cloth_id: wp.array(dtype=int), self_collision: int, between_cloths: int,
                  grid_xy: wp.array(dtype=int), exclude_adjacent: wp.array(dtype=int), max_neighbors: int,
                  neighbors: wp.array(dtype=int), count: int, overflow: wp.array(dtype=int)) -> int:
    """Appends j to i's list if it is a candidate; returns the list's new length (a full list counts an
    overflow instead)."""
    if not is_candidate(i, j, x, radius, separation, search_scale, cloth_id, self_collision, between_cloths,
                        grid_xy, exclude_adjacent):
        return count
    if count < max_neighbors:
        neighbors[i * max_neighbors + count] = j
        return count + 1
    wp.atomic_add(overflow, 0, 1)
    return count


@wp.func
def sort_and_drop_repeats(neighbors: wp.array(dtype=int), start: int, count: int) -> int:
    """Insertion sort of one particle's list, then repeats dropped (a bucket two cells of the block hash to
    is visited twice); returns the new count. The order, and so the float sums over the list, are then the
    same on every run and device, whatever order atomics filled the buckets in."""
    for a in range(1, count):
        value = neighbors[start + a]
        b = a - 1
        while b >= 0 and neighbors[start + b] > value:
            neighbors[start + b + 1] = neighbors[start + b]
            b -= 1
        neighbors[start + b + 1] = value
    kept = wp.min(count, 1)
    for a in range(1, count):
        if neighbors[start + a] != neighbors[start + kept - 1]:
            neighbors[start + kept] = neighbors[start + a]
            kept += 1
    return kept


@wp.func
def end_remake(rebuild: wp.array(dtype=int), epoch: wp.array(dtype=int)):
    """After the last reader of ``rebuild`` (by one thread): clear it, and where lists were remade, start the
    hash's next epoch."""
    if rebuild[0] != 0:
        rebuild[0] = 0
        epoch[0] = epoch[0] + 1


@wp.kernel
def end_remake_once(rebuild: wp.array(dtype=int), epoch: wp.array(dtype=int)):
    """``end_remake`` for lists remade outside a substep."""
    end_remake(rebuild, epoch)


@wp.kernel
def gather_neighbors(x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), inv_cell: float, mask: int,
                     capacity: int, bucket_size: wp.array(dtype=int), bucket_items: wp.array(dtype=int),
                     epoch: wp.array(dtype=int), separation: float, search_scale: float, cloth_id: wp.array(dtype=int),
                     self_collision: int, between_cloths: int, grid_xy: wp.array(dtype=int),
                     exclude_adjacent: wp.array(dtype=int), max_neighbors: int, rebuild: wp.array(dtype=int),
                     neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), overflow: wp.array(dtype=int),
                     x_built: wp.array(dtype=wp.vec3)):
    """Each particle's candidates, from the spatial hash of this epoch: pairs allowed to collide and closer
    than search_scale contact distances, in index order, and the positions they were made from; where
    ``rebuild`` is set (else nothing)."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    center = spatial_hash.cell_of(x[i], inv_cell)
    stamp = spatial_hash.stamp_of(epoch[0])
    count = int(0)
    for k in range(27):
        bucket = spatial_hash.neighbour_bucket(center, k, mask)
        for s in range(wp.min(spatial_hash.count_in(bucket_size[bucket], stamp), capacity)):
            count = add_candidate(i, bucket_items[bucket * capacity + s], x, radius, separation, search_scale,
                                  cloth_id, self_collision, between_cloths, grid_xy, exclude_adjacent,
                                  max_neighbors, neighbors, count, overflow)
    counts[i] = sort_and_drop_repeats(neighbors, i * max_neighbors, count)
    x_built[i] = x[i]


@wp.func
def first_visit(center: wp.vec3i, k: int, bucket: int, mask: int) -> bool:
    """Whether no cell before the k-th of the 27 around ``center`` hashes to ``bucket``."""
    for earlier in range(k):
        if spatial_hash.neighbour_bucket(center, earlier, mask) == bucket:
            return False
    return True


@functools.cache
def gather_neighbors_lanes(lanes: int, block: int) -> wp.Kernel:
    """``gather_neighbors`` with ``lanes`` threads per particle (see lanes.py), making the same lists: lane
    s visits cells s, s + lanes, ... of the 27 and appends candidates to ``unsorted`` through the atomic
    count in ``appended`` (zero on entry, and left zero for the next gather); after the block's barrier
    each lane writes its entries at their rank, so the list is in index order. Ranks need distinct
    entries, so a bucket two cells share is visited once, at its first cell (the one-thread kernel drops
    repeats after its sort instead)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def gather_neighbors(x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), inv_cell: float, mask: int,
                         capacity: int, bucket_size: wp.array(dtype=int), bucket_items: wp.array(dtype=int),
                         epoch: wp.array(dtype=int), separation: float, search_scale: float,
                         cloth_id: wp.array(dtype=int), self_collision: int, between_cloths: int,
                         grid_xy: wp.array(dtype=int), exclude_adjacent: wp.array(dtype=int), max_neighbors: int,
                         rebuild: wp.array(dtype=int), unsorted: wp.array(dtype=int), appended: wp.array(dtype=int),
                         neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), overflow: wp.array(dtype=int),
                         x_built: wp.array(dtype=wp.vec3)):
        if rebuild[0] == 0:  # the same for the whole block, so its tile sum is not left waiting
            return
        block_id, lane = wp.tid()
        i, slot, owner = lane_layout(block_id, lane, wp.static(per_block), wp.static(lanes), x.shape[0])
        found = int(0)
        if i >= 0:
            center = spatial_hash.cell_of(x[i], inv_cell)
            stamp = spatial_hash.stamp_of(epoch[0])
            for k in range(slot, 27, wp.static(lanes)):
                bucket = spatial_hash.neighbour_bucket(center, k, mask)
                if first_visit(center, k, bucket, mask):
                    for s in range(wp.min(spatial_hash.count_in(bucket_size[bucket], stamp), capacity)):
                        j = bucket_items[bucket * capacity + s]
                        if is_candidate(i, j, x, radius, separation, search_scale, cloth_id, self_collision,
                                        between_cloths, grid_xy, exclude_adjacent):
                            at = wp.atomic_add(appended, i, 1)
                            found += 1
                            if at < max_neighbors:
                                unsorted[i * max_neighbors + at] = j
                            else:
                                wp.atomic_add(overflow, 0, 1)
        found = sum_over_lanes(found, lane)  # also the barrier after which the block's appends are seen
        if i >= 0:
            count = wp.min(found, max_neighbors)
            start = i * max_neighbors
            for e in range(slot, count, wp.static(lanes)):
                j = unsorted[start + e]
                rank = int(0)
                for f in range(count):
                    if unsorted[start + f] < j:
                        rank += 1
                neighbors[start + rank] = j
            if owner:
                counts[i] = count
                appended[i] = 0
                x_built[i] = x[i]

    return gather_neighbors


@wp.func
def separating_direction(d: wp.vec3, dist: float, i: int, j: int) -> wp.vec3:
    """The unit direction from j to i; for particles on top of each other, a fixed direction whose sign
    the pair's indices decide, so that the two are pushed apart rather than left coincident."""
    if dist > 1.0e-9:
        return d / dist
    direction = wp.normalize(wp.vec3(0.267, 0.535, 0.802))
    if i < j:
        return direction
    return -direction


@wp.func
def push_out(i: int, j: int, xi: wp.vec3, wi: float, rests: bool, ri: float, x: wp.array(dtype=wp.vec3),
             inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float), separation: float,
             resting: wp.array(dtype=int), read_bit: int):
    """Particle i's push out of its overlap with j, and 1 if they overlap (else zero and 0)."""
    d = xi - x[j]
    dist = wp.length(d)
    target = contact_distance(ri, radius[j], separation)
    if dist >= target:
        return wp.vec3(0.0), 0
    n = separating_direction(d, dist, i, j)
    share = wi / (wi + inv_mass[j])
    if resting.shape[0] > 0:
        other_rests = (resting[j] & read_bit) != 0
        if rests and not other_rests:
            share = 0.0
        elif other_rests and not rests:
            share = 1.0
    return share * (target - dist) * n, 1


@wp.func
def gather_pushes(i: int, first: int, stride: int, xi: wp.vec3, wi: float, x: wp.array(dtype=wp.vec3),
                  inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float), separation: float,
                  neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                  resting: wp.array(dtype=int), read_bit: int):
    """Sum of particle i's pushes out of its candidates first, first + stride, ..., and how many overlap."""
    rests = resting.shape[0] > 0 and (resting[i] & read_bit) != 0
    ri = radius[i]
    correction = wp.vec3(0.0)
    touching = int(0)
    for k in range(first, counts[i], stride):
        c, t = push_out(i, neighbors[i * max_neighbors + k], xi, wi, rests, ri, x, inv_mass, radius, separation,
                        resting, read_bit)
        correction = correction + c
        touching += t
    return correction, touching


@wp.func
def finish_separation(i: int, xi: wp.vec3, correction: wp.vec3, touching: int, h: float, read_bit: int,
                      colliders: RigidColliders, resting: wp.array(dtype=int), x_out: wp.array(dtype=wp.vec3),
                      v: wp.array(dtype=wp.vec3), pushed: wp.array(dtype=float)):
    vel = v[i]
    if touching > 0:
        correction = correction / float(touching)
        vel = vel + correction / h
        pushed[i] = pushed[i] + wp.length(correction)
    p, vel = collide_and_mark(i, xi + correction, vel, colliders, h, resting, read_bit)
    x_out[i] = p
    v[i] = vel


@wp.kernel
def separate_particles(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float),
                       separation: float, h: float, neighbors: wp.array(dtype=int), counts: wp.array(dtype=int),
                       max_neighbors: int, resting: wp.array(dtype=int), read_bit: int, colliders: RigidColliders,
                       x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), pushed: wp.array(dtype=float)):
    """One Jacobi pass: move each particle by the mean of the pushes out of its overlapping pairs, then
    out of the rigid colliders (an empty ``RigidColliders`` for none), which mark whom they hold up.

    A particle that a rigid collider holds up (``resting``) does not give way to one that is not: the
    other takes the whole push, as if the resting one were as heavy as the ground under it. Without this,
    a heavy cloth on a light one on the ground sinks in, since each pass shares the push by mass and the
    ground then undoes the light cloth's share."""
    i = wp.tid()
    xi = x[i]
    wi = inv_mass[i]
    if wi == 0.0:
        x_out[i] = xi
        return
    correction, touching = gather_pushes(i, 0, 1, xi, wi, x, inv_mass, radius, separation, neighbors, counts,
                                         max_neighbors, resting, read_bit)
    finish_separation(i, xi, correction, touching, h, read_bit, colliders, resting, x_out, v, pushed)


@functools.cache
def separate_particles_lanes(lanes: int, block: int) -> wp.Kernel:
    """``separate_particles`` with ``lanes`` threads per particle (see lanes.py)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def separate_particles(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                           radius: wp.array(dtype=float), separation: float, h: float,
                           neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                           resting: wp.array(dtype=int), read_bit: int, colliders: RigidColliders,
                           x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                           pushed: wp.array(dtype=float)):
        block_id, lane = wp.tid()
        i, slot, owner, xi, wi = lane_particle(block_id, lane, wp.static(per_block), wp.static(lanes), x, inv_mass)
        correction = wp.vec3(0.0)
        touching = int(0)
        if wi != 0.0:
            correction, touching = gather_pushes(i, slot, wp.static(lanes), xi, wi, x, inv_mass, radius,
                                                 separation, neighbors, counts, max_neighbors, resting, read_bit)
        correction = sum_over_lanes(correction, lane)
        touching = sum_over_lanes(touching, lane)
        if owner:
            if wi == 0.0:
                x_out[i] = xi
            else:
                finish_separation(i, xi, correction, touching, h, read_bit, colliders, resting, x_out, v, pushed)

    return separate_particles


@wp.func
def inelastic_change(i: int, j: int, xi: wp.vec3, vi: wp.vec3, wi: float, ri: float, pushed_speed: float,
                     x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
                     inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float), separation: float,
                     contact_slack: float, friction: float):
    """Particle i's velocity change from its contact with j, as its normal part and the friction taken off
    (added to the sum one after the other, as they always were, so results stay as they were), and 1 if
    they touch (else zeros and 0)."""
    d = xi - x[j]
    dist = wp.length(d)
    if dist >= contact_slack * contact_distance(ri, radius[j], separation):
        return wp.vec3(0.0), wp.vec3(0.0), 0
    n = separating_direction(d, dist, i, j)
    relative = vi - v[j]
    vn = wp.dot(relative, n)
    allowed = wp.max(0.0, wp.dot(v_start[i] - v_start[j], n))
    target = wp.clamp(vn, 0.0, allowed)
    share = wi / (wi + inv_mass[j])
    stopped = pushed_speed + wp.max(0.0, -vn)
    tangential = relative - vn * n
    speed = wp.length(tangential)
    taken = wp.vec3(0.0)
    if speed > 0.0:
        taken = share * tangential * wp.min(1.0, friction * stopped / speed)
    return share * (target - vn) * n, taken, 1


@wp.func
def gather_velocity_changes(i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                            v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
                            inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float), separation: float,
                            contact_slack: float, friction: float, h: float, pushed: wp.array(dtype=float),
                            neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int):
    """Sum of particle i's velocity changes from its candidates first, first + stride, ..., and how many
    of them touch it."""
    xi = x[i]
    vi = v[i]
    wi = inv_mass[i]
    ri = radius[i]
    pushed_speed = pushed[i] / h
    change = wp.vec3(0.0)
    touching = int(0)
    for k in range(first, counts[i], stride):
        c, taken, t = inelastic_change(i, neighbors[i * max_neighbors + k], xi, vi, wi, ri, pushed_speed, x, v,
                                       v_start, inv_mass, radius, separation, contact_slack, friction)
        change = change + c - taken
        touching += t
    return change, touching


@wp.func
def finish_velocities(i: int, change: wp.vec3, touching: int, v: wp.array(dtype=wp.vec3),
                      pushed: wp.array(dtype=float), v_out: wp.array(dtype=wp.vec3), rebuild: wp.array(dtype=int),
                      epoch: wp.array(dtype=int)):
    if touching > 0:
        change = change / float(touching)
    v_out[i] = v[i] + change
    pushed[i] = 0.0
    if i == 0:
        end_remake(rebuild, epoch)


@wp.kernel
def resolve_contact_velocities(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
                               inv_mass: wp.array(dtype=float), radius: wp.array(dtype=float), separation: float,
                               contact_slack: float, friction: float, h: float, pushed: wp.array(dtype=float),
                               neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                               v_out: wp.array(dtype=wp.vec3), rebuild: wp.array(dtype=int),
                               epoch: wp.array(dtype=int)):
    """Contacts are inelastic: each touching pair's relative normal velocity ends between 0 and what it
    was before the collision stage (so pushes out of a deep overlap do not launch particles apart), the
    particle taking its mass share of the change, averaged over its contacts; friction takes tangential
    relative speed in proportion to the normal speed taken away, this substep's pushes included."""
    i = wp.tid()
    change = wp.vec3(0.0)
    touching = int(0)
    if inv_mass[i] != 0.0:
        change, touching = gather_velocity_changes(i, 0, 1, x, v, v_start, inv_mass, radius, separation,
                                                   contact_slack, friction, h, pushed, neighbors, counts,
                                                   max_neighbors)
    finish_velocities(i, change, touching, v, pushed, v_out, rebuild, epoch)


@functools.cache
def resolve_contact_velocities_lanes(lanes: int, block: int) -> wp.Kernel:
    """``resolve_contact_velocities`` with ``lanes`` threads per particle (see lanes.py)."""
    per_block = block // lanes
    sum_over_lanes = lane_sum(per_block, lanes)

    @wp.kernel(module="unique", module_options=FAST_MATH)
    def resolve_contact_velocities(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                                   v_start: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                                   radius: wp.array(dtype=float), separation: float, contact_slack: float,
                                   friction: float, h: float, pushed: wp.array(dtype=float),
                                   neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                                   v_out: wp.array(dtype=wp.vec3), rebuild: wp.array(dtype=int),
                                   epoch: wp.array(dtype=int)):
        block_id, lane = wp.tid()
        i, slot, owner = lane_layout(block_id, lane, wp.static(per_block), wp.static(lanes), x.shape[0])
        change = wp.vec3(0.0)
        touching = int(0)
        if i >= 0:
            if inv_mass[i] != 0.0:
                change, touching = gather_velocity_changes(i, slot, wp.static(lanes), x, v, v_start, inv_mass,
                                                           radius, separation, contact_slack, friction, h, pushed,
                                                           neighbors, counts, max_neighbors)
        change = sum_over_lanes(change, lane)
        touching = sum_over_lanes(touching, lane)
        if owner:
            finish_velocities(i, change, touching, v, pushed, v_out, rebuild, epoch)

    return resolve_contact_velocities


@wp.kernel
def closest_contact_ratio(x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), separation: float,
                          neighbors: wp.array(dtype=int), counts: wp.array(dtype=int), max_neighbors: int,
                          ratio: wp.array(dtype=float)):
    """Diagnostic: the smallest distance / contact distance over the pairs of freshly made lists."""
    i = wp.tid()
    xi = x[i]
    smallest = float(1.0e30)
    for k in range(counts[i]):
        j = neighbors[i * max_neighbors + k]
        smallest = wp.min(smallest, wp.length(xi - x[j]) / contact_distance(radius[i], radius[j], separation))
    wp.atomic_min(ratio, 0, smallest)


@wp.kernel
def gather_neighbors_brute_force(x: wp.array(dtype=wp.vec3), radius: wp.array(dtype=float), separation: float,
                                 search_scale: float, cloth_id: wp.array(dtype=int), self_collision: int,
                                 between_cloths: int, grid_xy: wp.array(dtype=int),
                                 exclude_adjacent: wp.array(dtype=int), max_neighbors: int,
                                 rebuild: wp.array(dtype=int), neighbors: wp.array(dtype=int),
                                 counts: wp.array(dtype=int), overflow: wp.array(dtype=int),
                                 x_built: wp.array(dtype=wp.vec3)):
    """The O(n^2) way to fill the same lists as ``gather_neighbors`` (every particle against every other,
    as the seed did), for small scenes and to measure what the spatial hash saves."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    count = int(0)
    for j in range(x.shape[0]):
        count = add_candidate(i, j, x, radius, separation, search_scale, cloth_id, self_collision, between_cloths,
                              grid_xy, exclude_adjacent, max_neighbors, neighbors, count, overflow)
    counts[i] = count
    x_built[i] = x[i]
