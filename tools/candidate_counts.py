"""How many candidates the surface thickness's edge and face lists really hold in the stacked drape, and how
full the edge and face hashes' buckets get (they hold every point: counted_hash.py): the lists made long
enough never to fill (``--room``), read at the end of every frame (the lists of that frame's last remake).
What sized ``state.EDGE_NEIGHBORS`` (docs/notebook/layers.md).

    python tools/candidate_counts.py --sheets 3 --n 32 --frames 60 --thickness 0.004 --json docs/results/x.json

The scene is tools/stacked_drape.py's, with the surface thickness asked (4 mm unless told) and the lab's
displacement bounds (their defaults).
"""

from __future__ import annotations

import argparse
import json
import time

import warp as wp

import warp_cloth as wc
import warp_cloth.face_contacts as face_contacts
import warp_cloth.neighbour_lists as neighbour_lists
import warp_cloth.passes as passes
import warp_cloth.state as state
from stacked_drape import stacked_drape_scene
from warp_cloth.displacement_bounds import BoundSettings, lab_hooks
from warp_cloth.counted_hash import CountedHash
from warp_cloth.lab.bench import environment


def fullest_bucket(hash: CountedHash) -> int:
    """The most a bucket of its latest fill holds."""
    return int(hash.buckets.count.numpy().max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sheets", type=int, default=3)
    parser.add_argument("--n", type=int, default=32)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--radius", type=float, default=0.004)
    parser.add_argument("--thickness", type=float, default=0.004,
                        help="[collision] thickness in metres: edge and face contacts held that far apart")
    parser.add_argument("--room", type=int, default=512, help="entries every list holds")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.log_level = wp.LOG_ERROR
    wc.set_verbose(False)
    state.EDGE_NEIGHBORS = passes.EDGE_NEIGHBORS = face_contacts.FACE_NEIGHBORS = args.room
    scene = stacked_drape_scene(args.sheets, args.n, frames=args.frames, radius=args.radius,
                                thickness=args.thickness)
    with lab_hooks(BoundSettings.parse("on")):
        sim = wc.Simulator(scene, device=args.device)
    lists = sim.plan.lists
    sim.prepare()
    rows, started = [], time.perf_counter()
    for frame in range(1, args.frames + 1):
        sim.step()
        row = {"frame": frame, "edge_list": int(lists.edges.edges.counts.numpy().max()),
               "edge_bucket": fullest_bucket(lists.edges.hash), "dropped": lists.overflow + lists.surface_dropped}
        if lists.faces is not None:
            faces = lists.faces
            row |= {"vertex_list": int(faces.args.vertex_counts.numpy().max()),
                    "triangle_list": int(faces.args.face_counts.numpy().max()),
                    "face_bucket": fullest_bucket(faces.hash)}
        rows.append(row)
        print(row, flush=True)
    most = {key: max(row[key] for row in rows) for key in rows[0] if key != "frame"}
    print("most over the frames:", most)
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"environment": environment(args.device), "settings": vars(args), "edges": lists.edges.m,
                       "reach": neighbour_lists.widest_reach(lists.edges), "longest": lists.edges.longest, "most": most,
                       "seconds": time.perf_counter() - started, "per_frame": rows}, out, indent=1)
            out.write("\n")


if __name__ == "__main__":
    main()
