"""Seams closing: each sewn pair's allowed length, its start distance shrunk linearly to 0 over its closing
time, written where the strain limits keep it (limits.py projects and checks it as any limited spring's)."""

import warp as wp

from .motion import clock_time


@wp.kernel
def close_seams(clock: wp.array(dtype=int), h: float, entry: wp.array(dtype=int),
                start_length: wp.array(dtype=float), close_time: wp.array(dtype=float),
                closes_at: wp.array(dtype=float), max_length: wp.array(dtype=float)):
    k = wp.tid()
    left = wp.clamp((closes_at[k] - clock_time(clock, h)) / close_time[k], 0.0, 1.0)
    max_length[entry[k]] = start_length[k] * left
