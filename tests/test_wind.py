"""Wind: the drag a flat sheet feels is the model's (1/2 rho C_D A u^2), integrated over a second as the
sheet is blown along; a tilted sheet is lifted across the flow; gusts are the same on every run."""

import dataclasses
import math

import numpy as np
import pytest

import warp_cloth as wc

DENSITY, AIR, DRAG, SPEED = 0.2, 1.2, 1.0, 3.0


def sheet_in_wind(rotation=(0.0, 0.0, 0.0), lift=0.0, turbulence=0.0, substeps=40, fps=24.0) -> wc.Scene:
    """A free 1 x 1 m sheet, no gravity, facing +Z (vertical), the wind blowing along +Z."""
    cloth = wc.Cloth(resolution=(8, 8), size=(1.0, 1.0), orientation="vertical", origin=(-0.5, -0.5, 0.0),
                     rotation=rotation, density=DENSITY, limit=wc.Limit(0.1, 0.1),
                     structural=wc.SpringKind(15.0, 0.02), shear=wc.SpringKind(15.0, 0.02),
                     bend=wc.SpringKind(5.0, 0.01, "compression", "compression"))
    return wc.Scene(name="sail", cloths=(cloth,),
                    wind=wc.Wind(velocity=(0.0, 0.0, SPEED), air_density=AIR, drag=DRAG, lift=lift,
                                 turbulence=turbulence),
                    simulation=wc.Simulation(fps=fps, frames=24, substeps=substeps, integrator="symplectic",
                                             gravity=(0.0, 0.0, 0.0)))


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_a_flat_sheet_facing_the_wind_is_blown_along_as_the_drag_law_integrates(device):
    sim = wc.Simulator(sheet_in_wind(), device=device)
    for _ in range(24):
        sim.step()
    v = sim.velocities().astype(np.float64)
    # m dv/dt = 1/2 rho C_D A (U - v)^2 with m = density A: U - v(t) = 1 / (1/U + k t), k = rho C_D / (2 density)
    k = AIR * DRAG / (2.0 * DENSITY)
    expected = SPEED - 1.0 / (1.0 / SPEED + k * 1.0)
    assert np.ptp(v[:, 2]) < 1e-4 * expected  # every particle alike: the sheet moves as one
    assert float(v[:, 2].mean()) == pytest.approx(expected, rel=0.01)
    assert np.abs(v[:, :2]).max() < 1e-5  # no force across the flow when it meets the sheet square on


def test_a_tilted_sheet_feels_drag_along_its_normal_and_lift_across_the_flow():
    tilt, lift = 30.0, 0.3
    sim = wc.Simulator(sheet_in_wind(rotation=(tilt, 0.0, 0.0), lift=lift, substeps=1, fps=2400.0), device="cpu")
    sim.step()
    momentum = (sim.model.masses[:, None] * sim.velocities().astype(np.float64)).sum(axis=0)
    force = momentum * 2400.0  # one step of 0.42 ms from rest: the force at rest
    a = math.radians(tilt)
    normal = np.array([0.0, -math.sin(a), math.cos(a)])  # +Z turned 30 degrees about X
    cos_t = math.cos(a)  # between the wind (+Z) and the normal
    q = 0.5 * AIR * 1.0 * SPEED ** 2
    across = normal - cos_t * np.array([0.0, 0.0, 1.0])
    expected = q * DRAG * cos_t ** 2 * normal + q * lift * cos_t * across  # |across| = sin
    assert force[1] < 0.0  # the sheet leans back (its normal points down-wind and down): pushed down
    np.testing.assert_allclose(force, expected, rtol=0.03, atol=1e-3 * np.linalg.norm(expected))


def test_gusts_are_the_same_on_every_run_and_vary_over_the_sheet():
    runs = []
    for _ in range(2):
        sim = wc.Simulator(sheet_in_wind(turbulence=0.5), device="cpu")
        for _ in range(6):
            sim.step()
        runs.append(sim.positions())
    np.testing.assert_array_equal(runs[0], runs[1])
    calm = wc.Simulator(sheet_in_wind(), device="cpu")
    for _ in range(6):
        calm.step()
    assert np.ptp(runs[0][:, 2]) > 10 * np.ptp(calm.positions()[:, 2])  # the noise bends the sheet


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_keyed_wind_rising_then_held_blows_the_sheet_as_the_drag_law_integrates(device):
    """Wind keyed from still at 0.25 s to SPEED at 0.75 s, then held: the sheet's speed over 1.5 s follows
    dv/dt = k (u(t) - v) |u(t) - v|, integrated here by RK4."""
    keys = (wc.WindKey(0.25, (0.0, 0.0, 0.0)), wc.WindKey(0.75, (0.0, 0.0, SPEED)))
    scene = sheet_in_wind()
    scene = dataclasses.replace(scene, wind=dataclasses.replace(scene.wind, velocity=(0.0, 0.0, 0.0), keys=keys))
    sim = wc.Simulator(scene, device=device)
    k = AIR * DRAG / (2.0 * DENSITY)

    def dv_dt(t: float, v: float) -> float:
        u = SPEED * min(max((t - 0.25) / 0.5, 0.0), 1.0)
        return k * (u - v) * abs(u - v)

    v, t, h = 0.0, 0.0, 1e-4
    for frame in range(1, 37):
        sim.step()
        while t < frame / 24.0 - 1e-12:
            a = dv_dt(t, v)
            b = dv_dt(t + h / 2, v + h / 2 * a)
            c = dv_dt(t + h / 2, v + h / 2 * b)
            d = dv_dt(t + h, v + h * c)
            v, t = v + h / 6 * (a + 2 * b + 2 * c + d), t + h
        speed = float(sim.velocities().astype(np.float64)[:, 2].mean())
        if frame <= 6:
            assert speed == 0.0  # still air until the first key
        else:
            assert speed == pytest.approx(v, rel=0.02, abs=1e-3), frame


def test_wind_with_both_a_velocity_and_keys_is_refused():
    with pytest.raises(wc.SceneError, match="velocity: expected a velocity or keys, not both"):
        wc.Wind(velocity=(1.0, 0.0, 0.0), keys=(wc.WindKey(0.0, (1.0, 0.0, 0.0)),))
