"""The nearest distance of each vertex to the primitives that share no vertex with a primitive of its own and that
the surfaces' contact rule lets touch it (``Primitives.rules``), within a query radius r: each vertex against
the triangles, each edge against the edges (Offset Geometric Contact's d_min, Chen et al. 2025). Each such
pair closer than r lowers ``nearest`` (filled with r before) at every vertex of the pair, so that a vertex's
entry is the least of its own distance to the triangles, that of each of its triangles to the vertices and
that of each of its edges to the edges. kernels/displacement_bounds.py turns it into the vertex's bound;
warp_cloth/displacement_bounds.py launches both.

r is chosen on the device (``query[0]``): the settings' radius, widened where a step is measured so that
gamma r covers the longest motion of a free particle (``widen_to_motion``). Nothing within r of a particle
then bounds it at gamma r, at least its own step: a particle with nothing near takes its whole step, and a
pair found nearer than r bounds its vertices as before.

The pairs are found through a spatial hash of the particles whose buckets hold them all (spatial_hash.py's
``Buckets``), its cells r plus the longest edge wide (``choose_cells``): a triangle within r of a vertex has
every vertex within r + L of it (L its longest edge), so its first vertex is among the 27 cells around the
vertex; an edge within r of another
has an end within r + (l + L) / 2 of the other's midpoint, l the other's length (each closest point lies
within half its segment's length of the middle and of its nearer end), so the 27 cells around the midpoint
hold that end. A triangle is visited
from its first vertex (``owned``), an edge from each of its ends found, each pair of edges from the lower
numbered one's thread.
"""

import warp as wp

from .edge_collision import EdgeRules, closest_points, may_touch
from .face_collision import may_touch as may_touch_face
from .spatial_hash import Buckets, box_gap_sq, cell_of, neighbour_bucket

# The radius a step's longest motion asks for, over motion / gamma: so that gamma times it, rounded, is not
# below the motion and a particle with nothing near is never held short by a rounding.
MOTION_SLACK = wp.constant(1.001)


@wp.struct
class Primitives:
    """A cloth mesh's triangles and edges, and which of their pairs count (``rules``: the surfaces' contact
    rule, warp_cloth/surface_pairs.py)."""
    triangles: wp.array(dtype=wp.vec3i)
    owned_offsets: wp.array(dtype=int)  # (n + 1,) particle i's triangles, those whose first vertex it is, are
    owned: wp.array(dtype=int)  # owned[owned_offsets[i]:owned_offsets[i + 1]]
    ends: wp.array(dtype=wp.vec2i)  # each edge's, once per edge
    edge_offsets: wp.array(dtype=int)  # (n + 1,) particle i's edges are edges_at[edge_offsets[i]:...[i + 1]]
    edges_at: wp.array(dtype=int)
    rules: EdgeRules


@wp.func
def point_segment_distance(p: wp.vec3, a: wp.vec3, b: wp.vec3) -> float:
    ab = b - a
    length_sq = wp.dot(ab, ab)
    t = float(0.0)
    if length_sq > 0.0:
        t = wp.clamp(wp.dot(p - a, ab) / length_sq, 0.0, 1.0)
    return wp.length(p - (a + t * ab))


