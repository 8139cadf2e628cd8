"""Capture where seed_default's cloths cross: run the scene with gravity scaled by 1 + k 1e-6 (as
crossing_spread.py does) and, at the first frame that ends with a crossing triangle pair, keep the checkpoint
of the frame before, then replay that frame substep by substep and keep the positions before and after the
first substep that makes the crossing.

    python tools/capture_crossing.py OUT_DIR DEVICE FRAMES K [K ...]
"""

import dataclasses
import shutil
import sys
from pathlib import Path

import numpy as np
import warp as wp

import warp_cloth as wc
from warp_cloth.diagnostics import TriangleIntersections


def scene_for(k: int, frames: int):
    base = wc.load_scene("seed_default")
    gravity = tuple(g * (1.0 + 1e-6 * k) for g in base.simulation.gravity)
    return dataclasses.replace(base, simulation=dataclasses.replace(base.simulation, gravity=gravity, frames=frames))


def capture(out: Path, device: str, frames: int, k: int) -> None:
    scene = scene_for(k, frames)
    sim = wc.Simulator(scene, device=device)
    crossings = TriangleIntersections(sim)
    before = out / f"k{k}-rolling.npz"
    for frame in range(frames):
        sim.save_checkpoint(before)
        sim.step()
        count = crossings(sim)
        if count:
            kept = out / f"k{k}-before-frame{frame + 1}.npz"
            shutil.copy(before, kept)
            print(f"k={k}: {count} crossing pairs at frame {frame + 1}; kept {kept.name}", flush=True)
            replay(out, scene, device, kept, k, frame + 1)
            break
    else:
        print(f"k={k}: no crossing in {frames} frames", flush=True)
    before.unlink(missing_ok=True)


def replay(out: Path, scene, device: str, checkpoint: Path, k: int, frame: int) -> None:
    sim = wc.Simulator(scene, device=device, graph=False)
    sim.restore(checkpoint)
    crossings = TriangleIntersections(sim)
    for substep in range(sim.substeps_per_frame):
        x0, v0 = sim.positions().copy(), sim.velocities().copy()
        sim.substep()
        count = crossings(sim)
        if count:
            np.savez(out / f"k{k}-frame{frame}-substep{substep}.npz", x_before=x0, v_before=v0,
                     x_after=sim.positions(), v_after=sim.velocities())
            print(f"  replayed without the graph: {count} pairs after substep {substep}", flush=True)
            return
    print("  replayed without the graph: no crossing within the frame", flush=True)


def main() -> None:
    wp.config.log_level = wp.LOG_ERROR
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    device, frames = sys.argv[2], int(sys.argv[3])
    for k in sys.argv[4:]:
        capture(out, device, frames, int(k))


if __name__ == "__main__":
    main()
