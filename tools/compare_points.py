"""Compare the points of two USD results of the same scene, every time sample of every mesh: bit for bit,
or the largest difference. Used to check that a change leaves results as they were (docs/architecture.md:
the restructure of issue 14 left every built-in scene's points bit-identical on the CPU).

    python tools/compare_points.py BEFORE.usdc AFTER.usdc [BEFORE2.usdc AFTER2.usdc ...]

Exit code 0 where every pair is identical, 1 otherwise; one line per pair."""

from __future__ import annotations

import sys

import numpy as np
from pxr import Usd, UsdGeom


def points_by_prim(path: str) -> dict[str, dict[float, np.ndarray]]:
    stage = Usd.Stage.Open(path)
    result = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.PointBased):
            attribute = UsdGeom.PointBased(prim).GetPointsAttr()
            result[str(prim.GetPath())] = {t: np.asarray(attribute.Get(t), dtype=np.float32)
                                           for t in attribute.GetTimeSamples()}
    return result


def compare(before: str, after: str) -> tuple[bool, str]:
    a, b = points_by_prim(before), points_by_prim(after)
    if a.keys() != b.keys():
        return False, f"different meshes: {sorted(a)} and {sorted(b)}"
    worst, first_differing, samples = 0.0, None, 0
    for prim in sorted(a):
        if a[prim].keys() != b[prim].keys():
            return False, f"{prim}: different time samples"
        for t in sorted(a[prim]):
            samples += 1
            x, y = a[prim][t], b[prim][t]
            if x.shape != y.shape:
                return False, f"{prim} at {t}: shapes {x.shape} and {y.shape}"
            if not np.array_equal(x.view(np.uint32), y.view(np.uint32)):
                worst = max(worst, float(np.abs(x.astype(np.float64) - y).max()))
                first_differing = first_differing or f"{prim} at time {t:g}"
    if first_differing is None:
        return True, f"bit-identical ({len(a)} meshes, {samples} samples)"
    return False, f"differ from {first_differing}, at most {worst:.3g} m apart"


def main(paths: list[str]) -> int:
    if len(paths) < 2 or len(paths) % 2:
        print(__doc__.strip().splitlines()[-3].strip(), file=sys.stderr)
        return 2
    same = True
    for before, after in zip(paths[::2], paths[1::2]):
        equal, text = compare(before, after)
        same = same and equal
        print(f"{after}: {text}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
