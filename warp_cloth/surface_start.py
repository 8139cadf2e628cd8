"""The start check of a scene with a surface thickness (``[collision] thickness``, issue 34): surfaces that
start closer than the thickness, of two cloths or of one (a fold, or triangles finer than the thickness), would
be pushed apart at their overlap over a substep, and the displacement bounds' guarantee holds only between
triangles apart at the start. Refused with one line naming the cloths and the gap; layers at least a thickness
apart are accepted at any resolution (the distances are the surfaces', not the particles')."""

from __future__ import annotations

import numpy as np
import warp as wp

from .device_model import DeviceModel
from .displacement_bounds import BoundSettings, DisplacementBounds
from .errors import SceneError
from .model import Model
from .scene import Scene

ROUNDING_SLACK = 4.0  # float32 roundings of the largest coordinate: a gap of the thickness measures that short


def refuse_surfaces_closer_than_thickness(scene: Scene, model: Model, device_model: DeviceModel,
                                          x: wp.array) -> None:
    """Raises ``SceneError`` where a vertex-triangle or edge-edge pair sharing no vertex (any cloths, one
    world) starts closer than the scene's thickness; nothing where the scene sets none."""
    thickness = None if scene.collision is None else scene.collision.thickness
    if thickness is None:
        return
    measure = DisplacementBounds(model, device_model, BoundSettings(radius=thickness))
    measure.measure_at(x)
    nearest = measure.nearest.numpy()
    gap = float(nearest.min(initial=thickness))
    slack = ROUNDING_SLACK * float(np.finfo(np.float32).eps) * float(np.abs(x.numpy()).max(initial=0.0))
    if gap >= thickness - slack:
        return
    cloths = sorted({int(c) for c in model.cloth_id[nearest <= gap]})
    names = " and ".join(f"'{scene.cloths[c].name}'" for c in cloths)
    whose = f"{names} (a fold, or triangles finer than the thickness)" if len(cloths) == 1 else names
    raise SceneError("collision.thickness", f"surfaces at least the thickness apart at the start: those of {whose} "
                                            f"start {gap:.3g} m apart, the thickness is {thickness:.3g} m; move the "
                                            "cloths apart or make the thickness smaller", has_got=False)
