"""The displacement bounds' nearest distances (primitive_distances.py's d_min) read off the surface contacts'
candidate lists instead of a search of their own: each vertex's triangles, each triangle's vertices and each
edge's edges, as the lists hold them, at the positions ``x`` (where the substep started).

Where the lists are made and kept so that every pair left out lies farther apart than the thickness plus
twice the largest bound of the substep (surface_reach.py), a pair left out cannot come near enough in the
substep to need a lower bound, and a full list keeps the nearest pairs (candidate_lists.py), so a vertex's
least distance over its lists is its least over every pair that matters. Each vertex's own list sets its
``nearest`` (at most the query radius), then each triangle's and each edge's list lowers it at their
vertices; a pair is in both its sides' lists, or the side that left it out holds nearer ones."""

import warp as wp

from .edge_collision import EdgeContacts
from .face_collision import FaceContacts
from .primitive_distances import lower_nearest, point_triangle_distance, segment_distance


@wp.kernel
def nearest_listed_triangles(x: wp.array(dtype=wp.vec3), faces: FaceContacts, query: wp.array(dtype=float),
                             nearest: wp.array(dtype=float)):
    """Each vertex's least distance to the triangles its list holds (entries 2 t + side), at most the query
    radius (``query[0]``): the first of the three, which sets ``nearest``."""
    v = wp.tid()
    p = x[v]
    start = v * faces.max_neighbors
    d = query[0]
    for k in range(faces.vertex_counts[v]):
        t = faces.triangles[faces.vertex_faces[start + k] >> 1]
        d = wp.min(d, point_triangle_distance(p, x[t[0]], x[t[1]], x[t[2]]))
    nearest[v] = d


@wp.kernel
def nearest_listed_vertices(x: wp.array(dtype=wp.vec3), faces: FaceContacts, nearest: wp.array(dtype=float)):
    """Each triangle's least distance to the vertices its list holds (entries 2 v + side), at its three
    vertices."""
    i = wp.tid()
    t = faces.triangles[i]
    a = x[t[0]]
    b = x[t[1]]
    c = x[t[2]]
    start = i * faces.max_neighbors
    d = float(1.0e30)
    for k in range(faces.face_counts[i]):
        d = wp.min(d, point_triangle_distance(x[faces.face_vertices[start + k] >> 1], a, b, c))
    lower_nearest(nearest, t[0], d)
    lower_nearest(nearest, t[1], d)
    lower_nearest(nearest, t[2], d)


@wp.kernel
def nearest_listed_edges(x: wp.array(dtype=wp.vec3), edges: EdgeContacts, nearest: wp.array(dtype=float)):
    """Each edge's least distance to the edges its list holds, at its two ends."""
    e = wp.tid()
    ends = edges.ends[e]
    p = x[ends[0]]
    q = x[ends[1]]
    start = e * edges.max_neighbors
    d = float(1.0e30)
    for k in range(edges.counts[e]):
        other = edges.ends[edges.neighbors[start + k]]
        d = wp.min(d, segment_distance(p, q, x[other[0]], x[other[1]]))
    lower_nearest(nearest, ends[0], d)
    lower_nearest(nearest, ends[1], d)
