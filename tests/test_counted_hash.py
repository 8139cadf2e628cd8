"""The spatial hash whose buckets hold every point (warp_cloth/counted_hash.py): its prefix sum against numpy's,
every point in its cell's bucket however many share it, and (on a GPU) its fill captured inside a graph's
conditional body, where the surface lists are remade."""

import numpy as np
import pytest
import warp as wp

from warp_cloth.counted_hash import CountedHash, PrefixSum
from warp_cloth.kernels import spatial_hash

DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("size", [1, 255, 256, 257, 300_001])  # the last: more tiles than one piece of totals
def test_the_prefix_sum_is_numpys(device, size):
    values = np.random.default_rng(size).integers(0, 9, size).astype(np.int32)
    prefix = wp.zeros(size, dtype=int, device=device)
    PrefixSum(size, device).exclusive(wp.array(values, dtype=int, device=device), prefix)
    np.testing.assert_array_equal(prefix.numpy(), np.concatenate([[0], np.cumsum(values)[:-1]]))


def bucket_contents(hash: CountedHash) -> dict[int, list[int]]:
    buckets = hash.buckets
    count, start, items = buckets.count.numpy(), buckets.start.numpy(), buckets.items.numpy()
    return {b: sorted(items[start[b]:start[b] + count[b]]) for b in np.flatnonzero(count)}


@pytest.mark.parametrize("device", DEVICES)
def test_every_point_is_in_its_cells_bucket_however_many_share_it(device):
    """1,000 points in one cell and 2,000 scattered over a 10-cell cube: each bucket holds exactly the points
    whose cells hash to it (a bucket of fixed room held 127 edges or 64 particles, and dropped the rest).
    Not asked to remake, the hash keeps its last fill."""
    rng = np.random.default_rng(1)
    points = np.concatenate([rng.uniform(0.1, 0.9, (1000, 3)), rng.uniform(-5.0, 5.0, (2000, 3))]).astype(np.float32)
    world = np.zeros(len(points), dtype=np.int32)
    hash = CountedHash(len(points), 1024, device)
    hash.buckets.inv_width.fill_(1.0)
    x = wp.array(points, dtype=wp.vec3, device=device)
    hash.fill(x, wp.array(world, dtype=int, device=device), wp.ones(1, dtype=int, device=device))
    cells = np.floor(points).astype(np.int32)
    expected: dict[int, list[int]] = {}
    for i, bucket in enumerate(bucket_of(cells, 1023, device)):
        expected.setdefault(int(bucket), []).append(i)
    assert bucket_contents(hash) == expected
    assert max(len(items) for items in expected.values()) >= 1000
    hash.fill(wp.array(points[::-1].copy(), dtype=wp.vec3, device=device), wp.array(world, dtype=int, device=device),
              wp.zeros(1, dtype=int, device=device))
    assert bucket_contents(hash) == expected


@wp.kernel
def buckets_of(cells: wp.array(dtype=wp.vec3i), mask: int, bucket: wp.array(dtype=int)):
    i = wp.tid()
    bucket[i] = spatial_hash.bucket_of(cells[i], 0, mask)


def bucket_of(cells: np.ndarray, mask: int, device) -> np.ndarray:
    out = wp.zeros(len(cells), dtype=int, device=device)
    wp.launch(buckets_of, dim=len(cells), inputs=[wp.array(cells, dtype=wp.vec3i, device=device), mask], outputs=[out],
              device=device)
    return out.numpy()


@wp.kernel
def count_down(left: wp.array(dtype=int)):
    left[0] = left[0] - 1


@pytest.mark.cuda
def test_a_fill_is_captured_inside_a_conditional_graph_body():
    """The limit solve's and the substep loop's conditional bodies remake the surface lists: a fill there
    allocates nothing (cub's scan did, and CUDA refused the capture)."""
    device = "cuda"
    points = np.random.default_rng(2).uniform(-2.0, 2.0, (5000, 3)).astype(np.float32)
    hash = CountedHash(len(points), 4096, device)
    hash.buckets.inv_width.fill_(1.0)
    x = wp.array(points, dtype=wp.vec3, device=device)
    world, rebuild = wp.zeros(len(points), dtype=int, device=device), wp.ones(1, dtype=int, device=device)
    left = wp.array([2], dtype=int, device=device)

    def body():
        hash.fill(x, world, rebuild)
        wp.launch(count_down, dim=1, outputs=[left], device=device)

    with wp.ScopedCapture(device=device) as capture:
        wp.capture_while(left, body)
    wp.capture_launch(capture.graph)
    assert int(left.numpy()[0]) == 0
    expected: dict[int, list[int]] = {}
    for i, bucket in enumerate(bucket_of(np.floor(points).astype(np.int32), 4095, device)):
        expected.setdefault(int(bucket), []).append(i)
    assert bucket_contents(hash) == expected
