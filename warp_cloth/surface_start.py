"""The start check of a scene with a surface thickness (``[collision] thickness``, issue 34): surfaces of two
cloths that start closer than the thickness would be pushed apart at their overlap over a substep, and the
displacement bounds' guarantee holds only between triangles apart at the start. Refused with one line naming
the cloths and the gap; layers at least a thickness apart are accepted at any resolution (the distances are the
surfaces', not the particles'). Only pairs that are contacts count (surface_pairs.py), so a cloth alone is never
refused: its rest state is where it starts, and its pairs nearer than the thickness there are none (triangles
finer than the thickness, a mesh's layers closer than it)."""

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
                                          bounds: DisplacementBounds | None, x: wp.array) -> None:
    """Raises ``SceneError`` where a vertex-triangle or edge-edge pair that is a contact starts closer than the
    scene's thickness; nothing where the scene sets none. Measured by the simulator's ``bounds`` (a thickness
    has them), or by bounds of its own where a lab's query radius is below the thickness."""
    thickness = None if scene.collision is None else scene.collision.thickness
    if thickness is None:
        return
    measure = bounds if bounds is not None and bounds.settings.radius >= thickness else \
        DisplacementBounds(model, device_model, BoundSettings(radius=thickness))
    measure.measure_at(x)
    nearest = measure.nearest.numpy()
    gap = float(nearest.min(initial=thickness))
    slack = ROUNDING_SLACK * float(np.finfo(np.float32).eps) * float(np.abs(x.numpy()).max(initial=0.0))
    if gap >= thickness - slack:
        return
    cloths = sorted({int(c) for c in model.cloth_id[nearest <= gap]})
    names = " and ".join(f"'{scene.cloths[c].name}'" for c in cloths)
    raise SceneError("collision.thickness", f"surfaces at least the thickness apart at the start: those of {names} "
                                            f"start {gap:.3g} m apart, the thickness is {thickness:.3g} m; move the "
                                            "cloths apart or make the thickness smaller", has_got=False)
