"""A frame of many substeps captured as a loop on the device over rounds of them (warp_cloth/substep_rounds.py):
the same frames as launching every substep, and the blow-up guard's flags at the substeps they belong to."""

import numpy as np
import pytest

import warp_cloth as wc
from warp_cloth.errors import UnstableSimulation
from warp_cloth.substep_rounds import LOOPED_FROM, ROUND

OFF = wc.SpringKind(enabled=False)
DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name", ["flag", "spinning_sphere"])  # 94 substeps: rounds and 14 after; 80: rounds alone
def test_a_looped_frame_makes_the_frames_of_every_substep_launched(device, name):
    scene = wc.load_scene(name)
    runs = []
    for graph in (True, False):
        sim = wc.Simulator(scene, device=device, graph=graph)
        assert sim.substeps_per_frame >= LOOPED_FROM
        sim.run(2)
        runs.append((sim.positions(), sim.velocities()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("first_too_fast", [ROUND + 4, 4 * ROUND + 3])  # in the second round; after the rounds
def test_the_guard_names_the_substep_of_a_looped_frame(device, first_too_fast):
    # A free particle falls from rest: after k substeps of explicit Euler its speed is g k h. With max_speed
    # between g (K - 1) h and g K h the guard must first flag substep K.
    substeps, g = 4 * ROUND + 6, 9.81
    h = 1.0 / (24 * substeps)
    cloth = wc.Cloth(resolution=(1, 1), limit=None, structural=OFF, shear=OFF, bend=OFF)
    scene = wc.Scene(cloths=(cloth,), simulation=wc.Simulation(
        fps=24, substeps=substeps, integrator="explicit", max_speed=g * (first_too_fast - 0.5) * h))
    sim = wc.Simulator(scene, device=device)
    with pytest.raises(UnstableSimulation) as info:
        sim.step()
    assert (info.value.frame, info.value.substep) == (1, first_too_fast)
