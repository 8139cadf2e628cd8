"""Face contacts (issue 34, a scene's ``[collision] thickness``): every vertex kept ``thickness`` from the
triangles it is not a vertex of.

Particle contacts keep points apart, and edge contacts edges; neither holds a vertex off the middle of a
triangle larger than the contact distance, where layers pass through each other. Each vertex's candidate
triangles, and each triangle's candidate vertices (the same pairs, listed from both sides so that a
particle can gather its pairs as a vertex and as a triangle's vertex without atomics), are remade with the
particle lists (neighbour_search.py), as long as those stay valid. A pair is listed with the side of the
triangle its vertex was on then, so that a pair that has crossed since is pushed back, not through.

A pass then moves each pair closer than the thickness apart along the closest points' direction (the
triangle's normal, towards the listed side, where the vertex projects inside the triangle), the vertex and
the triangle's three vertices by their shares (barycentric weights over the pair's inverse mass, as Offset
Geometric Contact's and the edge contacts' pairs), every particle by the mean of its pairs' moves (Jacobi).
Each pair is worked out from the same arguments whichever of its four particles asks, so that the moves
agree to the bit and a pair's moves conserve momentum.
"""

import warp as wp

from .edge_collision import EdgeRules, sliding_taken

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)


@wp.struct
class FaceContacts:
    triangles: wp.array(dtype=wp.vec3i)
    incident_offsets: wp.array(dtype=int)  # (n + 1,) the triangles each particle is a vertex of (CSR)
    incident: wp.array(dtype=int)
    vertex_faces: wp.array(dtype=int)  # (n * max_neighbors,) each vertex's triangles as 2 t + side, in order
    vertex_counts: wp.array(dtype=int)  # (n,)
    face_vertices: wp.array(dtype=int)  # (t * max_neighbors,) each triangle's vertices as 2 v + side, in order
    face_counts: wp.array(dtype=int)  # (t,)
    max_neighbors: int
    thickness: float  # how far a vertex is held from a triangle


