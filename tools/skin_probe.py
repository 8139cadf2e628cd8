"""How the neighbour lists' skin (the search radius over the contact distance) trades list remakes for
longer lists, on the matrix's self-collision cloth: ms a frame as `warp-cloth bench --suite matrix` times
it (48 frames after warm-up, 3 repeats continuing one simulator), the worst edge strain, the lists'
overflow (candidates lost so far, after 48 frames and a remake) and their mean and longest length then,
for each search scale.

The scale is ``warp_cloth.kernels.particle_collision.SEARCH_SCALE`` (1.5), which the probe sets.

    [DEVICE=cpu] python tools/skin_probe.py OUT.json [sizes...]

(DEVICE=cpu: a check that it runs.) docs/results/skin-probe-h200.json is its output on the H200 at c2d7455
(the sphere scenes' old start, with the sphere through the cloth).
"""

import json
import os
import sys

import numpy as np
import warp as wp

from warp_cloth.bench import Case, matrix_frames, matrix_scene, time_case
from warp_cloth.kernels import particle_collision
from warp_cloth.simulator import Simulator

wp.config.log_level = wp.LOG_ERROR
SCALES = (1.5, 2.0, 2.5, 3.0)


def main() -> None:
    device = os.environ.get("DEVICE", "cuda")
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    rows = []
    for n in sizes:
        for scale in SCALES:
            particle_collision.SEARCH_SCALE = scale  # read by the simulators made from here on
            scene = matrix_scene("self", n, "symplectic")
            case = Case(f"self {n}^2", scene, matrix_frames(n, device), fresh=False)
            result = time_case(case, device, 3)
            probe = Simulator(case.scene, device=device)
            probe.run(48)
            lists = probe.plan.lists
            lists.remake_now(probe.state.x)
            lengths = np.array([len(candidates) for candidates in lists.candidates()])
            row = {"n": n, "search_scale": scale, "ms_per_frame": result.ms_per_frame,
                   "max_strain": result.max_strain, "overflow": lists.overflow,
                   "mean_list": float(np.mean(lengths)), "max_list": int(lengths.max())}
            rows.append(row)
            print(row, flush=True)
    json.dump({"device": wp.get_device(device).name, "warp": wp.config.version, "rows": rows},
              open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
