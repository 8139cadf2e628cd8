"""Pins follow their formula; colliders keep particles out; friction decelerates at mu g."""

import dataclasses
import math

import numpy as np
import pytest

import warp_cloth as wc
from conftest import with_simulation

OFF = wc.SpringKind(enabled=False)


def test_oscillating_pins_follow_their_formula_every_frame():
    scene = wc.load_scene("oscillating_pins")
    sim = wc.Simulator(scene, device="cpu")
    pins = sim.model.pins
    cloth = scene.cloths[0]
    motions = [p.motion for p in cloth.pins]
    for frame in range(1, 73):
        sim.step()
        t = frame / scene.simulation.fps
        x, v = sim.positions(), sim.velocities()
        for k, motion in enumerate(motions):
            i = pins.index[k]
            np.testing.assert_allclose(x[i], pins.anchor[k] + np.array(motion.offset(t)), atol=2e-5)
            np.testing.assert_allclose(v[i], motion.velocity(t), atol=2e-4)


def test_oscillating_pins_start_on_their_path():
    motion = wc.Oscillation(axis=(0.0, 2.0, 0.0), amplitude=0.5, frequency=2.0, phase=1.0)
    cloth = wc.Cloth(resolution=(2, 2), size=(1.0, 1.0), pins=(wc.Pin(indices=(0,), motion=motion),))
    sim = wc.Simulator(wc.Scene(cloths=(cloth,)), device="cpu")
    np.testing.assert_allclose(sim.positions()[0], [0.0, 0.5 * math.sin(1.0), 0.0], atol=1e-6)
    np.testing.assert_allclose(sim.velocities()[0], [0.0, 0.5 * 4 * math.pi * math.cos(1.0), 0.0], atol=1e-5)


@pytest.mark.parametrize("name", ["drape", "sphere_push"])
def test_no_particle_ends_a_frame_inside_a_sphere_or_under_the_ground(name):
    scene = with_simulation(wc.load_scene(name), frames=96)
    sim = wc.Simulator(scene, device="cpu")
    radii = np.array([s.radius + s.thickness for s in scene.spheres])  # where the cloth is kept outside
    contact_frames = 0
    for _ in range(96):
        sim.step()
        x = sim.positions()
        centers = sim.sphere_centers()
        distance = np.linalg.norm(x[:, None, :] - centers[None, :, :], axis=2)
        assert (distance >= radii * (1 - 1e-5)).all()
        contact_frames += bool((distance <= radii * (1 + 1e-3)).any())
        if scene.ground is not None:
            assert x[:, 1].min() >= scene.ground.surface - 1e-6
    assert contact_frames > 10, "the scene should bring cloth and sphere into contact"


@pytest.mark.parametrize("thickness", [0.0, 0.02])
def test_cloth_rests_its_thickness_off_the_ground_and_a_sphere(thickness):
    # A cloth dropped across a sphere onto the ground: at rest its lowest particles lie on the plane raised by
    # the thickness, and no particle comes nearer the sphere's centre than its radius and the thickness.
    cloth = wc.Cloth(resolution=(16, 16), size=(3.0, 3.0), orientation="horizontal", origin=(-1.5, 1.2, 1.5),
                     density=0.2, limit=wc.Limit())
    scene = wc.Scene(cloths=(cloth,), ground=wc.Ground(height=0.1, friction=0.5, thickness=thickness),
                     spheres=(wc.Sphere(center=(0.0, 0.6, 0.0), radius=0.5, thickness=thickness, friction=0.5),),
                     simulation=wc.Simulation(fps=24, integrator="symplectic", limit_solve="converged"))
    sim = wc.Simulator(scene, device="cpu")
    nearest = np.inf
    for _ in range(48):
        sim.step()
        x = sim.positions()
        nearest = min(nearest, float(np.linalg.norm(x - np.array([0.0, 0.6, 0.0]), axis=1).min()))
        assert x[:, 1].min() >= 0.1 + thickness - 1e-6
    assert nearest >= (0.5 + thickness) * (1 - 1e-5) and nearest <= (0.5 + thickness) * (1 + 1e-3)
    assert sim.positions()[:, 1].min() == pytest.approx(0.1 + thickness, abs=1e-4)  # resting on the raised plane


