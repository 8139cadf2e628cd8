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


# Springs of a particle gathered in straight-line code before the rest in a loop: a grid particle has 4
# structural, 4 shear and 4 bend springs. Unrolled, every spring's loads are issued at once instead of
# one spring after another, which is what a small cloth's substep waits on (a loop of dependent loads).
UNROLLED_SPRINGS = wp.constant(12)


@wp.func
def gather_spring_forces(i: int, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                         offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                         spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                         stiffness: wp.array(dtype=float), damping: wp.array(dtype=float),
                         flags: wp.array(dtype=int)) -> wp.vec3:
    """Sum of the spring forces on particle i, in the order of its adjacency list."""
    xi = x[i]
    vi = v[i]
    f = wp.vec3(0.0)
    start = offsets[i]
    end = offsets[i + 1]
    if end == start:
        return f
    last = other.shape[0] - 1
    for k in range(UNROLLED_SPRINGS):
        e = wp.min(start + k, last)  # past the end: another particle's spring, computed and left out
        j = other[e]
        s = spring[e]
        fk = spring_force(xi, x[j], vi, v[j], rest[s], stiffness[s], damping[s], flags[s])
        if start + k < end:
            f = f + fk
    for e in range(start + UNROLLED_SPRINGS, end):
        j = other[e]
        s = spring[e]
        f = f + spring_force(xi, x[j], vi, v[j], rest[s], stiffness[s], damping[s], flags[s])
    return f
