"""Several threads ("lanes") per particle for the kernels that gather over a particle's springs, limits or
contacts.

A small cloth has too few particles to fill a GPU: with a thread per particle, 4096 threads run on 16 of
an H200's 132 multiprocessors, and a kernel takes as long as one thread's chain of dependent loads and
arithmetic over its 12 springs. With ``lanes`` threads per particle, lane s of particle i takes its
incidences s, s + lanes, ..., and a tile sum along the lane axis adds the lanes' parts (``per_block``
particles to a block of ``per_block * lanes`` threads). Lane 0 then finishes the particle as the
one-thread kernel does. The kernels' factories take (lanes, block) and are compiled on first use.

The sum's order differs from the one-thread loop's, so results differ by rounding; it is fixed for a
given (lanes, block), so runs stay deterministic. Tiles need a GPU (a CPU block has one thread), and
on the CPU the one-thread kernels run.

FAST_MATH: the kernels of the explicit step, the strain limit, the colliders and particle collision compile
for CUDA with fast math (division and square root to within 2 ulp, denormals flushed to zero), which
took 8-31 % off the spring kernel on an H200, least at 1024^2, in two runs of tools/lanes_probe.py; the
CPU build ignores it. Not for kernels with sines (pins, sphere motion), whose fast form loses accuracy as the clock's
argument grows.
"""

import functools
from typing import Any

import warp as wp

FAST_MATH = {"fast_math": True}


@wp.func
def lane_layout(block: int, lane: int, per_block: int, lanes: int, n: int):
    """Particle (-1 past the end), lane slot, and whether this thread finishes the particle."""
    i = block * per_block + lane / lanes
    if i >= n:
        i = -1
    slot = lane % lanes
    return i, slot, i >= 0 and slot == 0


@wp.func
def lane_particle(block: int, lane: int, per_block: int, lanes: int, x: wp.array(dtype=wp.vec3),
                  inv_mass: wp.array(dtype=float)):
    """``lane_layout``'s particle, slot and owner, and the particle's position and inverse mass (zeros past
    the end, so that those lanes, like a pinned particle's, gather nothing)."""
    i, slot, owner = lane_layout(block, lane, per_block, lanes, x.shape[0])
    xi = wp.vec3(0.0)
    wi = float(0.0)
    if i >= 0:
        xi = x[i]
        wi = inv_mass[i]
    return i, slot, owner, xi, wi


@functools.cache
def lane_sum(per_block: int, lanes: int) -> wp.Function:
    """A function that sums a value (a vector or a count) over each particle's lanes and gives every lane
    its particle's sum. Every thread of the block must call it (the tile sum is cooperative)."""

    @wp.func
    def sum_over_lanes(value: Any, lane: int):
        sums = wp.tile_sum(wp.tile_reshape(wp.tile(value, preserve_type=True), shape=(per_block, lanes)), axis=1)
        return sums[lane / lanes]

    return sum_over_lanes
