"""Would a global projection of the active limits and contacts (Goldenthal et al. 2007, "fast projection")
converge the settled drape in fewer pass-equivalents than the Jacobi passes? A probe for issue 15
(docs/strain-solve.md). Needs scipy and pyamg (pip install scipy pyamg; not warp-cloth's dependencies).

As tools/anchor_probe.py: the speed matrix's sphere cloth at n^2 runs with the converged limit solve, and
from its state every 5 frames one substep's prediction is projected until no limit or attachment is 0.5%
past (nothing inside the sphere). Fast projection repeats, at most 50 times: every constraint violated now
(a limited spring too long or too short, an attachment too far from its pin, a particle inside the
sphere), and every one held at its bound in the iteration before whose multiplier, summed over the
iterations, still pushes the right way, is linearised at x, and x moves by -W J^T l with
(J W J^T) l = C solved by conjugate gradients to a relative residual ``rtol``; then the particles still
inside the sphere are put on it. J W J^T is singular where more limits than the particles' freedom are
active, so ``--regularisation`` (default 0.1) times its mean diagonal is added to it: each linearised
solve then falls short of the bounds, and the next iteration goes on from there.

A pass-equivalent is one Jacobi pass's work: an evaluation of the constraints, or one product with
J W J^T (a gather and a scatter over the constraints). With pyamg's smoothed aggregation as the
preconditioner, each iteration also applies one V-cycle, counted as its cycle complexity in products
(its set-up, done again for every linearisation, is not counted).

    cd tools && python fast_projection_probe.py [N] [--regularisation R]     (default 64: runs the cloth here)
    cd tools && python fast_projection_probe.py N --states FILE... [--no-passes]
        (from states tools/sphere_states.py saved; --no-passes leaves out the numpy Jacobi and Chebyshev)
"""

import argparse

import numpy as np
import pyamg
import scipy.sparse as sp
from scipy.sparse.linalg import cg

from anchor_probe import TOLERANCE, Cloth, converged_sphere_cloth, predictions

OUTER_CAP = 50


class Linearised:
    """The active constraints at x: each joins particle ``a`` to ``b`` (-1: a fixed point), its value
    ``c`` (> 0: violated) and its gradient ``g`` at a (-g at b)."""

    def __init__(self, a, b, key, c, g) -> None:
        self.a, self.b, self.key, self.c, self.g = a, b, key, c, g

    def jacobian(self, n: int) -> sp.csr_matrix:
        m = len(self.c)
        rows = np.repeat(np.arange(m), 3)
        at_a = (3 * self.a[:, None] + np.arange(3)).ravel()
        joined = self.b >= 0
        rows_b = np.repeat(np.nonzero(joined)[0], 3)
        at_b = (3 * self.b[joined, None] + np.arange(3)).ravel()
        return sp.csr_matrix((np.concatenate([self.g.ravel(), -self.g[joined].ravel()]),
                              (np.concatenate([rows, rows_b]), np.concatenate([at_a, at_b]))), shape=(m, 3 * n))


class ProjectedCloth(Cloth):
    def candidates(self, x: np.ndarray) -> Linearised:
        """Every constraint there is, active or not; keys: spring s too long s, too short S + s,
        attachment of i 2S + i, sphere on i 2S + n + i."""
        s = len(self.a)
        d = x[self.a] - x[self.b]
        length = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        unit = d / length[:, None]
        attached = np.nonzero(self.pin >= 0)[0]
        to_pin = x[attached] - x[self.pin[attached]]
        reach = np.maximum(np.linalg.norm(to_pin, axis=1), 1e-12)
        free = np.nonzero(self.free)[0]
        from_center = x[free] - self.center
        distance = np.maximum(np.linalg.norm(from_center, axis=1), 1e-12)
        return Linearised(
            np.concatenate([self.a, self.a, attached, free]),
            np.concatenate([self.b, self.b, self.pin[attached], np.full(len(free), -1)]),
            np.concatenate([np.arange(s), s + np.arange(s), 2 * s + attached, 2 * s + self.n + free]),
            np.concatenate([length - self.high, self.low - length, reach - self.reach[attached],
                            self.radius - distance]),
            np.concatenate([unit, -unit, to_pin / reach[:, None], -from_center / distance[:, None]]))

    def key_count(self) -> int:
        return 2 * len(self.a) + 2 * self.n

    def project(self, x: np.ndarray, rtol: float, multilevel: bool, regularisation: float) -> tuple[int, int, float]:
        """Iterations, conjugate-gradient iterations and pass-equivalents to within tolerance (the
        iterations are OUTER_CAP where it is not reached)."""
        x, multiplier = self.out_of_sphere(x.copy(), self.free), np.zeros(self.key_count())
        inner, cost = 0, 1.0
        weights = np.repeat(self.w, 3)
        for outer in range(OUTER_CAP + 1):
            if self.residual(x) <= TOLERANCE:
                return outer, inner, cost
            every = self.candidates(x)
            on = (every.c > 0) | (multiplier[every.key] > 0)
            active = Linearised(every.a[on], every.b[on], every.key[on], every.c[on], every.g[on])
            jacobian = active.jacobian(self.n)
            system = (jacobian.multiply(weights) @ jacobian.T).tocsr()
            system = system + sp.identity(system.shape[0]) * (regularisation * system.diagonal().mean())
            iterations = [0]
            preconditioner, cycle = None, 0.0
            if multilevel:
                hierarchy = pyamg.smoothed_aggregation_solver(system, max_coarse=200)
                preconditioner, cycle = hierarchy.aspreconditioner(), hierarchy.cycle_complexity()
            step, _ = cg(system, active.c, rtol=rtol, maxiter=1000, M=preconditioner,
                         callback=lambda _: iterations.__setitem__(0, iterations[0] + 1))
            inner += iterations[0]
            cost += iterations[0] * (1 + cycle) + 1
            x -= (weights * (jacobian.T @ step)).reshape(-1, 3)
            multiplier[active.key] += step
            x = self.out_of_sphere(x, self.free)
        return OUTER_CAP, inner, cost


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("n", type=int, nargs="?", default=64)
    parser.add_argument("--regularisation", type=float, default=0.1)
    parser.add_argument("--states", nargs="+")
    parser.add_argument("--no-passes", action="store_true")
    args = parser.parse_args()
    sim = converged_sphere_cloth(args.n)
    cloth = ProjectedCloth(sim)
    settings = [(0.1, False), (1e-3, False), (0.1, True), (1e-3, True)]
    print(f"passes (pass-equivalents) to within {TOLERANCE:.1%}; fast projection, regularisation "
          f"{args.regularisation:g}: iterations, CG iterations, pass-equivalents")
    print("frame  real solve (mean / most)  jacobi  chebyshev 0.95  "
          + "  ".join(f"{'pcg-amg' if amg else 'cg'} rtol {rtol:g}" for rtol, amg in settings))
    for frame, most, mean, _, predicted in predictions(sim, cloth, args.states):
        rows = [cloth.project(predicted, rtol, amg, args.regularisation) for rtol, amg in settings]
        passes = (0, 0) if args.no_passes else (cloth.passes(predicted), cloth.chebyshev(predicted, 0.95))
        print(f"{frame:5d}  {mean:6.1f} / {most:4d}  {passes[0]:6d}  {passes[1]:14d}  "
              + "  ".join(f"{o:3d} {i:5d} {c:7.1f}" for o, i, c in rows), flush=True)


if __name__ == "__main__":
    main()
