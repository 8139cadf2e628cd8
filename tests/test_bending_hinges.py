"""Bergou's hinges (materials.py, kernels/bending.py) on meshes of triangles: the plate's bending energy on a
cylinder, no force in any flat placement of the rest state, and Peirce's cantilever against the heavy
elastica, with the bend springs they replaced beside it."""

import numpy as np
import pytest

from test_materials import _scene, _tip_sag, elastica_tip_sag, write_grid_obj
from warp_cloth.fabric_presets import PRESETS
from warp_cloth.model import build_model


def _curvatures(bending, x: np.ndarray) -> np.ndarray:
    return np.einsum("sr,srk->sk", bending.weights, x[bending.particles])


def _energy(bending, x: np.ndarray) -> float:
    curvature = _curvatures(bending, x)
    return float(np.sum(0.5 * bending.stiffness * np.einsum("sk,sk->s", curvature, curvature)))


@pytest.mark.parametrize("cells", [10, 20, 40])
@pytest.mark.parametrize("axis", [0, 1])
def test_a_mesh_of_triangles_bent_round_a_cylinder_stores_the_plates_bending_energy(tmp_path, axis, cells):
    """A panel of denim (B differs along warp and weft), 20 x 10 cm in right triangles (each cell of a grid
    split along one diagonal), wrapped round a cylinder of radius 10 cm along one direction: its hinges'
    energy is the plate's 1/2 B kappa^2 over the area of its interior edges' triangle pairs (all but half a
    cell at the two ends along the bend), within an error that falls as the square of the cell (0.7%, 0.2%,
    0.04% at 1, 0.5, 0.25 cm cells). No bend spring is left; the diagonals' hinges stay flat."""
    size, radius = (0.2, 0.1), 0.1
    along_cells = cells * (1 + (axis == 0)) // 2
    mesh = write_grid_obj(tmp_path / "panel.obj", cells, cells // 2, *size, triangles=True)
    model = build_model(_scene(mesh=str(mesh), material="denim"))
    assert not (model.springs.kind == 2).any()
    flat = model.positions.astype(float)
    along = flat[:, axis] - flat[:, axis].min()
    bent = flat.copy()
    bent[:, axis] = radius * np.sin(along / radius)
    bent[:, 2] = flat[:, 2] + radius * (1.0 - np.cos(along / radius))
    bent_length = size[axis] * (along_cells - 1) / along_cells
    expected = 0.5 * PRESETS["denim"].bending[axis] / radius ** 2 * bent_length * size[1 - axis]
    assert _energy(model.bending, bent) == pytest.approx(expected, rel=0.007 * (10 / cells) ** 2)


def test_no_hinge_pulls_on_a_flat_placement_of_its_rest_state(tmp_path):
    """Bergou's model takes the rest state flat: turned, mirrored and moved anywhere, a flat mesh keeps every
    hinge's curvature vector at zero (so its force, -k w d, too), against 1/(10 cm) bent round a cylinder."""
    mesh = write_grid_obj(tmp_path / "panel.obj", 12, 9, 0.12, 0.09, triangles=True)
    model = build_model(_scene(mesh=str(mesh), material="cotton"))
    flat = model.cloths[0].positions  # as the hinges were derived from, in float64
    rng = np.random.default_rng(3)
    turn, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    bent = flat.copy()
    bent[:, 0], bent[:, 2] = 0.1 * np.sin(flat[:, 0] / 0.1), 0.1 * (1.0 - np.cos(flat[:, 0] / 0.1))
    scale = np.abs(_curvatures(model.bending, bent)).max()
    for mirror in (1.0, -1.0):
        placed = (flat * [mirror, 1.0, 1.0]) @ turn.T + rng.normal(size=3)
        assert np.abs(_curvatures(model.bending, placed)).max() < 1e-9 * scale


@pytest.mark.parametrize("preset, length, springs", [("cotton", 0.075, (0.3069, 0.3508, 0.3805)),
                                                      ("denim", 0.05, (0.3848, 0.4463, 0.4919))])
def test_a_clamped_strip_of_triangles_sags_closer_to_the_elastica_than_with_bend_springs(
        tmp_path, preset, length, springs):
    """Peirce's cantilever of test_materials on the same grid split into right triangles, at 10, 20 and 40
    cells along it: the hinges bend it, a stiffness linear in the curvature, where the rows' stencils cannot
    (no straight row under a bend spring between triangles). They do not match the stencils: the strip sags
    6.0, 7.9, 8.9% (cotton) and 11.4, 14.7, 16.3% (denim) further than the elastica, the more the finer, where
    the rows' stencils on the quads stay within 0.3%; the bend springs they replaced sagged ``springs``
    further (commit 54a9c1a). A hinge's curvature vector across a side of a cell mixes the row's bend with
    the twist between the cell's two rows, which the diagonal's hinge takes the other way, so a strip that
    twists a little bends for half the energy (denim's weft bends more easily than its warp: more so)."""
    data = PRESETS[preset]
    free = 0.8 * length
    c = (data.bending[0] / (data.density * 9.81)) ** (1.0 / 3.0)
    sags = []
    for cells, spring_error in zip((10, 20, 40), springs):
        expected = elastica_tip_sag(c, free + 0.5 * length / cells)
        mesh = write_grid_obj(tmp_path / f"strip{cells}.obj", cells, cells // 10, length, 0.01, triangles=True)
        error = _tip_sag(preset, length, (cells, cells // 10), mesh) / expected - 1.0
        assert 0.0 < error < 0.5 * spring_error
        sags.append(error)
    assert sags == pytest.approx({"cotton": [0.0596, 0.0792, 0.0888], "denim": [0.1142, 0.1470, 0.1632]}[preset],
                                 abs=5e-4)
