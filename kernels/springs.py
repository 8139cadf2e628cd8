"""Spring forces of the mass-spring cloth (strain based, as the seed: k does not change with resolution).

Springs are gathered per particle from an adjacency list (CSR: ``offsets``, then per incidence the other
particle and the spring's id), so every particle sums its own forces: no atomics, the same result on
every run and device ordering.
"""

import warp as wp

# Regime flags of a spring: in which state its elastic part and its dashpot act.
ELASTIC_TENSION = wp.constant(1)
ELASTIC_COMPRESSION = wp.constant(2)
DAMPING_TENSION = wp.constant(4)
DAMPING_COMPRESSION = wp.constant(8)


@wp.func
def elastic_acts(stretched: bool, flags: int) -> bool:
    return (stretched and (flags & ELASTIC_TENSION) != 0) or (not stretched and (flags & ELASTIC_COMPRESSION) != 0)


@wp.func
def damping_acts(stretched: bool, flags: int) -> bool:
    return (stretched and (flags & DAMPING_TENSION) != 0) or (not stretched and (flags & DAMPING_COMPRESSION) != 0)


@wp.func
def spring_force(xi: wp.vec3, xj: wp.vec3, vi: wp.vec3, vj: wp.vec3, rest: float, stiffness: float,
                 damping: float, flags: int) -> wp.vec3:
    """Force on particle i of the spring i-j: -k (l/L0 - 1) n - b (n . (vi - vj)) n, n = (xi - xj)/l."""
    d = xi - xj
    length = wp.length(d)
    if length < 1.0e-12:
        return wp.vec3(0.0)
    n = d / length
    stretched = length > rest
    f = wp.vec3(0.0)
    if elastic_acts(stretched, flags):
        f = f - stiffness * (length / rest - 1.0) * n
    if damping_acts(stretched, flags):
        f = f - damping * wp.dot(n, vi - vj) * n
    return f


@wp.func
def gather_spring_forces(i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                         offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                         spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                         stiffness: wp.array(dtype=float), damping: wp.array(dtype=float),
                         flags: wp.array(dtype=int)) -> wp.vec3:
    """Sum of the spring forces on particle i from its incidences first, first + stride, ... (one thread
    sums them all with offsets[i] and 1; see lanes.py for several)."""
    xi = x[i]
    vi = v[i]
    f = wp.vec3(0.0)
    for k in range(first, offsets[i + 1], stride):
        j = other[k]
        s = spring[k]
        f = f + spring_force(xi, x[j], vi, v[j], rest[s], stiffness[s], damping[s], flags[s])
    return f
