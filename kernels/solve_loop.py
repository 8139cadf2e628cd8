"""The bookkeeping of an iterative solve whose loop runs on the device (``wp.capture_while`` over ``active``):
it goes on while the residual its passes leave is above the tolerance and the passes taken are below the
cap, and keeps the worst figures since the host last read them.

``counts`` = [passes this substep, cap, passes after which ``switched`` is set]; ``residual`` = [the worst violation the last check found];
``stats`` = [most passes a substep, largest residual a solve ended with, passes in all, solves] since they
were last read."""

import warp as wp


@wp.kernel
def start_solve(max_passes: int, switch_at: int, active: wp.array(dtype=int), counts: wp.array(dtype=int),
                residual: wp.array(dtype=float), switched: wp.array(dtype=int)):
    active[0] = 1
    counts[0] = 0
    counts[1] = max_passes
    counts[2] = switch_at
    residual[0] = 0.0
    switched[0] = 0


@wp.func
def continue_or_stop(tolerance: float, passes: int, active: wp.array(dtype=int), counts: wp.array(dtype=int),
                     residual: wp.array(dtype=float), stats: wp.array(dtype=float), switched: wp.array(dtype=int)):
    """After ``passes`` more passes and a check: stop within the tolerance or at the cap, recording how it
    ended; else clear the residual for the next check, and switch the loop to its other body once the
    passes reach ``counts[2]``."""
    counts[0] = counts[0] + passes
    if counts[0] >= counts[2]:
        switched[0] = 1
    if residual[0] <= tolerance or counts[0] >= counts[1]:
        active[0] = 0
        stats[0] = wp.max(stats[0], float(counts[0]))
        stats[1] = wp.max(stats[1], residual[0])
        stats[2] = stats[2] + float(counts[0])
        stats[3] = stats[3] + 1.0
    else:
        residual[0] = 0.0


@wp.kernel
def continue_solve(tolerance: float, passes: int, active: wp.array(dtype=int), counts: wp.array(dtype=int),
                   residual: wp.array(dtype=float), stats: wp.array(dtype=float), switched: wp.array(dtype=int)):
    continue_or_stop(tolerance, passes, active, counts, residual, stats, switched)


EXTRAPOLATION_MOST = wp.constant(4.0)  # times the iteration's own move: see chebyshev_extrapolation


