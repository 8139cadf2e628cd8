"""Which surface pairs are contacts (warp_cloth/surface_pairs.py): pairs of one cloth near at rest are none, so
a cloth whose triangles are finer than the thickness starts and folds onto itself without a crossing and with
its other pairs held a thickness apart; without ``self`` a cloth's own pairs are neither measured nor
checked at the start."""

from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
from test_mesh_cloth import write_obj
from warp_cloth.diagnostics import TriangleIntersections
from warp_cloth.displacement_bounds import BoundSettings, DisplacementBounds
from warp_cloth.errors import SceneError
from warp_cloth.surface_start import refuse_surfaces_closer_than_thickness

THICKNESS = 0.004
MATERIAL = {"density": 0.2, "structural": wc.SpringKind(50.0, 0.05), "shear": wc.SpringKind(50.0, 0.05),
            "bend": wc.SpringKind(20.0, 0.02, "compression", "compression")}  # scenes/drape.toml's


@pytest.fixture(autouse=True)
def quiet():
    wc.set_verbose(False)


def two_sheets(path: Path, cell: float, cells: int, gap: float) -> Path:
    """One mesh of two flat square sheets of ``cells`` x ``cells`` triangulated cells, ``gap`` apart, the upper
    shifted a third of a cell in both directions (no vertex over another)."""
    u = np.arange(cells + 1) * cell
    points, faces = [], []
    for sheet, (height, shift) in enumerate([(0.0, 0.0), (gap, cell / 3.0)]):
        gx, gz = np.meshgrid(u + shift, u + shift, indexing="ij")
        points += [(x, height, z) for x, z in zip(gx.ravel(), gz.ravel())]
        at = lambda i, j: sheet * (cells + 1) ** 2 + i * (cells + 1) + j  # noqa: E731
        for i in range(cells):
            for j in range(cells):
                faces += [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]]
    return write_obj(path / "two_sheets.obj", np.array(points), faces)


def sheets_scene(mesh: Path, self_collision: bool = True) -> wc.Scene:
    cloth = wc.Cloth.from_mesh(str(mesh), name="sheets", limit=wc.Limit(0.1, 0.1), **MATERIAL)
    return wc.Scene(name="sheets", cloths=(cloth,), ground=wc.Ground(),
                    collision=wc.Collision(self_collision=self_collision, between_cloths=True, thickness=THICKNESS),
                    simulation=wc.Simulation(fps=60, frames=6, integrator="implicit"))


def test_cells_finer_than_the_thickness_start_and_fold_without_crossing(tmp_path):
    """2 mm cells at 4 mm, one mesh of two sheets 1 cm apart, the upper falling onto the lower on the ground.
    Before the rule the start check refused it ("start 0.00141 m apart": a vertex from the triangles across
    its diagonal); now each sheet's own pairs are left out (nearer than 4 / 0.9 = 4.4 mm at rest) and the
    sheets' pairs, 1 cm apart at rest, are contacts: no crossing in 6 frames (the upper lands in frame 2), and
    every pair that is a contact at least 0.9 of the thickness apart (0.980 at the closest when written,
    frame 6)."""
    sim = wc.Simulator(sheets_scene(two_sheets(tmp_path, 0.002, 20, 0.01)), device="cpu")
    np.testing.assert_allclose(sim.model.contacts.rest_apart, THICKNESS / 0.9, rtol=1e-6)
    surfaces = DisplacementBounds(sim.model, sim.device_model, BoundSettings(radius=THICKNESS))
    crossings = TriangleIntersections(sim)
    upper = sim.model.particle_count // 2
    counts, closest = [], []
    for _ in range(6):
        sim.step()
        counts.append(crossings(sim))
        surfaces.measure_at(sim.state.x)
        closest.append(float(surfaces.nearest.numpy().min()))
    assert max(counts) == 0, counts
    assert min(closest) >= 0.9 * THICKNESS, closest
    assert sim.positions()[upper:, 1].max() < 1.5 * THICKNESS  # it has landed on the lower sheet


