"""Pinned particles: held at their rest position, or driven along an oscillation with its velocity."""

import warp as wp

from .motion import clock_time, oscillation_offset, oscillation_velocity


@wp.kernel
def hold_pins(index: wp.array(dtype=int), anchor: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3),
              v: wp.array(dtype=wp.vec3)):
    p = wp.tid()
    i = index[p]
    x[i] = anchor[p]
    v[i] = wp.vec3(0.0)


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
