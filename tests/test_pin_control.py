"""Pins on any mesh (the boundary's corners and edges, proximity to a collider), soft pins, and pins and
spheres driven from Python between frames (warp_cloth/pin_selection.py, kernels/forces.py, control.py)."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

import warp_cloth as wc
from conftest import run_cli_in_process
from warp_cloth.pin_selection import CORNER_ANGLE


def square_with_a_hole(path):
    """A 5 x 5 quad mesh of 1 m cells without its middle quad: 36 vertices, 20 on the outline, 4 round the
    hole, 12 inside."""
    points = [(x, y, 0.0) for y in range(6) for x in range(6)]
    faces = [[x + 6 * y + 1, x + 1 + 6 * y + 1, x + 1 + 6 * (y + 1) + 1, x + 6 * (y + 1) + 1]
             for y in range(5) for x in range(5) if (x, y) != (2, 2)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in points) +
                    "".join("f " + " ".join(map(str, f)) + "\n" for f in faces))
    return path


def disc(path, sides: int):
    """A fan of ``sides`` triangles round a centre: a boundary that turns by 360 / sides at each vertex."""
    points = [(0.0, 0.0, 0.0)] + [(math.cos(2 * math.pi * k / sides), math.sin(2 * math.pi * k / sides), 0.0)
                                  for k in range(sides)]
    faces = [[1, 2 + k, 2 + (k + 1) % sides] for k in range(sides)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in points) +
                    "".join("f " + " ".join(map(str, f)) + "\n" for f in faces))
    return path


def pinned(cloth, *colliders, spheres=(), ground=None) -> list[int]:
    scene = wc.Scene(cloths=(cloth,), colliders=colliders, spheres=spheres, ground=ground)
    return sorted(wc.Simulator(scene, device="cpu").model.pins.index.tolist())


def test_a_meshs_boundary_edges_and_corners_round_its_outline_and_its_hole(tmp_path):
    mesh = square_with_a_hole(tmp_path / "holed.obj")
    edges = pinned(wc.Cloth.from_mesh(mesh, pins=(wc.Pin(edges=("boundary",)),)))
    corners = pinned(wc.Cloth.from_mesh(mesh, pins=(wc.Pin(corners=("boundary",)),)))
    outline = [x + 6 * y for y in range(6) for x in range(6) if x in (0, 5) or y in (0, 5)]
    hole = [2 + 6 * 2, 3 + 6 * 2, 2 + 6 * 3, 3 + 6 * 3]
    assert len(edges) == 24 and edges == sorted(outline + hole)
    assert corners == sorted([0, 5, 30, 35] + hole)


def test_a_grids_boundary_is_its_four_edges_and_four_corners():
    cloth = wc.Cloth(resolution=(4, 3), pins=(wc.Pin(corners=("boundary",)),))
    assert pinned(cloth) == [0, 4, 15, 19]
    cloth = wc.Cloth(resolution=(4, 3), pins=(wc.Pin(edges=("boundary",)),))
    assert len(pinned(cloth)) == 2 * 5 + 2 * 2


def test_a_round_outline_has_corners_only_where_it_turns_past_the_angle(tmp_path):
    assert CORNER_ANGLE == 45.0
    square = pinned(wc.Cloth.from_mesh(disc(tmp_path / "four.obj", 4), pins=(wc.Pin(corners=("boundary",)),)))
    assert square == [1, 2, 3, 4]
    seven = pinned(wc.Cloth.from_mesh(disc(tmp_path / "seven.obj", 7), pins=(wc.Pin(corners=("boundary",)),)))
    assert seven == list(range(1, 8))  # turns by 51.4 degrees
    with pytest.raises(wc.SceneError, match=r"pins\[0\].corners: expected a boundary with a corner"):
        pinned(wc.Cloth.from_mesh(disc(tmp_path / "nine.obj", 9), pins=(wc.Pin(corners=("boundary",)),)))
    assert len(pinned(wc.Cloth.from_mesh(disc(tmp_path / "sixteen.obj", 16),
                                         pins=(wc.Pin(edges=("boundary",)),)))) == 16


def test_pins_near_a_sphere_a_mesh_collider_and_the_ground(tmp_path):
    """A 2 x 2 m cloth of 0.2 m cells lying 5 cm above a unit sphere's top: within 10 cm of its surface are
    the particles within sqrt(1.1^2 - 1.05^2) = 0.328 m of the axis, 9 of them; a 0.6 m square mesh 5 cm
    below the cloth holds, within 6 cm, the 9 particles above it."""
    cloth = dict(resolution=(10, 10), size=(2.0, 2.0), orientation="horizontal", origin=(-1.0, 1.05, 1.0))
    sphere = wc.Sphere(name="ball", radius=1.0)
    near_ball = wc.Pin(near=wc.Near("ball", 0.1))
    chosen = pinned(wc.Cloth(pins=(near_ball,), **cloth), spheres=(sphere,))
    assert len(chosen) == 9 and 5 + 11 * 5 in chosen
    plate = tmp_path / "plate.obj"
    plate.write_text("v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\nf 1 4 3 2\n")
    collider = wc.MeshCollider(name="plate", mesh=wc.MeshSource(str(plate)))
    on_plate = wc.Pin(near=wc.Near("plate", 0.06), target="plate")
    assert pinned(wc.Cloth(pins=(on_plate,), **cloth), collider) == chosen
    ground = wc.Pin(near=wc.Near("ground", 0.01))
    assert len(pinned(wc.Cloth(pins=(ground,), **cloth), ground=wc.Ground(height=1.05))) == 121


def settled_sag(integrator: str, stiffness: float) -> float:
    """How far a 1 x 1 cell cloth hangs below where its four soft pins hold it: equal particles, equally
    held, so its springs stay at rest and each particle hangs on its pin alone."""
    pin = wc.Pin(corners=("boundary",), stiffness=stiffness, damping=2.0 * math.sqrt(stiffness * 0.025))
    cloth = wc.Cloth(resolution=(1, 1), size=(0.5, 0.5), orientation="horizontal", mass=0.025, pins=(pin,))
    scene = wc.Scene(cloths=(cloth,), simulation=wc.Simulation(frames=72, integrator=integrator, substeps=20))
    sim = wc.Simulator(scene, device="cpu")
    start = sim.positions()
    for _ in range(72):
        sim.step()
    return float(np.mean(start[:, 1] - sim.positions()[:, 1]))


@pytest.mark.parametrize("integrator", ["symplectic", "implicit"])
def test_a_soft_pin_stretches_by_its_weight_over_its_stiffness(integrator):
    for stiffness in (1.0, 4.0):
        expected = 0.025 * 9.81 / stiffness
        assert settled_sag(integrator, stiffness) == pytest.approx(expected, rel=0.02)


def test_a_soft_pinned_particle_keeps_its_mass_and_a_hard_one_does_not():
    pins = (wc.Pin(indices=(0,), stiffness=10.0), wc.Pin(indices=(1,)))
    sim = wc.Simulator(wc.Scene(cloths=(wc.Cloth(resolution=(2, 2), pins=pins),)), device="cpu")
    assert sim.model.inv_mass[0] > 0 and sim.model.inv_mass[1] == 0


DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)]


def hanging(pins, spheres=(), frames=24, device="cpu"):
    cloth = wc.Cloth(resolution=(8, 8), size=(1.0, 1.0), pins=pins, limit=wc.Limit())
    return wc.Simulator(wc.Scene(cloths=(cloth,), spheres=spheres, simulation=wc.Simulation(frames=frames)),
                        device=device)


@pytest.mark.parametrize("device", DEVICES)
def test_a_pin_driven_from_python_goes_in_a_line_and_ends_where_it_was_sent(device):
    sim = hanging((wc.Pin(corners=("top-left",), name="hand"), wc.Pin(corners=("top-right",))), device=device)
    corner = 8 * 9
    assert "control" not in str(sim.plan)
    start = sim.positions()[corner]
    goal = start + np.array([0.3, -0.1, 0.2])
    sim.control.pins["hand"].set_transform(translate=(0.3, -0.1, 0.2))
    assert "pins:control" in str(sim.plan)
    substeps = sim.substeps_per_frame
    for k in range(substeps):
        sim.substep()
        w = (k + 1) / substeps
        np.testing.assert_allclose(sim.positions()[corner], (1 - w) * start + w * goal, atol=1e-6)
    assert np.array_equal(sim.positions()[corner], goal.astype(np.float32))
    for _ in range(3):
        sim.step()
    assert np.array_equal(sim.positions()[corner], goal.astype(np.float32))
    assert np.all(sim.velocities()[corner] == 0.0)
    turned = sim.control.pins["hand"]
    turned.set_positions(turned.rest + [0.0, 0.4, 0.0])
    sim.step()
    assert np.array_equal(sim.positions()[corner], (turned.rest[0] + [0.0, 0.4, 0.0]).astype(np.float32))
    with pytest.raises(ValueError, match=r"positions: finite points of shape \(1, 3\)"):
        turned.set_positions(np.zeros((2, 3)))
    with pytest.raises(KeyError, match="no pin named 'foot' \\(hand\\)"):
        sim.control.pins["foot"]


def test_a_pin_sent_out_of_the_cloths_reach_is_refused_and_nothing_is_sent():
    """The top corners of a 1 m cloth with a 10% stretch limit may end at most 1.1 m apart: a corner sent
    to end 1.12 m from the other is refused (no solve could hold the limit, and substeps auto would double
    the frame's substeps to the most it takes, to no avail), whether the other is where it is or was sent
    for the same frame; 1.08 m is accepted."""
    sim = hanging((wc.Pin(corners=("top-left",), name="hand"), wc.Pin(corners=("top-right",), name="other")))
    hand, other = sim.control.pins["hand"], sim.control.pins["other"]
    left, right = 8 * 9, 8 * 9 + 8
    with pytest.raises(ValueError, match=re.escape(
            "pin 'hand' sent too far: pins that 'cloth' can follow within its 10% stretch limit: its pinned "
            f"particles {left} and {right} would be 1.12 m apart, across 1 m of cloth (at most 1.1 m)")):
        hand.set_positions(hand.rest + [0.0, 0.5, 0.0])
    assert not sim.control.started
    sim.step()
    assert np.array_equal(sim.positions()[left], np.float32([0.0, 1.0, 0.0]))
    hand.set_positions(hand.rest + [0.0, 0.4, 0.0])
    with pytest.raises(ValueError, match=f"particles {right} and {left} would be 1.12 m apart"):
        other.set_positions(other.rest - [0.0, 0.1, 0.0])
    sim.step()
    assert np.array_equal(sim.positions()[[left, right]], np.float32([[0.0, 1.4, 0.0], [1.0, 1.0, 0.0]]))


def test_a_scene_whose_pins_move_out_of_the_cloths_reach_is_refused():
    """Two corners of a 1 m cloth with a 10% limit swung 0.06 m apart each way at most (1.12 m apart) are
    refused with the pair and the time; 0.04 m each way (1.08 m) is accepted."""
    def swinging(amplitude):
        pins = tuple(wc.Pin(corners=(corner,), motion=wc.Oscillation(axis=(sign, 0.0, 0.0), amplitude=amplitude,
                                                                      frequency=1.0, phase=0.0))
                     for corner, sign in (("top-left", -1.0), ("top-right", 1.0)))
        return hanging(pins)
    with pytest.raises(wc.SceneError, match=re.escape(
            "cloth[0].pins: expected pins that 'cloth' can follow within its 10% stretch limit: particles 72 and 80 "
            "move 1.12 m apart at t = 0.25 s, across 1 m of cloth (at most 1.1 m)")):
        swinging(0.06)
    assert swinging(0.04).frame == 0


@pytest.mark.parametrize("device", DEVICES)
def test_a_sphere_sent_from_python_pushes_the_cloth(device):
    """A cloth hangs in z = 0 beside a sphere; sent through it over a frame, the sphere pushes it along."""
    ball = wc.Sphere(name="ball", center=(0.5, 0.4, -0.5), radius=0.2)
    sim = hanging((wc.Pin(edges=("top",)),), spheres=(ball,), device=device)
    sim.control.spheres["ball"].set_center((0.5, 0.4, 0.5))
    sim.step()
    assert np.array_equal(sim.sphere_centers()[0], np.float32([0.5, 0.4, 0.5]))
    x = sim.positions()
    distance = np.linalg.norm(x - [0.5, 0.4, 0.5], axis=1)
    assert distance.min() >= 0.2 * 0.99  # kept outside it
    assert x[:, 2].max() > 0.65  # carried along


BAD_PINS = [
    ('near = { collider = "nope", distance = 0.1 }', "cloth[0].pins[0].near.collider",
     "the name of a sphere, a [[collider]] or the ground"),
    ('corners = ["boundary"]\ndamping = 1.0', "cloth[0].pins[0].damping", "no damping on a hard pin"),
    ('corners = ["boundary"]\nstiffness = -1.0', "cloth[0].pins[0].stiffness", "a number > 0"),
    ('corners = ["middle"]', "cloth[0].pins[0].corners", "boundary"),
    ('edges = ["boundary"]\nname = "a b"', "cloth[0].pins[0].name", ""),
]


@pytest.mark.parametrize("text, key, expected", BAD_PINS, ids=[b[1] + str(k) for k, b in enumerate(BAD_PINS)])
def test_bad_pin_keys_are_one_line_naming_file_and_key(tmp_path, text, key, expected):
    scene = tmp_path / "scene.toml"
    scene.write_text(f"[[sphere]]\nname = \"ball\"\n[[cloth]]\n[[cloth.pins]]\n{text}\n")
    code, _, err = run_cli_in_process("run", str(scene), "--out", "out", cwd=tmp_path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err
    assert "scene.toml" in lines[0] and key in lines[0] and expected in lines[0], lines[0]


def test_a_mesh_cloth_refuses_the_grids_named_corners(tmp_path):
    mesh = square_with_a_hole(tmp_path / "holed.obj")
    with pytest.raises(wc.SceneError, match=r"pins\[0\].corners: expected \[\"boundary\"\] on a mesh cloth"):
        wc.Cloth.from_mesh(mesh, pins=(wc.Pin(corners=("top-left",)),))


def test_pin_names_are_unique():
    pins = (wc.Pin(indices=(0,), name="hand"), wc.Pin(indices=(1,), name="hand"))
    with pytest.raises(wc.SceneError, match=r"cloth\[0\].pins\[1\].name: expected a name no other pin has"):
        wc.Scene(cloths=(wc.Cloth(pins=pins),))


def test_the_python_guides_control_example_runs():
    text = (Path(__file__).parent.parent / "docs" / "guide" / "python-api.md").read_text()
    example = re.search(r"## Driving pins and spheres from Python: the control input\n\n.*?```python\n(.*?)```",
                        text, re.S).group(1)
    names: dict = {}
    exec(compile(example, "python-api.md", "exec"), names)
    sim, hand = names["sim"], names["sim"].control.pins["hand"]
    assert sim.frame == 24
    assert np.array_equal(sim.positions()[8 * 9], (hand.rest[0] + [0.23, 0.0, 0.0]).astype(np.float32))
    assert np.array_equal(sim.sphere_centers()[0], np.float32([0.5, 0.4, -0.5 + 0.04 * 23]))


def test_a_soft_pin_pulls_toward_where_its_keys_and_the_control_put_it():
    """Keys carry the soft pins' targets 0.5 m along x over the first second; then the control sends them
    0.5 m along z. Each time the cloth settles hanging m g / k below its targets."""
    damping = 2.0 * math.sqrt(4.0 * 0.025)
    keys = (wc.TransformKey(0.0), wc.TransformKey(1.0, translate=(0.5, 0.0, 0.0)))
    pin = wc.Pin(corners=("boundary",), stiffness=4.0, damping=damping, keys=keys, name="frame")
    cloth = wc.Cloth(resolution=(1, 1), size=(0.5, 0.5), orientation="horizontal", mass=0.025, pins=(pin,))
    sim = wc.Simulator(wc.Scene(cloths=(cloth,), simulation=wc.Simulation(substeps=20)), device="cpu")
    start, sag = sim.positions(), 0.025 * 9.81 / 4.0
    for _ in range(72):
        sim.step()
    np.testing.assert_allclose(sim.positions() - start, np.tile([0.5, -sag, 0.0], (4, 1)), atol=0.02 * sag)
    sim.control.pins["frame"].set_transform(translate=(0.5, 0.0, 0.5))
    for _ in range(48):
        sim.step()
    np.testing.assert_allclose(sim.positions() - start, np.tile([0.5, -sag, 0.5], (4, 1)), atol=0.02 * sag)


@pytest.mark.parametrize("device", DEVICES)
def test_a_mesh_collider_sent_from_python_carries_the_pins_that_touch_it(tmp_path, device):
    """A cloth lies over a 4 m plate, 5 cm above it at one edge and tilted 1.5 degrees: its 4 rows of
    particles within 7 cm of the plate (5 cm + 0.2 m x sin 1.5 degrees a row) are pinned to it. The plate
    sent up 2 cm a frame, then turned 3 degrees about its origin, carries them with it."""
    plate = tmp_path / "plate.obj"
    plate.write_text("v -2 1 -2\nv 2 1 -2\nv 2 1 2\nv -2 1 2\nf 1 4 3 2\n")
    collider = wc.MeshCollider(name="plate", mesh=wc.MeshSource(str(plate)))
    pin = wc.Pin(near=wc.Near("plate", 0.07), target="plate")
    cloth = wc.Cloth(resolution=(10, 10), size=(2.0, 2.0), orientation="horizontal", origin=(-1.0, 1.05, 1.0),
                     rotation=(1.5, 0.0, 0.0), pins=(pin,), limit=wc.Limit())
    sim = wc.Simulator(wc.Scene(cloths=(cloth,), colliders=(collider,)), device=device)
    start = sim.positions()
    held = sim.model.pins.index
    assert len(held) == 4 * 11
    for frame in range(1, 4):
        sim.control.colliders["plate"].set_transform(translate=(0.0, 0.02 * frame, 0.0))
        sim.step()
        np.testing.assert_allclose(sim.positions()[held], start[held] + [0.0, 0.02 * frame, 0.0], atol=1e-5)
    sim.control.colliders["plate"].set_transform(translate=(0.0, 0.06, 0.0), rotate=(0.0, 3.0, 0.0))
    sim.step()
    turn = np.radians(3.0)
    rotation = np.array([[np.cos(turn), 0, np.sin(turn)], [0, 1, 0], [-np.sin(turn), 0, np.cos(turn)]])
    np.testing.assert_allclose(sim.positions()[held], start[held] @ rotation.T + [0.0, 0.06, 0.0], atol=1e-5)


def test_pins_near_the_ground_select_in_their_own_world_of_a_batch():
    """Two scenes, their grounds 5 and 30 cm under the same hanging cloth of 25 cm rows: within 35 cm of its
    ground, each world pins two rows and one (the packed scene has no ground), their pins' names apart."""
    cloth = wc.Cloth(resolution=(4, 4), size=(1.0, 1.0), pins=(wc.Pin(near=wc.Near("ground", 0.35), name="hem"),))
    scenes = [wc.Scene(cloths=(cloth,), ground=wc.Ground(height=h)) for h in (-0.05, -0.3)]
    sim = wc.Batch(scenes, device="cpu").simulator
    assert sim.model.pins.index.tolist() == list(range(10)) + [25 + i for i in range(5)]
    assert sorted(sim.control.pins) == ["w0_hem", "w1_hem"]
