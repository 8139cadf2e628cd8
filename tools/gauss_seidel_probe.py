"""Would Gauss-Seidel over a colouring of the particles converge the settled drape's limits in fewer passes
than the averaged Jacobi passes? A probe for issue 15 (docs/notebook/strain-solve.md).

The speed matrix's sphere cloth at n^2 runs with the converged limit solve (cap 1000), as
tools/anchor_probe.py does, and from its state every 5 frames one substep's prediction is projected by a
numpy copy of the limit pass until no limit is 0.5% past (checked every two passes, at most 1000):
- ``jacobi``: the pass as warp-cloth runs it (every particle's mean correction from the same positions);
- ``gauss-seidel``: the particles coloured greedily so that no limited spring joins two of a colour (any
  spring graph; 4 colours on a grid with diagonals), and one pass a sweep over the colours, each colour's
  particles moving by their mean correction from the positions the colours before left, then held within
  their attachments and put out of the sphere;
- ``gauss-seidel, sor W``: the same, each move scaled by W (successive over-relaxation);
- ``chebyshev R``: Jacobi pairs of passes accelerated as warp-cloth's converged solve does with
  the fixed radius R (the extrapolation put out of the sphere, restarted where a pair leaves more
  than 1.5 times the residual before), for comparison.
A Gauss-Seidel pass would cost one launch a colour on a GPU, over a quarter of the particles each.

    python tools/gauss_seidel_probe.py [N]          (default 64)
    python tools/gauss_seidel_probe.py N --radii R ...   (Chebyshev at those radii only, beside Jacobi)
"""

import sys

import numpy as np

import warp_cloth as wc
from anchor_probe import CAP, TOLERANCE, Cloth, converged_sphere_cloth, held_within, predictions


def colouring(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each particle's colour, the smallest its neighbours along the springs (a, b) have not taken."""
    neighbours = [[] for _ in range(n)]
    for i, j in zip(a.tolist(), b.tolist()):
        neighbours[i].append(j)
        neighbours[j].append(i)
    colour = np.full(n, -1)
    for i in range(n):
        taken = {colour[j] for j in neighbours[i]}
        colour[i] = next(c for c in range(len(taken) + 1) if c not in taken)
    return colour


class ColouredCloth(Cloth):
    def __init__(self, sim: wc.Simulator) -> None:
        super().__init__(sim)
        colour = colouring(self.n, self.a, self.b)
        self.colours = [np.nonzero((colour == c) & self.free)[0] for c in range(colour.max() + 1)]

    def sweep(self, x: np.ndarray, over_relaxation: float) -> np.ndarray:
        x = x.copy()
        for members in self.colours:
            mine = np.zeros(self.n, dtype=bool)
            mine[members] = True
            total, count = self.corrections(x, mine)
            p = x.copy()
            p[members] = x[members] + over_relaxation * total[members] / np.maximum(count[members], 1)[:, None]
            p = self.out_of_sphere(held_within(p, x, self.pin, self.reach), mine)
            x[members] = p[members]
        return x

    def sweeps(self, x: np.ndarray, over_relaxation: float) -> int:
        for k in range(2, CAP + 1, 2):
            x = self.sweep(self.sweep(x, over_relaxation), over_relaxation)
            if self.residual(x) <= TOLERANCE:
                return k
        return CAP


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 64
    chosen = [float(r) for r in sys.argv[sys.argv.index("--radii") + 1:]] if "--radii" in sys.argv else None
    sim = converged_sphere_cloth(n)
    cloth = ColouredCloth(sim)
    relaxations, radii = ((), chosen) if chosen else ((1.0, 1.8, 1.9), (0.95, 0.99))
    print(f"{len(cloth.colours)} colours; passes to within {TOLERANCE:.1%}, at most {CAP}")
    print("frame  real solve (mean / most)  jacobi  " + "  ".join(f"chebyshev {r}" for r in radii) + "  "
          + "  ".join(f"gauss-seidel, sor {w}" for w in relaxations))
    for frame, most, mean, _, predicted in predictions(sim, cloth):
        counts = [cloth.chebyshev(predicted, r) for r in radii] + [cloth.sweeps(predicted, w) for w in relaxations]
        print(f"{frame:5d}  {mean:6.1f} / {most:4d}  {cloth.passes(predicted):6d}  "
              + "  ".join(f"{c:14d}" for c in counts), flush=True)


if __name__ == "__main__":
    main()
