"""The drape test's table for the docs: every preset with a published range at the default resolution and
twice it, each run to the scene's frames (not stopped when settled), its drape coefficient every second of
simulated time, so that how far the settling criterion is from rest shows:

    python tools/drape_table.py [--device cuda] [--frames 240] [--resolutions 30 60] [--json OUT]
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from warp_cloth import drape_geometry as geometry
from warp_cloth.drape_test import SETTLED_FRAMES, SETTLED_SPEED, drape_scene
from warp_cloth.fabric_presets import PRESETS
from warp_cloth.materials import Material
from warp_cloth.simulator import Simulator


def measure(preset: str, resolution: int, device: str | None, frames: int, bending_scale: float = 1.0) -> dict:
    import tempfile

    material = Material(preset=preset)
    if bending_scale != 1.0:
        material = Material(preset=preset, bending=tuple(bending_scale * b for b in material.bending))
    with tempfile.TemporaryDirectory() as folder:
        sim = Simulator(drape_scene(material, resolution, Path(folder)), device=device)
        sim.prepare()
    mesh = geometry.specimen(resolution)
    triangles, area = mesh.triangles(), mesh.area
    fps = sim.scene.simulation.fps
    history, calm, settled_at, started = [], 0, None, time.perf_counter()
    for frame in range(1, frames + 1):
        sim.step()
        fastest = float(np.linalg.norm(sim.velocities(), axis=1).max())
        calm = calm + 1 if fastest < SETTLED_SPEED else 0
        if calm >= SETTLED_FRAMES and settled_at is None:
            settled_at = frame
            dc_settled = geometry.drape_coefficient(geometry.projected_area(sim.positions(), triangles).area, area)
        if frame % int(fps) == 0:
            dc = geometry.drape_coefficient(geometry.projected_area(sim.positions(), triangles).area, area)
            history.append((frame, round(dc, 4), fastest))
    return {"preset": preset, "bending_scale": bending_scale, "resolution": resolution, "substeps_per_frame": sim.substeps_per_frame,
            "particles": sim.model.particle_count, "seconds": time.perf_counter() - started,
            "settled_at": settled_at, "dc_settled": None if settled_at is None else round(dc_settled, 4),
            "history": history}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device")
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--resolutions", type=int, nargs="+", default=[30, 60])
    parser.add_argument("--presets", nargs="+", default=list(PRESETS))
    parser.add_argument("--bending-scales", type=float, nargs="+", default=[1.0],
                        help="the preset's bending stiffness times these (the coefficient's sensitivity to it)")
    parser.add_argument("--json")
    args = parser.parse_args()
    rows = []
    runs = [(p, r, s) for p in args.presets for r in args.resolutions for s in args.bending_scales]
    for preset, resolution, scale in runs:
        row = measure(preset, resolution, args.device, args.frames, scale)
        rows.append(row)
        print(json.dumps(row), flush=True)
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=1))

if __name__ == "__main__":
    main()
