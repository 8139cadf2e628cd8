"""The seed's 10x10 cloth with the seed's parameters and its explicit Euler: stable at dt = 0.0025,
blows up at dt = 0.0104 (the seed's table: explodes from 0.0052 on, at frame 6 for 0.0104)."""

import numpy as np
import pytest

import warp_cloth as wc
from warp_cloth.errors import UnstableSimulation
from conftest import with_simulation


def first_unstable_frame(scene: wc.Scene, frames: int) -> int | None:
    """The frame at which the blow-up guard stops the run (checked independently: every frame before it is
    finite and bounded)."""
    sim = wc.Simulator(scene, device="cpu")
    for frame in range(1, frames + 1):
        try:
            sim.step()
        except UnstableSimulation as exc:
            assert exc.frame == frame
            return frame
        x, v = sim.positions(), sim.velocities()
        assert np.isfinite(x).all() and np.isfinite(v).all() and np.abs(v).max() <= scene.simulation.max_speed
    return None


def test_seed_cloth_is_stable_at_seed_step():
    scene = wc.load_scene("hanging")
    assert scene.simulation.dt == 0.0025 and scene.simulation.integrator == "explicit"
    assert first_unstable_frame(scene, 240) is None


@pytest.mark.parametrize("dt", [0.0104, 0.0208])
def test_seed_cloth_blows_up_at_large_explicit_steps(dt):
    frame = first_unstable_frame(with_simulation(wc.load_scene("hanging"), dt=dt), 240)
    assert frame is not None and frame <= 24
