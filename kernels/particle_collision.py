"""Self and cloth-cloth collision between particles (spheres): candidate pairs, Jacobi separation, and
inelastic contact velocities with friction.

One substep: if some particle has moved far enough since they were made, each particle's list of candidate
neighbours within a search radius is remade (from the spatial hash, spatial_hash.py, or by checking all
pairs); Jacobi passes push overlapping pairs apart (each particle moves by the mean of its corrections,
weighted by inverse mass: no races, deterministic; its velocity changes by the same correction over h);
then each contact is made inelastic (averaged the same way), with friction in proportion to the normal
speed taken away. Two particles i, j touch when closer than ``separation * (r_i + r_j) / 2``.

The remake is asked for by ``rebuild[0]``, which the contacts' start sets and the substep's last kernel
clears (``end_remake``), once every kernel that reads it has run; the kernels that remake run every
substep and return at once where it is not set (two such launches cost a GPU graph less than one
conditional node: docs/benchmarks.md).
"""

import warp as wp

from .candidate_lists import keeping_nearest

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)

# Candidates are listed within this many contact distances: a wider skin remakes the lists less often and
# makes them longer (tools/skin_probe.py measures the trade, and sets this to do so).
SEARCH_SCALE = 1.5


@wp.struct
class Contacts:
    radius: wp.array(dtype=float)  # (n,) each particle's sphere
    separation: float  # contact distance in mean radii
    neighbors: wp.array(dtype=int)  # (n * max_neighbors,) each particle's candidates (the nearest where more
    # are within reach than fit), sorted by index
    counts: wp.array(dtype=int)  # (n,) the length of each list
    max_neighbors: int
    resting: wp.array(dtype=int)  # (n,) or empty without rigid colliders: see colliders.py
    pushed: wp.array(dtype=float)  # (n,) how far the passes of this substep pushed each particle
    friction: wp.array(dtype=float)  # (n,) each particle's cloth's coefficient (its material's), or empty: none


@wp.struct
class PairRules:
    """Which pairs may collide, and how far apart candidates may be."""
    world: wp.array(dtype=int)  # (n,) each particle's: particles of different worlds never collide
    cloth_id: wp.array(dtype=int)
    self_collision: int
    between_cloths: int
    adjacent_offsets: wp.array(dtype=int)  # (n + 1,) particles that share a face (CSR), or empty where no
    adjacent_other: wp.array(dtype=int)  # cloth skips them; each particle's list sorted
    exclude_adjacent: wp.array(dtype=int)  # (cloths,) 1 where a cloth skips them, or empty
    sewn_offsets: wp.array(dtype=int)  # (n + 1,) pairs a seam keeps from colliding (CSR), or empty: no seam
    sewn_other: wp.array(dtype=int)  # each particle's list sorted
    search_scale: float  # candidates lie within this many contact distances


@wp.struct
class ListState:
    """Where the lists were made, and the remake's request and count of what did not fit."""
    x_built: wp.array(dtype=wp.vec3)
    rebuild: wp.array(dtype=int)
    epoch: wp.array(dtype=int)  # the spatial hash's (spatial_hash.py)
    overflow: wp.array(dtype=int)


@wp.func
def contact_distance(ri: float, rj: float, separation: float) -> float:
    return separation * 0.5 * (ri + rj)


@wp.func
def may_collide(rules: PairRules, i: int, j: int) -> bool:
    """Whether the pair i-j is one the scene asks to collide. Rest-adjacent particles of a cloth (that share
    a face: on a grid, neighbours with diagonals) are skipped only where that cloth's strain limit cannot
    keep them apart by itself. Sewn particles, and those around them (model.ParticleContacts.sewn), never
    collide."""
    if rules.world[i] != rules.world[j]:
        return False
    if rules.sewn_offsets.shape[0] > 0:
        for k in range(rules.sewn_offsets[i], rules.sewn_offsets[i + 1]):
            if rules.sewn_other[k] == j:
                return False
    ci = rules.cloth_id[i]
    if ci != rules.cloth_id[j]:
        return rules.between_cloths != 0
    if rules.self_collision == 0:
        return False
    if rules.exclude_adjacent.shape[0] > 0:
        if rules.exclude_adjacent[ci] != 0:
            for k in range(rules.adjacent_offsets[i], rules.adjacent_offsets[i + 1]):
                if rules.adjacent_other[k] == j:
                    return False
    return True


@wp.func
def is_candidate(contacts: Contacts, rules: PairRules, i: int, j: int, x: wp.array(dtype=wp.vec3)) -> bool:
    """Whether j belongs in i's list: a pair that may collide, within search_scale contact distances."""
    if j == i:
        return False
    reach = rules.search_scale * contact_distance(contacts.radius[i], contacts.radius[j], contacts.separation)
    if wp.length_sq(x[i] - x[j]) >= reach * reach:
        return False
    return may_collide(rules, i, j)


@wp.struct
class ParticleListOwner:
    x: wp.array(dtype=wp.vec3)
    i: int


