"""Would tethers to the particles a collider holds up carry the settled drape's load? A probe for issue 15.

The speed matrix's sphere cloth at n^2 runs with the converged limit solve (cap 1000), its state kept every
5 frames. From each kept state, one symplectic substep's prediction (x + h (v + h g), pins held; the soft
springs left out) is projected by a numpy copy of warp-cloth's limit pass (averaged Jacobi over the limited
springs, then the attachments to the pins, then the sphere) until no limit is 0.5% past, checked every two
passes as the converged solve does, at most 1000 passes: once as it is, once with each free particle also
tethered to the particle nearest it along the cloth's edges among those the sphere holds up (touching it)
or pinned, within (1 + stretch) times that path (a limit the springs' own limits imply, as the attachments
are), the tether's far end held still in the pass, as a pin is.

    python tools/anchor_probe.py [N]          (default 64: about 20 s for the run on this CPU)
"""

import dataclasses
import sys

import numpy as np

import warp_cloth as wc
from warp_cloth.lab.bench import matrix_scene
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from warp_cloth.spring_paths import nearest_along_edges

TOLERANCE = 0.005
CAP = 1000


class Cloth:
    """The limits, attachments and sphere of the matrix cloth, as numpy arrays."""

    def __init__(self, sim: wc.Simulator) -> None:
        model = sim.model
        springs = model.springs
        limited = np.isfinite(springs.limit_max)
        self.a, self.b = springs.pairs[limited, 0], springs.pairs[limited, 1]
        self.low = springs.limit_min[limited].astype(np.float64)
        self.high = springs.limit_max[limited].astype(np.float64)
        self.w = model.inv_mass.astype(np.float64)
        self.free = self.w > 0
        self.pin, self.reach = model.limits.attachment_pin, model.limits.attachment_length.astype(np.float64)
        self.center, self.radius = model.spheres.initial_center[0].astype(np.float64), float(model.spheres.radius[0])
        mesh = model.cloths[0]
        self.edges, self.edge_rest = mesh.springs[mesh.is_edge], mesh.rest_lengths[mesh.is_edge]
        self.stretch = sim.scene.cloths[0].limit.stretch
        self.n = model.particle_count

    def tethers(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        touching = np.linalg.norm(x - self.center, axis=1) <= self.radius * (1 + 1e-3)
        held = np.nonzero(~self.free | touching)[0]
        nearest, distance = nearest_along_edges(self.n, self.edges, self.edge_rest, held)
        nearest = np.where(self.free & (nearest >= 0) & (nearest != np.arange(self.n)), nearest, -1)
        return nearest, (1 + self.stretch) * distance

    def residual(self, x: np.ndarray) -> float:
        length = np.linalg.norm(x[self.a] - x[self.b], axis=1)
        worst = max(np.max((length - self.high) / self.high), np.max((self.low - length) / self.low))
        attached = self.pin >= 0
        reach = np.linalg.norm(x[attached] - x[self.pin[attached]], axis=1)
        return max(worst, float(np.max((reach - self.reach[attached]) / np.maximum(self.reach[attached], 1e-12))))

    def corrections(self, x: np.ndarray, movers: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each particle's sum of the corrections (its share, by inverse mass) of its limited springs out of
        range at ``x``, and their count; for ``movers`` only (a mask; None: every particle)."""
        d = x[self.a] - x[self.b]
        length = np.linalg.norm(d, axis=1)
        target = np.clip(length, self.low, self.high)
        out = (target != length) & (length > 1e-12)
        correction = ((target - length) / np.maximum(length, 1e-12))[:, None] * d
        weight = np.maximum(self.w[self.a] + self.w[self.b], 1e-30)  # two pins: neither moves
        at_a, at_b = (out, out) if movers is None else (out & movers[self.a], out & movers[self.b])
        total, count = np.zeros((self.n, 3)), np.zeros(self.n)
        np.add.at(total, self.a[at_a], (self.w[self.a] / weight)[at_a, None] * correction[at_a])
        np.add.at(total, self.b[at_b], -(self.w[self.b] / weight)[at_b, None] * correction[at_b])
        np.add.at(count, self.a[at_a], 1)
        np.add.at(count, self.b[at_b], 1)
        return total, count

    def out_of_sphere(self, p: np.ndarray, which: np.ndarray | None = None) -> np.ndarray:
        """``p`` with its particles inside the sphere (of ``which``, a mask; None: all) put on its surface."""
        r = p - self.center
        distance = np.linalg.norm(r, axis=1)
        inside = distance < self.radius
        if which is not None:
            inside &= which
        p[inside] = self.center + r[inside] * (self.radius / distance[inside])[:, None]
        return p

    def one_pass(self, x: np.ndarray, tethers=None) -> np.ndarray:
        total, count = self.corrections(x)
        p = x + total / np.maximum(count, 1)[:, None]
        p[~self.free] = x[~self.free]
        p = held_within(p, x, self.pin, self.reach)
        if tethers is not None:
            p = held_within(p, x, *tethers)
        return self.out_of_sphere(p)

    def passes(self, x: np.ndarray, tethers=None) -> int:
        for k in range(2, CAP + 1, 2):
            x = self.one_pass(self.one_pass(x, tethers), tethers)
            if self.residual(x) <= TOLERANCE:
                return k
        return CAP

    def chebyshev(self, x: np.ndarray, rho: float) -> int:
        """Passes to within tolerance of Jacobi pairs accelerated as the converged solve does with
        the radius ``rho`` (restarted where a pair leaves 1.5 times the residual before)."""
        start, before, omega, k, last = x.copy(), x.copy(), 1.0, 0, np.inf
        for passes in range(2, CAP + 1, 2):
            k += 1
            omega = 1.0 if k == 1 else 2.0 / (2.0 - rho * rho) if k == 2 else 4.0 / (4.0 - rho * rho * omega)
            paired = self.one_pass(self.one_pass(x))
            base = start if k == 1 else before
            x = np.where(self.free[:, None], omega * (paired - base) + base, paired)
            before, start = start, x.copy()
            x = self.out_of_sphere(x, self.free)
            residual = self.residual(x)
            if residual <= TOLERANCE:
                return passes
            if residual > 1.5 * last:
                k = 0
            last = residual
        return CAP


def held_within(p: np.ndarray, x: np.ndarray, other: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Each particle with an other end (>= 0) put back within ``reach`` of where that end was."""
    tied = np.nonzero(other >= 0)[0]
    d = p[tied] - x[other[tied]]
    length = np.linalg.norm(d, axis=1)
    over = length > reach[tied]
    moved = tied[over]
    p[moved] = x[other[moved]] + d[over] * (reach[moved] / length[over])[:, None]
    return p


def converged_sphere_cloth(n: int, device: str = "cpu", rho: float = 0.0) -> wc.Simulator:
    """The speed matrix's sphere cloth at n^2 with the converged limit solve, at most CAP passes, accelerated
    by Chebyshev at ``rho`` (0: plain Jacobi)."""
    scene = matrix_scene("sphere", n, "symplectic")
    with lab_hooks(SolveChoices(chebyshev_rho=rho)):
        return wc.Simulator(dataclasses.replace(scene, simulation=dataclasses.replace(
            scene.simulation, limit_solve="converged", limit_max_passes=CAP)), device=device)


def states(sim: wc.Simulator, frames: int = 120, every: int = 5):
    """Every ``every`` frames of the run: the frame, the real solve's most and mean passes a substep in that
    frame, the positions and the velocities."""
    for frame in range(1, frames + 1):
        sim.step()
        stats = sim.solver_stats()
        if frame % every == 0:
            yield frame, stats.limit_passes, stats.limit_mean_passes, sim.positions(), sim.velocities()


def saved_states(paths: list[str]):
    """The states tools/sphere_states.py saved, in the order of ``states``."""
    for path in paths:
        with np.load(path) as saved:
            yield from zip(saved["frame"].tolist(), saved["most"].tolist(), saved["mean"].tolist(), saved["x"],
                           saved["v"])


def predictions(sim: wc.Simulator, cloth: Cloth, saved: list[str] | None = None):
    """From each of the run's states (or those ``saved``): the frame, the real solve's most and mean passes,
    the positions, and one symplectic substep's prediction from them (x + h (v + h g), pins held)."""
    gravity = np.array([0.0, -9.81, 0.0])
    for frame, most, mean, x, v in (saved_states(saved) if saved else states(sim)):
        x, v = x.astype(np.float64), v.astype(np.float64) + sim.dt * gravity
        v[~cloth.free] = 0.0
        yield frame, most, mean, x, x + sim.dt * v


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 64
    sim = converged_sphere_cloth(n)
    cloth = Cloth(sim)
    print("frame  passes of the real solve (mean / most)  copy, as it is  copy, with tethers  tethered particles")
    for frame, most, mean, x, predicted in predictions(sim, cloth):
        tethers = cloth.tethers(x)
        print(f"{frame:5d}  {mean:6.1f} / {most:4d}  {cloth.passes(predicted):14d}  "
              f"{cloth.passes(predicted, tethers):18d}  {int((tethers[0] >= 0).sum()):18d}", flush=True)


if __name__ == "__main__":
    main()