@wp.func
def closest_weights(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> wp.vec3:
    """The barycentric weights of the point of triangle a, b, c closest to p (Ericson, Real-Time Collision
    Detection, 5.1.5); all three above zero where p projects inside the triangle."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return wp.vec3(1.0, 0.0, 0.0)
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return wp.vec3(0.0, 1.0, 0.0)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / (d1 - d3)
        return wp.vec3(1.0 - s, s, 0.0)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return wp.vec3(0.0, 0.0, 1.0)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / (d2 - d6)
        return wp.vec3(1.0 - s, 0.0, s)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return wp.vec3(0.0, 1.0 - s, s)
    total = va + vb + vc
    if total <= 0.0:  # a triangle of no area that no edge region claimed
        return wp.vec3(1.0, 0.0, 0.0)
    s = vb / total
    u = vc / total
    return wp.vec3(1.0 - s - u, s, u)


@wp.func
def may_touch(rules: EdgeRules, v: int, t: wp.vec3i) -> bool:
    """Whether vertex v and triangle t may touch: as edge_collision's pairs, v not one of t's vertices nor
    sewn to one, nor (with a rest rule) of t's cloth and nearer it at rest than the cloth's ``rest_apart``."""
    return may_touch_but_at_rest(rules, v, t) and apart_at_rest(rules, v, t)


@wp.func
def may_touch_but_at_rest(rules: EdgeRules, v: int, t: wp.vec3i) -> bool:
    """``may_touch`` but for the rest rule (``apart_at_rest``), which costs a distance: the lists' gathers
    test it last, on the pairs within reach."""
    if v == t[0] or v == t[1] or v == t[2]:
        return False
    if rules.sewn_offsets.shape[0] > 0:
        for k in range(rules.sewn_offsets[v], rules.sewn_offsets[v + 1]):
            other = rules.sewn_other[k]
            if other == t[0] or other == t[1] or other == t[2]:
                return False
    if rules.world[v] != rules.world[t[0]]:
        return False
    if rules.cloth_id[v] != rules.cloth_id[t[0]]:
        return rules.between_cloths != 0
    return rules.self_collision != 0


@wp.func
def apart_at_rest(rules: EdgeRules, v: int, t: wp.vec3i) -> bool:
    """Whether vertex v and triangle t are no pair of one cloth nearer at rest than its ``rest_apart``."""
    if rules.rest.shape[0] == 0 or rules.cloth_id[v] != rules.cloth_id[t[0]]:
        return True
    rest = rules.rest
    a = rest[t[0]]
    b = rest[t[1]]
    c = rest[t[2]]
    weights = closest_weights(rest[v], a, b, c)
    apart = wp.length(rest[v] - (weights[0] * a + weights[1] * b + weights[2] * c))
    return apart >= rules.rest_apart[rules.cloth_id[v]]


@wp.func
def side_bit(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> int:
    """0 where p lies on the side of triangle a, b, c its normal (b - a) x (c - a) points to, else 1."""
    if wp.dot(p - a, wp.cross(b - a, c - a)) >= 0.0:
        return 0
    return 1


@wp.func
def pair_gap(faces: FaceContacts, vertex: int, code: int, x: wp.array(dtype=wp.vec3)):
    """How far ``vertex`` lies from the triangle ``code`` holds (2 t + side bit) along the direction it is to
    be moved in (below zero once it has crossed to the other side where it projects inside the triangle),
    that direction, and the closest point's barycentric weights."""
    t = faces.triangles[code >> 1]
    side = 1.0 - 2.0 * float(code & 1)
    p = x[vertex]
    a = x[t[0]]
    b = x[t[1]]
    c = x[t[2]]
    weights = closest_weights(p, a, b, c)
    d = p - (weights[0] * a + weights[1] * b + weights[2] * c)
    normal = wp.cross(b - a, c - a)
    has_normal = wp.length_sq(normal) > 0.0
    n = wp.vec3(0.0)
    gap = float(0.0)
    if weights[0] > 0.0 and weights[1] > 0.0 and weights[2] > 0.0 and has_normal:
        n = side * wp.normalize(normal)
        gap = wp.dot(d, n)  # below zero once the vertex has crossed to the other side
    else:
        gap = wp.length(d)
        if gap > 1.0e-6 * faces.thickness:
            n = d / gap
        elif has_normal:
            n = side * wp.normalize(normal)
        else:
            n = wp.normalize(wp.vec3(0.267, 0.535, 0.802))
    return gap, n, weights


@wp.func
def pair_inverse_mass(vertex: int, t: wp.vec3i, weights: wp.vec3, inv_mass: wp.array(dtype=float)) -> float:
    """The pair's inverse mass along its normal: the vertex's and the triangle's, its particles' weighted by
    the squares of the closest point's barycentric ``weights``."""
    return inv_mass[vertex] + weights[0] * weights[0] * inv_mass[t[0]] + weights[1] * weights[1] * inv_mass[t[1]] \
        + weights[2] * weights[2] * inv_mass[t[2]]


@wp.func
def particle_share(i: int, t: wp.vec3i, weights: wp.vec3) -> float:
    """Particle i's share of its pair's move: 1 for the vertex, minus its barycentric weight for a triangle's."""
    share = float(1.0)
    if i == t[0]:
        share = -weights[0]
    elif i == t[1]:
        share = -weights[1]
    elif i == t[2]:
        share = -weights[2]
    return share


@wp.func
def face_push(faces: FaceContacts, i: int, vertex: int, code: int, x: wp.array(dtype=wp.vec3),
              inv_mass: wp.array(dtype=float)):
    """Particle i's move (the vertex or one of the triangle's) out of the pair of ``vertex`` and the triangle
    ``code`` holds (2 t + side bit), and 1 if the two are closer than the thickness (else zero and 0)."""
    gap, n, weights = pair_gap(faces, vertex, code, x)
    if gap >= faces.thickness:
        return wp.vec3(0.0), 0
    t = faces.triangles[code >> 1]
    weight = pair_inverse_mass(vertex, t, weights, inv_mass)
    if weight == 0.0:
        return wp.vec3(0.0), 0
    share = particle_share(i, t, weights)
    return (inv_mass[i] * share * (faces.thickness - gap) / weight) * n, 1


@wp.func
def deepest_face_overlap(faces: FaceContacts, i: int, x: wp.array(dtype=wp.vec3)) -> float:
    """How far vertex i lies inside the thickness of its closest listed triangle, as a fraction of the
    thickness (0 where none): every pair is in its vertex's list, so a check over every particle reads them
    all."""
    worst = float(0.0)
    for c in range(faces.vertex_counts[i]):
        gap, unused_n, unused_weights = pair_gap(faces, i, faces.vertex_faces[i * faces.max_neighbors + c], x)
        worst = wp.max(worst, (faces.thickness - gap) / faces.thickness)
    return worst


@wp.func
def face_pushes(faces: FaceContacts, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                inv_mass: wp.array(dtype=float)) -> wp.vec4:
    """Sum of particle i's moves out of its pairs as a vertex and as a vertex of its triangles (candidates
    first, first + stride, ... of each list), and how many pairs are closer than the thickness (w)."""
    total = wp.vec4(0.0)
    start = i * faces.max_neighbors
    for c in range(first, faces.vertex_counts[i], stride):
        move, close = face_push(faces, i, i, faces.vertex_faces[start + c], x, inv_mass)
        total = total + wp.vec4(move[0], move[1], move[2], float(close))
    for k in range(faces.incident_offsets[i], faces.incident_offsets[i + 1]):
        t = faces.incident[k]
        for c in range(first, faces.face_counts[t], stride):
            code = faces.face_vertices[t * faces.max_neighbors + c]
            move, close = face_push(faces, i, code >> 1, 2 * t + (code & 1), x, inv_mass)
            total = total + wp.vec4(move[0], move[1], move[2], float(close))
    return total


@wp.kernel
def widen_face_cells(x: wp.array(dtype=wp.vec3), triangles: wp.array(dtype=wp.vec3i), rebuild: wp.array(dtype=int),
                     longest: float, thickness: float, widest: wp.array(dtype=float), inv_width: wp.array(dtype=float)):
    """Where ``rebuild`` is set, the face hash's cells widened to the longest triangle side longer than
    ``longest`` plus the largest reach (the thickness plus twice the largest allowance, ``widest[0]``), after
    edge_collision.start_edge_cells set the least width, so that the 27 cells around a vertex hold the first
    vertex of every triangle within reach of it, and those around a triangle's first vertex every vertex
    within reach of the triangle."""
    if rebuild[0] == 0:
        return
    t = triangles[wp.tid()]
    a = x[t[0]]
    b = x[t[1]]
    c = x[t[2]]
    side = wp.max(wp.max(wp.length(b - a), wp.length(c - b)), wp.length(a - c))
    if side > longest:
        wp.atomic_min(inv_width, 0, 1.0 / (side + thickness + 2.0 * widest[0]))


@wp.func
def face_friction(faces: FaceContacts, i: int, vertex: int, code: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3), v_start: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                  coefficient: float, slack: float):
    """Particle i's velocity change (the vertex or one of the triangle's) from friction in the pair of
    ``vertex`` and the triangle ``code`` holds, times its barycentric weight in the pair (1 for the vertex),
    and that weight if the pair touches (within ``slack`` thicknesses), else zero and 0: the pair's relative
    velocity at the closest point loses ``sliding_taken``, each particle taking its barycentric share over the
    pair's inverse mass (as ``face_push``). Summed over a particle's pairs and divided by the weights' sum, a
    pair whose closest point lies near another particle counts little: with a plain mean those pairs' small
    changes diluted the rest, and a sheet on a slope slid as at 0.35 of a 0.5 coefficient."""
    gap, n, weights = pair_gap(faces, vertex, code, x)
    if gap >= slack * faces.thickness:
        return wp.vec3(0.0), 0.0
    t = faces.triangles[code >> 1]
    weight = pair_inverse_mass(vertex, t, weights, inv_mass)
    if weight == 0.0:
        return wp.vec3(0.0), 0.0
    relative = v[vertex] - (weights[0] * v[t[0]] + weights[1] * v[t[1]] + weights[2] * v[t[2]])
    start = v_start[vertex] - (weights[0] * v_start[t[0]] + weights[1] * v_start[t[1]] + weights[2] * v_start[t[2]])
    share = particle_share(i, t, weights)
    return (-inv_mass[i] * share * wp.abs(share) / weight) * sliding_taken(relative, start, n, coefficient), \
        wp.abs(share)