@wp.func
def particle_list_owner(x: wp.array(dtype=wp.vec3), i: int) -> ParticleListOwner:
    owner = ParticleListOwner()
    owner.x = x
    owner.i = i
    return owner


@wp.func
def squared_distance(owner: ParticleListOwner, slot: int, j: int) -> float:
    return wp.length_sq(owner.x[j] - owner.x[owner.i])


@wp.func
def forget_gap(owner: ParticleListOwner, slot: int, gap: float):
    pass


insert_particle = keeping_nearest(squared_distance, forget_gap)


@wp.func
def add_candidate(contacts: Contacts, rules: PairRules, lists: ListState, i: int, j: int, x: wp.array(dtype=wp.vec3),
                  count: int) -> int:
    """Puts j in i's list if it is a candidate (a full list keeps the nearest: candidate_lists.py); returns
    the list's new length."""
    if not is_candidate(contacts, rules, i, j, x):
        return count
    owner = particle_list_owner(x, i)
    return insert_particle(contacts.neighbors, i * contacts.max_neighbors, count, contacts.max_neighbors, j,
                           squared_distance(owner, 0, j), lists.overflow, owner)


@wp.func
def sort_and_drop_repeats(neighbors: wp.array(dtype=int), start: int, count: int) -> int:
    """Insertion sort of one particle's list, then repeats dropped; returns the new count. The order, and
    so the float sums over the list, are then the same on every run and device, whatever order atomics
    filled the buckets in."""
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
def end_remake(lists: ListState):
    """After the last reader of ``rebuild`` (by one thread): clear it, and where lists were remade, start the
    hash's next epoch."""
    if lists.rebuild[0] != 0:
        lists.rebuild[0] = 0
        lists.epoch[0] = lists.epoch[0] + 1


@wp.kernel
def end_remake_once(lists: ListState):
    """``end_remake`` for lists remade outside a substep."""
    end_remake(lists)


@wp.kernel
def gather_neighbors_brute_force(x: wp.array(dtype=wp.vec3), contacts: Contacts, rules: PairRules, lists: ListState):
    """Every particle's candidates, checking it against every other (as the seed did), where ``rebuild`` is
    set: for small scenes and to measure what the spatial hash saves. The lists are those the hash makes."""
    if lists.rebuild[0] == 0:
        return
    i = wp.tid()
    count = int(0)
    for j in range(x.shape[0]):
        count = add_candidate(contacts, rules, lists, i, j, x, count)
    contacts.counts[i] = count
    lists.x_built[i] = x[i]


@wp.func
def begin_contact(i: int, p: wp.vec3, v_before: wp.vec3, hit: int, contacts: Contacts, lists: ListState,
                  v_start: wp.array(dtype=wp.vec3), rebuild_distance: float):
    """The contacts' start for particle i, now at p after the rigid colliders (``hit``: whether they touched
    it): remembers the velocity the contacts start from, marks the particle resting if a collider holds it
    up (both bits: the first pass reads either), and asks for a remake of the lists if it has moved
    farther than ``rebuild_distance`` since they were made."""
    v_start[i] = v_before
    if contacts.resting.shape[0] > 0:
        contacts.resting[i] = 3 * hit
    if wp.length_sq(p - lists.x_built[i]) > rebuild_distance * rebuild_distance:
        lists.rebuild[0] = 1


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
def push_out(contacts: Contacts, i: int, j: int, xi: wp.vec3, wi: float, ri: float, rests: bool,
             x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), read_bit: int):
    """Particle i's push out of its overlap with j, and 1 if they overlap (else zero and 0).

    A particle that a rigid collider holds up (``resting``) does not give way to one that is not: the
    other takes the whole push, as if the resting one were as heavy as the ground under it. Without this,
    a heavy cloth on a light one on the ground sinks in, since each pass shares the push by mass and the
    ground then undoes the light cloth's share."""
    d = xi - x[j]
    dist = wp.length(d)
    target = contact_distance(ri, contacts.radius[j], contacts.separation)
    if dist >= target:
        return wp.vec3(0.0), 0
    n = separating_direction(d, dist, i, j)
    share = wi / (wi + inv_mass[j])
    if contacts.resting.shape[0] > 0:
        other_rests = (contacts.resting[j] & read_bit) != 0
        if rests and not other_rests:
            share = 0.0
        elif other_rests and not rests:
            share = 1.0
    return share * (target - dist) * n, 1


@wp.func
def pushes(contacts: Contacts, i: int, first: int, stride: int, xi: wp.vec3, wi: float, x: wp.array(dtype=wp.vec3),
           inv_mass: wp.array(dtype=float), read_bit: int) -> wp.vec4:
    """Sum of free particle i's (at xi, inverse mass wi) pushes out of its candidates first, first + stride,
    ... (xyz), and how many overlap it (w)."""
    ri = contacts.radius[i]
    rests = contacts.resting.shape[0] > 0 and (contacts.resting[i] & read_bit) != 0
    total = wp.vec4(0.0)
    for k in range(first, contacts.counts[i], stride):
        c, t = push_out(contacts, i, contacts.neighbors[i * contacts.max_neighbors + k], xi, wi, ri, rests, x,
                        inv_mass, read_bit)
        total = total + wp.vec4(c[0], c[1], c[2], float(t))
    return total


