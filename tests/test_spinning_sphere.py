"""A spinning sphere carries the cloth that rests on it round by friction, at the rate Coulomb's law
predicts, until the cloth turns with it."""

import math

import numpy as np
import pytest

import warp_cloth as wc

RADIUS = 100.0  # so large that a 1 m cloth on its top lies flat on it: the normal force is the weight
MU, SPIN = 0.4, 180.0  # Codim-IPC's test: friction 0.4, 180 degrees a second


def resting_cloth_on_spinning_sphere() -> wc.Scene:
    cloth = wc.Cloth(resolution=(10, 10), size=(1.0, 1.0), orientation="horizontal", origin=(-0.5, 0.0, 0.5),
                     density=0.2, limit=wc.Limit(0.1, 0.1), structural=wc.SpringKind(15.0, 0.02),
                     shear=wc.SpringKind(15.0, 0.02), bend=wc.SpringKind(5.0, 0.01, "compression", "compression"))
    sphere = wc.Sphere(name="ball", center=(0.0, -RADIUS, 0.0), radius=RADIUS, friction=MU, spin=(0.0, SPIN, 0.0))
    return wc.Scene(name="spin", cloths=(cloth,), spheres=(sphere,),
                    simulation=wc.Simulation(fps=24, frames=24, substeps=30, integrator="symplectic",
                                             limit_solve="converged"))


def angular_momentum(sim: wc.Simulator) -> float:
    x, v, m = sim.positions().astype(np.float64), sim.velocities().astype(np.float64), sim.model.masses
    return float((m * (x[:, 2] * v[:, 0] - x[:, 0] * v[:, 2])).sum())  # about +Y


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_friction_turns_the_cloth_at_mu_g_until_it_turns_with_the_sphere(device):
    sim = wc.Simulator(resting_cloth_on_spinning_sphere(), device=device)
    m = sim.model.masses
    x0 = sim.positions().astype(np.float64)
    lever = float((m * np.hypot(x0[:, 0], x0[:, 2])).sum())
    sim.step()
    # While every particle slips, each is pushed round at mu g: dL/dt = mu g sum(m r). Over the first
    # frame, particles within mu g t / omega of the axis already turn with the sphere (about 2% of the
    # mass); the edge particles start 5 mm above the curved top and land within half a frame.
    predicted = MU * 9.81 * lever / 24.0
    assert angular_momentum(sim) == pytest.approx(predicted, rel=0.05)
    for _ in range(23):
        sim.step()
    omega = math.radians(SPIN)
    x, v = sim.positions().astype(np.float64), sim.velocities().astype(np.float64)
    carried = x[:, 2] * v[:, 0] - x[:, 0] * v[:, 2]  # (r x v)_y, as the spin: about +Y, right-handed
    r2 = x[:, 0] ** 2 + x[:, 2] ** 2
    # After one second (the edge catches up within 0.3 s) the cloth turns with the sphere.
    assert float((m * carried).sum() / (m * r2).sum()) == pytest.approx(omega, rel=0.02)
