"""Kernels that gather over each particle's springs, limits or contacts, written once and launched with one
thread per particle or several.

A small cloth has too few particles to fill a GPU: with a thread per particle, 4096 threads run on 16 of
an H200's 132 multiprocessors, and a kernel takes as long as one thread's chain of dependent loads and
arithmetic over its 12 springs. With ``threads`` threads per particle, thread s of particle i takes its
incidences s, s + threads, ..., and a tile sum along the thread axis adds their parts (``BLOCK / threads``
particles to a block of ``BLOCK`` threads); the particle's first thread then finishes it. With one thread
per particle the same kernel runs without the sum, and gathers in the order the incidences are stored.

A gathering kernel is a pass's ``gather(args, i, first, stride, x, v)`` (its particle's sum over
incidences first, first + stride, ...; zero where i < 0, a thread past the last particle) and its
``finish(args, i, total, x, v, x_out, v_out)``, over one ``args`` struct of what the pass reads besides the
state. ``gathering_kernel`` makes the kernel for a number of threads; ``launch_gathering`` launches it.

The several threads' sum adds in another order than one thread, so results differ by rounding; the order
is fixed for a number of threads, so runs stay deterministic. Tiles need a GPU (a CPU block has one
thread): on the CPU every gathering kernel runs with one thread per particle.

FAST_MATH: the kernels of the explicit step, the strain limit, the colliders and particle collision compile
for CUDA with fast math (division and square root to within 2 ulp, denormals flushed to zero), which
took 8-31 % off the spring kernel on an H200, least at 1024^2, in two runs of tools/lanes_probe.py; the
CPU build ignores it. Not for kernels with sines (pins, sphere motion), whose fast form loses accuracy as
the clock's argument grows, nor for the implicit solve.
"""

import functools
from typing import Any, Callable

import warp as wp

FAST_MATH = {"fast_math": True}
BLOCK = 128  # threads of a block


@wp.func
def thread_layout(block: int, lane: int, per_block: int, threads: int, n: int):
    """Particle (-1 past the end), the thread's slot among its particle's threads, and whether this thread
    finishes the particle."""
    i = block * per_block + lane / threads
    if i >= n:
        i = -1
    slot = lane % threads
    return i, slot, i >= 0 and slot == 0


@wp.func
def gathers(args: Any, i: int) -> bool:
    """Whether a thread gathers for particle i: one that exists (i >= 0: not past the last) and is free
    (a pinned particle's incidences move nothing)."""
    if i < 0:
        return False
    return args.inv_mass[i] != 0.0


@functools.cache
def sum_over_threads(per_block: int, threads: int) -> wp.Function:
    """A function that sums a value (a vector or a count) over each particle's threads and gives every
    thread its particle's sum (the value itself for one thread). Every thread of the block must call it
    (the tile sum is cooperative)."""
    if threads == 1:
        @wp.func
        def one_thread(value: Any, lane: int):
            return value

        return one_thread

    @wp.func
    def tile_sum(value: Any, lane: int):
        sums = wp.tile_sum(wp.tile_reshape(wp.tile(value, preserve_type=True), shape=(per_block, threads)), axis=1)
        return sums[lane / threads]

    return tile_sum


def gathering_kernel(name: str, args_type: type, gather: Callable, finish: Callable, threads: int,
                     options: dict = FAST_MATH) -> wp.Kernel:
    """The kernel ``name`` (an identifier) of ``gather`` then ``finish`` (see above) with ``threads`` threads per
    particle (see ``load_gathering``)."""
    per_block = BLOCK // threads
    total_over_threads = sum_over_threads(per_block, threads)

    def kernel(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), x_out: wp.array(dtype=wp.vec3),
               v_out: wp.array(dtype=wp.vec3), args: args_type):
        block, lane = wp.tid()
        i, slot, owner = thread_layout(block, lane, wp.static(per_block), wp.static(threads), x.shape[0])
        total = total_over_threads(gather(args, i, slot, wp.static(threads), x, v), lane)
        if owner:
            finish(args, i, total, x, v, x_out, v_out)

    kernel.__name__ = kernel.__qualname__ = name
    return wp.kernel(kernel, module="unique", module_options=options)


def load_gathering(kernel: wp.Kernel, threads: int, device) -> None:
    """Compiles and loads a gathering kernel of several threads a particle for its block size now: a graph
    capture loads modules for the default block size only, and cannot compile."""
    if threads > 1:
        kernel.module.load(device, block_dim=BLOCK)


def launch_gathering(kernel: wp.Kernel, threads: int, n: int, x: wp.array, v: wp.array, x_out: wp.array,
                     v_out: wp.array, args: Any) -> None:
    """Launches a ``gathering_kernel`` over ``n`` particles."""
    per_block = BLOCK // threads
    blocks = (n + per_block - 1) // per_block
    inputs = [x, v, x_out, v_out, args]
    if threads == 1:
        wp.launch(kernel, dim=(blocks, BLOCK), inputs=inputs, device=x.device)
    else:
        wp.launch_tiled(kernel, dim=[blocks], inputs=inputs, block_dim=BLOCK, device=x.device)
