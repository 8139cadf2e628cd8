"""Backward Euler (Baraff & Witkin 1998), matrix free.

Unknown: the velocity change dv of a step, from (M - h df/dv - h^2 df/dx) dv = rhs. Every product with
that matrix is a gather over each particle's springs, with the spring Jacobians rebuilt from positions on
the fly: no matrix is ever assembled. Per spring, with n the unit direction, l its length, L its rest
length and k' = k / L:
    stiffness   K = k' (n n^T + max(0, 1 - L/l) (I - n n^T))   (clamped so that K stays semi-definite)
    damping     D = b n n^T
and the matrix's block for the spring is S = h D + h^2 K, added on the diagonal of both ends and
subtracted off the diagonal: A p_i = m_i (1 + h drag) p_i + sum_s S_s (p_i - p_j). Pinned particles
(inverse mass 0) are held by Baraff & Witkin's filter: their dv is prescribed and their rows are zeroed
in every residual and search direction, so the solve never moves them.
"""

import warp as wp

from .cg import CG_RZ, CG_RZ0, ITERATIONS
from .springs import damping_acts, elastic_acts, gather_spring_forces


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


@wp.kernel
def newton_rhs(y: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v0: wp.array(dtype=wp.vec3),
               mass: wp.array(dtype=float), inv_mass: wp.array(dtype=float), gravity: wp.vec3, drag: float, h: float,
               linearized_at_start: int, offsets: wp.array(dtype=int), other: wp.array(dtype=int),
               spring: wp.array(dtype=int), rest: wp.array(dtype=float), stiffness: wp.array(dtype=float),
               damping: wp.array(dtype=float), flags: wp.array(dtype=int), rhs: wp.array(dtype=wp.vec3)):
    """Right-hand side of one Newton step for v' with M (v' - v0) = h f(x0 + h v', v').

    With forces evaluated at y = x0 + h v, this is h f(y, v) - M (v - v0). Baraff & Witkin's single step
    linearises at the start of the step instead (y = x0, v = v0), which adds h^2 K v0 for the motion
    x0 -> x0 + h v0 that y leaves out: ``linearized_at_start`` = 1 selects that."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        rhs[i] = wp.vec3(0.0)
        return
    m = mass[i]
    f = gather_spring_forces(i, offsets[i], 1, y, v, offsets, other, spring, rest, stiffness, damping, flags)
    f = f + m * gravity - (drag * m) * v[i]
    out = h * f - m * (v[i] - v0[i])
    if linearized_at_start != 0:
        yi = y[i]
        correction = wp.vec3(0.0)
        for k in range(offsets[i], offsets[i + 1]):
            j = other[k]
            s = spring[k]
            correction = correction + stiffness_times(yi, y[j], rest[s], stiffness[s], flags[s], v0[i] - v0[j])
        out = out - (h * h) * correction
    rhs[i] = out


@wp.kernel
def system_times(y: wp.array(dtype=wp.vec3), mass: wp.array(dtype=float), inv_mass: wp.array(dtype=float),
                 drag: float, h: float, offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                 spring: wp.array(dtype=int), rest: wp.array(dtype=float), stiffness: wp.array(dtype=float),
                 damping: wp.array(dtype=float), flags: wp.array(dtype=int), p: wp.array(dtype=wp.vec3),
                 active: wp.array(dtype=int), out: wp.array(dtype=wp.vec3)):
    """out = A p on free particles, 0 on pinned ones (the filter). Does nothing once ``active`` is 0."""
    i = wp.tid()
    if active[0] == 0:
        return
    if inv_mass[i] == 0.0:
        out[i] = wp.vec3(0.0)
        return
    yi = y[i]
    pi = p[i]
    result = (mass[i] * (1.0 + h * drag)) * pi
    for k in range(offsets[i], offsets[i + 1]):
        j = other[k]
        s = spring[k]
        result = result + spring_system_block(yi, y[j], rest[s], stiffness[s], damping[s], flags[s], h) * (pi - p[j])
    out[i] = result


@wp.kernel
def block_jacobi_inverse(y: wp.array(dtype=wp.vec3), mass: wp.array(dtype=float), inv_mass: wp.array(dtype=float),
                         drag: float, h: float, offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                         spring: wp.array(dtype=int), rest: wp.array(dtype=float), stiffness: wp.array(dtype=float),
                         damping: wp.array(dtype=float), flags: wp.array(dtype=int),
                         inverse: wp.array(dtype=wp.mat33)):
    """The inverse of each particle's 3x3 diagonal block of A: the preconditioner (0 on pinned)."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        inverse[i] = wp.mat33(0.0)
        return
    yi = y[i]
    block = (mass[i] * (1.0 + h * drag)) * wp.identity(n=3, dtype=float)
    for k in range(offsets[i], offsets[i + 1]):
        s = spring[k]
        block = block + spring_system_block(yi, y[other[k]], rest[s], stiffness[s], damping[s], flags[s], h)
    inverse[i] = wp.inverse(block)


@wp.kernel
def predict_positions(x0: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), h: float,
                      y: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    y[i] = x0[i] + h * v[i]


@wp.kernel
def finish_step(x0: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3), h: float,
                newton: wp.array(dtype=int), x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    """v' = v + dv (skipped once Newton has converged), x' = x0 + h v'."""
    i = wp.tid()
    vi = v[i]
    if newton[0] != 0:
        vi = vi + dv[i]
    v_out[i] = vi
    x_out[i] = x0[i] + h * vi


# Bookkeeping of the Newton loop, in ``newton`` = [on (0 once converged), steps taken this substep], and of
# the worst values since the host last read them, in ``stats`` = [CG iterations, r.z / r0.z0 at the end of
# a solve, Newton steps, Newton residual (RMS of |M (v - v0) - h f| / m, m/s)].


@wp.kernel
def start_newton(newton: wp.array(dtype=int)):
    newton[0] = 1
    newton[1] = 1


@wp.kernel
def per_unit_mass(r: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = r[i] * inv_mass[i]


@wp.func
def rms(partial: wp.array(dtype=float), count: float) -> float:
    total = float(0.0)
    for k in range(partial.shape[0]):
        total += partial[k]
    return wp.sqrt(total / count)


@wp.kernel
def continue_newton(partial: wp.array(dtype=float), free_particles: float, tolerance: float,
                    newton: wp.array(dtype=int)):
    """Before another Newton step: stop if the residual (per unit mass, RMS) is below the tolerance."""
    if newton[0] == 0:
        return
    if rms(partial, free_particles) <= tolerance:
        newton[0] = 0
    else:
        newton[1] = newton[1] + 1


@wp.kernel
def record_newton(partial: wp.array(dtype=float), free_particles: float, newton: wp.array(dtype=int),
                  stats: wp.array(dtype=float)):
    stats[2] = wp.max(stats[2], float(newton[1]))
    stats[3] = wp.max(stats[3], rms(partial, free_particles))


@wp.kernel
def record_solve(scalars: wp.array(dtype=float), cg_counts: wp.array(dtype=int), stats: wp.array(dtype=float)):
    stats[0] = wp.max(stats[0], float(cg_counts[ITERATIONS]))
    if scalars[CG_RZ0] > 0.0:
        stats[1] = wp.max(stats[1], scalars[CG_RZ] / scalars[CG_RZ0])
