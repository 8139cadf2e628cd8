"""Edge contacts: triangle edges kept a thickness apart, where particle contacts alone let them cross.

Particle contacts keep points apart, not the edges between them. Two edges of length L crossing at their
middles keep every end sqrt(2) L / 2 from the other's: past the contact distance for a grid's triangle
diagonals (1.41 cells against the seed's 0.82), so a cloth folded flat onto itself can pass a diagonal
through another while every particle stays apart. With a surface thickness the model lists every triangle
edge (warp_cloth/model.py, ``_contact_edges``); each edge's candidates are the listed edges whose segments lie
within ``reach``, found through a spatial hash of the edges' midpoints (neighbour_search.py), its cells as
wide as the longest edge then plus the reach, whenever the particle lists are remade, so that they stay valid
as long as those do; a pass then moves each pair's closest points apart to ``thickness``, each end by its
share (its barycentric weight over the pair's inverse mass), every particle by the mean of its edges' moves
(Jacobi, as the particle contacts).
"""

import warp as wp

from .spatial_hash import box_gap_sq

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)


@wp.struct
class EdgeContacts:
    ends: wp.array(dtype=wp.vec2i)  # (m,) each contact edge's two particles
    incident_offsets: wp.array(dtype=int)  # (n + 1,) the contact edges at each particle (CSR)
    incident: wp.array(dtype=int)
    neighbors: wp.array(dtype=int)  # (m * max_neighbors,) each edge's candidates (the nearest where more are
    # within reach than fit), in index order
    counts: wp.array(dtype=int)  # (m,)
    max_neighbors: int
    thickness: float  # how far apart the pass holds two edges


@wp.struct
class EdgeRules:
    """Which edges (and, face_collision.may_touch, which vertex-triangle pairs) may touch: as particles'
    (particle_collision.may_collide), but no two that share a particle nor a pair of particles a seam keeps
    from colliding, and, with a surface thickness, no two of one cloth nearer at rest than its ``rest_apart``
    (warp_cloth/surface_pairs.py says why)."""
    world: wp.array(dtype=int)  # (n,) each particle's
    cloth_id: wp.array(dtype=int)
    self_collision: int
    between_cloths: int
    sewn_offsets: wp.array(dtype=int)  # as particle_collision.PairRules': empty where no pair is sewn
    sewn_other: wp.array(dtype=int)
    rest: wp.array(dtype=wp.vec3)  # (n,) where each particle lies at rest, or empty: no pair left out by it
    rest_apart: wp.array(dtype=float)  # (cloths,) a pair of one cloth nearer than this at rest is none


@wp.func
def closest_points(p1: wp.vec3, q1: wp.vec3, p2: wp.vec3, q2: wp.vec3) -> wp.vec2:
    """Where segments p1-q1 and p2-q2 come closest, as fractions (s, t) along each (Ericson, Real-Time
    Collision Detection, 5.1.9), a segment of no length taken as its point."""
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = wp.dot(d1, d1)
    e = wp.dot(d2, d2)
    f = wp.dot(d2, r)
    tiny = 1.0e-12
    if a <= tiny and e <= tiny:
        return wp.vec2(0.0, 0.0)
    if a <= tiny:
        return wp.vec2(0.0, wp.clamp(f / e, 0.0, 1.0))
    c = wp.dot(d1, r)
    if e <= tiny:
        return wp.vec2(wp.clamp(-c / a, 0.0, 1.0), 0.0)
    b = wp.dot(d1, d2)
    denominator = a * e - b * b
    s = float(0.0)
    if denominator > 1.0e-6 * a * e:
        s = wp.clamp((b * f - c * e) / denominator, 0.0, 1.0)
    else:  # parallel to float32's precision: the middle of where the two overlap, seen along the first
        s = 0.5 * (wp.clamp(-c / a, 0.0, 1.0) + wp.clamp((b - c) / a, 0.0, 1.0))
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = wp.clamp(-c / a, 0.0, 1.0)
    elif t > 1.0:
        t = 1.0
        s = wp.clamp((b - c) / a, 0.0, 1.0)
    return wp.vec2(s, t)


@wp.func
def shares_particle(a: wp.vec2i, b: wp.vec2i) -> bool:
    return a[0] == b[0] or a[0] == b[1] or a[1] == b[0] or a[1] == b[1]