def test_moving_sphere_follows_its_motion():
    scene = wc.load_scene("sphere_push")
    sim = wc.Simulator(scene, device="cpu")
    sphere = scene.spheres[0]
    for frame in range(1, 25):
        sim.step()
        expected = np.add(sphere.center, sphere.motion.offset(frame / scene.simulation.fps))
        np.testing.assert_allclose(sim.sphere_centers()[0], expected, atol=1e-5)


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_ground_friction_stops_a_sliding_cloth_after_v0_squared_over_2_mu_g(mu):
    v0, g = 3.0, 9.81
    cloth = wc.Cloth(resolution=(1, 1), size=(0.2, 0.2), orientation="horizontal", origin=(0.0, 0.0, 0.0),
                     velocity=(v0, 0.0, 0.0), structural=OFF, shear=OFF, bend=OFF)
    scene = wc.Scene(cloths=(cloth,), ground=wc.Ground(friction=mu),
                     simulation=wc.Simulation(fps=24, substeps=40, integrator="symplectic"))
    sim = wc.Simulator(scene, device="cpu")
    x0 = sim.positions()[:, 0].copy()
    sim.run(48)
    travelled = sim.positions()[:, 0] - x0
    expected = v0 * v0 / (2 * mu * g)
    # Each substep's contact removes g h of normal speed and mu g h of tangential speed: the discrete
    # stopping distance differs from the analytic one by O(v0 h).
    np.testing.assert_allclose(travelled, expected, atol=v0 * sim.dt)
    assert np.abs(sim.velocities()).max() < 1e-6


def test_pins_that_pull_the_cloth_past_its_limit_are_refused(tmp_path):
    # two corners of an 8 m cloth swinging 1.5 m in opposite phase along the edge between them: 11 m apart
    # at the extremes, where a 10% limit allows 8.8 m
    scene = wc.load_scene("oscillating_pins")
    cloth = scene.cloths[0]
    along = tuple(dataclasses.replace(pin, motion=dataclasses.replace(pin.motion, axis=(1.0, 0.0, 0.0)))
                  for pin in cloth.pins)
    pulled = dataclasses.replace(scene, cloths=(dataclasses.replace(cloth, pins=along),))
    with pytest.raises(wc.SceneError, match=r"cloth\[0\]\.pins.*move 11 m apart.*across 8 m of cloth \(at most 8\.8 m\)"):
        wc.Simulator(pulled, device="cpu")
    shorter = dataclasses.replace(pulled, simulation=dataclasses.replace(scene.simulation, frames=12))
    wc.Simulator(shorter, device="cpu")  # over half a second they stay within reach
    loose = dataclasses.replace(pulled, cloths=(dataclasses.replace(pulled.cloths[0], limit=None),))
    wc.Simulator(loose, device="cpu")  # without a limit nothing bounds the stretch
    wc.Simulator(scene, device="cpu")  # the built-in scene swings them across the cloth: 8.54 m at most


def keyed_sphere_scene(keys: tuple[wc.TransformKey, ...]) -> wc.Scene:
    cloth = wc.Cloth(resolution=(8, 8), size=(0.6, 0.6), orientation="horizontal", origin=(-0.3, 0.52, 0.3),
                     density=0.2, limit=wc.Limit(0.1, 0.1), structural=wc.SpringKind(15.0, 0.02),
                     shear=wc.SpringKind(15.0, 0.02), bend=wc.SpringKind(5.0, 0.01, "compression", "compression"))
    return wc.Scene(cloths=(cloth,), spheres=(wc.Sphere(radius=0.5, friction=0.5, keys=keys),),
                    simulation=wc.Simulation(fps=24, frames=36, integrator="symplectic", limit_solve="converged"))


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_keyed_sphere_follows_its_keys_and_carries_the_cloth(device):
    keys = (wc.TransformKey(time=0.1), wc.TransformKey(time=0.9, translate=(0.0, 0.4, 0.0)))
    moved = wc.Simulator(keyed_sphere_scene(keys), device=device)
    still = wc.Simulator(keyed_sphere_scene(()), device=device)
    for frame in range(1, 37):
        moved.step()
        still.step()
        t = frame / 24.0
        rise = 0.4 * min(max((t - 0.1) / 0.8, 0.0), 1.0)
        np.testing.assert_allclose(moved.sphere_centers()[0], [0.0, rise, 0.0], atol=1e-5)
    # The sphere rose 0.4 m at 0.5 m/s and stopped 0.6 s ago: the cloth on it rose with it, draped as on the
    # sphere that stayed (its own 1.3 cm ballistic rise when the sphere stopped long settled).
    lift = moved.positions().astype(np.float64) - still.positions().astype(np.float64)
    assert lift[:, 1].mean() == pytest.approx(0.4, abs=0.01)
    assert np.abs(lift[:, [0, 2]]).max() < 0.02


def test_a_sphere_key_with_a_rotation_is_refused():
    with pytest.raises(wc.SceneError, match=r"keys\[0\].rotate: expected no rotation on a sphere's key"):
        wc.Sphere(keys=(wc.TransformKey(rotate=(0.0, 90.0, 0.0)),))
