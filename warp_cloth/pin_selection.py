"""Which particles each pin of a scene holds: ``geometry_checks.validate`` checks the pins with it, and the
model pins them. It reads a cloth's initial pose (the grid's or the mesh's positions) without building the
model.
"""

from __future__ import annotations

import numpy as np

from .cloth_grid import grid_positions, pinned_indices
from .errors import SceneError
from .mesh_cloth import mesh_positions
from .scene import Cloth, Scene


def select_pins(scene: Scene) -> list[list[np.ndarray]]:
    """Per cloth, per pin, the particles it selects (cloth-local indices); a SceneError if a pin selects
    nothing, an index out of range, or a particle another pin already holds."""
    selections = []
    for c, cloth in enumerate(scene.cloths):
        if not cloth.pins:
            selections.append([])
            continue
        # Only a region needs the particles' positions: a whole grid's worth, skipped for corners and edges.
        positions = initial_positions(cloth) if any(pin.region is not None for pin in cloth.pins) else None
        owner: dict[int, str] = {}
        chosen_per_pin = []
        for p, pin in enumerate(cloth.pins):
            key = f"cloth[{c}].pins[{p}]"
            chosen = pinned_indices(cloth, pin, positions, key)
            for i in chosen.tolist():
                if i in owner:
                    raise SceneError(key, f"pins that select each particle once (particle {i} is also pinned "
                                          f"by {owner[i]})", has_got=False)
                owner[i] = key
            chosen_per_pin.append(chosen)
        selections.append(chosen_per_pin)
    return selections


def initial_positions(cloth: Cloth) -> np.ndarray:
    """A cloth's particles in its initial pose, (n, 3) float64, without building the rest of it."""
    return grid_positions(cloth) if cloth.mesh is None else mesh_positions(cloth)