@wp.func
def sewn_near(rules: EdgeRules, a: wp.vec2i, b: wp.vec2i) -> bool:
    """Whether an end of edge a and an end of b are a pair that a seam keeps from colliding."""
    for end in range(2):
        i = a[end]
        for k in range(rules.sewn_offsets[i], rules.sewn_offsets[i + 1]):
            other = rules.sewn_other[k]
            if other == b[0] or other == b[1]:
                return True
    return False


@wp.func
def may_touch(rules: EdgeRules, a: wp.vec2i, b: wp.vec2i) -> bool:
    return may_touch_but_at_rest(rules, a, b) and apart_at_rest(rules, a, b)


@wp.func
def may_touch_but_at_rest(rules: EdgeRules, a: wp.vec2i, b: wp.vec2i) -> bool:
    """``may_touch`` but for the rest rule (``apart_at_rest``), which costs a distance: the lists' gathers
    test it last, on the pairs within reach."""
    if shares_particle(a, b):
        return False
    if rules.sewn_offsets.shape[0] > 0:
        if sewn_near(rules, a, b):
            return False
    i = a[0]
    j = b[0]
    if rules.world[i] != rules.world[j]:
        return False
    if rules.cloth_id[i] != rules.cloth_id[j]:
        return rules.between_cloths != 0
    return rules.self_collision != 0


@wp.func
def apart_at_rest(rules: EdgeRules, a: wp.vec2i, b: wp.vec2i) -> bool:
    """Whether edges a and b are no pair of one cloth nearer at rest than its ``rest_apart``."""
    i = a[0]
    if rules.rest.shape[0] == 0 or rules.cloth_id[i] != rules.cloth_id[b[0]]:
        return True
    rest = rules.rest
    st = closest_points(rest[a[0]], rest[a[1]], rest[b[0]], rest[b[1]])
    apart = wp.length(wp.lerp(rest[a[0]], rest[a[1]], st[0]) - wp.lerp(rest[b[0]], rest[b[1]], st[1]))
    return apart >= rules.rest_apart[rules.cloth_id[i]]


@wp.func
def pair_gap(ends: wp.array(dtype=wp.vec2i), x: wp.array(dtype=wp.vec3), e: int, f: int) -> float:
    """How close edges e and f come, worked out lower-numbered edge first (as ``edge_push`` does), so that
    both edges of a pair find the same gap."""
    a = ends[wp.min(e, f)]
    b = ends[wp.max(e, f)]
    st = closest_points(x[a[0]], x[a[1]], x[b[0]], x[b[1]])
    return wp.length(wp.lerp(x[a[0]], x[a[1]], st[0]) - wp.lerp(x[b[0]], x[b[1]], st[1]))


@wp.kernel
def start_edge_cells(rebuild: wp.array(dtype=int), longest: float, thickness: float, widest: wp.array(dtype=float),
                     inv_width: wp.array(dtype=float)):
    """The hash's cells at their least width (one thread), where ``rebuild`` is set: as wide as the longest
    an edge (or a triangle's side) may get plus the largest reach, the thickness plus twice the largest
    allowance (kernels/surface_reach.py), before ``midpoints_and_cell_width`` or
    face_collision.widen_face_cells."""
    if rebuild[0] != 0:
        inv_width[0] = 1.0 / (longest + thickness + 2.0 * widest[0])


@wp.kernel
def midpoints_and_cell_width(x: wp.array(dtype=wp.vec3), ends: wp.array(dtype=wp.vec2i),
                             rebuild: wp.array(dtype=int), longest: float, thickness: float,
                             widest: wp.array(dtype=float), midpoint: wp.array(dtype=wp.vec3),
                             half_extent: wp.array(dtype=wp.vec3), inv_width: wp.array(dtype=float)):
    """Where ``rebuild`` is set, each edge's midpoint, for the hash, and its box's half extent (the box is
    midpoint -+ it), and the hash's cells widened to the longest edge longer than ``longest`` plus the
    largest reach (its inverse width the least over those edges), so that the 27 cells around any edge's
    midpoint hold every edge within reach of it: two edges' midpoints lie up to half their lengths plus the
    reach apart."""
    if rebuild[0] == 0:
        return
    e = wp.tid()
    ends_e = ends[e]
    p, q = x[ends_e[0]], x[ends_e[1]]
    midpoint[e] = 0.5 * (p + q)
    half_extent[e] = 0.5 * wp.vec3(wp.abs(q[0] - p[0]), wp.abs(q[1] - p[1]), wp.abs(q[2] - p[2]))
    length = wp.length(q - p)
    if length > longest:
        wp.atomic_min(inv_width, 0, 1.0 / (length + thickness + 2.0 * widest[0]))


