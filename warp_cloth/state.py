"""The simulation state on the device: positions and velocities, double buffered, and the clock."""

from __future__ import annotations

import numpy as np
import warp as wp


class DeviceState:
    """``x``/``v`` are the current state; ``x_next``/``v_next`` receive a stage's output, after which the
    stage swaps them. ``parity`` says which buffer of each pair is current: a captured CUDA graph replays
    fixed buffers, so it is only valid at the parity it was captured at."""

    def __init__(self, positions: np.ndarray, velocities: np.ndarray, device: wp.context.Device) -> None:
        x = wp.array(positions, dtype=wp.vec3, device=device)
        v = wp.array(velocities, dtype=wp.vec3, device=device)
        self._x = (x, wp.empty_like(x))
        self._v = (v, wp.empty_like(v))
        self.clock = wp.zeros(1, dtype=int, device=device)
        self.device = device
        self.parity = 0

    @property
    def x(self) -> wp.array:
        return self._x[self.parity & 1]

    @property
    def x_next(self) -> wp.array:
        return self._x[1 - (self.parity & 1)]

    @property
    def v(self) -> wp.array:
        return self._v[(self.parity >> 1) & 1]

    @property
    def v_next(self) -> wp.array:
        return self._v[1 - ((self.parity >> 1) & 1)]

    def swap_positions(self) -> None:
        self.parity ^= 1

    def swap_velocities(self) -> None:
        self.parity ^= 2
