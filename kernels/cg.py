"""Preconditioned conjugate gradient building blocks for systems over vec3 arrays, kept on the device.

Scalars live in a small array so that no iteration waits for the host: ``CG_*`` name its slots. The
kernels of an iteration do nothing once the solve has converged, so a fixed number of iterations can be
captured and the surplus ones cost only their launch.
Dot products are reduced in a fixed order (interleaved partial sums, then a second level, then one
thread), so the result is the same on every run, with no atomics.
"""

import warp as wp

CG_RZ = wp.constant(0)  # r . z of the current residual
CG_RZ0 = wp.constant(1)  # r . z at the start: the reference for the relative tolerance
CG_ALPHA = wp.constant(2)
CG_BETA = wp.constant(3)
CG_TOLERANCE_SQ = wp.constant(4)  # squared relative tolerance on sqrt(r . z)
CG_SLOTS = 5

# Integer state: ``active`` (one element, the loop's condition: 1 while iterating) and ``counts``:
# [0] iterations done, [1] iteration cap.
ITERATIONS = wp.constant(0)
MAX_ITERATIONS = wp.constant(1)


@wp.kernel
def dot_partials(a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), stride: int, active: wp.array(dtype=int),
                 partial: wp.array(dtype=float)):
    if active[0] == 0:
        return
    t = wp.tid()
    total = float(0.0)
    k = t
    while k < a.shape[0]:
        total += wp.dot(a[k], b[k])
        k += stride
    partial[t] = total


@wp.kernel
def sum_partials(values: wp.array(dtype=float), stride: int, active: wp.array(dtype=int),
                 partial: wp.array(dtype=float)):
    if active[0] == 0:
        return
    t = wp.tid()
    total = float(0.0)
    k = t
    while k < values.shape[0]:
        total += values[k]
        k += stride
    partial[t] = total


@wp.func
def total(partial: wp.array(dtype=float)) -> float:
    s = float(0.0)
    for k in range(partial.shape[0]):
        s += partial[k]
    return s


@wp.kernel
def start(partial: wp.array(dtype=float), tolerance: float, max_iterations: int, enabled: wp.array(dtype=int),
          scalars: wp.array(dtype=float), active: wp.array(dtype=int), counts: wp.array(dtype=int)):
    """After r . z of the first residual: arm the loop unless there is nothing to solve."""
    rz = total(partial)
    scalars[CG_RZ] = rz
    scalars[CG_RZ0] = rz
    scalars[CG_TOLERANCE_SQ] = tolerance * tolerance
    counts[ITERATIONS] = 0
    counts[MAX_ITERATIONS] = max_iterations
    active[0] = 0
    if enabled[0] != 0 and rz > 0.0 and max_iterations > 0:
        active[0] = 1


@wp.kernel
def step_length(partial: wp.array(dtype=float), active: wp.array(dtype=int), scalars: wp.array(dtype=float)):
    if active[0] == 0:
        return
    p_ap = total(partial)
    scalars[CG_ALPHA] = 0.0
    if p_ap > 0.0:
        scalars[CG_ALPHA] = scalars[CG_RZ] / p_ap


@wp.kernel
def advance(p: wp.array(dtype=wp.vec3), ap: wp.array(dtype=wp.vec3), scalars: wp.array(dtype=float),
            active: wp.array(dtype=int), x: wp.array(dtype=wp.vec3), r: wp.array(dtype=wp.vec3)):
    if active[0] == 0:
        return
    i = wp.tid()
    alpha = scalars[CG_ALPHA]
    x[i] = x[i] + alpha * p[i]
    r[i] = r[i] - alpha * ap[i]


@wp.kernel
def precondition(inverse: wp.array(dtype=wp.mat33), r: wp.array(dtype=wp.vec3), active: wp.array(dtype=int),
                 z: wp.array(dtype=wp.vec3)):
    if active[0] == 0:
        return
    i = wp.tid()
    z[i] = inverse[i] * r[i]


@wp.kernel
def next_direction_scale(partial: wp.array(dtype=float), scalars: wp.array(dtype=float),
                         active: wp.array(dtype=int), counts: wp.array(dtype=int)):
    """After r . z of the new residual: beta, the iteration count, and whether to go on."""
    if active[0] == 0:
        return
    rz = total(partial)
    beta = float(0.0)
    if scalars[CG_RZ] > 0.0:
        beta = rz / scalars[CG_RZ]
    scalars[CG_BETA] = beta
    scalars[CG_RZ] = rz
    counts[ITERATIONS] = counts[ITERATIONS] + 1
    if rz <= scalars[CG_TOLERANCE_SQ] * scalars[CG_RZ0] or counts[ITERATIONS] >= counts[MAX_ITERATIONS]:
        active[0] = 0


@wp.kernel
def update_direction(z: wp.array(dtype=wp.vec3), scalars: wp.array(dtype=float), active: wp.array(dtype=int),
                     p: wp.array(dtype=wp.vec3)):
    if active[0] == 0:
        return
    i = wp.tid()
    p[i] = z[i] + scalars[CG_BETA] * p[i]


@wp.kernel
def subtract(a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = a[i] - b[i]


@wp.kernel
def record_solve(scalars: wp.array(dtype=float), counts: wp.array(dtype=int), stats: wp.array(dtype=float)):
    """After a solve: stats[0] and stats[1] keep the most iterations and the largest r.z / r0.z0 so far."""
    stats[0] = wp.max(stats[0], float(counts[ITERATIONS]))
    if scalars[CG_RZ0] > 0.0:
        stats[1] = wp.max(stats[1], scalars[CG_RZ] / scalars[CG_RZ0])
