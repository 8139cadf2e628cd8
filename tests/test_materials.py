"""Materials in SI units: the springs and masses derived from a material carry its stretch and shear at any
resolution and on a mesh, weigh its density times the area, bend alike at two resolutions; bad material keys
and a material beside raw springs are refused with one line; ``warp-cloth materials`` lists the presets."""

import json
from pathlib import Path

import numpy as np
import pytest

import warp_cloth as wc
from conftest import run_cli, run_cli_in_process
from warp_cloth.fabric_presets import PRESETS
from warp_cloth.cloth_mesh import BendStencils
from warp_cloth.model import build_model

STRAIN = 1e-3


def _springs_stiffness(springs, points: np.ndarray, active: np.ndarray) -> np.ndarray:
    """The springs' small-displacement stiffness matrix in the plane, (2n, 2n): (k / L) n n^T each."""
    pairs, rest = springs.pairs, springs.rest.astype(float)
    d = points[pairs[:, 0]] - points[pairs[:, 1]]
    unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    blocks = np.where(active, springs.stiffness / rest, 0.0)[:, None, None] * unit[:, :, None] * unit[:, None, :]
    size, corner = 2 * len(points), np.arange(2)
    rows, cols, values = [], [], []
    for a, sign_a in ((0, 1.0), (1, -1.0)):
        for b, sign_b in ((0, 1.0), (1, -1.0)):
            rows.append(2 * pairs[:, a, None, None] + corner[None, :, None] + 0 * corner[None, None, :])
            cols.append(2 * pairs[:, b, None, None] + 0 * corner[None, :, None] + corner[None, None, :])
            values.append(sign_a * sign_b * blocks)
    flat = np.concatenate(rows).ravel() * size + np.concatenate(cols).ravel()
    return np.bincount(flat, weights=np.concatenate(values).ravel(), minlength=size * size).reshape(size, size)


def _solved(stiffness: np.ndarray, held: np.ndarray, displacement: np.ndarray) -> np.ndarray:
    free = ~held
    u = displacement.copy()
    u[free] = np.linalg.solve(stiffness[np.ix_(free, free)], -stiffness[np.ix_(free, held)] @ displacement[held])
    return u


def pulled_stiffness(model, axis: int) -> float:
    """The tension per unit width over the strain of the flat sheet ``model`` (in the XY plane) pulled along
    ``axis`` by its two ends, free to narrow: the model's static equations at small displacement, each
    spring acting in its regimes (iterated until every spring's regime is the one its strain puts it in)."""
    points, springs = model.positions[:, :2].astype(float), model.springs
    low, high = np.isclose(points[:, axis], points[:, axis].min()), np.isclose(points[:, axis], points[:, axis].max())
    held = np.zeros(2 * len(points), dtype=bool)
    held[2 * np.nonzero(low | high)[0] + axis] = True
    held[2 * np.nonzero(low)[0][0] + 1 - axis] = True  # no sliding across
    displacement = np.zeros(2 * len(points))
    displacement[2 * np.nonzero(high)[0] + axis] = STRAIN * np.ptp(points[:, axis])
    active = np.ones(len(springs.pairs), dtype=bool)
    unit = points[springs.pairs[:, 0]] - points[springs.pairs[:, 1]]
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    for _ in range(20):
        stiffness = _springs_stiffness(springs, points, active)
        u = _solved(stiffness, held, displacement).reshape(-1, 2)
        strain = np.einsum("si,si->s", unit, u[springs.pairs[:, 0]] - u[springs.pairs[:, 1]])
        acting = np.where(strain > 0, springs.flags & 1, springs.flags & 2) != 0
        if np.array_equal(acting, active):
            break
        active = acting
    pull = (stiffness @ u.ravel()).reshape(-1, 2)[high, axis].sum()
    return pull / (np.ptp(points[:, 1 - axis]) * STRAIN)


