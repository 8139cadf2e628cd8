"""The fitted stencils (bend_fits.py, kernels/bending.py) on meshes of triangles: the plate's bending energy on
a cylinder, none for a twist, no force in any flat placement of the rest state, and Peirce's cantilever
against the heavy elastica, converging as the rows' stencils on quads do."""

import numpy as np
import pytest

from test_materials import _scene, _tip_sag, elastica_tip_sag, write_grid_obj
from warp_cloth.fabric_presets import PRESETS
from warp_cloth.model import build_model


def _energy(bending, x: np.ndarray) -> float:
    curvature = bending.curvatures(x)
    return float(np.sum(0.5 * bending.stiffness * np.einsum("sk,sk->s", curvature, curvature)))


@pytest.mark.parametrize("cells", [10, 20, 40])
@pytest.mark.parametrize("axis", [0, 1])
def test_a_mesh_of_triangles_bent_round_a_cylinder_stores_the_plates_bending_energy(tmp_path, axis, cells):
    """A panel of denim (B differs along warp and weft), 20 x 10 cm in right triangles (each cell of a grid
    split along one diagonal), wrapped round a cylinder of radius 10 cm along one direction: its fits'
    energy is the plate's 1/2 B kappa^2 over its area but half a cell at the two ends along the bend (free
    borders, across which the fits take the curvature as zero, as no row's stencil ends there), within an
    error that falls as the square of the cell. No bend spring is left."""
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


@pytest.mark.parametrize("uvs", [True, False], ids=["uvs", "no uvs"])
def test_no_fit_pulls_on_a_flat_placement_of_its_rest_state(tmp_path, uvs):
    """The fits take the rest state flat: turned, mirrored and moved anywhere, a flat mesh keeps every
    fit's curvature vector at zero (so its force, -k w d, too), against 1/(10 cm) bent round a cylinder;
    with UVs or without (u then along each particle's first side)."""
    mesh = write_grid_obj(tmp_path / "panel.obj", 12, 9, 0.12, 0.09, triangles=True, uvs=uvs)
    model = build_model(_scene(mesh=str(mesh), material="cotton"))
    flat = model.cloths[0].positions  # as the fits were derived from, in float64
    rng = np.random.default_rng(3)
    turn, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    bent = flat.copy()
    bent[:, 0], bent[:, 2] = 0.1 * np.sin(flat[:, 0] / 0.1), 0.1 * (1.0 - np.cos(flat[:, 0] / 0.1))
    scale = np.abs(model.bending.curvatures(bent)).max()
    assert len(model.bending.stiffness) > 150  # both directions at most of the 130 particles
    for mirror in (1.0, -1.0):
        placed = (flat * [mirror, 1.0, 1.0]) @ turn.T + rng.normal(size=3)
        assert np.abs(model.bending.curvatures(placed)).max() < 1e-9 * scale


def test_a_twist_costs_nothing_and_lets_no_bend_off(tmp_path):
    """Heights 1/2 (a x^2 + 2 b x y + c y^2) on a panel of denim in right triangles: the stencils' energy
    is the bend a's plus the bend c's, whatever the twist b, which alone costs nothing (it was the hinges' flaw: a
    hinge across a side of a cell read a + b, so that a cantilever twisting a little bent for 0.75 to 0.79 of
    B; docs/notebook/accuracy.md)."""
    mesh = write_grid_obj(tmp_path / "panel.obj", 12, 12, 0.06, 0.06, triangles=True)
    model = build_model(_scene(mesh=str(mesh), material="denim"))
    flat = model.cloths[0].positions  # as the stencils were derived from, in float64
    x, y = flat[:, 0] - 0.03, flat[:, 1] - 0.03

    def energy(a, b, c):
        bent = flat.copy()
        bent[:, 2] = 0.5 * (a * x * x + 2 * b * x * y + c * y * y)  # the stencils are linear: any size will do
        return _energy(model.bending, bent)

    bend = energy(1.0, 0.0, 0.0)
    assert energy(0.0, 1.0, 0.0) < 1e-9 * bend
    assert energy(1.0, 1.0, 0.0) == pytest.approx(bend, rel=1e-9)
    assert energy(1.0, 0.5, 1.0) == pytest.approx(bend + energy(0.0, 0.0, 1.0), rel=1e-9)