@pytest.mark.parametrize("self_collision", [True, False])
def test_without_self_a_cloths_own_pairs_are_not_checked(tmp_path, self_collision):
    """The upper sheet moved to 1 mm over the lower (their pairs are 1 cm apart at rest, so contacts with
    ``self``): the surfaces' measure and the start check see the gap with ``self``, nothing without."""
    sim = wc.Simulator(sheets_scene(two_sheets(tmp_path, 0.01, 5, 0.01), self_collision), device="cpu")
    x = sim.model.positions.copy()
    x[sim.model.particle_count // 2:, 1] = 0.001
    folded = wp.array(x, dtype=wp.vec3, device="cpu")
    surfaces = DisplacementBounds(sim.model, sim.device_model, BoundSettings(radius=THICKNESS))
    surfaces.measure_at(folded)
    nearest = float(surfaces.nearest.numpy().min())
    if not self_collision:
        assert nearest == pytest.approx(THICKNESS)
        refuse_surfaces_closer_than_thickness(sim.scene, sim.model, sim.device_model, sim.plan.bounds, folded)
        return
    assert nearest == pytest.approx(0.001, rel=1e-4)
    with pytest.raises(SceneError, match="those of 'sheets' start 0.001 m apart"):
        refuse_surfaces_closer_than_thickness(sim.scene, sim.model, sim.device_model, sim.plan.bounds, folded)


def slope_scene(slope: float, friction: float) -> wc.Scene:
    """A 10 cm sheet of 2 cm cells 4.5 mm over a pinned 0.6 m one, gravity tilted by atan(``slope``) (a
    slope), the surfaces 4 mm apart with ``friction``; particle contacts reach 2.1 mm, short of the
    thickness, so that the surface pairs alone hold the sheet."""
    pinned = wc.Pin(region=wc.Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)))
    floor = wc.Cloth(name="slope", resolution=(10, 10), size=(0.6, 0.3), orientation="horizontal",
                     origin=(-0.3, 0.0, 0.15), pins=(pinned,), limit=wc.Limit(0.05, 0.05), **MATERIAL)
    sheet = wc.Cloth(name="sheet", resolution=(5, 5), size=(0.1, 0.1), orientation="horizontal",
                     origin=(-0.2, 0.0045, 0.05), limit=wc.Limit(0.05, 0.05), **MATERIAL)
    angle = np.arctan(slope)
    return wc.Scene(name="slope", cloths=(floor, sheet),
                    collision=wc.Collision(radius=0.001, friction=friction, thickness=THICKNESS),
                    simulation=wc.Simulation(fps=60, frames=12, gravity=(9.81 * np.sin(angle),
                                                                         -9.81 * np.cos(angle), 0.0)))


@pytest.mark.parametrize("slope", [0.3, 0.7])
def test_a_sheet_on_a_slope_slides_only_past_its_friction(slope):
    """Friction 0.5 on the surface pairs: on a slope of 0.3 the sheet stops within its first frames (its mean
    speed down the slope below 1 mm/s from frame 6 on: 1e-4 m/s at frames 12 and 18 when written); on 0.7 it
    slides at g (sin - 0.5 cos), 1.607 m/s^2, within 5% (1.658 between frames 6 and 12 when written, 3%
    over; a plain mean of each particle's pairs, the particle contacts' way, let it slide at 2.8 m/s^2, as at
    a coefficient of 0.35)."""
    sim = wc.Simulator(slope_scene(slope, 0.5), device="cpu")
    assert "surface_friction" in sim.plan.pass_names
    sheet = sim.model.cloth_slice(1)
    speeds = []
    for frame in range(12):
        sim.step()
        speeds.append(float(sim.velocities()[sheet, 0].mean()))
    if slope < 0.5:
        assert max(abs(s) for s in speeds[5:]) < 1e-3, speeds
        return
    angle = np.arctan(slope)
    expected = 9.81 * (np.sin(angle) - 0.5 * np.cos(angle))
    assert (speeds[11] - speeds[5]) * 10.0 == pytest.approx(expected, rel=0.05), speeds


def test_no_friction_no_pass(tmp_path):
    sim = wc.Simulator(sheets_scene(two_sheets(tmp_path, 0.01, 5, 0.01)), device="cpu")
    assert "surface_friction" not in sim.plan.pass_names