@wp.func
def point_triangle_distance(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> float:
    """The distance from p to the closed triangle a, b, c: to its plane where p projects inside it, else to
    the nearest of its edges (a triangle of no area has only edges)."""
    n = wp.cross(b - a, c - a)
    area_sq = wp.dot(n, n)
    if area_sq > 0.0:
        inside = (wp.dot(wp.cross(b - a, p - a), n) >= 0.0 and wp.dot(wp.cross(c - b, p - b), n) >= 0.0
                  and wp.dot(wp.cross(a - c, p - c), n) >= 0.0)
        if inside:
            return wp.abs(wp.dot(p - a, n)) / wp.sqrt(area_sq)
    return wp.min(wp.min(point_segment_distance(p, a, b), point_segment_distance(p, b, c)),
                  point_segment_distance(p, c, a))


@wp.func
def segment_distance(p0: wp.vec3, p1: wp.vec3, q0: wp.vec3, q1: wp.vec3) -> float:
    """The distance between the segments p0-p1 and q0-q1, between their closest points (edge_collision's)."""
    st = closest_points(p0, p1, q0, q1)
    return wp.length(p0 + st[0] * (p1 - p0) - (q0 + st[1] * (q1 - q0)))


@wp.kernel
def longest_edge(x: wp.array(dtype=wp.vec3), ends: wp.array(dtype=wp.vec2i), longest: wp.array(dtype=float)):
    """The longest edge's length into ``longest[0]`` (zero before)."""
    e = wp.tid()
    wp.atomic_max(longest, 0, wp.length(x[ends[e][1]] - x[ends[e][0]]))


@wp.kernel
def widen_to_motion(x: wp.array(dtype=wp.vec3), target: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                    gamma: float, radius: wp.array(dtype=float)):
    """Raises ``radius[0]`` so that gamma times it covers the longest step a free particle takes from ``x`` to
    ``target`` (with ``MOTION_SLACK``): a particle no pair is near within it then takes its whole step."""
    i = wp.tid()
    if inv_mass[i] > 0.0:
        wp.atomic_max(radius, 0, MOTION_SLACK * wp.length(target[i] - x[i]) / gamma)


@wp.kernel
def fill_with_radius(radius: wp.array(dtype=float), nearest: wp.array(dtype=float)):
    """Every particle's ``nearest`` at the query radius, before the pairs lower it."""
    nearest[wp.tid()] = radius[0]


@wp.kernel
def choose_cells(radius: wp.array(dtype=float), longest: wp.array(dtype=float), inv_width: wp.array(dtype=float)):
    """By one thread: the hash's cells ``radius`` plus the longest edge wide."""
    inv_width[0] = 1.0 / (radius[0] + longest[0])


@wp.func
def lower_nearest(nearest: wp.array(dtype=float), i: int, d: float):
    wp.atomic_min(nearest, i, d)


@wp.kernel
def nearest_to_triangles(x: wp.array(dtype=wp.vec3), mesh: Primitives, grid: Buckets,
                         query: wp.array(dtype=float), longest: wp.array(dtype=float), nearest: wp.array(dtype=float)):
    """Each vertex against the triangles it is not a vertex of: a pair closer than the query radius
    (``query[0]``) lowers ``nearest`` at its four vertices."""
    v = wp.tid()
    radius = query[0]
    p = x[v]
    world = mesh.rules.world[v]
    reach = radius + longest[0]
    center = cell_of(p, grid.inv_width[0])
    for k in range(27):
        bucket = neighbour_bucket(center, world, k, grid.mask)
        for s in range(grid.count[bucket]):
            q = grid.items[grid.start[bucket] + s]
            if mesh.rules.world[q] == world and wp.length_sq(x[q] - p) < reach * reach:
                for o in range(mesh.owned_offsets[q], mesh.owned_offsets[q + 1]):
                    t = mesh.triangles[mesh.owned[o]]
                    if t[0] != v and t[1] != v and t[2] != v:
                        a = x[t[0]]
                        b = x[t[1]]
                        c = x[t[2]]
                        if box_gap_sq(p, p, wp.min(wp.min(a, b), c), wp.max(wp.max(a, b), c)) < radius * radius:
                            d = point_triangle_distance(p, a, b, c)
                            if d < radius and may_touch_face(mesh.rules, v, t):
                                lower_nearest(nearest, v, d)
                                lower_nearest(nearest, t[0], d)
                                lower_nearest(nearest, t[1], d)
                                lower_nearest(nearest, t[2], d)


@wp.kernel
def nearest_between_edges(x: wp.array(dtype=wp.vec3), mesh: Primitives, grid: Buckets,
                          query: wp.array(dtype=float), longest: wp.array(dtype=float), nearest: wp.array(dtype=float)):
    """Each edge against the higher numbered edges it shares no vertex with: a pair closer than the query
    radius (``query[0]``) lowers ``nearest`` at its four vertices."""
    e = wp.tid()
    radius = query[0]
    a = mesh.ends[e][0]
    b = mesh.ends[e][1]
    pa = x[a]
    pb = x[b]
    middle = 0.5 * (pa + pb)
    world = mesh.rules.world[a]
    reach = radius + 0.5 * (wp.length(pb - pa) + longest[0])
    center = cell_of(middle, grid.inv_width[0])
    for k in range(27):
        bucket = neighbour_bucket(center, world, k, grid.mask)
        for s in range(grid.count[bucket]):
            c = grid.items[grid.start[bucket] + s]
            if mesh.rules.world[c] == world and wp.length_sq(x[c] - middle) < reach * reach:
                for o in range(mesh.edge_offsets[c], mesh.edge_offsets[c + 1]):
                    f = mesh.edges_at[o]
                    if f > e:
                        g = mesh.ends[f][0]
                        h = mesh.ends[f][1]
                        if g != a and g != b and h != a and h != b:
                            pg = x[g]
                            ph = x[h]
                            # from its second end only where its first is out of reach (else found from there)
                            if c == g or wp.length_sq(pg - middle) >= reach * reach:
                                if box_gap_sq(wp.min(pa, pb), wp.max(pa, pb), wp.min(pg, ph),
                                              wp.max(pg, ph)) < radius * radius:
                                    d = segment_distance(pa, pb, pg, ph)
                                    if d < radius and may_touch(mesh.rules, mesh.ends[e], mesh.ends[f]):
                                        lower_nearest(nearest, a, d)
                                        lower_nearest(nearest, b, d)
                                        lower_nearest(nearest, g, d)
                                        lower_nearest(nearest, h, d)