def sheared_stiffness(model) -> float:
    """The shear stiffness of the flat sheet ``model`` whose border is sheared by a small angle (x += gamma y),
    inside free: twice its springs' energy per area over gamma^2."""
    points, springs = model.positions[:, :2].astype(float), model.springs
    stiffness = _springs_stiffness(springs, points, np.ones(len(springs.pairs), dtype=bool))
    x, y = points[:, 0], points[:, 1]
    border = np.isclose(x, x.min()) | np.isclose(x, x.max()) | np.isclose(y, y.min()) | np.isclose(y, y.max())
    displacement = np.zeros(2 * len(points))
    displacement[0::2] = STRAIN * (y - y.min())
    u = _solved(stiffness, np.repeat(border, 2), displacement)
    return u @ stiffness @ u / (np.ptp(x) * np.ptp(y) * STRAIN ** 2)


def write_grid_obj(path: Path, nx: int, ny: int, width: float, height: float, triangles: bool,
                   uvs: bool = True) -> Path:
    """A flat nx x ny grid of quads (or each split into two triangles) in the XY plane, its UV u along x."""
    xs, ys = np.meshgrid(np.linspace(0, width, nx + 1), np.linspace(0, height, ny + 1), indexing="xy")
    lines = [f"v {x} {y} 0" for x, y in zip(xs.ravel(), ys.ravel())]
    if uvs:
        lines += [f"vt {x / width} {y / height}" for x, y in zip(xs.ravel(), ys.ravel())]
    corner = lambda i, j: j * (nx + 1) + i + 1  # noqa: E731
    for j in range(ny):
        for i in range(nx):
            q = [corner(i, j), corner(i + 1, j), corner(i + 1, j + 1), corner(i, j + 1)]
            for face in ([q[:3], [q[0], q[2], q[3]]] if triangles else [q]):
                lines.append("f " + " ".join(f"{v}/{v}" if uvs else f"{v}" for v in face))
    path.write_text("\n".join(lines) + "\n")
    return path


def _scene(**cloth) -> wc.Scene:
    return wc.scene_from_dict({"name": "material", "cloth": [cloth]})


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_a_grid_carries_the_materials_stretch_and_shear_at_two_resolutions(preset):
    data = PRESETS[preset]
    for resolution in ((8, 8), (16, 16)):
        model = build_model(_scene(resolution=resolution, size=[1.0, 1.0], material=preset))
        assert pulled_stiffness(model, 0) == pytest.approx(data.stretch[0], rel=1e-3)
        assert pulled_stiffness(model, 1) == pytest.approx(data.stretch[1], rel=1e-3)
        assert sheared_stiffness(model) == pytest.approx(data.shear, rel=1e-3)


@pytest.mark.parametrize("triangles", [False, True], ids=["quads", "triangles"])
def test_a_mesh_along_its_uvs_carries_the_materials_stretch_and_shear(tmp_path, triangles):
    mesh = write_grid_obj(tmp_path / "panel.obj", 9, 7, 0.9, 0.7, triangles)
    for preset, data in PRESETS.items():
        model = build_model(_scene(mesh=str(mesh), material=preset))
        assert pulled_stiffness(model, 0) == pytest.approx(data.stretch[0], rel=1e-3), preset
        assert pulled_stiffness(model, 1) == pytest.approx(data.stretch[1], rel=1e-3), preset
        assert sheared_stiffness(model) == pytest.approx(data.shear, rel=1e-3), preset


def test_a_wovens_oblong_cells_carry_its_stretch():
    """A woven's shear is far below its stretch, so cells twice as long as wide still leave its sides a
    positive stiffness (a knit's would not: see materials.py)."""
    model = build_model(_scene(resolution=(10, 20), size=[1.0, 1.0], material="denim"))
    assert pulled_stiffness(model, 0) == pytest.approx(PRESETS["denim"].stretch[0], rel=1e-3)
    assert pulled_stiffness(model, 1) == pytest.approx(PRESETS["denim"].stretch[1], rel=1e-3)


