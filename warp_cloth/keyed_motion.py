"""Points moved along keys, on the host: where a keyed mesh or pin is at a time, and a mesh's path along
transform keys sampled for the motion kernels (kernels/motion.py places them on the device alike)."""

from __future__ import annotations

import numpy as np

from .cloth_grid import rotation_matrix
from .scene import MeshCollider


def keyed_at(times: np.ndarray, points: np.ndarray, t: float) -> np.ndarray:
    """Keyed points (``points[k]`` at ``times[k]`` seconds) at ``t``: linearly between the keys around it,
    held at the first before it and at the last after it, as the motion kernels place them."""
    after = int(np.searchsorted(times, t, side="right"))
    if after == 0 or after == len(times):
        return points[min(after, len(times) - 1)]
    w = (t - times[after - 1]) / (times[after] - times[after - 1])
    return points[after - 1] + w * (points[after].astype(np.float64) - points[after - 1])


def keyed_points(points: np.ndarray, keys, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """A mesh moved along transform keys, sampled at the keys and every frame between the first and the
    last (translations and rotation angles interpolated linearly, so that a turn stays a turn)."""
    times = np.array([k.time for k in keys])
    samples = np.union1d(times, np.arange(np.ceil(times[0] * fps), np.floor(times[-1] * fps) + 1) / fps)
    translate = np.stack([np.interp(samples, times, [k.translate[a] for k in keys]) for a in range(3)], axis=1)
    rotate = np.stack([np.interp(samples, times, [k.rotate[a] for k in keys]) for a in range(3)], axis=1)
    placed = np.stack([points @ rotation_matrix(tuple(r)).T + t for r, t in zip(rotate, translate)])
    return samples, placed


def collider_keys(collider: MeshCollider, fps: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A mesh collider's key times and its points then: its own keys', its USD time samples', or (None,
    None) for a mesh that does not move."""
    surface = collider.surface()
    if collider.keys:
        return keyed_points(surface.points, collider.keys, fps)
    return surface.key_times, surface.key_points


def collider_points_at(collider: MeshCollider, fps: float, t: float) -> np.ndarray:
    """A mesh collider's points where it is at ``t`` seconds."""
    times, points = collider_keys(collider, fps)
    return collider.surface().points if points is None else keyed_at(times, points, t)
