"""A spatial hash of points (particles, contact edges' midpoints), built from kernels alone so that it can be
remade inside a captured graph: cells of a given width are hashed (Teschner et al. 2003) into a power-of-two
table of buckets. Cells are hashed in blocks of 2 x 2 x 2 to runs of 8 buckets, so that the 27 cells around a
point lie in at most 8 runs of the table, not 27 scattered places (a table of 4M particles' buckets outgrows a
GPU's L2 cache). A query visits the 27 cells around a point; points from other cells in a bucket are
candidates like any other (callers test the distance), and a bucket that two of the 27 cells share is visited
at the first of them (``first_visit``). A query within a known reach of a point or a box visits only the cells
within that reach of it (``cell_within``). Each world of a batch (warp_cloth/batch.py) hashes its cells apart
from the others' (its number mixed into the hash), so that worlds simulated in one place do not crowd each
other's buckets.

Two kinds of bucket. The particle contacts' have a fixed capacity (``insert_points``), each point appended
to its cell's bucket, those past it counted as dropped; a bucket's size is stamped with the epoch of the table
it belongs to (the caller counts epochs up), so a new table needs no clearing: a bucket whose stamp is not
the current epoch's is empty (stamps keep the epoch's low 24 bits; a bucket left untouched for 2^24 epochs
would read as filled again). The surface contacts' and the displacement bounds' (``Buckets``) hold every
point, at cells a kernel chose at the fill.
"""

import warp as wp


@wp.func
def cell_of(p: wp.vec3, inv_width: float) -> wp.vec3i:
    return wp.vec3i(int(wp.floor(p[0] * inv_width)), int(wp.floor(p[1] * inv_width)), int(wp.floor(p[2] * inv_width)))


WORLD_MIX = wp.constant(wp.uint32(2654435761))  # typed: as a plain literal it compiles as an int32, with a warning


@wp.func
def bucket_of(cell: wp.vec3i, world: int, mask: int) -> int:
    """The cell's bucket in ``world``: its 2 x 2 x 2 block's run of 8 (``mask`` + 1, the table size, a power
    of two of at least 8), then its place in the block."""
    h = (wp.uint32(cell[0] >> 1) * wp.uint32(73856093)) ^ (wp.uint32(cell[1] >> 1) * wp.uint32(19349663)) ^ (
        wp.uint32(cell[2] >> 1) * wp.uint32(83492791)) ^ (wp.uint32(world) * WORLD_MIX)
    within = (cell[0] & 1) | ((cell[1] & 1) << 1) | ((cell[2] & 1) << 2)
    return int(h & wp.uint32(mask >> 3)) * 8 + within


@wp.func
def cell_offset(k: int) -> wp.vec3i:
    """The k-th (0..26) cell of a 3x3x3 block, from its center."""
    return wp.vec3i(k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1)


@wp.func
def neighbour_bucket(center: wp.vec3i, world: int, k: int, mask: int) -> int:
    """The bucket of the k-th (0..26) cell of the 3x3x3 block around ``center`` in ``world``."""
    return bucket_of(center + cell_offset(k), world, mask)


@wp.func
def box_gap_sq(lo_a: wp.vec3, hi_a: wp.vec3, lo_b: wp.vec3, hi_b: wp.vec3) -> float:
    """The squared distance between two axis-aligned boxes, a lower bound of their contents' (a cheap test
    that rejects most neighbours of a layer, which lie side by side in it)."""
    gap = wp.max(wp.max(lo_b - hi_a, lo_a - hi_b), wp.vec3(0.0))
    return wp.dot(gap, gap)


@wp.func
def cell_within(cell: wp.vec3i, width: float, low: wp.vec3, high: wp.vec3, reach_sq: float) -> bool:
    """Whether the cell (of ``width``) lies within the reach of the box from ``low`` to ``high`` (a point where
    they are equal): a cell out of reach holds no point a query within it looks for. Its box is widened by
    far more than the rounding of ``cell_of``'s floor, which grows with the distance from the origin."""
    corner = wp.vec3(float(cell[0]), float(cell[1]), float(cell[2])) * width
    farthest = wp.max(wp.max(wp.abs(cell[0]), wp.abs(cell[1])), wp.abs(cell[2]))
    margin = 1.0e-5 * float(farthest + 1) * width
    return box_gap_sq(corner - wp.vec3(margin), corner + wp.vec3(width + margin), low, high) < reach_sq


