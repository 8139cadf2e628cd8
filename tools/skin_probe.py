"""How the neighbour lists' skin (the search radius over the contact distance) trades list remakes for
longer lists, on the matrix's self-collision cloth: ms a frame as `warp-cloth bench --suite matrix` times
it (48 frames after warm-up, 3 repeats continuing one simulator), the worst edge strain, the lists'
overflow and mean length, for each search scale.

    python tools/skin_probe.py OUT.json [sizes...]

docs/results/skin-probe-h200.json is its output on the H200 at c2d7455 (the sphere scenes' old start,
with the sphere through the cloth).
"""

import json
import sys

import numpy as np
import warp as wp

from warp_cloth.bench import Case, matrix_frames, matrix_scene, time_case
from warp_cloth.simulator import Simulator
from warp_cloth.stages import ParticleCollision

SCALES = (1.5, 2.0, 2.5, 3.0)


def main() -> None:
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    rows = []
    default = ParticleCollision.SEARCH_SCALE
    for n in sizes:
        for scale in SCALES:
            ParticleCollision.SEARCH_SCALE = scale
            case = Case(f"self {n}^2", matrix_scene("self", n, "symplectic"), matrix_frames(n, "cuda"), fresh=False,
                        grid=n)
            result = time_case(case, "cuda", 3)
            probe = Simulator(case.scene, device="cuda")
            probe.run(48)
            stage = next(s for s in probe.stages if isinstance(s, ParticleCollision))
            stage.make_lists(probe.state.x)
            counts = stage.counts.numpy()
            row = {"n": n, "search_scale": scale, "ms_per_frame": 1e3 * result.median_seconds / result.frames,
                   "max_strain": result.max_strain, "overflow": int(stage.overflow.numpy()[0]),
                   "mean_list": float(np.mean(counts)), "max_list": int(counts.max())}
            rows.append(row)
            print(row, flush=True)
    ParticleCollision.SEARCH_SCALE = default
    json.dump({"device": wp.get_device("cuda").name, "warp": wp.config.version, "rows": rows}, open(sys.argv[1], "w"),
              indent=1)


if __name__ == "__main__":
    main()
