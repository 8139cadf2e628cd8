"""Backward Euler (Baraff & Witkin 1998), matrix free: the end of a step and the Newton loop's bookkeeping.

Unknown: the velocity change dv of a step, from (M - h df/dv - h^2 df/dx) dv = rhs. The right-hand side,
the products with that matrix and its diagonal blocks are gathers over each particle's springs (the
Jacobians of kernels/springs.py, rebuilt from positions on the fly: no matrix is ever assembled), with the
external forces' part (kernels/forces.py); kernels/passes.py assembles them. Pinned particles (inverse
mass 0) are held by Baraff & Witkin's filter: their dv is prescribed and their rows are zeroed in every
residual and search direction, so the solve never moves them.

Each world (warp_cloth/batch.py; a scene alone is one) runs its own Newton loop: ``newton[w]`` = [on (0 once
converged), steps taken this substep]. The worst values over the worlds since the host last read them are
in ``stats`` = [CG iterations, r.z / r0.z0 at the end of a solve, Newton steps, Newton residual (RMS of
|M (v - v0) - h f| / m, m/s)] (the first two: cg.record_solve).
"""

import warp as wp


@wp.kernel
def finish_step(x0: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3), h: float,
                world: wp.array(dtype=int), newton: wp.array2d(dtype=int), x_out: wp.array(dtype=wp.vec3),
                v_out: wp.array(dtype=wp.vec3)):
    """v' = v + dv (skipped once the world's Newton loop has converged), x' = x0 + h v'."""
    i = wp.tid()
    vi = v[i]
    if newton[world[i], 0] != 0:
        vi = vi + dv[i]
    v_out[i] = vi
    x_out[i] = x0[i] + h * vi


@wp.kernel
def start_newton(newton: wp.array2d(dtype=int)):
    w = wp.tid()
    newton[w, 0] = 1
    newton[w, 1] = 1


@wp.kernel
def per_unit_mass(r: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = r[i] * inv_mass[i]


@wp.func
def rms(partial: wp.array(dtype=float), w: int, lanes: int, count: float) -> float:
    total = float(0.0)
    for k in range(lanes):
        total += partial[w * lanes + k]
    return wp.sqrt(total / count)


@wp.kernel
def continue_newton(partial: wp.array(dtype=float), lanes: int, free_particles: wp.array(dtype=float),
                    tolerance: float, newton: wp.array2d(dtype=int)):
    """Before another Newton step: a world stops if its residual (per unit mass, RMS) is below the tolerance."""
    w = wp.tid()
    if newton[w, 0] == 0:
        return
    if rms(partial, w, lanes, free_particles[w]) <= tolerance:
        newton[w, 0] = 0
    else:
        newton[w, 1] = newton[w, 1] + 1


@wp.kernel
def record_newton(partial: wp.array(dtype=float), lanes: int, free_particles: wp.array(dtype=float),
                  newton: wp.array2d(dtype=int), stats: wp.array(dtype=float)):
    w = wp.tid()
    wp.atomic_max(stats, 2, float(newton[w, 1]))
    wp.atomic_max(stats, 3, rms(partial, w, lanes, free_particles[w]))
