"""Preconditioned conjugate gradient building blocks for systems over vec3 arrays, kept on the device: one
system a world (warp_cloth/batch.py; a scene alone is one world), each with its own scalars, iteration
count and convergence, so that the worlds of a batch solve as each would alone.

Scalars live in small arrays, a row a world (``CG_*`` name its columns), so that no iteration waits for the
host. The kernels of an iteration do nothing for a world whose solve has converged; ``iterating[0]`` is the
loop's condition, 1 while any world's goes on, so a fixed number of iterations can be captured too and the
surplus ones cost only their launch.
Dot products are reduced in a fixed order, with no atomics, so the result is the same on every run: each
world's as ``lanes`` interleaved partial sums (written by the kernel that makes the vectors where it can),
which the scalar kernel after totals, a block a world (a second level of 128 serial sums cost a third of an
H200's conjugate gradient on the stacked drape, docs/notebook/layers.md). An iteration is six launches:
A p, p . A p, alpha, the step with the preconditioner and r . z, beta, the next direction.
"""

import warp as wp

CG_RZ = wp.constant(0)  # r . z of the current residual
CG_RZ0 = wp.constant(1)  # b . P b of the right-hand side: the reference for the relative tolerance
CG_ALPHA = wp.constant(2)
CG_BETA = wp.constant(3)
CG_TOLERANCE_SQ = wp.constant(4)  # squared relative tolerance on sqrt(r . z)
CG_SLOTS = 5


@wp.func
def lane_particles(world_start: wp.array(dtype=int), lanes: int, t: int):
    """Thread t's world, its first particle and the end of its world's particles: it takes every
    ``lanes``-th from the first."""
    w = t / lanes
    return w, world_start[w] + t - w * lanes, world_start[w + 1]


@wp.kernel
def world_dot_partials(a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), world_start: wp.array(dtype=int),
                       lanes: int, active: wp.array(dtype=int), partial: wp.array(dtype=float)):
    """Each world's a . b over its particles (``world_start[w]`` to ``[w + 1]``) as ``lanes`` partial sums."""
    t = wp.tid()
    w, k, end = lane_particles(world_start, lanes, t)
    if active[w] == 0:
        return
    total = float(0.0)
    while k < end:
        total += wp.dot(a[k], b[k])
        k += lanes
    partial[t] = total


@wp.func
def precondition_at(inverse: wp.array(dtype=wp.mat33), r: wp.array(dtype=wp.vec3), k: int,
                    z: wp.array(dtype=wp.vec3)) -> float:
    """z = P r at particle k; its part of r . z."""
    rk = r[k]
    zk = inverse[k] * rk
    z[k] = zk
    return wp.dot(rk, zk)


@wp.kernel
def precondition_and_dot(inverse: wp.array(dtype=wp.mat33), r: wp.array(dtype=wp.vec3),
                         world_start: wp.array(dtype=int), lanes: int, active: wp.array(dtype=int),
                         z: wp.array(dtype=wp.vec3), partial: wp.array(dtype=float)):
    """z = P r (the block-Jacobi ``inverse``), and each world's r . z as ``lanes`` partial sums (as
    ``world_dot_partials``)."""
    t = wp.tid()
    w, k, end = lane_particles(world_start, lanes, t)
    if active[w] == 0:
        return
    total = float(0.0)
    while k < end:
        total += precondition_at(inverse, r, k, z)
        k += lanes
    partial[t] = total


@wp.kernel
def advance_and_precondition(p: wp.array(dtype=wp.vec3), ap: wp.array(dtype=wp.vec3),
                             inverse: wp.array(dtype=wp.mat33), world_start: wp.array(dtype=int), lanes: int,
                             scalars: wp.array2d(dtype=float), active: wp.array(dtype=int), x: wp.array(dtype=wp.vec3),
                             r: wp.array(dtype=wp.vec3), z: wp.array(dtype=wp.vec3), partial: wp.array(dtype=float)):
    """x += alpha p, r -= alpha A p, z = P r, and each world's new r . z as ``lanes`` partial sums."""
    t = wp.tid()
    w, k, end = lane_particles(world_start, lanes, t)
    if active[w] == 0:
        return
    alpha = scalars[w, CG_ALPHA]
    total = float(0.0)
    while k < end:
        x[k] = x[k] + alpha * p[k]
        r[k] = r[k] - alpha * ap[k]
        total += precondition_at(inverse, r, k, z)
        k += lanes
    partial[t] = total


SUM_BLOCK = 256  # threads of a world's total: Warp's default block size, the one a graph capture has the module
# loaded for
SUM_TILE = 4096  # partial sums a block loads at a time: 16 a thread (1,024: twice the time on an H200)