@wp.func
def first_visit(center: wp.vec3i, world: int, k: int, bucket: int, mask: int) -> bool:
    """Whether no cell before the k-th of the 27 around ``center`` hashes to ``bucket`` (so that a query
    visits each bucket once)."""
    return first_visit_within(center, world, k, bucket, mask, 1.0, wp.vec3(0.0), wp.vec3(0.0), 1.0e30)


@wp.func
def first_visit_within(center: wp.vec3i, world: int, k: int, bucket: int, mask: int, width: float,
                       low: wp.vec3, high: wp.vec3, reach_sq: float) -> bool:
    """Whether no cell before the k-th of the 27 around ``center`` that a query within the reach visits
    (``cell_within``) hashes to ``bucket``. Two cells share a bucket only where their places in the block
    (their coordinates' parities) agree, so the only cells to compare are the earlier ones among the k-th
    with some of its -1 and +1 offsets turned over (at most 7; all 26 earlier cells were hashed before)."""
    offset = cell_offset(k)
    moving = int(0)
    for axis in range(3):
        if offset[axis] != 0:
            moving = moving | (1 << axis)
    turned = moving
    while turned != 0:
        other = wp.vec3i(offset[0], offset[1], offset[2])
        for axis in range(3):
            if (turned >> axis) & 1 != 0:
                other[axis] = -other[axis]
        if (other[0] + 1) + 3 * (other[1] + 1) + 9 * (other[2] + 1) < k:
            if bucket_of(center + other, world, mask) == bucket:
                if cell_within(center + other, width, low, high, reach_sq):
                    return False
        turned = (turned - 1) & moving
    return True


COUNT_BITS = 7  # a bucket's size: its stamp above these bits, its count (up to the capacity) in them
COUNT_MASK = (1 << COUNT_BITS) - 1
EPOCH_MASK = (1 << 24) - 1


@wp.func
def stamp_of(epoch: int) -> int:
    return (epoch & wp.static(EPOCH_MASK)) << wp.static(COUNT_BITS)


@wp.func
def count_in(size: int, stamp: int) -> int:
    """The count a bucket's ``size`` holds in the table of ``stamp`` (0 if stamped otherwise)."""
    if (size >> wp.static(COUNT_BITS)) != (stamp >> wp.static(COUNT_BITS)):
        return 0
    return size & wp.static(COUNT_MASK)


@wp.func
def claim_slot(bucket_size: wp.array(dtype=int), bucket: int, stamp: int, capacity: int) -> int:
    """The next free slot of the bucket in the table of ``stamp`` (-1 where the bucket is full)."""
    size = bucket_size[bucket]
    while True:
        count = count_in(size, stamp)
        if count >= capacity:
            return -1
        seen = wp.atomic_cas(bucket_size, bucket, size, stamp | (count + 1))
        if seen == size:
            return count
        size = seen
    return -1  # not reached; the generated C++ function still needs a return after its loop


# A count of dropped candidates stops here, so that a long run's count never wraps past int32's range (the
# stacked drape at 128^2 wrapped it, and its summary read a negative count).
DROPPED_MOST = wp.constant(1 << 30)


@wp.func
def count_dropped(dropped: wp.array(dtype=int)):
    """One more candidate dropped (a full bucket or list), the count staying at ``DROPPED_MOST`` once there
    (within a few of it: threads may read it below at once)."""
    if dropped[0] < DROPPED_MOST:
        wp.atomic_add(dropped, 0, 1)


