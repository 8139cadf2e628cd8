"""A spatial hash of particles, built from kernels alone so that it can be rebuilt inside a conditional
node of a captured graph: cells of a given width are hashed (Teschner et al. 2003) into a power-of-two table
of buckets of fixed capacity, and each particle is appended to its cell's bucket. Cells are hashed in
blocks of 2 x 2 x 2 to runs of 8 buckets, so that the 27 cells around a point lie in at most 8 runs of the
table, not 27 scattered places (a table of 4M particles' buckets outgrows a GPU's L2 cache). A query visits the 27
cells around a point; points from other cells in a bucket are candidates like any other (callers test the
distance), and a bucket that two of the 27 cells share is visited twice (callers drop the repeats)."""

import warp as wp


@wp.func
def cell_of(p: wp.vec3, inv_width: float) -> wp.vec3i:
    return wp.vec3i(int(wp.floor(p[0] * inv_width)), int(wp.floor(p[1] * inv_width)), int(wp.floor(p[2] * inv_width)))


@wp.func
def bucket_of(cell: wp.vec3i, mask: int) -> int:
    """The cell's bucket: its 2 x 2 x 2 block's run of 8 (``mask`` + 1, the table size, a power of two of
    at least 8), then its place in the block."""
    h = (wp.uint32(cell[0] >> 1) * wp.uint32(73856093)) ^ (wp.uint32(cell[1] >> 1) * wp.uint32(19349663)) ^ (
        wp.uint32(cell[2] >> 1) * wp.uint32(83492791))
    within = (cell[0] & 1) | ((cell[1] & 1) << 1) | ((cell[2] & 1) << 2)
    return int(h & wp.uint32(mask >> 3)) * 8 + within


@wp.func
def neighbour_bucket(center: wp.vec3i, k: int, mask: int) -> int:
    """The bucket of the k-th (0..26) cell of the 3x3x3 block around ``center``."""
    return bucket_of(center + wp.vec3i(k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1), mask)


@wp.kernel
def insert_points(x: wp.array(dtype=wp.vec3), inv_width: float, mask: int, capacity: int,
                  bucket_size: wp.array(dtype=int), bucket_items: wp.array(dtype=int), overflow: wp.array(dtype=int)):
    i = wp.tid()
    bucket = bucket_of(cell_of(x[i], inv_width), mask)
    slot = wp.atomic_add(bucket_size, bucket, 1)
    if slot < capacity:
        bucket_items[bucket * capacity + slot] = i
    else:
        wp.atomic_add(overflow, 0, 1)