@wp.func
def world_total(partial: wp.array(dtype=float), w: int, lanes: int, lane: int) -> float:
    """World w's ``lanes`` partial sums added up by its block (``wp.launch_tiled``, a block a world; every
    thread of the block must call it, and every thread gets the total): a tile at a time where ``lanes`` is a
    multiple of ``SUM_TILE`` (a large world alone), else each thread's share of the few (a batch world's, or a
    small world's), then the block's tree. (Each thread's share of one world's 16,384, one load after another,
    took 21 us a total on an H200: the CG 25% slower.) The tree's sum waits for the whole block, so that the
    kernels after it may let one thread write what every thread read before (``active``, a Newton loop's
    state)."""
    if lanes % SUM_TILE == 0:
        s = wp.tile_zeros(shape=1, dtype=float)
        for offset in range(w * lanes, (w + 1) * lanes, SUM_TILE):
            s += wp.tile_sum(wp.tile_load(partial, shape=SUM_TILE, offset=offset))
        return s[0]
    share = float(0.0)
    k = lane
    while k < lanes:
        share += partial[w * lanes + k]
        k += wp.block_dim()
    return wp.tile_sum(wp.tile(share))[0]


@wp.kernel
def reference(partial: wp.array(dtype=float), lanes: int, scalars: wp.array2d(dtype=float)):
    """After b . P b of each world's right-hand side (the preconditioned size of what a solve from zero would
    start with): the reference of the relative tolerance, so that a solve from a first guess stops where one
    from zero would."""
    w, lane = wp.tid()
    total = world_total(partial, w, lanes, lane)
    if lane == 0:
        scalars[w, CG_RZ0] = total


@wp.kernel
def start(partial: wp.array(dtype=float), lanes: int, tolerance: float, max_iterations: int,
          enabled: wp.array2d(dtype=int), scalars: wp.array2d(dtype=float), active: wp.array(dtype=int),
          iterating: wp.array(dtype=int), iterations: wp.array(dtype=int)):
    """After r . z of each world's first residual (``reference`` before): arm its solve unless its first
    guess is within the tolerance already or it is not ``enabled`` (its Newton loop has converged). A world
    whose right-hand side is zero takes its first residual as the reference. ``iterating`` must be 0 before."""
    w, lane = wp.tid()
    rz = world_total(partial, w, lanes, lane)
    if lane != 0:
        return
    scalars[w, CG_RZ] = rz
    if scalars[w, CG_RZ0] <= 0.0:
        scalars[w, CG_RZ0] = rz
    scalars[w, CG_TOLERANCE_SQ] = tolerance * tolerance
    iterations[w] = 0
    active[w] = 0
    if enabled[w, 0] != 0 and rz > tolerance * tolerance * scalars[w, CG_RZ0] and max_iterations > 0:
        active[w] = 1
        iterating[0] = 1


@wp.kernel
def step_length(partial: wp.array(dtype=float), lanes: int, active: wp.array(dtype=int),
                scalars: wp.array2d(dtype=float), iterating: wp.array(dtype=int)):
    """After p . A p of each world (a block a world): alpha."""
    w, lane = wp.tid()
    if w == 0 and lane == 0:
        iterating[0] = 0  # raised again by next_direction_scale for each world that goes on
    if active[w] == 0:  # the same for the whole block
        return
    p_ap = world_total(partial, w, lanes, lane)
    if lane != 0:
        return
    scalars[w, CG_ALPHA] = 0.0
    if p_ap > 0.0:
        scalars[w, CG_ALPHA] = scalars[w, CG_RZ] / p_ap


@wp.kernel
def next_direction_scale(partial: wp.array(dtype=float), lanes: int, max_iterations: int,
                         scalars: wp.array2d(dtype=float), active: wp.array(dtype=int),
                         iterating: wp.array(dtype=int), iterations: wp.array(dtype=int)):
    """After r . z of each world's new residual (a block a world): beta, the iteration count, and whether it
    goes on."""
    w, lane = wp.tid()
    if active[w] == 0:  # the same for the whole block
        return
    rz = world_total(partial, w, lanes, lane)
    if lane != 0:
        return
    beta = float(0.0)
    if scalars[w, CG_RZ] > 0.0:
        beta = rz / scalars[w, CG_RZ]
    scalars[w, CG_BETA] = beta
    scalars[w, CG_RZ] = rz
    iterations[w] = iterations[w] + 1
    if rz <= scalars[w, CG_TOLERANCE_SQ] * scalars[w, CG_RZ0] or iterations[w] >= max_iterations:
        active[w] = 0
    else:
        iterating[0] = 1


@wp.kernel
def update_direction(z: wp.array(dtype=wp.vec3), world: wp.array(dtype=int), scalars: wp.array2d(dtype=float),
                     active: wp.array(dtype=int), p: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    w = world[i]
    if active[w] == 0:
        return
    p[i] = z[i] + scalars[w, CG_BETA] * p[i]


@wp.kernel
def subtract(a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = a[i] - b[i]


@wp.kernel
def record_solve(scalars: wp.array2d(dtype=float), iterations: wp.array(dtype=int), enabled: wp.array2d(dtype=int),
                 stats: wp.array(dtype=float)):
    """After a solve, over the worlds that solved: stats[0] and stats[1] keep the most iterations and the
    largest r.z / b.Pb (relative to the right-hand side's) so far."""
    w = wp.tid()
    if enabled[w, 0] == 0:
        return
    wp.atomic_max(stats, 0, float(iterations[w]))
    if scalars[w, CG_RZ0] > 0.0:
        wp.atomic_max(stats, 1, scalars[w, CG_RZ] / scalars[w, CG_RZ0])
