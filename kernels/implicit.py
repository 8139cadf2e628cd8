"""Backward Euler (Baraff & Witkin 1998), matrix free: the system of a Newton step, the end of a step and
the Newton loop's bookkeeping.

Unknown: the velocity change dv of a step, from (M - h df/dv - h^2 df/dx) dv = rhs. The right-hand side,
the products with that matrix and its diagonal blocks are gathers over each particle's springs and bending
stencils (the Jacobians of kernels/springs.py, rebuilt from positions on the fly, and the constant ones of
kernels/bending.py: no matrix is ever assembled), with the external forces' part (kernels/forces.py): the
system's kernels, last below. Pinned particles (inverse mass 0) are held by Baraff & Witkin's filter: their
dv is prescribed and their rows are zeroed in every residual and search direction, so the solve never
moves them.

Each world (warp_cloth/batch.py; a scene alone is one) runs its own Newton loop: ``newton[w]`` = [on (0 once
converged), steps taken this substep]. The worst values over the worlds since the host last read them are
in ``stats`` = [CG iterations, r.z / r0.z0 at the end of a solve, Newton steps, Newton residual (RMS of
|M (v - v0) - h f| / m, m/s)] (the first two: cg.record_solve).
"""

import warp as wp

from .bending import Bending, add_bending_diagonal, add_bending_times, bending_forces, bending_stiffness_times
from .cg import world_total
from .forces import ExternalForces, external_acceleration, external_damping, external_stiffness
from .springs import Springs, add_system_diagonal, add_system_times, spring_forces, stiffness_times_motion


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
def warm_start(inv_mass: wp.array(dtype=float), dv: wp.array(dtype=wp.vec3)):
    """The last substep's dv as this one's first guess, for the free particles (a pinned particle's is 0, or
    prescribed after)."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        dv[i] = wp.vec3(0.0)


@wp.kernel
def start_newton(newton: wp.array2d(dtype=int)):
    w = wp.tid()
    newton[w, 0] = 1
    newton[w, 1] = 1


@wp.kernel
def per_unit_mass(r: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = r[i] * inv_mass[i]


@wp.kernel
def continue_newton(partial: wp.array(dtype=float), lanes: int, free_particles: wp.array(dtype=float),
                    tolerance: float, newton: wp.array2d(dtype=int)):
    """Before another Newton step (a block a world, cg.world_total): a world stops if its residual (per unit
    mass, RMS, from its partial sums of the squares) is below the tolerance."""
    w, lane = wp.tid()
    if newton[w, 0] == 0:  # the same for the whole block
        return
    rms = wp.sqrt(world_total(partial, w, lanes, lane) / free_particles[w])
    if lane != 0:
        return
    if rms <= tolerance:
        newton[w, 0] = 0
    else:
        newton[w, 1] = newton[w, 1] + 1


@wp.kernel
def record_newton(partial: wp.array(dtype=float), lanes: int, free_particles: wp.array(dtype=float),
                  newton: wp.array2d(dtype=int), stats: wp.array(dtype=float)):
    """A block a world (cg.world_total): the worst Newton steps and residual (RMS per unit mass) so far."""
    w, lane = wp.tid()
    rms = wp.sqrt(world_total(partial, w, lanes, lane) / free_particles[w])
    if lane == 0:
        wp.atomic_max(stats, 2, float(newton[w, 1]))
        wp.atomic_max(stats, 3, rms)


# --- the system: the springs' Jacobians with the external forces' part ----------------------------------

@wp.struct
class SpringSystemArgs:
    springs: Springs
    bending: Bending
    forces: ExternalForces
    mass: wp.array(dtype=float)
    inv_mass: wp.array(dtype=float)
    h: float


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def newton_rhs(y: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), v0: wp.array(dtype=wp.vec3),
               args: SpringSystemArgs, linearized_at_start: int, rhs: wp.array(dtype=wp.vec3)):
    """Right-hand side of one Newton step for v' with M (v' - v0) = h f(x0 + h v', v').

    With forces evaluated at y = x0 + h v, this is h f(y, v) - M (v - v0). Baraff & Witkin's single step
    linearises at the start of the step instead (y = x0, v = v0), which adds h^2 K v0 for the motion
    x0 -> x0 + h v0 that y leaves out: ``linearized_at_start`` = 1 selects that."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        rhs[i] = wp.vec3(0.0)
        return
    m = args.mass[i]
    f = spring_forces(args.springs, i, 0, 1, y, v) + bending_forces(args.bending, i, 0, 1, y, v)
    f = f + m * external_acceleration(args.forces, i, y[i], v[i])
    out = args.h * f - m * (v[i] - v0[i])
    if linearized_at_start != 0:
        out = out - (args.h * args.h) * (stiffness_times_motion(args.springs, i, y, v0)
                                         + bending_stiffness_times(args.bending, i, v0))
        if args.forces.pin_rate.shape[0] > 0:
            out = out - (args.h * args.h * m * external_stiffness(args.forces, i)) * v0[i]
    rhs[i] = out


@wp.func
def mass_term(args: SpringSystemArgs, i: int) -> float:
    """The diagonal of M - h (d external force / dv) - h^2 (d external force / dx) for particle i."""
    if args.forces.pin_rate.shape[0] > 0:
        h = args.h
        return args.mass[i] * (1.0 + h * external_damping(args.forces, i) + h * h * external_stiffness(args.forces, i))
    return args.mass[i] * (1.0 + args.h * external_damping(args.forces, i))


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def system_times(y: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3), active: wp.array(dtype=int),
                 args: SpringSystemArgs, out: wp.array(dtype=wp.vec3)):
    """out = A p on free particles, 0 on pinned ones (the filter). Does nothing in a world whose ``active``
    is 0."""
    i = wp.tid()
    if active[args.forces.world[i]] == 0:
        return
    if args.inv_mass[i] == 0.0:
        out[i] = wp.vec3(0.0)
        return
    total = add_system_times(args.springs, i, y, p, args.h, mass_term(args, i) * p[i])
    out[i] = add_bending_times(args.bending, i, p, args.h, total)


@wp.kernel(module="unique")  # without fast math, as the rest of the implicit solve
def block_jacobi_inverse(y: wp.array(dtype=wp.vec3), args: SpringSystemArgs, inverse: wp.array(dtype=wp.mat33)):
    """The inverse of each particle's 3x3 diagonal block of A: the preconditioner (0 on pinned)."""
    i = wp.tid()
    if args.inv_mass[i] == 0.0:
        inverse[i] = wp.mat33(0.0)
        return
    block = add_system_diagonal(args.springs, i, y, args.h, mass_term(args, i) * wp.identity(n=3, dtype=float))
    block = add_bending_diagonal(args.bending, i, args.h, block)
    inverse[i] = wp.inverse(block)