@wp.func
def insert_point(i: int, p: wp.vec3, world: int, inv_width: float, mask: int, capacity: int, stamp: int,
                 bucket_size: wp.array(dtype=int), bucket_items: wp.array(dtype=int), overflow: wp.array(dtype=int)):
    bucket = bucket_of(cell_of(p, inv_width), world, mask)
    slot = claim_slot(bucket_size, bucket, stamp, capacity)
    if slot >= 0:
        bucket_items[bucket * capacity + slot] = i
    else:
        count_dropped(overflow)


@wp.kernel
def insert_points(x: wp.array(dtype=wp.vec3), world: wp.array(dtype=int), inv_width: float, mask: int, capacity: int,
                  epoch: wp.array(dtype=int), rebuild: wp.array(dtype=int), bucket_size: wp.array(dtype=int),
                  bucket_items: wp.array(dtype=int), overflow: wp.array(dtype=int)):
    """Fills the table of the current epoch, where ``rebuild`` is set (else does nothing)."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    insert_point(i, x[i], world[i], inv_width, mask, capacity, stamp_of(epoch[0]), bucket_size, bucket_items,
                 overflow)


# Buckets that hold every point, for the surface contacts' lists and the bounds' distances, whose guarantee
# needs every pair within reach: a kernel counts each bucket's points, a scan of the counts places the buckets
# in one array, and a kernel puts each point at its place. Their cells are as wide as the reach, which follows
# the step's motion: at seed_default's 4 mm thickness, a 2.9 m query radius made 4.4 m cells whose fullest
# buckets held more than the fixed room of 127 edges, and 164 edges left out of every list let two pairs
# cross under the bounds (docs/notebook/layers.md).


@wp.struct
class Buckets:
    """A spatial hash whose buckets hold every point, filled by ``empty_buckets``, ``count_points``, an
    exclusive scan of ``count`` into ``start`` and ``place_points``; bucket b's points are
    ``items[start[b]:start[b] + count[b]]``."""
    inv_width: wp.array(dtype=float)  # (1,) its cells' inverse width, chosen by a kernel before each fill
    mask: int  # the table's size - 1
    count: wp.array(dtype=int)  # (table,)
    start: wp.array(dtype=int)  # (table,)
    items: wp.array(dtype=int)  # (points,)
    points: wp.array(dtype=wp.vec3)  # (points,) the items' positions, in the items' order: read in a row
    bucket: wp.array(dtype=int)  # (points,) each point's bucket, while the hash is filled
    rank: wp.array(dtype=int)  # (points,) each point's place in its bucket, while the hash is filled


@wp.kernel
def empty_buckets(rebuild: wp.array(dtype=int), count: wp.array(dtype=int)):
    """Every bucket's count zeroed, where ``rebuild`` is set (else the last fill's counts stay)."""
    if rebuild[0] != 0:
        count[wp.tid()] = 0


@wp.kernel
def count_points(x: wp.array(dtype=wp.vec3), world: wp.array(dtype=int), rebuild: wp.array(dtype=int),
                 buckets: Buckets):
    """Each point's bucket and its place there, counted, where ``rebuild`` is set."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    bucket = bucket_of(cell_of(x[i], buckets.inv_width[0]), world[i], buckets.mask)
    buckets.bucket[i] = bucket
    buckets.rank[i] = wp.atomic_add(buckets.count, bucket, 1)


@wp.func
def place_of(buckets: Buckets, i: int) -> int:
    """Point i's place in ``items``, after the scan of the counts."""
    return buckets.start[buckets.bucket[i]] + buckets.rank[i]


@wp.kernel
def place_points(x: wp.array(dtype=wp.vec3), rebuild: wp.array(dtype=int), buckets: Buckets):
    """Each point, and its position, at its place, after the scan of the counts, where ``rebuild`` is set."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    slot = place_of(buckets, i)
    buckets.items[slot] = i
    buckets.points[slot] = x[i]


@wp.kernel
def place_values(values: wp.array(dtype=wp.vec3), rebuild: wp.array(dtype=int), buckets: Buckets,
                 placed: wp.array(dtype=wp.vec3)):
    """Each point's value at its place, as ``place_points`` puts its position, where ``rebuild`` is set: for
    a gather to read in a row beside the positions."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    placed[place_of(buckets, i)] = values[i]
