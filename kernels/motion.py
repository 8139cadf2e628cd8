"""Prescribed motion: the simulation clock, and oscillations x0 + A sin(2 pi f t + phase) along an axis that
drive pins and move spheres. (A fixed pin needs no kernel: its particle has inverse mass 0, starts at rest
at its anchor, and nothing moves it.)"""

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


@wp.kernel
def drive_pins(index: wp.array(dtype=int), anchor: wp.array(dtype=wp.vec3), amplitude: wp.array(dtype=wp.vec3),
               frequency: wp.array(dtype=float), phase: wp.array(dtype=float), clock: wp.array(dtype=int),
               h: float, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    p = wp.tid()
    i = index[p]
    t = clock_time(clock, h)
    x[i] = anchor[p] + oscillation_offset(t, amplitude[p], frequency[p], phase[p])
    v[i] = oscillation_velocity(t, amplitude[p], frequency[p], phase[p])


@wp.kernel
def pinned_velocity_change(index: wp.array(dtype=int), amplitude: wp.array(dtype=wp.vec3),
                           frequency: wp.array(dtype=float), phase: wp.array(dtype=float), clock: wp.array(dtype=int),
                           h: float, v: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3)):
    """For an implicit solve: the change that brings each pinned particle to its prescribed velocity at the
    end of the substep (zero for fixed pins)."""
    p = wp.tid()
    i = index[p]
    dv[i] = oscillation_velocity(clock_time(clock, h), amplitude[p], frequency[p], phase[p]) - v[i]


@wp.kernel
def place_keyed_points(clock: wp.array(dtype=int), h: float, key_times: wp.array(dtype=float),
                       keys: wp.array2d(dtype=wp.vec3), points: wp.array(dtype=wp.vec3),
                       velocities: wp.array(dtype=wp.vec3)):
    """An animated mesh's vertex where its keys put it at the end of the substep, linearly between the two
    keys around that time, with the velocity between them; before the first key and after the last it
    holds still there."""
    j = wp.tid()
    t = clock_time(clock, h)
    last = key_times.shape[0] - 1
    if t <= key_times[0]:
        points[j] = keys[0, j]
        velocities[j] = wp.vec3(0.0)
        return
    if t >= key_times[last]:
        points[j] = keys[last, j]
        velocities[j] = wp.vec3(0.0)
        return
    k = int(0)
    while key_times[k + 1] < t:
        k += 1
    span = key_times[k + 1] - key_times[k]
    step = keys[k + 1, j] - keys[k, j]
    points[j] = keys[k, j] + ((t - key_times[k]) / span) * step
    velocities[j] = step / span