@wp.func
def chebyshev_extrapolation(i: int, x: wp.array(dtype=wp.vec3), omega: wp.array(dtype=float),
                            x_start: wp.array(dtype=wp.vec3), x_before: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """Chebyshev's semi-iterative acceleration of an iteration that took ``x_start`` to ``x`` (Wang 2015):
    particle i's x' = omega (x - x_before) + x_before; the iterates shift (x_start then holds x'). ``omega``
    as ``start_chebyshev`` says; an accelerated iteration's only (the plain ones only shift the iterates:
    converged_projection.chebyshev_step_and_colliders).

    The extrapolation beyond x is at most EXTRAPOLATION_MOST times the iteration's own move (x - x_start), so
    a particle that the passes leave where it is stays there. Unbounded, it goes on by its earlier moves: a
    contact that one pass separated, free on its far side, is carried on past it, which no check sees (the
    pair is within tolerance), and the move becomes velocity: seed_default's crumpled cloth on the CPU gained
    speed to 153 m/s and took 2,400 s to frame 233; bounded at 4, its particles stay at their fall's 42 m/s
    and the run takes 720 s. At 1 pile's solves took 12.6 passes a substep against 7.7 unbounded, at 2 one
    reached the cap; at 4, 9.1 (docs/notebook/layers.md, "The extrapolation bounded")."""
    xs = x_start[i]
    xb = x_before[i]
    xi = x[i]
    xn = omega[0] * (xi - xb) + xb
    ahead = xn - xi
    beyond = wp.length(ahead)
    most = EXTRAPOLATION_MOST * wp.length(xi - xs)
    if beyond > most:
        xn = xi + ahead * (most / beyond)
    x_before[i] = xs
    x_start[i] = xn
    return xn


@wp.func
def next_chebyshev_weight(omega: wp.array(dtype=float)):
    """1 (and 1 before it from a solve's start), then 2 / (2 - rho^2), then 4 / (4 - rho^2 omega)."""
    k = omega[2] + 1.0
    omega[2] = k
    if k < 1.5:
        omega[0] = 1.0
    elif k < 2.5:
        omega[0] = 2.0 / (2.0 - omega[1])
    else:
        omega[0] = 4.0 / (4.0 - omega[1] * omega[0])


CHEBYSHEV_SLOTS = 6
RESTART_GROWTH = wp.constant(1.5)
RHO_MOST = wp.constant(0.95)  # the estimate's start and the most it rises to
FAR = wp.constant(4.0)  # tolerances: a solve's first iteration left it so far out that it will take more


@wp.func
def set_rho(omega: wp.array(dtype=float), gap: float):
    """The spectral radius 1 - ``gap``, at most RHO_MOST."""
    rho = 1.0 - wp.clamp(gap, 1.0 - RHO_MOST, 1.0)
    omega[4] = rho
    omega[1] = rho * rho


@wp.kernel
def start_chebyshev(omega: wp.array(dtype=float)):
    """A solve's first iteration, and its second unless the first left it more than FAR tolerances out
    (plain ones: an easy substep's solve, of one or two iterations, ends as plain passes end it). ``omega`` = [this iteration's weight, the spectral radius
    squared, iterations since the acceleration (re)started, the last residual, the spectral radius, 1 where
    the solver estimates it (0: the scene's, fixed)]. An estimated radius starts from the one the solve
    before ended with, halfway back to RHO_MOST (from 1 - it)."""
    omega[2] = -1.0
    omega[3] = 1.0e30
    if omega[5] > 0.5:
        set_rho(omega, 0.5 * (1.0 - omega[4]))
    next_chebyshev_weight(omega)


@wp.kernel
def continue_chebyshev_solve(tolerance: float, passes: int, active: wp.array(dtype=int),
                             counts: wp.array(dtype=int), residual: wp.array(dtype=float),
                             stats: wp.array(dtype=float), switched: wp.array(dtype=int),
                             omega: wp.array(dtype=float)):
    """``continue_solve`` of an accelerated solve, and the next iteration's weight. Where an iteration left a
    residual more than RESTART_GROWTH times the one before (a collider's projection undoing the
    extrapolation), the acceleration starts over: the next iteration is a plain one. Without it the
    matrix's sphere cloth never converged (30 to 50 tolerances at 300 passes); at every growth the hanging
    cloth took 2 to 8 times as many passes (docs/notebook/strain-solve.md). Where the solver estimates the
    radius, any growth is the evidence that the extrapolation outruns the passes (Chebyshev's method holds
    only while the radius is at least the iteration's own): it starts over with the radius's distance from
    1 doubled (0.95, 0.9, 0.8, 0.6, 0.2, then plain passes). Growths under 1.5 times let the pile's
    accelerated solves wander 10 to 40 tolerances out for their 1000 passes (docs/notebook/strain-solve.md).
    So does the loop's switch to its other body (``switched``): the iterates before it are another
    iteration's. A first iteration that left more than FAR tolerances has the second accelerated. One kernel
    for all of it, as the loop's launches are what a small cloth's iteration costs."""
    if residual[0] > RESTART_GROWTH * omega[3]:
        omega[2] = 0.0
        if omega[5] > 0.5:
            set_rho(omega, 2.0 * (1.0 - omega[4]))
    elif omega[2] < 0.5 and residual[0] > FAR:
        omega[2] = 1.0  # far out after the first iteration: accelerate from the second
    omega[3] = residual[0]
    was_switched = switched[0]
    continue_or_stop(tolerance, passes, active, counts, residual, stats, switched)
    if switched[0] != was_switched:
        omega[2] = 0.0
    next_chebyshev_weight(omega)
