"""Neighbour lists of particles, of contact edges and of vertex-triangle pairs, gathered from spatial hashes
(spatial_hash.py): the candidates particle_collision.py, edge_collision.py and face_collision.py allow.
warp_cloth/neighbour_lists.py and warp_cloth/face_contacts.py run them.
"""

import functools

import warp as wp

from .candidate_lists import insert_keeping_gaps
from .edge_collision import EdgeContacts, EdgeRules, apart_at_rest, may_touch_but_at_rest, pair_gap
from .face_collision import FaceContacts, side_bit
from .face_collision import apart_at_rest as apart_at_rest_face
from .face_collision import may_touch_but_at_rest as may_touch_face_but_at_rest
from .gathering import BLOCK, FAST_MATH, sum_over_threads, thread_layout
from .particle_collision import (Contacts, ListState, PairRules, add_candidate, is_candidate,
                                 sort_and_drop_repeats)
from .primitive_distances import point_triangle_distance
from .surface_reach import edge_allowance, triangle_allowance
from .spatial_hash import (Buckets, box_gap_sq, cell_of, cell_offset, cell_within, count_in, first_visit,
                           first_visit_within, neighbour_bucket, stamp_of)

wp.set_module_options(FAST_MATH)

# The edge and face gathers reject a candidate that a cheap bound (its midpoint's or first vertex's distance,
# its box's) puts out of reach before its exact test, which costs several times more; a bound rejects only
# this factor past it, so that float32's rounding (far below 1%) leaves every pair at the reach to the exact
# test alone and the lists as they were without the bounds.
BOX_SLACK = wp.constant(1.01)


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
                           allowance: wp.array(dtype=float), widest: wp.array(dtype=float), buckets: Buckets,
                           half_extents: wp.array(dtype=wp.vec3), gaps: wp.array(dtype=float),
                           dropped: wp.array(dtype=int)):
    """Each edge's candidates from the hash of its midpoint's 27 cells (each bucket once; ``buckets.inv_width``
    the cells' inverse width this remake), where ``rebuild`` is set: edges that may touch it whose segments
    lie within the thickness plus both edges' allowances (surface_reach.py; ``widest[0]`` the largest)
    (``pair_gap``: each lists the other; the nearest where more than fit, the others counted in
    ``dropped``, their gaps kept in ``gaps`` meanwhile, laid out as the lists), in index order. Each
    candidate's box is its midpoint (``buckets.points``) -+ its half extent (``half_extents``, in the buckets'
    order), both read in a row, so that an edge out of reach costs no look-up of its ends."""
    if lists.rebuild[0] == 0:
        return
    e = wp.tid()
    ends_e = edges.ends[e]
    middle = midpoint[e]
    center = cell_of(middle, buckets.inv_width[0])
    world = edge_world[e]
    start = e * edges.max_neighbors
    p = x[ends_e[0]]
    q = x[ends_e[1]]
    low = wp.min(p, q)
    high = wp.max(p, q)
    own = edges.thickness + edge_allowance(allowance, ends_e)
    reach = own + widest[0]
    box_reach_sq = (BOX_SLACK * reach) * (BOX_SLACK * reach)
    # an edge within reach has its midpoint within half of both lengths plus the reach, and no edge is longer
    # than the cells' width less the reach
    width = 1.0 / buckets.inv_width[0]
    near = BOX_SLACK * 0.5 * (wp.length(q - p) + width + reach)
    cells_reach_sq = (BOX_SLACK * near) * (BOX_SLACK * near)
    count = int(0)
    for k in range(27):
        if not cell_within(center + cell_offset(k), width, middle, middle, cells_reach_sq):
            continue
        bucket = neighbour_bucket(center, world, k, buckets.mask)
        if first_visit_within(center, world, k, bucket, buckets.mask, width, middle, middle, cells_reach_sq):
            first = buckets.start[bucket]
            for s in range(buckets.count[bucket]):
                middle_f = buckets.points[first + s]
                half_f = half_extents[first + s]
                if box_gap_sq(low, high, middle_f - half_f, middle_f + half_f) < box_reach_sq:
                    f = buckets.items[first + s]
                    ends_f = edges.ends[f]
                    if f != e and may_touch_but_at_rest(rules, ends_e, ends_f):
                        gap = pair_gap(edges.ends, x, e, f)
                        within = gap < own + edge_allowance(allowance, ends_f)
                        if within and apart_at_rest(rules, ends_e, ends_f):
                            count = insert_keeping_gaps(edges.neighbors, start, count, edges.max_neighbors, f,
                                                        gap, dropped, gaps)
    edges.counts[e] = sort_and_drop_repeats(edges.neighbors, start, count)


