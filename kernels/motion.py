"""Prescribed motion: the simulation clock and oscillations x0 + A sin(2 pi f t + phase) along an axis."""

import warp as wp


@wp.func
def oscillation_offset(t: float, amplitude: wp.vec3, frequency: float, phase: float) -> wp.vec3:
    return amplitude * wp.sin(2.0 * wp.pi * frequency * t + phase)


@wp.func
def oscillation_velocity(t: float, amplitude: wp.vec3, frequency: float, phase: float) -> wp.vec3:
    omega = 2.0 * wp.pi * frequency
    return amplitude * (omega * wp.cos(omega * t + phase))


@wp.func
def clock_time(clock: wp.array(dtype=int), h: float) -> float:
    """Time at the end of the current substep (the clock counts finished substeps)."""
    return float(clock[0] + 1) * h


@wp.kernel
def advance_clock(clock: wp.array(dtype=int)):
    clock[0] = clock[0] + 1


@wp.kernel
def move_spheres(clock: wp.array(dtype=int), h: float, base: wp.array(dtype=wp.vec3),
                 amplitude: wp.array(dtype=wp.vec3), frequency: wp.array(dtype=float),
                 phase: wp.array(dtype=float), center: wp.array(dtype=wp.vec3), velocity: wp.array(dtype=wp.vec3)):
    s = wp.tid()
    t = clock_time(clock, h)
    center[s] = base[s] + oscillation_offset(t, amplitude[s], frequency[s], phase[s])
    velocity[s] = oscillation_velocity(t, amplitude[s], frequency[s], phase[s])
