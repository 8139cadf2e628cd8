"""Pins the strain limit can follow: driven pins that move farther apart than their cloth can stretch make
the limit impossible, so such a scene is refused rather than silently overstretched."""

from __future__ import annotations

import numpy as np

from .errors import SceneError
from .model import Model
from .scene import Scene
from .shot_clock import shot_clock

SAMPLES = 2000  # times over the run at which the pins' distances are checked
MOST_PINS = 256  # pinned particles of a cloth checked (evenly chosen where it has more)
PAIRS_AT_ONCE = 4096


def check_pins_within_reach(scene: Scene, model: Model) -> None:
    """A SceneError if two pinned particles of a strain-limited cloth move farther apart than (1 + stretch)
    times their distance across the cloth at rest (its flat grid: the geodesic distance), at any of
    ``SAMPLES`` times over the run."""
    pins = model.pins
    if pins is None or not pins.moving:
        return
    clock = shot_clock(scene)
    times = np.linspace(clock.first_time, clock.end_time, SAMPLES)
    for c, cloth in enumerate(scene.cloths):
        if cloth.strain_limit is None:
            continue
        rows = np.nonzero((pins.index >= model.offsets[c]) & (pins.index < model.offsets[c + 1]))[0]
        if len(rows) > MOST_PINS:
            rows = rows[np.linspace(0, len(rows) - 1, MOST_PINS).astype(int)]
        if len(rows) < 2 or not np.any(pins.amplitude[rows]):
            continue
        rest = model.cloths[c].positions[pins.index[rows] - model.offsets[c]]
        offsets = (pins.amplitude[rows].astype(np.float64)[:, None, :]
                   * np.sin(2.0 * np.pi * pins.frequency[rows, None] * times[None, :]
                            + pins.phase[rows, None])[:, :, None])  # (pins, times, 3)
        a, b = np.triu_indices(len(rows), k=1)
        for start in range(0, len(a), PAIRS_AT_ONCE):
            p, q = a[start:start + PAIRS_AT_ONCE], b[start:start + PAIRS_AT_ONCE]
            across = np.linalg.norm(rest[p] - rest[q], axis=1)
            apart = np.linalg.norm((rest[p] - rest[q])[:, None, :] + offsets[p] - offsets[q], axis=2)
            allowed = (1.0 + cloth.strain_limit.stretch) * across
            excess = apart.max(axis=1) - allowed
            worst = int(np.argmax(excess))
            if excess[worst] > 1e-6 * max(allowed[worst], 1e-12):
                k = int(np.argmax(apart[worst]))
                i, j = pins.index[rows[p[worst]]] - model.offsets[c], pins.index[rows[q[worst]]] - model.offsets[c]
                raise SceneError(f"cloth[{c}].pins", f"pins that '{cloth.name}' can follow within its "
                                 f"{100 * cloth.strain_limit.stretch:.3g}% stretch limit: particles {i} and {j} move "
                                 f"{apart[worst, k]:.3g} m apart at t = {times[k]:.3g} s, across "
                                 f"{across[worst]:.3g} m of cloth (at most {allowed[worst]:.3g} m); move them less "
                                 "or along other axes", has_got=False)
