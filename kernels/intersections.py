"""Diagnostic: count pairs of cloth triangles that pass through each other, with the triangle BVH of a
``wp.Mesh`` as broad phase. Two triangles intersect when an edge of one crosses the interior of the other
(signs of signed volumes in double precision); triangles that share a vertex are mesh neighbours and are
skipped (a vertex as ``welded`` numbers it: the particles a seam sews together are one vertex), and
triangles that only touch or lie in one plane do not cross, so they are not counted (Moller's coplanar
branch reports such neighbours of a flat cloth as overlapping)."""

import warp as wp


@wp.func
def as_double(p: wp.vec3) -> wp.vec3d:
    return wp.vec3d(wp.float64(p[0]), wp.float64(p[1]), wp.float64(p[2]))


@wp.func
def orientation(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, d: wp.vec3d) -> wp.float64:
    """Six times the signed volume of the tetrahedron a, b, c, d."""
    return wp.dot(wp.cross(b - a, c - a), d - a)


@wp.func
def segment_crosses_triangle(p: wp.vec3d, q: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> bool:
    zero = wp.float64(0.0)
    sp = orientation(a, b, c, p)
    sq = orientation(a, b, c, q)
    if (sp > zero and sq > zero) or (sp < zero and sq < zero) or sp == zero or sq == zero:
        return False
    s1 = orientation(p, q, a, b)
    s2 = orientation(p, q, b, c)
    s3 = orientation(p, q, c, a)
    return (s1 > zero and s2 > zero and s3 > zero) or (s1 < zero and s2 < zero and s3 < zero)


@wp.func
def triangles_cross(a0: wp.vec3d, a1: wp.vec3d, a2: wp.vec3d, b0: wp.vec3d, b1: wp.vec3d, b2: wp.vec3d) -> bool:
    return (segment_crosses_triangle(a0, a1, b0, b1, b2) or segment_crosses_triangle(a1, a2, b0, b1, b2)
            or segment_crosses_triangle(a2, a0, b0, b1, b2) or segment_crosses_triangle(b0, b1, a0, a1, a2)
            or segment_crosses_triangle(b1, b2, a0, a1, a2) or segment_crosses_triangle(b2, b0, a0, a1, a2))


@wp.kernel
def count_intersecting_triangles(mesh: wp.uint64, points: wp.array(dtype=wp.vec3),
                                 triangles: wp.array(dtype=int), welded: wp.array(dtype=int),
                                 count: wp.array(dtype=int)):
    t = wp.tid()
    p0 = points[triangles[3 * t]]
    p1 = points[triangles[3 * t + 1]]
    p2 = points[triangles[3 * t + 2]]
    a0 = welded[triangles[3 * t]]
    a1 = welded[triangles[3 * t + 1]]
    a2 = welded[triangles[3 * t + 2]]
    query = wp.mesh_query_aabb(mesh, wp.min(wp.min(p0, p1), p2), wp.max(wp.max(p0, p1), p2))
    u = int(0)
    while wp.mesh_query_aabb_next(query, u):
        if u <= t:
            continue
        b0 = welded[triangles[3 * u]]
        b1 = welded[triangles[3 * u + 1]]
        b2 = welded[triangles[3 * u + 2]]
        if a0 == b0 or a0 == b1 or a0 == b2 or a1 == b0 or a1 == b1 or a1 == b2 or a2 == b0 or a2 == b1 or a2 == b2:
            continue
        if triangles_cross(as_double(p0), as_double(p1), as_double(p2), as_double(points[triangles[3 * u]]),
                           as_double(points[triangles[3 * u + 1]]), as_double(points[triangles[3 * u + 2]])):
            wp.atomic_add(count, 0, 1)
