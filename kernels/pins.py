"""Driven pins: moved along their oscillation, with its velocity. (A fixed pin needs no kernel: its
particle has inverse mass 0, starts at rest at its anchor, and nothing moves it.)"""

import warp as wp

from .motion import clock_time, oscillation_offset, oscillation_velocity


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
