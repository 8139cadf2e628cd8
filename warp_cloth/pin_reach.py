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
        rows = _some(np.nonzero((pins.index >= model.offsets[c]) & (pins.index < model.offsets[c + 1]))[0])
        if len(rows) < 2 or not np.any(pins.amplitude[rows]):
            continue
        rest = model.cloths[c].positions[pins.index[rows] - model.offsets[c]]
        offsets = (pins.amplitude[rows].astype(np.float64)[:, None, :]
                   * np.sin(2.0 * np.pi * pins.frequency[rows, None] * times[None, :]
                            + pins.phase[rows, None])[:, :, None])  # (pins, times, 3)
        a, b = np.triu_indices(len(rows), k=1)
        worst = farthest_past_reach(rest, rest[:, None, :] + offsets, a, b, cloth.strain_limit.stretch)
        if worst is not None:
            p, q, k, apart, across, allowed = worst
            i, j = pins.index[rows[p]] - model.offsets[c], pins.index[rows[q]] - model.offsets[c]
            raise SceneError(f"cloth[{c}].pins", f"pins that '{cloth.name}' can follow within its "
                             f"{100 * cloth.strain_limit.stretch:.3g}% stretch limit: particles {i} and {j} move "
                             f"{apart:.3g} m apart at t = {times[k]:.3g} s, across "
                             f"{across:.3g} m of cloth (at most {allowed:.3g} m); move them less "
                             "or along other axes", has_got=False)


def sent_pins_past_reach(scene: Scene, model: Model, sent: np.ndarray, where: np.ndarray) -> str | None:
    """Where hard pins are sent from Python (``control.py``): particles ``sent`` to go to ``where[sent]``
    (``where``: (n, 3) every particle once the sends are reached). What is wrong where two hard pins of a
    strain-limited cloth, one of them sent, would be farther apart than (1 + stretch) times their distance
    at rest, a limit no solve can then hold; None where none would."""
    pins = model.pins
    hard = pins.index[~pins.soft]
    for c, cloth in enumerate(scene.cloths):
        first, end = model.offsets[c], model.offsets[c + 1]
        moved = _some(np.unique(sent[(sent >= first) & (sent < end)]))
        others = _some(hard[(hard >= first) & (hard < end)])
        if cloth.strain_limit is None or len(moved) == 0:
            continue
        particles = np.concatenate([moved, others])
        a, b = np.divmod(np.arange(len(moved) * len(others)), len(others))
        b += len(moved)
        rest = model.cloths[c].positions[particles - first]
        worst = farthest_past_reach(rest, where[particles, None, :], a, b, cloth.strain_limit.stretch)
        if worst is not None:
            p, q, _, apart, across, allowed = worst
            return (f"pins that '{cloth.name}' can follow within its {100 * cloth.strain_limit.stretch:.3g}% "
                    f"stretch limit: its pinned particles {particles[p] - first} and {particles[q] - first} "
                    f"would be {apart:.3g} m apart, across {across:.3g} m of cloth (at most {allowed:.3g} m)")
    return None


def farthest_past_reach(rest: np.ndarray, where: np.ndarray, a: np.ndarray, b: np.ndarray,
                        stretch: float) -> tuple[int, int, int, float, float, float] | None:
    """Of the pairs (a, b) of pins at ``rest`` (n, 3) and at ``where`` (n, times, 3): the one farthest past
    (1 + stretch) times its distance at rest, as (p, q, the time's column, how far apart, the distance at
    rest, the distance allowed); None where every pair is within it."""
    worst, most = None, 0.0
    for start in range(0, len(a), PAIRS_AT_ONCE):
        p, q = a[start:start + PAIRS_AT_ONCE], b[start:start + PAIRS_AT_ONCE]
        across = np.linalg.norm(rest[p] - rest[q], axis=1)
        apart = np.linalg.norm(where[p] - where[q], axis=2)
        allowed = (1.0 + stretch) * across
        excess = apart.max(axis=1) - allowed
        w = int(np.argmax(excess))
        if excess[w] > 1e-6 * max(allowed[w], 1e-12) and excess[w] > most:
            k = int(np.argmax(apart[w]))
            worst, most = (int(p[w]), int(q[w]), k, float(apart[w, k]), float(across[w]), float(allowed[w])), excess[w]
    return worst


def _some(rows: np.ndarray) -> np.ndarray:
    """At most ``MOST_PINS`` of ``rows``, evenly chosen."""
    return rows[np.linspace(0, len(rows) - 1, MOST_PINS).astype(int)] if len(rows) > MOST_PINS else rows