@wp.func
def apart_direction(d: wp.vec3, gap: float, p1: wp.vec3, q1: wp.vec3, p2: wp.vec3, q2: wp.vec3,
                    thickness: float) -> wp.vec3:
    """The unit direction from the second edge's closest point to the first's; for segments that (to
    float32's precision) meet, the normal of the two, or for parallel ones a fixed direction."""
    if gap > 1.0e-6 * thickness:
        return d / gap
    n = wp.cross(q1 - p1, q2 - p2)
    if wp.length_sq(n) > 1.0e-18:
        return wp.normalize(n)
    return wp.normalize(wp.vec3(0.267, 0.535, 0.802))


@wp.func
def boxes_apart(edges: EdgeContacts, e: int, f: int, x: wp.array(dtype=wp.vec3)) -> bool:
    """Whether edges e and f's boxes lie a thickness apart or more, so the edges do too: a listed pair's
    exact test skipped (a fine cloth's lists hold many pairs of its own plane a few cells apart)."""
    ends_e = edges.ends[e]
    ends_f = edges.ends[f]
    p_e = x[ends_e[0]]
    q_e = x[ends_e[1]]
    p_f = x[ends_f[0]]
    q_f = x[ends_f[1]]
    return box_gap_sq(wp.min(p_e, q_e), wp.max(p_e, q_e), wp.min(p_f, q_f), wp.max(p_f, q_f)) >= \
        edges.thickness * edges.thickness


@wp.func
def pair_closest(edges: EdgeContacts, e: int, f: int, x: wp.array(dtype=wp.vec3)):
    """Edges e and f's closest points, worked out in one order (the lower-numbered edge first): their
    parameters along the two, the vector from the second's point to the first's, and the four ends' positions
    (the first edge's, then the second's)."""
    ends_1 = edges.ends[wp.min(e, f)]
    ends_2 = edges.ends[wp.max(e, f)]
    p1 = x[ends_1[0]]
    q1 = x[ends_1[1]]
    p2 = x[ends_2[0]]
    q2 = x[ends_2[1]]
    st = closest_points(p1, q1, p2, q2)
    return st, wp.lerp(p1, q1, st[0]) - wp.lerp(p2, q2, st[1]), p1, q1, p2, q2


@wp.func
def edge_push(edges: EdgeContacts, i: int, e: int, f: int, x: wp.array(dtype=wp.vec3),
              inv_mass: wp.array(dtype=float)):
    """Particle i's move (an end of edge e) out of edge f's thickness, and 1 if the two are closer than it
    (else zero and 0).

    The pair is worked out in one order, the lower-numbered edge first, whichever of its edges' particles
    asks: in float32 two edges' closest points seen from each side differ by rounding, and where the edges
    (nearly) meet, so would the directions each side pushes its edge."""
    if boxes_apart(edges, e, f, x):
        return wp.vec3(0.0), 0
    second = wp.max(e, f)
    ends_1 = edges.ends[wp.min(e, f)]
    ends_2 = edges.ends[second]
    st, d, p1, q1, p2, q2 = pair_closest(edges, e, f, x)
    gap = wp.length(d)
    if gap >= edges.thickness:
        return wp.vec3(0.0), 0
    w_1 = (1.0 - st[0]) * (1.0 - st[0]) * inv_mass[ends_1[0]] + st[0] * st[0] * inv_mass[ends_1[1]]
    w_2 = (1.0 - st[1]) * (1.0 - st[1]) * inv_mass[ends_2[0]] + st[1] * st[1] * inv_mass[ends_2[1]]
    n = apart_direction(d, gap, p1, q1, p2, q2, edges.thickness)
    along = st[0]
    if e == second:
        n = -n
        along = st[1]
    weight = 1.0 - along
    if i == edges.ends[e][1]:
        weight = along
    if w_1 + w_2 == 0.0:
        return wp.vec3(0.0), 0
    return (inv_mass[i] * weight * (edges.thickness - gap) / (w_1 + w_2)) * n, 1


