"""An exclusive prefix sum of ints made of kernels alone, with no memory allocated while it runs, so that it can
be captured inside a graph's conditional body (cub's scan behind ``wp.utils.array_scan`` allocates its
scratch there, which CUDA refuses): each tile of ``TILE`` values scanned by its block, with its total; the
totals scanned by one block, ``TOTALS_TILE`` at a time; each value's tile's offset added."""

import warp as wp

TILE = 256
TOTALS_TILE = 1024


@wp.kernel
def scan_tiles(values: wp.array(dtype=int), prefix: wp.array(dtype=int), totals: wp.array(dtype=int)):
    """Each tile's exclusive prefix sum, and its total (values past the end read as zero)."""
    tile, _lane = wp.tid()
    loaded = wp.tile_load(values, shape=TILE, offset=tile * TILE)
    wp.tile_store(prefix, wp.tile_scan_exclusive(loaded), offset=tile * TILE)
    wp.tile_store(totals, wp.tile_sum(loaded), offset=tile)


@wp.kernel
def scan_totals(totals: wp.array(dtype=int), pieces: int, offsets: wp.array(dtype=int)):
    """By one block: every tile's offset, the exclusive prefix sum of the tiles' totals, ``pieces`` of
    ``TOTALS_TILE`` at a time."""
    carried = int(0)
    for piece in range(pieces):
        loaded = wp.tile_load(totals, shape=TOTALS_TILE, offset=piece * TOTALS_TILE)
        scanned = wp.tile_scan_exclusive(loaded) + wp.tile_ones(shape=TOTALS_TILE, dtype=int) * carried
        wp.tile_store(offsets, scanned, offset=piece * TOTALS_TILE)
        carried = carried + wp.tile_sum(loaded)[0]


@wp.kernel
def add_offsets(offsets: wp.array(dtype=int), prefix: wp.array(dtype=int)):
    i = wp.tid()
    prefix[i] = prefix[i] + offsets[i / TILE]
