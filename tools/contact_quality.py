"""How well particle collision holds the cloth, frame by frame, on the scenes with particle collision: the
built-in ones, the stability suite's hard cases and the speed matrix's self-collision cloth. For each:
the closest contact (fraction of the contact distance, 1.0 = no overlap), the most intersecting triangle
pairs at once, and the worst strain of a limited spring (stretch > 0, compression < 0), all over every
frame; and the wall time. Used to compare a change to particle collision's passes with the code before it:

    python tools/contact_quality.py OUT.jsonl [--projection sequential] [SCENE ...]   (SCENE: name[:frames])

(--projection joint or sequential: the converged solve's passes so throughout, ``lab_hooks``; without it
the solver's order, joint for 200 passes, then sequential.)

Writes one JSON line per scene after a line with the environment (docs/results/contact-quality-*.jsonl).
"""

import dataclasses
import json
import pathlib
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))

import hard_cases  # noqa: E402

import warp_cloth as wc  # noqa: E402
from warp_cloth.lab.bench import environment, matrix_scene  # noqa: E402
from warp_cloth.diagnostics import ContactGaps, TriangleIntersections  # noqa: E402
from warp_cloth.limit_solve import SolveChoices, lab_hooks  # noqa: E402

SCENES = {
    "fold": lambda: wc.load_scene("fold"),
    "pile": lambda: wc.load_scene("pile"),
    "seed_default": lambda: wc.load_scene("seed_default"),
    "twisted": hard_cases.twisted,
    "heavy_and_light": hard_cases.heavy_and_light,
    "fast_sphere": hard_cases.fast_sphere,
    "matrix_self_64": lambda: matrix_scene("self", 64, "symplectic"),
}


def limited_strain(sim: wc.Simulator) -> tuple[float, float]:
    """The largest stretch and compression of the model's limited springs."""
    springs = sim.model.springs
    limited = np.isfinite(springs.limit_max)
    pairs = springs.pairs[limited]
    x = sim.positions()
    ratio = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) / springs.rest[limited] - 1.0
    return float(ratio.max()), float(ratio.min())


def measure(name: str, frames: int | None, device: str, projection: str | None) -> dict:
    scene = SCENES[name]()
    if frames is not None:
        scene = dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, frames=frames))
    choices = {"joint": SolveChoices(joint_passes=10**9), "sequential": SolveChoices(joint_passes=0)}.get(
        projection, SolveChoices())  # None: the solver's
    with lab_hooks(choices):
        sim = wc.Simulator(scene, device=device)
    crossings, gaps = TriangleIntersections(sim), ContactGaps(sim)
    worst = {"closest_contact": np.inf, "most_crossings": 0, "stretch": -np.inf, "compression": np.inf}
    stepping = 0.0
    for frame in range(scene.simulation.frames):
        started = time.perf_counter()
        sim.step()
        wp.synchronize_device(sim.device)
        stepping += time.perf_counter() - started
        if not np.isfinite(sim.positions()).all():
            return {"scene": name, "error": f"non-finite positions at frame {frame}"}
        worst["closest_contact"] = min(worst["closest_contact"], gaps(sim))
        worst["most_crossings"] = max(worst["most_crossings"], crossings(sim))
        stretch, compression = limited_strain(sim)
        worst["stretch"] = max(worst["stretch"], stretch)
        worst["compression"] = min(worst["compression"], compression)
    return {"scene": name, "projection": projection, "frames": scene.simulation.frames,
            "step_seconds": stepping, **worst}


def main(out_path: str, items: list[str]) -> None:
    wp.config.log_level = wp.LOG_ERROR
    device = "cuda" if wp.is_cuda_available() else "cpu"
    projection = None
    if items[:1] == ["--projection"]:
        projection, items = items[1], items[2:]
    items = items or list(SCENES)
    with open(out_path, "a") as out:
        print(json.dumps({"environment": environment(device)}), file=out, flush=True)
        for k, item in enumerate(items, 1):
            name, _, frames = item.partition(":")
            row = measure(name, int(frames) if frames else None, device, projection)
            print(json.dumps(row), file=out, flush=True)
            print(f"[{k}/{len(items)}] {json.dumps(row)}", flush=True)
    print(f"{len(items)} scenes measured on {device}; rows in {out_path}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