@wp.kernel
def gather_vertex_faces(x: wp.array(dtype=wp.vec3), faces: FaceContacts, rules: EdgeRules, lists: ListState,
                        allowance: wp.array(dtype=float), widest: wp.array(dtype=float),
                        owned_offsets: wp.array(dtype=int), owned: wp.array(dtype=int), buckets: Buckets,
                        gaps: wp.array(dtype=float), dropped: wp.array(dtype=int)):
    """Each vertex's candidate triangles at positions ``x``, where ``rebuild`` is set: those it may touch
    within the thickness plus the vertex's and the triangle's allowances (surface_reach.py; ``widest[0]`` the
    largest) (the nearest where more than fit, the others counted in ``dropped``, their gaps kept in ``gaps``
    meanwhile), as 2 t + the side it lies on, in index order. The hash holds the particles (cells of inverse
    width ``buckets.inv_width[0]``, wider than the largest reach plus any triangle's side), each triangle found
    from its first vertex (``owned``)."""
    if lists.rebuild[0] == 0:
        return
    v = wp.tid()
    p = x[v]
    center = cell_of(p, buckets.inv_width[0])
    world = rules.world[v]
    start = v * faces.max_neighbors
    width = 1.0 / buckets.inv_width[0]
    near = BOX_SLACK * width  # a triangle within reach has its first vertex within reach plus its side
    own = faces.thickness + allowance[v]
    box_reach = BOX_SLACK * (own + widest[0])
    box_reach_sq = box_reach * box_reach
    cells_reach_sq = (BOX_SLACK * near) * (BOX_SLACK * near)
    count = int(0)
    for k in range(27):
        if not cell_within(center + cell_offset(k), width, p, p, cells_reach_sq):
            continue
        bucket = neighbour_bucket(center, world, k, buckets.mask)
        if first_visit_within(center, world, k, bucket, buckets.mask, width, p, p, cells_reach_sq):
            first = buckets.start[bucket]
            for s in range(buckets.count[bucket]):
                if wp.length_sq(buckets.points[first + s] - p) < near * near:
                    q = buckets.items[first + s]
                    for o in range(owned_offsets[q], owned_offsets[q + 1]):
                        t_index = owned[o]
                        t = faces.triangles[t_index]
                        a = x[t[0]]
                        b = x[t[1]]
                        c = x[t[2]]
                        if box_gap_sq(p, p, wp.min(wp.min(a, b), c), wp.max(wp.max(a, b), c)) < box_reach_sq:
                            if may_touch_face_but_at_rest(rules, v, t):
                                gap = point_triangle_distance(p, a, b, c)
                                within = gap < own + triangle_allowance(allowance, t)
                                if within and apart_at_rest_face(rules, v, t):
                                    count = insert_keeping_gaps(faces.vertex_faces, start, count, faces.max_neighbors,
                                                                2 * t_index + side_bit(p, a, b, c), gap,
                                                                dropped, gaps)
    faces.vertex_counts[v] = sort_and_drop_repeats(faces.vertex_faces, start, count)


@wp.kernel
def gather_face_vertices(x: wp.array(dtype=wp.vec3), faces: FaceContacts, rules: EdgeRules, lists: ListState,
                         allowance: wp.array(dtype=float), widest: wp.array(dtype=float), buckets: Buckets,
                         gaps: wp.array(dtype=float), dropped: wp.array(dtype=int)):
    """Each triangle's candidate vertices, where ``rebuild`` is set: the pairs ``gather_vertex_faces`` lists,
    seen from the triangle (the same test on the same positions), as 2 v + the side v lies on, in index
    order; found in the 27 cells around the triangle's first vertex."""
    if lists.rebuild[0] == 0:
        return
    t_index = wp.tid()
    t = faces.triangles[t_index]
    a = x[t[0]]
    b = x[t[1]]
    c = x[t[2]]
    center = cell_of(a, buckets.inv_width[0])
    world = rules.world[t[0]]
    start = t_index * faces.max_neighbors
    low = wp.min(wp.min(a, b), c)
    high = wp.max(wp.max(a, b), c)
    own = faces.thickness + triangle_allowance(allowance, t)
    box_reach = BOX_SLACK * (own + widest[0])
    box_reach_sq = box_reach * box_reach
    width = 1.0 / buckets.inv_width[0]
    cells_reach_sq = (BOX_SLACK * box_reach) * (BOX_SLACK * box_reach)
    count = int(0)
    for k in range(27):
        if not cell_within(center + cell_offset(k), width, low, high, cells_reach_sq):
            continue
        bucket = neighbour_bucket(center, world, k, buckets.mask)
        if first_visit_within(center, world, k, bucket, buckets.mask, width, low, high, cells_reach_sq):
            first = buckets.start[bucket]
            for s in range(buckets.count[bucket]):
                p = buckets.points[first + s]
                if box_gap_sq(p, p, low, high) < box_reach_sq:
                    v = buckets.items[first + s]
                    if may_touch_face_but_at_rest(rules, v, t):
                        gap = point_triangle_distance(p, a, b, c)
                        if gap < own + allowance[v] and apart_at_rest_face(rules, v, t):
                            count = insert_keeping_gaps(faces.face_vertices, start, count, faces.max_neighbors,
                                                        2 * v + side_bit(p, a, b, c), gap, dropped, gaps)
    faces.face_counts[t_index] = sort_and_drop_repeats(faces.face_vertices, start, count)