@pytest.mark.parametrize("preset, length", [("cotton", 0.075), ("denim", 0.05)])
def test_a_clamped_strip_of_triangles_sags_as_the_elastica(tmp_path, preset, length):
    """Peirce's cantilever of test_materials on the same grid split into right triangles, at 10, 20 and 40
    cells along it (1, 2 and 4 across): it sags as the heavy elastica, -0.37, -0.08, -0.02% (cotton) and -0.39,
    -0.08, -0.01% (denim), as the rows' stencils on the quads do (-0.31 to -0.01%), the finer the closer. The
    hinges it replaced sagged +6.0 to +8.9% and +11.4 to +16.3% further, the finer the further (commit
    819e2e3); the bend springs before them +31 to +49%."""
    data = PRESETS[preset]
    free = 0.8 * length
    c = (data.bending[0] / (data.density * 9.81)) ** (1.0 / 3.0)
    errors = []
    for cells in (10, 20, 40):
        expected = elastica_tip_sag(c, free + 0.5 * length / cells)
        mesh = write_grid_obj(tmp_path / f"strip{cells}.obj", cells, cells // 10, length, 0.01, triangles=True)
        errors.append(_tip_sag(preset, length, (cells, cells // 10), mesh) / expected - 1.0)
    assert abs(errors[0]) < 0.005 and abs(errors[1]) < 0.3 * abs(errors[0]) and abs(errors[2]) < 0.3 * abs(errors[1])
    assert errors == pytest.approx({"cotton": [-0.00372, -0.00083, -0.00019],
                                    "denim": [-0.00387, -0.00079, -0.00008]}[preset], abs=5e-5)


def test_a_rows_stencil_names_its_three_particles_and_a_fit_its_own(tmp_path):
    """Stencils are as wide as they are (kernels/bending.py reads each one's entries alone): a grid's rows
    three particles each; a mesh of triangles' fits a particle and up to seven neighbours, as many as it
    has."""
    rows = build_model(_scene(resolution=[8, 6], size=[0.4, 0.3], material="denim")).bending
    assert (np.diff(rows.starts) == 3).all() and len(rows.particles) == 3 * len(rows.stiffness)
    mesh = write_grid_obj(tmp_path / "panel.obj", 8, 6, 0.4, 0.3, triangles=True)
    fits = build_model(_scene(mesh=str(mesh), material="denim")).bending
    widths = np.diff(fits.starts)
    assert widths.max() <= 8 and len(set(widths)) > 1  # a right-triangle grid: 7 inside, 5 on a side


@pytest.mark.parametrize("resolution", [30, 61])
def test_every_particle_of_the_drape_specimens_rim_is_bent_along_warp_and_weft(tmp_path, resolution):
    """The specimen's rim of triangles (drape_geometry.py): every particle of them has a stencil along the
    warp and one along the weft, a row's or a fit's (those with fewer points than a quadratic's six
    coefficients fitted to their neighbours' neighbours: 40 of 207 at 30 cells lacked one), and each reads
    the curvature of heights 1/2 (a x^2 + 2 b x z + c z^2) exactly, a along the warp and c along the weft,
    away from the hem (where a fit takes the curvature across it as zero)."""
    from warp_cloth.cloth_mesh import lumped_masses
    from warp_cloth.drape_test import drape_scene
    from warp_cloth.materials import Material
    from warp_cloth.mesh_io import face_edges, unique_pairs

    scene = drape_scene(Material(preset="denim"), resolution, tmp_path)
    model = build_model(scene)
    rest = scene.cloths[0].surface().points
    counts, indices = model.cloths[0].face_counts, model.cloths[0].face_indices
    rim = np.unique(indices[np.repeat(counts, counts) == 3])
    sides, uses = unique_pairs(face_edges(counts, indices), len(rest))
    hem = np.unique(sides[uses == 1])
    bending = model.bending
    first = bending.starts[:-1]
    row = np.diff(bending.starts) == 3  # a row's ends and middle; a fit reads its particle first
    centre = np.where(row, bending.particles[np.minimum(first + 1, len(bending.particles) - 1)],
                      bending.particles[first])
    area = lumped_masses(rest, counts, indices, 1.0)[centre]
    along_warp = np.isclose(bending.stiffness / area, PRESETS["denim"].bending[0])
    for axis, stencils in ((0, along_warp), (1, ~along_warp)):
        assert np.isin(rim, centre[stencils]).all()
        for a, b, c in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
            bent = rest.copy()
            bent[:, 1] = 0.5 * (a * rest[:, 0] ** 2 + 2 * b * rest[:, 0] * rest[:, 2] + c * rest[:, 2] ** 2)
            read = bending.curvatures(bent)[:, 1]
            inside = stencils & np.isin(centre, rim) & ~np.isin(centre, hem)
            assert read[inside] == pytest.approx((a, c)[axis], abs=1e-4)  # exact within 1e-6 in a fit's scaled terms
