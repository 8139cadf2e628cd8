"""The spatial hash whose buckets hold every point (kernels/spatial_hash.py's ``Buckets``), for the lists and
distances that a guarantee needs whole: the surface contacts' (face pairs and edge pairs) and the
displacement bounds' own search."""

from __future__ import annotations

import warp as wp

from warp_cloth.kernels import prefix_sum, spatial_hash
from warp_cloth.kernels.spatial_hash import Buckets


class PrefixSum:
    """The exclusive prefix sum of ``size`` ints (kernels/prefix_sum.py), its scratch made once."""

    kernels = [prefix_sum.scan_tiles, prefix_sum.scan_totals, prefix_sum.add_offsets]  # as exclusive launches them

    def __init__(self, size: int, device) -> None:
        self.size, self.device = size, device
        self.tiles = -(-size // prefix_sum.TILE)
        self.pieces = -(-self.tiles // prefix_sum.TOTALS_TILE)  # of the totals, for the one block that scans them
        # a block's threads share its tiles on a GPU; on the CPU a block is one thread (as wp.launch_tiled
        # launches it there: 256 would each scan the whole tile)
        self.lanes, self.totals_lanes = (prefix_sum.TILE, prefix_sum.TOTALS_TILE) if wp.get_device(device).is_cuda \
            else (1, 1)
        self.totals = wp.zeros(self.tiles, dtype=int, device=device)
        self.offsets = wp.zeros(self.tiles, dtype=int, device=device)

    def exclusive(self, values: wp.array, prefix: wp.array) -> None:
        device = self.device
        wp.launch(prefix_sum.scan_tiles, dim=(self.tiles, self.lanes), inputs=[values],
                  outputs=[prefix, self.totals], block_dim=self.lanes, device=device)
        wp.launch(prefix_sum.scan_totals, dim=(1, self.totals_lanes), inputs=[self.totals, self.pieces],
                  outputs=[self.offsets], block_dim=self.totals_lanes, device=device)
        wp.launch(prefix_sum.add_offsets, dim=self.size, inputs=[self.offsets], outputs=[prefix], device=device)


class CountedHash:
    """A hash of ``points`` points in a table of ``table`` buckets (a power of two), its cells' inverse width
    in ``buckets.inv_width``, which a kernel chooses before each ``fill``."""

    kernels = [spatial_hash.empty_buckets, spatial_hash.count_points, *PrefixSum.kernels,
               spatial_hash.place_points]  # as fill launches them

    def __init__(self, points: int, table: int, device) -> None:
        buckets = self.buckets = Buckets()
        buckets.inv_width = wp.zeros(1, dtype=float, device=device)
        buckets.mask = table - 1
        buckets.count = wp.zeros(table, dtype=int, device=device)
        buckets.start = wp.zeros(table, dtype=int, device=device)
        buckets.items = wp.zeros(points, dtype=int, device=device)
        buckets.points = wp.zeros(points, dtype=wp.vec3, device=device)
        buckets.bucket = wp.zeros(points, dtype=int, device=device)
        buckets.rank = wp.zeros(points, dtype=int, device=device)
        self.scan = PrefixSum(table, device)
        self.device = device

    def fill(self, x: wp.array, world: wp.array, rebuild: wp.array) -> None:
        """The points ``x`` (of ``world``) hashed at the cells' chosen width, where ``rebuild[0]`` is set (else
        the last fill stays; the scan then finds the same places)."""
        buckets, device = self.buckets, self.device
        wp.launch(spatial_hash.empty_buckets, dim=buckets.count.shape[0], inputs=[rebuild], outputs=[buckets.count],
                  device=device)
        wp.launch(spatial_hash.count_points, dim=x.shape[0], inputs=[x, world, rebuild, buckets], device=device)
        self.scan.exclusive(buckets.count, buckets.start)
        wp.launch(spatial_hash.place_points, dim=x.shape[0], inputs=[x, rebuild, buckets], device=device)
