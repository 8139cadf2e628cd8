"""warp-cloth: mass-spring cloth on NVIDIA Warp kernels, on the CPU or a CUDA GPU.

    import warp_cloth
    scene = warp_cloth.load_scene("hanging")
    sim = warp_cloth.Simulator(scene, device="cpu")
    sim.run(24)
    print(sim.positions()[:3])
"""

from __future__ import annotations

import importlib
import importlib.metadata
from typing import TYPE_CHECKING

from .errors import SceneError, UnstableSimulation
from .materials import Material
from .scene import (Box, Cloth, Collision, Ground, ImplicitSolver, Limit, MeshCollider, MeshSource, Near,
                    Oscillation, Output, Pin, Scene, Seam, SeamSide, Simulation, Sphere, SpringKind, TransformKey,
                    Wind, WindKey)

if TYPE_CHECKING:
    from .batch import Batch
    from .metrics import MetricsWriter
    from .preview import render_preview
    from .scene_file import builtin_scene_names, load_scene, scene_from_dict
    from .simulator import RunSummary, Simulator
    from .stability import UnstableStepWarning
    from .strain import StrainMonitor, StrainReport
    from .warp_init import set_verbose
    from .writers import CheckpointWriter, PolyWriter, UsdWriter

# Imported at first use: they load numpy, Warp and USD (seconds on a first run), which the command line
# does only once it can answer Ctrl-C with one line instead of a traceback.
_IMPORTED_AT_FIRST_USE = {
    "Batch": "batch", "MetricsWriter": "metrics", "render_preview": "preview",
    "builtin_scene_names": "scene_file", "load_scene": "scene_file", "scene_from_dict": "scene_file",
    "RunSummary": "simulator", "Simulator": "simulator", "PolyWriter": "writers", "UsdWriter": "writers",
    "CheckpointWriter": "writers",
    "UnstableStepWarning": "stability", "StrainMonitor": "strain", "StrainReport": "strain",
    "set_verbose": "warp_init",
}

try:  # pyproject.toml's, as installed: the one place the version is written
    __version__ = importlib.metadata.version("warp-cloth")
except importlib.metadata.PackageNotFoundError:  # a source tree on sys.path, never installed
    __version__ = "0+unknown"

__all__ = [
    "Batch", "Box", "CheckpointWriter", "Cloth", "Collision", "Ground", "ImplicitSolver", "Limit", "Material",
    "MeshCollider",
    "MeshSource", "MetricsWriter", "Near",
    "Oscillation", "Output",
    "Pin", "PolyWriter", "RunSummary", "Scene", "SceneError", "Seam", "SeamSide", "Simulation", "Simulator", "Sphere", "SpringKind",
    "StrainMonitor", "StrainReport", "TransformKey", "Wind", "WindKey",
    "UnstableSimulation", "UnstableStepWarning", "UsdWriter", "builtin_scene_names", "load_scene", "render_preview",
    "scene_from_dict", "set_verbose",
]


def __getattr__(name: str) -> object:
    module = _IMPORTED_AT_FIRST_USE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