@wp.func
def edge_pushes(edges: EdgeContacts, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                inv_mass: wp.array(dtype=float)) -> wp.vec4:
    """Sum of particle i's moves out of the pairs its contact edges are in (candidates first, first +
    stride, ... of each edge), and how many pairs are closer than the thickness (w)."""
    total = wp.vec4(0.0)
    for k in range(edges.incident_offsets[i], edges.incident_offsets[i + 1]):
        e = edges.incident[k]
        for c in range(first, edges.counts[e], stride):
            move, close = edge_push(edges, i, e, edges.neighbors[e * edges.max_neighbors + c], x, inv_mass)
            total = total + wp.vec4(move[0], move[1], move[2], float(close))
    return total


@wp.func
def deepest_edge_overlap(edges: EdgeContacts, i: int, x: wp.array(dtype=wp.vec3)) -> float:
    """How far the closest listed pair of particle i's contact edges lies inside the thickness, as a fraction
    of it (0 where none does): every listed pair is in the lists of its edges' ends, so a check over every
    particle reads them all."""
    worst = float(0.0)
    for k in range(edges.incident_offsets[i], edges.incident_offsets[i + 1]):
        e = edges.incident[k]
        for c in range(edges.counts[e]):
            f = edges.neighbors[e * edges.max_neighbors + c]
            if not boxes_apart(edges, e, f, x):
                unused_st, d, unused_p1, unused_q1, unused_p2, unused_q2 = pair_closest(edges, e, f, x)
                worst = wp.max(worst, (edges.thickness - wp.length(d)) / edges.thickness)
    return worst


@wp.func
def sliding_taken(relative: wp.vec3, start_relative: wp.vec3, n: wp.vec3, coefficient: float) -> wp.vec3:
    """The tangential relative velocity friction takes off a touching pair: in proportion to the normal speed
    its contacts gave it since the contacts' start (relative now less ``start_relative``, along ``n``), as
    particle_collision.inelastic_change and the colliders take it, at most all of it."""
    vn = wp.dot(relative, n)
    stopped = wp.max(0.0, vn - wp.dot(start_relative, n))
    tangential = relative - vn * n
    speed = wp.length(tangential)
    if speed > 0.0:
        return tangential * wp.min(1.0, coefficient * stopped / speed)
    return wp.vec3(0.0)


@wp.func
def edge_friction(edges: EdgeContacts, i: int, e: int, f: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                  coefficient: float, slack: float):
    """Particle i's velocity change (an end of edge e) from friction with edge f times its end's weight in
    the pair, and that weight if the two touch (within ``slack`` thicknesses), else zero and 0 (summed and
    divided as ``face_collision.face_friction``'s): the closest points' relative velocity loses
    ``sliding_taken`` of it, each end taking its share over the pair's inverse mass (as
    ``edge_push``, worked out lower-numbered edge first)."""
    ends_1 = edges.ends[wp.min(e, f)]
    ends_2 = edges.ends[wp.max(e, f)]
    st, d, p1, q1, p2, q2 = pair_closest(edges, e, f, x)
    gap = wp.length(d)
    if gap >= slack * edges.thickness:
        return wp.vec3(0.0), 0.0
    w_1 = (1.0 - st[0]) * (1.0 - st[0]) * inv_mass[ends_1[0]] + st[0] * st[0] * inv_mass[ends_1[1]]
    w_2 = (1.0 - st[1]) * (1.0 - st[1]) * inv_mass[ends_2[0]] + st[1] * st[1] * inv_mass[ends_2[1]]
    if w_1 + w_2 == 0.0:
        return wp.vec3(0.0), 0.0
    n = apart_direction(d, gap, p1, q1, p2, q2, edges.thickness)
    relative = wp.lerp(v[ends_1[0]], v[ends_1[1]], st[0]) - wp.lerp(v[ends_2[0]], v[ends_2[1]], st[1])
    start = wp.lerp(v_start[ends_1[0]], v_start[ends_1[1]], st[0]) - \
        wp.lerp(v_start[ends_2[0]], v_start[ends_2[1]], st[1])
    along = st[0]
    sign = float(1.0)
    if e != wp.min(e, f):
        along = st[1]
        sign = -1.0
    weight = 1.0 - along
    if i == edges.ends[e][1]:
        weight = along
    return (-sign * inv_mass[i] * weight * weight / (w_1 + w_2)) * sliding_taken(relative, start, n, coefficient), \
        weight
