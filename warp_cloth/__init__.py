"""warp-cloth: mass-spring cloth on NVIDIA Warp kernels, on the CPU or a CUDA GPU.

    import warp_cloth
    scene = warp_cloth.load_scene("hanging")
    sim = warp_cloth.Simulator(scene, device="cpu")
    sim.run(24)
    print(sim.positions()[:3])
"""

from .errors import SceneError
from .scene import (Box, Cloth, Collision, Ground, ImplicitSolver, Limit, Oscillation, Output, Pin, Scene,
                    Simulation, Sphere, SpringKind)
from .scene_file import builtin_scene_names, load_scene, scene_from_dict
from .simulator import RunSummary, Simulator
from .writers import CheckpointWriter, PolyWriter, UsdWriter

__version__ = "0.1.0"

__all__ = [
    "Box", "CheckpointWriter", "Cloth", "Collision", "Ground", "ImplicitSolver", "Limit", "Oscillation", "Output", "Pin", "PolyWriter",
    "RunSummary", "Scene", "SceneError", "Simulation", "Simulator", "Sphere", "SpringKind", "UsdWriter",
    "builtin_scene_names", "load_scene", "scene_from_dict",
]