def test_a_mesh_without_uvs_is_isotropic_at_the_mean_stretch(tmp_path):
    mesh = write_grid_obj(tmp_path / "panel.obj", 8, 8, 0.8, 0.8, triangles=True, uvs=False)
    model = build_model(_scene(mesh=str(mesh), material={"density": 0.2, "stretch": [1000.0, 3000.0],
                                                         "shear": 50.0, "bending": 1e-5}))
    assert pulled_stiffness(model, 0) == pytest.approx(pulled_stiffness(model, 1), rel=1e-6)
    assert pulled_stiffness(model, 0) == pytest.approx(2000.0, rel=0.01)


@pytest.mark.parametrize("cloth", [dict(resolution=(7, 5), size=[1.3, 0.9]), dict(mesh="tablecloth.obj")],
                         ids=["grid", "mesh"])
def test_the_masses_are_the_density_times_the_area(cloth):
    if "mesh" in cloth:
        cloth = dict(mesh=str(Path(wc.__file__).parent.parent / "scenes" / cloth["mesh"]))
    model = build_model(_scene(**cloth, material={"preset": "denim", "density": 0.25}))
    mesh = model.cloths[0]
    from warp_cloth.mesh_io import face_areas

    area = face_areas(mesh.positions, mesh.face_counts, mesh.face_indices).sum()
    assert mesh.masses.sum() == pytest.approx(0.25 * area, rel=1e-12)


@pytest.mark.parametrize("axis", [0, 1])
def test_a_grid_bent_round_a_cylinder_stores_the_plates_bending_energy(axis):
    """The stencils' energy of a grid of denim (B differs along warp and weft) wrapped round a cylinder of
    radius 10 cm along one direction is the plate's 1/2 B kappa^2 over the area its stencils' middles stand
    for (all but the half cells at the two ends along the bend), within the second difference's error of
    (h kappa)^2 / 12 (0.1% at 1 cm cells); the rows across stay straight and store nothing."""
    nx, ny, size, radius = 20, 10, (0.2, 0.1), 0.1
    model = build_model(_scene(resolution=[nx, ny], size=list(size), material="denim"))
    flat, bending = model.positions.astype(float), model.bending
    along = flat[:, axis] - flat[:, axis].min()
    bent = flat.copy()
    bent[:, axis] = radius * np.sin(along / radius)
    bent[:, 2] = flat[:, 2] + radius * (1.0 - np.cos(along / radius))
    curvature = bending.curvatures(bent)
    energy = np.sum(0.5 * bending.stiffness * np.einsum("sk,sk->s", curvature, curvature))
    cells = (nx, ny)[axis]
    length = size[axis] * (cells - 1) / cells
    expected = 0.5 * PRESETS["denim"].bending[axis] / radius ** 2 * length * size[1 - axis]
    assert energy == pytest.approx(expected, rel=2e-3)


