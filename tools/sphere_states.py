"""Save states of the speed matrix's sphere cloth under the converged limit solve, for the probes that start
from saved states (``fast_projection_probe.py N --states FILE...``): a large cloth's run on a GPU, probed on
this CPU. Each file holds ``--per-file`` of the chosen frames (frame, the solve's most and mean passes a
substep in it, positions and velocities as float32).

    python tools/sphere_states.py N OUT_STEM --frames 45 85 [--device cuda] [--rho 0.95] [--per-file 8]
        writes OUT_STEM-0.npz, OUT_STEM-1.npz, ...
"""

import argparse

import numpy as np

from anchor_probe import converged_sphere_cloth, states


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("n", type=int)
    parser.add_argument("stem")
    parser.add_argument("--frames", type=int, nargs="+", required=True)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--rho", type=float, default=0.0)
    parser.add_argument("--per-file", type=int, default=8)
    args = parser.parse_args()
    sim = converged_sphere_cloth(args.n, args.device, args.rho)
    kept = [state for state in states(sim, max(args.frames), every=1) if state[0] in args.frames]
    for k in range(0, len(kept), args.per_file):
        frame, most, mean, x, v = zip(*kept[k:k + args.per_file])
        np.savez(f"{args.stem}-{k // args.per_file}.npz", frame=np.array(frame), most=np.array(most),
                 mean=np.array(mean), x=np.stack(x), v=np.stack(v))
        print(f"{args.stem}-{k // args.per_file}.npz: frames {list(frame)}; passes a substep, most {list(most)}",
              flush=True)


if __name__ == "__main__":
    main()
