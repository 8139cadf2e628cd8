"""Spring forces of the mass-spring cloth (strain based, as the seed: k does not change with resolution),
and their Jacobians for the implicit solve.

Springs are gathered per particle from an adjacency list (CSR: ``offsets``, then per incidence the other
particle and the spring's id), so every particle sums its own forces: no atomics, the same result on
every run and device ordering.

Per spring, with n the unit direction, l its length, L its rest length and k' = k / L, the Jacobians are
    stiffness   K = k' (n n^T + max(0, 1 - L/l) (I - n n^T))   (clamped so that K stays semi-definite)
    damping     D = b n n^T
and a backward Euler step's matrix has the block S = h D + h^2 K of each spring on the diagonal of both
ends and subtracted off the diagonal (see warp_cloth/implicit.py).
"""

import warp as wp

# Regime flags of a spring: in which state its elastic part and its dashpot act (warp_cloth/model.py sets
# them from a spring kind's ``acts`` and ``damping_acts``).
ELASTIC_TENSION = wp.constant(1)
ELASTIC_COMPRESSION = wp.constant(2)
DAMPING_TENSION = wp.constant(4)
DAMPING_COMPRESSION = wp.constant(8)


@wp.struct
class Springs:
    offsets: wp.array(dtype=int)  # (n + 1,) particle i's incidences are offsets[i]:offsets[i + 1]
    other: wp.array(dtype=int)  # per incidence: the particle at the other end
    spring: wp.array(dtype=int)  # per incidence: the spring
    rest: wp.array(dtype=float)  # per spring
    stiffness: wp.array(dtype=float)
    damping: wp.array(dtype=float)
    flags: wp.array(dtype=int)


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
def spring_forces(springs: Springs, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                  v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """Sum of the spring forces on particle i from its incidences offsets[i] + first, + stride, ..."""
    xi = x[i]
    vi = v[i]
    f = wp.vec3(0.0)
    for k in range(springs.offsets[i] + first, springs.offsets[i + 1], stride):
        j = springs.other[k]
        s = springs.spring[k]
        f = f + spring_force(xi, x[j], vi, v[j], springs.rest[s], springs.stiffness[s], springs.damping[s],
                             springs.flags[s])
    return f


@wp.func
def spring_system_block(xi: wp.vec3, xj: wp.vec3, rest: float, stiffness: float, damping: float, flags: int,
                        h: float) -> wp.mat33:
    """h D + h^2 K of one spring, in the regime its current length puts it in."""
    d = xi - xj
    length = wp.length(d)
    if length < 1.0e-12:
        return wp.mat33(0.0)
    n = d / length
    nn = wp.outer(n, n)
    stretched = length > rest
    block = wp.mat33(0.0)
    if elastic_acts(stretched, flags):
        transverse = wp.max(0.0, 1.0 - rest / length)
        block = block + (h * h * stiffness / rest) * (nn + transverse * (wp.identity(n=3, dtype=float) - nn))
    if damping_acts(stretched, flags):
        block = block + (h * damping) * nn
    return block


@wp.func
def stiffness_times(xi: wp.vec3, xj: wp.vec3, rest: float, stiffness: float, flags: int, u: wp.vec3) -> wp.vec3:
    """K u of one spring (the positive stiffness Jacobian above, without h)."""
    d = xi - xj
    length = wp.length(d)
    if length < 1.0e-12:
        return wp.vec3(0.0)
    n = d / length
    if elastic_acts(length > rest, flags):
        transverse = wp.max(0.0, 1.0 - rest / length)
        along = wp.dot(n, u) * n
        return (stiffness / rest) * (along + transverse * (u - along))
    return wp.vec3(0.0)


@wp.func
def add_system_times(springs: Springs, i: int, y: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3), h: float,
                     total: wp.vec3) -> wp.vec3:
    """``total`` plus the springs' part of particle i's row of the step's matrix times p, at positions y:
    the sum over its springs of S (p_i - p_j)."""
    yi = y[i]
    pi = p[i]
    for k in range(springs.offsets[i], springs.offsets[i + 1]):
        j = springs.other[k]
        s = springs.spring[k]
        total = total + spring_system_block(yi, y[j], springs.rest[s], springs.stiffness[s], springs.damping[s],
                                            springs.flags[s], h) * (pi - p[j])
    return total


@wp.func
def add_system_diagonal(springs: Springs, i: int, y: wp.array(dtype=wp.vec3), h: float, block: wp.mat33) -> wp.mat33:
    """``block`` plus the springs' part of particle i's 3x3 diagonal block of the step's matrix."""
    yi = y[i]
    for k in range(springs.offsets[i], springs.offsets[i + 1]):
        s = springs.spring[k]
        block = block + spring_system_block(yi, y[springs.other[k]], springs.rest[s], springs.stiffness[s],
                                            springs.damping[s], springs.flags[s], h)
    return block


@wp.func
def stiffness_times_motion(springs: Springs, i: int, y: wp.array(dtype=wp.vec3), u: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """Particle i's row of K u over its springs, at positions y: sum of K (u_i - u_j)."""
    yi = y[i]
    total = wp.vec3(0.0)
    for k in range(springs.offsets[i], springs.offsets[i + 1]):
        j = springs.other[k]
        s = springs.spring[k]
        total = total + stiffness_times(yi, y[j], springs.rest[s], springs.stiffness[s], springs.flags[s],
                                        u[i] - u[j])
    return total