def _tip_sag(preset: str, length: float, resolution: tuple[int, int], mesh: Path | None = None) -> float:
    """How far below its clamp the free end of a strip of ``preset``, ``length`` x 1 cm, hangs (clamped along
    its first fifth), at rest under gravity: the model's static equations (each spring in its regimes, and
    the bending stencils), solved by Newton's method with a Levenberg-Marquardt shift. A grid of quads, or
    ``mesh``, the same grid as an OBJ (``write_grid_obj``)."""
    cloth = {"mesh": str(mesh)} if mesh is not None else {"resolution": resolution, "size": [length, 0.01]}
    model = build_model(_scene(material=preset, **cloth))
    springs, x = model.springs, model.positions.astype(float)
    pairs, rest, k = springs.pairs, springs.rest.astype(float), springs.stiffness.astype(float)
    bending = model.bending or BendStencils(np.zeros(1, dtype=int), np.zeros(0, dtype=int), np.zeros(0), np.zeros(0),
                                            np.zeros(0))
    widths = np.diff(bending.starts)  # the stencils as a table, each row padded with zero weights
    used = np.arange(max(widths, default=1)) < widths[:, None]
    particles, weights = np.zeros(used.shape, dtype=int), np.zeros(used.shape)
    particles[used], weights[used] = bending.particles, bending.weights
    column = np.arange(len(x)) % (resolution[0] + 1)
    free = np.repeat(column > resolution[0] // 5, 3)
    weight = model.masses.astype(float) * 9.81
    size, corner = 3 * len(x), np.arange(3)

    def assembled(ends, blocks) -> np.ndarray:
        """The (size, size) matrix of ``blocks[s, a, b]`` (3 x 3) between particles ends[s, a] and ends[s, b]."""
        count = ends.shape[1]
        rows = 3 * ends[:, :, None, None, None] + corner[None, None, None, :, None] + 0 * corner
        cols = 3 * ends[:, None, :, None, None] + 0 * corner[:, None] + corner[None, None, None, None, :]
        shape = (len(ends), count, count, 3, 3)
        rows, cols = np.broadcast_to(rows, shape), np.broadcast_to(cols, shape)
        return np.bincount((rows * size + cols).ravel(), weights=blocks.ravel(), minlength=size * size).reshape(size, size)

    def energy(x, with_derivatives=True):
        d = x[pairs[:, 0]] - x[pairs[:, 1]]
        length = np.linalg.norm(d, axis=1)
        strain = length / rest - 1.0
        acting = np.where(strain > 0, springs.flags & 1, springs.flags & 2) != 0
        kk = np.where(acting, k, 0.0)
        curvature = np.einsum("sr,srk->sk", weights, x[particles])
        total = (np.sum(0.5 * kk * rest * strain ** 2) + np.sum(weight * x[:, 2])
                 + np.sum(0.5 * bending.stiffness * np.einsum("sk,sk->s", curvature, curvature)))
        if not with_derivatives:
            return total, None, None
        unit = d / length[:, None]
        force = (kk * strain)[:, None] * unit
        gradient = np.zeros_like(x)
        np.add.at(gradient, pairs[:, 0], force)
        np.add.at(gradient, pairs[:, 1], -force)
        np.add.at(gradient, particles, (bending.stiffness[:, None] * curvature)[:, None, :] * weights[:, :, None])
        gradient[:, 2] += weight
        outer = unit[:, :, None] * unit[:, None, :]
        blocks = (kk / rest)[:, None, None] * (outer + (1.0 - rest / length)[:, None, None] * (np.eye(3) - outer))
        hessian = assembled(pairs, np.stack([np.stack([blocks, -blocks], 1), np.stack([-blocks, blocks], 1)], 1))
        stencil = bending.stiffness[:, None, None] * weights[:, :, None] * weights[:, None, :]
        hessian += assembled(particles, stencil[:, :, :, None, None] * np.eye(3))
        return total, gradient.ravel()[free], hessian[np.ix_(free, free)]

    shift = 1e-3
    for _ in range(1000):
        total, gradient, hessian = energy(x)
        if np.linalg.norm(gradient) < 1e-8 * weight.sum():
            break
        scale = np.abs(np.diag(hessian)) + 1e-6 * np.abs(np.diag(hessian)).mean()
        while shift < 1e12:
            trial = x.ravel().copy()
            trial[free] += np.linalg.solve(hessian + shift * np.diag(scale), -gradient)
            if energy(trial.reshape(-1, 3), False)[0] < total:
                x, shift = trial.reshape(-1, 3), max(shift / 10.0, 1e-12)
                break
            shift *= 4.0
        else:  # no step lowers the energy any more in float64: a minimum to its rounding, where the gradient is small
            if np.linalg.norm(gradient) < 1e-6 * weight.sum():
                break
            raise AssertionError("the strip's Newton steps stalled short of its equilibrium")
    else:
        raise AssertionError("the strip's equilibrium was not found")
    return -x[column == resolution[0], 2].mean()


def elastica_tip_sag(bending_length: float, free: float, steps: int = 500) -> float:
    """How far the tip of an inextensible strip of ``free`` length, clamped level, hangs under its own weight:
    the heavy elastica B theta'' = -w (l - s) cos theta, theta(0) = 0, theta'(l) = 0 (theta the angle below
    level at arc length s, c^3 = B / w), shot on theta'(0) by bisection, integrated by RK4."""
    ds = free / steps

    def shot(slope: float) -> tuple[float, float]:
        def rate(s, y):
            return np.array([y[1], -(free - s) * np.cos(y[0]) / bending_length ** 3, np.sin(y[0])])

        y, s = np.array([0.0, slope, 0.0]), 0.0
        for _ in range(steps):
            k1 = rate(s, y)
            k2 = rate(s + ds / 2, y + ds / 2 * k1)
            k3 = rate(s + ds / 2, y + ds / 2 * k2)
            k4 = rate(s + ds, y + ds * k3)
            y, s = y + ds / 6 * (k1 + 2 * k2 + 2 * k3 + k4), s + ds
        return y[1], y[2]

    low, high = 0.0, free / bending_length ** 3 * free  # theta'(0) <= the weight's moment over B at level
    for _ in range(45):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if shot(middle)[0] < 0 else (low, middle)
    return shot(0.5 * (low + high))[1]


@pytest.mark.parametrize("preset, length", [("cotton", 0.075), ("denim", 0.05)])
def test_a_clamped_strip_sags_as_the_elastica_at_any_resolution(preset, length):
    """Peirce's cantilever (the textile bending-length test): a strip clamped level along its first fifth
    hangs under its weight as the heavy elastica of its bending length c = (B / w)^(1/3) says, at 10, 20 and
    40 cells along it (and 1, 2, 4 across): the bending stencils' moment is B kappa at every curvature. The
    clamp holds the tangent of its last held cell, so the strip bends from that cell's middle: the elastica
    compared with is the free length plus half a cell (a tenth of a cell of error at 10 cells, which halves
    twice at each doubling; against the free length alone the strip sags 13%, 7% and 3.5% more). Free
    lengths of about 2 c (cotton 2.05 c, denim 1.96 c). (The bend springs
    these stencils replaced, too weak at gentle curvature, sagged 25 to 46% further than this elastica, the
    more the finer: cotton 5.64, 5.49, 5.50 cm against 4.52, 4.25, 4.12.)"""
    data = PRESETS[preset]
    free = 0.8 * length
    c = (data.bending[0] / (data.density * 9.81)) ** (1.0 / 3.0)
    for cells in (10, 20, 40):
        expected = elastica_tip_sag(c, free + 0.5 * length / cells)
        assert 0.3 * free < expected < 0.8 * free  # neither level nor hanging straight down
        assert _tip_sag(preset, length, (cells, cells // 10)) == pytest.approx(expected, rel=0.004 * (10 / cells) ** 2)


@pytest.mark.parametrize("triangles", [False, True], ids=["rows", "fits"])
@pytest.mark.parametrize("integrator", ["symplectic", "implicit"])
def test_the_simulated_strip_comes_to_rest_where_its_static_equations_put_it(tmp_path, integrator, triangles):
    """The bending stencils' kernels (the explicit step's forces; the implicit system's forces, products and
    diagonal blocks) agree with the energy the static solve above minimises: a clamped strip of denim, a
    grid (bent by its rows' stencils) or the same grid's mesh of triangles (by its fits), run to rest under
    air drag, hangs where the static equations put it (within 1e-4, its tip still jittering at about 1 cm/s
    with the explicit step's undamped springs)."""
    nx, ny, length = 20, 2, 0.05
    mesh = write_grid_obj(tmp_path / "strip.obj", nx, ny, length, 0.01, triangles=True) if triangles else None
    shape = ({"mesh": str(mesh), "rotation": [-90.0, 0.0, 0.0]} if triangles
             else {"resolution": [nx, ny], "size": [length, 0.01], "orientation": "horizontal"})
    held = [x + (nx + 1) * y for y in range(ny + 1) for x in range(nx // 5 + 1)]
    simulation = {"fps": 24, "frames": 72, "integrator": integrator, "drag": 10.0}
    material = {"preset": "denim"}
    if integrator == "implicit":
        simulation["substeps"], material["damping"] = 8, 0.002
    scene = wc.scene_from_dict({"name": "strip", "simulation": simulation, "cloth": [
        {**shape, "origin": [0.0, 0.5, 0.0], "material": material, "pins": [{"indices": held}]}]})
    sim = wc.Simulator(scene, device="cpu")
    start = sim.positions()[:, 1].copy()
    sim.run(72)
    tip = np.arange(sim.model.particle_count) % (nx + 1) == nx
    assert float((start - sim.positions()[:, 1])[tip].mean()) == pytest.approx(
        _tip_sag("denim", length, (nx, ny), mesh), rel=1e-4)


def test_a_preset_scene_loads_and_runs(tmp_path):
    scene_file = tmp_path / "denim.toml"
    scene_file.write_text('[simulation]\nframes = 2\n[[cloth]]\nresolution = [6, 6]\nsize = [0.5, 0.5]\n'
                          'orientation = "horizontal"\norigin = [0.0, 0.5, 0.0]\nmaterial = "denim"\n[ground]\n')
    scene = wc.load_scene(scene_file)
    assert scene.cloths[0].material.stretch == pytest.approx(PRESETS["denim"].stretch)
    sim = wc.Simulator(scene, device="cpu")
    sim.run(2)
    assert np.isfinite(sim.positions()).all()
    assert sim.model.masses.sum() == pytest.approx(PRESETS["denim"].density * 0.25, rel=1e-6)


def test_a_table_overrides_its_presets_keys():
    material = _scene(material={"preset": "denim", "bending": 2e-5, "stretch_limit": [0.05, 0.1]}).cloths[0].material
    assert material.bending == 2e-5 and material.shear == PRESETS["denim"].shear
    assert material.stretch_limit == (0.05, 0.1)


def test_per_direction_strain_limits_hold_each_spring_by_its_direction():
    model = build_model(_scene(resolution=(4, 4), size=[1.0, 1.0],
                               material={"preset": "denim", "stretch_limit": [0.05, 0.2], "compression_limit": 0.02}))
    springs, positions = model.springs, model.positions
    along_u = np.abs(positions[springs.pairs[:, 0], 1] - positions[springs.pairs[:, 1], 1]) < 1e-9
    structural = springs.kind == 0
    assert np.allclose(springs.limit_max[structural & along_u] / springs.rest[structural & along_u], 1.05)
    assert np.allclose(springs.limit_max[structural & ~along_u] / springs.rest[structural & ~along_u], 1.2)
    assert np.allclose(springs.limit_min[structural] / springs.rest[structural], 0.98)
    diagonal = springs.kind == 1
    assert np.allclose(springs.limit_max[diagonal] / springs.rest[diagonal], 1.125)
    assert model.limits is not None


BAD_MATERIALS = [
    ('material = "velvet"', "cloth[0].material: expected a preset (one of cotton, denim, polyester, jersey), "
                            "got 'velvet'"),
    ('material = { preset = "denim", stretch = -1.0 }', "cloth[0].material.stretch: expected a number in "
                                                        "[0.001, 1e+08] N/m, or [warp, weft] such numbers, got -1.0"),
    ('material = { preset = "denim", stiffness = 3.0 }', "cloth[0].material.stiffness: expected a known key"),
    ('material = { density = 0.2, stretch = 1000.0, shear = 20.0 }', "cloth[0].material.bending: expected a number "
                                                                     "in N m (a material without a preset gives"),
    ('material = { preset = "denim", stretch = [1.0, 2.0, 3.0] }', "cloth[0].material.stretch: expected a number "
                                                                   "or a list of 2 numbers"),
    ('material = { preset = "denim", compression_limit = 1.5 }', "cloth[0].material.compression_limit: expected a "
                                                                 "fraction in (0, 1)"),
    ('material = "denim"\nstructural = { stiffness = 10.0 }', "cloth[0].structural: expected no structural springs "
                                                              "on a cloth with a material"),
    ('material = "denim"\ndensity = 0.2', "cloth[0].density: expected no density on a cloth with a material"),
    ('material = { preset = "denim", stretch_limit = 0.1 }\nlimit = { stretch = 0.1 }',
     "cloth[0].limit: expected no limit on a cloth whose material sets strain limits"),
]


@pytest.mark.parametrize("line, message", BAD_MATERIALS, ids=[m.split(":")[0] + str(k) for k, (_, m)
                                                              in enumerate(BAD_MATERIALS)])
def test_a_bad_material_is_refused_with_one_line_naming_file_key_and_expectation(tmp_path, line, message):
    scene_file = tmp_path / "bad.toml"
    scene_file.write_text(f"[[cloth]]\nresolution = [4, 4]\nsize = [1.0, 1.0]\n{line}\n")
    code, out, err = run_cli_in_process("run", str(scene_file), "--device", "cpu", cwd=tmp_path)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"warp-cloth: error: {scene_file}: {message}"), err


def test_the_command_refuses_a_material_beside_raw_springs_with_exit_code_2(tmp_path):
    scene_file = tmp_path / "both.toml"
    scene_file.write_text('[[cloth]]\nmaterial = "denim"\nbend = { stiffness = 2.0 }\n')
    result = run_cli("run", str(scene_file), "--device", "cpu", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr == (f"warp-cloth: error: {scene_file}: cloth[0].bend: expected no bend springs on a cloth "
                             "with a material (its springs come from the material; leave the material out to set "
                             "springs)\n")


def test_materials_lists_every_preset_and_writes_them_as_json(tmp_path):
    code, out, err = run_cli_in_process("materials", "--json", "presets.json", cwd=tmp_path)
    assert code == 0 and err == ""
    rows = {line.split()[0] for line in out.splitlines()[1:] if line and not line.startswith(" ")}
    assert set(PRESETS) <= rows
    for name, data in PRESETS.items():
        assert f"  {name}: {data.source}" in out
    document = json.loads((tmp_path / "presets.json").read_text())
    assert [p["name"] for p in document["presets"]] == list(PRESETS)
    for preset in document["presets"]:
        data = PRESETS[preset["name"]]
        assert (preset["density"], preset["stretch"], preset["shear"], preset["bending"], preset["source"]) == \
            (data.density, list(data.stretch), data.shear, list(data.bending), data.source)


def test_friction_of_a_material_slows_a_cloth_sliding_on_a_frictionless_ground():
    def slid(friction):
        material = {"preset": "denim"} if friction is None else {"preset": "denim", "friction": friction}
        scene = wc.scene_from_dict({"name": "slide", "simulation": {"frames": 6, "gravity": [0.0, -9.81, 0.0]},
                                    "ground": {}, "cloth": [{"resolution": [4, 4], "size": [0.2, 0.2],
                                                             "orientation": "horizontal", "origin": [0.0, 0.001, 0.0],
                                                             "velocity": [1.0, 0.0, 0.0], "material": material}]})
        sim = wc.Simulator(scene, device="cpu")
        sim.run(6)
        return sim.velocities()[:, 0].mean()

    assert slid(None) == pytest.approx(1.0, abs=0.02)  # the ground has no friction of its own
    assert slid(0.5) < 0.5 * slid(None)


def test_a_knits_step_bound_leaves_out_the_sides_that_carry_nothing():
    """Jersey's shear nears its stretch, so the long sides of cells twice as long as wide carry nothing (the
    diagonals do): the stable step's damping times come from the springs that pull, with no 0 / 0 among
    them."""
    from warp_cloth.stability import model_bound

    scene = wc.Scene(cloths=(wc.Cloth(resolution=(8, 16), size=(0.5, 0.5),
                                  material=wc.Material.from_string("jersey")),))
    sim = wc.Simulator(scene, device="cpu")
    assert np.any(sim.model.springs.stiffness == 0.0)
    with np.errstate(invalid="raise", divide="raise"):
        bound = model_bound(sim.model, sim.scene.simulation)
    assert np.isfinite(bound.step) and bound.step > 0
    assert np.isfinite(bound.damping_time_min)