@wp.func
def mean_push(contacts: Contacts, i: int, total: wp.vec4) -> wp.vec3:
    """The mean of the pushes whose sum and count ``total`` holds (zero for none), which is added to how far
    the particle has been pushed this substep."""
    push = wp.vec3(total[0], total[1], total[2])
    if total[3] > 0.0:
        push = push / total[3]
        contacts.pushed[i] = contacts.pushed[i] + wp.length(push)
    return push


@wp.func
def inelastic_change(contacts: Contacts, i: int, j: int, xi: wp.vec3, vi: wp.vec3, wi: float, ri: float,
                     pushed_speed: float,
                     x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3),
                     inv_mass: wp.array(dtype=float), contact_slack: float, friction: float):
    """Particle i's velocity change from its contact with j, as its normal part and the friction taken off
    (added to the sum one after the other, as they always were, so results stay as they were), and 1 if
    they touch (else zeros and 0)."""
    d = xi - x[j]
    dist = wp.length(d)
    if dist >= contact_slack * contact_distance(ri, contacts.radius[j], contacts.separation):
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
    coefficient = friction
    if contacts.friction.shape[0] > 0:  # the larger of the collision table's and the two cloths' mean
        coefficient = wp.max(friction, 0.5 * (contacts.friction[i] + contacts.friction[j]))
    if speed > 0.0:
        taken = share * tangential * wp.min(1.0, coefficient * stopped / speed)
    return share * (target - vn) * n, taken, 1


@wp.func
def velocity_changes(contacts: Contacts, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                     v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                     contact_slack: float, friction: float, h: float) -> wp.vec4:
    """Sum of free particle i's velocity changes from its candidates first, first + stride, ... (xyz), and
    how many of them touch it (w).

    Contacts are inelastic: each touching pair's relative normal velocity ends between 0 and what it
    was before the collision passes (so pushes out of a deep overlap do not launch particles apart), the
    particle taking its mass share of the change, averaged over its contacts; friction takes tangential
    relative speed in proportion to the normal speed taken away, this substep's pushes included."""
    xi = x[i]
    vi = v[i]
    wi = inv_mass[i]
    ri = contacts.radius[i]
    pushed_speed = contacts.pushed[i] / h
    total = wp.vec4(0.0)
    for k in range(first, contacts.counts[i], stride):
        c, taken, t = inelastic_change(contacts, i, contacts.neighbors[i * contacts.max_neighbors + k], xi, vi, wi, ri,
                                       pushed_speed, x, v, v_start, inv_mass, contact_slack, friction)
        total = total + wp.vec4(c[0], c[1], c[2], float(t)) - wp.vec4(taken[0], taken[1], taken[2], 0.0)
    return total


@wp.func
def deepest_overlap(contacts: Contacts, i: int, x: wp.array(dtype=wp.vec3)) -> float:
    """How far particle i's closest candidate lies inside their contact distance, as a fraction of it (0
    where none does)."""
    xi = x[i]
    ri = contacts.radius[i]
    worst = float(0.0)
    for k in range(contacts.counts[i]):
        j = contacts.neighbors[i * contacts.max_neighbors + k]
        target = contact_distance(ri, contacts.radius[j], contacts.separation)
        worst = wp.max(worst, (target - wp.length(xi - x[j])) / target)
    return worst


@wp.func
def closest_listed(i: int, x: wp.array(dtype=wp.vec3), contacts: Contacts):
    """Particle i's smallest distance / contact distance over its listed pairs, and that pair's other
    particle (1e30 and -1 where it lists none)."""
    xi = x[i]
    smallest = float(1.0e30)
    partner = int(-1)
    for k in range(contacts.counts[i]):
        j = contacts.neighbors[i * contacts.max_neighbors + k]
        ratio = wp.length(xi - x[j]) / contact_distance(contacts.radius[i], contacts.radius[j], contacts.separation)
        if ratio < smallest:
            smallest = ratio
            partner = j
    return smallest, partner


@wp.kernel
def closest_contact_ratio(x: wp.array(dtype=wp.vec3), contacts: Contacts, world: wp.array(dtype=int),
                          ratio: wp.array(dtype=float)):
    """Diagnostic: each world's smallest distance / contact distance over the pairs of freshly made lists."""
    i = wp.tid()
    smallest, partner = closest_listed(i, x, contacts)
    wp.atomic_min(ratio, world[i], smallest)


@wp.kernel
def closest_contact_partner(x: wp.array(dtype=wp.vec3), contacts: Contacts, ratio: wp.array(dtype=float),
                            partner: wp.array(dtype=int)):
    """Diagnostic: each particle's smallest distance / contact distance over its freshly listed pairs, and
    that pair's other particle (1e30 and -1 where it lists none)."""
    i = wp.tid()
    smallest, j = closest_listed(i, x, contacts)
    ratio[i] = smallest
    partner[i] = j
