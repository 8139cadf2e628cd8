"""Cloths from the user's meshes (OBJ and USD): the springs, masses and contact radii a mesh gives, checked
against the grid they generalise and against analytic values; mesh cloths simulated as grids are; bad
meshes refused with one line."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli_in_process, spring_strains
from warp_cloth.cloth_grid import build_grid
from warp_cloth.cloth_mesh import BEND, SHEAR, STRUCTURAL, rest_adjacent_pairs
from warp_cloth.mesh_cloth import build_mesh_cloth
from warp_cloth.model import collision_radii


def write_obj(path: Path, points: np.ndarray, faces: list[list[int]], uvs: np.ndarray | None = None) -> Path:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(points, dtype=float).tolist()]
    if uvs is not None:
        lines += [f"vt {u!r} {v!r}" for u, v in np.asarray(uvs, dtype=float).tolist()]
        lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in face) for face in faces]
    else:
        lines += ["f " + " ".join(str(i + 1) for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def grid_as_obj(tmp_path: Path, cloth: wc.Cloth, triangles: bool = False) -> Path:
    """The grid cloth's particles and quads (or each quad as two triangles) as an OBJ, with its UVs."""
    grid = build_grid(cloth)
    quads = grid.face_indices.reshape(-1, 4).tolist()
    faces = [t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])] if triangles else quads
    return write_obj(tmp_path / ("tris.obj" if triangles else "quads.obj"), grid.positions, faces, grid.uvs)


def spring_set(pairs, kinds, rests):
    return {(int(a), int(b), int(k), round(float(r), 9)) for (a, b), k, r in zip(np.sort(pairs, axis=1), kinds, rests)}


GRID = wc.Cloth(resolution=(5, 3), size=(2.0, 1.5), orientation="vertical", density=0.3, limit=wc.Limit(0.1, 0.1))


def test_a_grid_read_as_a_mesh_has_the_grids_springs_masses_and_contact_radii(tmp_path):
    grid = build_grid(GRID)
    cloth = wc.Cloth.from_mesh(grid_as_obj(tmp_path, GRID), density=0.3, limit=wc.Limit(0.1, 0.1))
    mesh = build_mesh_cloth(cloth)
    assert spring_set(mesh.springs, mesh.spring_kind, mesh.rest_lengths) == \
        spring_set(grid.springs, grid.spring_kind, grid.rest_lengths)
    np.testing.assert_allclose(mesh.masses, grid.masses, rtol=1e-12)
    np.testing.assert_allclose(collision_radii(cloth, mesh, None), collision_radii(GRID, grid, None), rtol=1e-12)
    np.testing.assert_allclose(mesh.uvs, grid.uvs[grid.face_indices])  # per face corner, as OBJ gives them
    # Particles that share a face are the grid's neighbours along rows, columns and diagonals.
    gx, gy = np.arange(24) % 6, np.arange(24) // 6
    adjacent = {(i, j) for i in range(24) for j in range(i + 1, 24) if abs(gx[i] - gx[j]) <= 1 and abs(gy[i] - gy[j]) <= 1}
    assert {tuple(p) for p in rest_adjacent_pairs(mesh.face_counts, mesh.face_indices).tolist()} == adjacent


def test_triangle_mesh_springs_are_its_edges_and_one_bend_across_each_interior_edge(tmp_path):
    cloth = wc.Cloth.from_mesh(grid_as_obj(tmp_path, GRID, triangles=True))
    mesh = build_mesh_cloth(cloth)
    nx, ny = GRID.resolution
    edges = nx * (ny + 1) + (nx + 1) * ny + nx * ny  # rows, columns, one diagonal a quad
    interior = edges - 2 * (nx + ny)
    assert (mesh.spring_kind == STRUCTURAL).sum() == edges
    assert (mesh.spring_kind == SHEAR).sum() == 0
    assert (mesh.spring_kind == BEND).sum() == interior  # each joins the two vertices opposite its edge
    bends = mesh.springs[mesh.spring_kind == BEND]
    # Across the first quad's diagonal 0-7 (triangles 0 1 7 and 0 7 6): the bend joins 1 and 6.
    assert [1, 6] in np.sort(bends, axis=1).tolist()


def test_density_gives_each_particle_a_share_of_its_faces_area_on_a_curved_mesh(tmp_path):
    # A half cylinder of radius 1, 8 x 4 quads: its total mass is density x the facets' area.
    angles, heights = np.linspace(0.0, np.pi, 9), np.linspace(0.0, 2.0, 5)
    points = np.array([[np.cos(a), h, np.sin(a)] for h in heights for a in angles])
    faces = [[j * 9 + i, j * 9 + i + 1, (j + 1) * 9 + i + 1, (j + 1) * 9 + i] for j in range(4) for i in range(8)]
    cloth = wc.Cloth.from_mesh(write_obj(tmp_path / "half.obj", points, faces), density=0.5)
    mesh = build_mesh_cloth(cloth)
    facet = 2.0 * np.sin(np.pi / 16)  # a chord
    assert mesh.masses.sum() == pytest.approx(0.5 * 8 * facet * 2.0, rel=1e-12)
    assert mesh.masses[0] == pytest.approx(0.5 * facet * 0.5 / 4, rel=1e-12)  # a corner: a quarter of one face
    lightest, heaviest = cloth.mass_range()
    assert (lightest, heaviest) == (pytest.approx(mesh.masses.min()), pytest.approx(mesh.masses.max()))


def hanging_pair(tmp_path, triangles: bool, limit_solve: str = "fixed"):
    grid = dataclasses.replace(GRID, pins=(wc.Pin(corners=("top-left", "top-right")),))
    corners = (GRID.resolution[1] * (GRID.resolution[0] + 1), GRID.particle_count - 1)
    mesh = wc.Cloth.from_mesh(grid_as_obj(tmp_path, GRID, triangles), name="mesh", density=0.3,
                              limit=wc.Limit(0.1, 0.1), pins=(wc.Pin(indices=corners),))
    simulation = wc.Simulation(fps=24, frames=24, substeps=20, integrator="symplectic", limit_solve=limit_solve)
    return (wc.Scene(name="grid", cloths=(grid,), simulation=simulation),
            wc.Scene(name="mesh", cloths=(mesh,), simulation=simulation))


def test_a_grid_read_as_a_quad_mesh_moves_as_the_grid_does(tmp_path):
    grid_scene, mesh_scene = hanging_pair(tmp_path, triangles=False)
    a, b = wc.Simulator(grid_scene, device="cpu"), wc.Simulator(mesh_scene, device="cpu")
    for _ in range(24):
        a.step()
        b.step()
    # The same springs in another order: float32 sums differ in their last bits, nothing more.
    assert np.abs(a.positions() - b.positions()).max() < 1e-4
    assert np.ptp(a.positions()[:, 1]) > 0.5  # the cloth has swung down, so the comparison means something


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_a_triangle_mesh_cloth_holds_its_strain_limit(tmp_path, device):
    _, scene = hanging_pair(tmp_path, triangles=True, limit_solve="converged")
    sim = wc.Simulator(scene, device=device)
    limited = np.isfinite(sim.model.springs.limit_max)
    worst = 0.0
    for _ in range(24):
        sim.step()
        worst = max(worst, float(np.abs(spring_strains(sim, sim.positions())[limited]).max()))
    assert worst <= 0.1 * 1.05 + 0.005  # within the solve's tolerance (0.5% of the allowed length)
    assert sim.solver_stats().limit_residual == 0.0  # every solve ended within it


def test_mesh_cloth_collides_with_itself_and_writes_its_faces(tmp_path):
    path = grid_as_obj(tmp_path, GRID, triangles=True)
    scene_file = tmp_path / "drop.toml"
    scene_file.write_text(f"""
[simulation]
frames = 6
substeps = 10
integrator = "symplectic"
[collision]
self = true
[ground]
[[cloth]]
name = "sheet"
mesh = "{path.name}"
origin = [0.0, 0.5, 0.0]
rotation = [-90.0, 0.0, 0.0]
density = 0.3
limit = {{ stretch = 0.1, compression = 0.1 }}
""")
    code, _, err = run_cli_in_process("run", str(scene_file), "--out", "out", "--check", cwd=tmp_path)
    assert code == 0, err
    stage = Usd.Stage.Open(str(tmp_path / "out" / "drop.usdc"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/sheet"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * 30
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying and len(st.Get()) == 90
    points = np.asarray(mesh.GetPointsAttr().Get(6))
    assert points[:, 1].min() >= -1e-6  # on the ground, not through it
    poly = (tmp_path / "out" / "drop" / "poly" / "sheet.0006.poly").read_text()
    assert "\n30: " in poly and "\n31: " not in poly and poly.split("POLYS\n")[1].startswith("1: 1 2 8 <")


def usd_shot(path: Path, meters_per_unit: float = 1.0, up: str = "Y") -> Path:
    """A stage with a 2 x 1 quad strip under a translated Xform, with vertex UVs."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    UsdGeom.Xform.Define(stage, "/World").AddTranslateOp().Set(Gf.Vec3d(0.0, 3.0, 0.0))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Shirt")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    st.Set([(0, 0), (0.5, 0), (1, 0), (0, 1), (0.5, 1), (1, 1)])
    UsdGeom.Sphere.Define(stage, "/World/Ball")
    stage.Save()
    return path


def test_usd_mesh_prim_in_world_metres_with_its_uvs(tmp_path):
    cloth = wc.Cloth.from_mesh(usd_shot(tmp_path / "shot.usda"), prim="/World/Shirt")
    surface = cloth.surface()
    np.testing.assert_allclose(surface.points[4], [1.0, 4.0, 0.0])  # the parent's translate applied
    np.testing.assert_allclose(surface.uvs[:4], [[0, 0], [0.5, 0], [0.5, 1], [0, 1]])  # per face corner
    assert surface.prim == "/World/Shirt" and surface.notes == ()
    assert wc.Cloth.from_mesh(tmp_path / "shot.usda").surface().prim == "/World/Shirt"  # the only Mesh

    centimetres = wc.Cloth.from_mesh(usd_shot(tmp_path / "cm.usda", 0.01, up="Z")).surface()
    # (x, y, z) cm, Z up -> (x, z, -y) m: the translate (0, 3, 0) lands at z = -0.03
    np.testing.assert_allclose(centimetres.points[4], [0.01, 0.0, -0.04])
    assert [n.split(": ", 1)[1] for n in centimetres.notes] == [
        "units of 0.01 m converted to metres", "Z-up stage turned Y-up (the simulation's gravity is -Y)"]


BAD_MESHES = [
    ("missing.obj", None, "mesh", "an existing, readable mesh file"),
    ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "mesh", "a surface mesh with faces"),
    ("lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n", "mesh", "lines and points are not a surface"),
    ("pentagon.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 2 0\nv 0 1 0\nf 1 2 3 4 5\n", "mesh",
     "faces of 3 or 4 vertices"),
    ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n", "mesh", "faces of non-zero area"),
    ("twice.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 1\n", "mesh", "each face once"),
    ("fin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n", "mesh",
     "a manifold surface"),
    ("stray.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n", "mesh", "every point on some face"),
    ("index.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n", "mesh", "refers to none of the 2"),
    ("mesh.ply", "", "mesh", "a mesh file ending in one of .obj"),
]


@pytest.mark.parametrize("name, text, key, expected", BAD_MESHES, ids=[b[0] for b in BAD_MESHES])
def test_bad_mesh_is_one_line_naming_file_and_key_and_nothing_is_written(tmp_path, name, text, key, expected):
    if text is not None:
        (tmp_path / name).write_text(text)
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[[cloth]]\nmesh = "{name}"\n')
    code, _, err = run_cli_in_process("run", str(scene), "--out", "out", cwd=tmp_path)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert "scene.toml" in lines[0] and f"cloth[0].{key}" in lines[0] and expected in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


def test_mesh_cloth_refuses_grid_settings_and_usd_prims_that_are_not_meshes(tmp_path):
    path = grid_as_obj(tmp_path, GRID)
    with pytest.raises(wc.SceneError, match=r"resolution: expected no grid setting on a mesh cloth"):
        wc.Cloth.from_mesh(path, resolution=(4, 4))
    with pytest.raises(wc.SceneError, match=r"pins\[0\].corners: expected \[\"boundary\"\] on a mesh cloth"):
        wc.Cloth.from_mesh(path, pins=(wc.Pin(corners=("top-left",)),))
    # A mesh file is read where the scene's geometry is checked: by the simulator, for a scene built in Python.
    shot = usd_shot(tmp_path / "shot.usda")
    with pytest.raises(wc.SceneError,
                       match=r"cloth\[0\].mesh.prim: expected a Mesh prim \(in .*shot.usda at /World/Ball\)"):
        wc.Simulator(wc.Scene(cloths=(wc.Cloth.from_mesh(shot, prim="/World/Ball"),)), device="cpu")
    with pytest.raises(wc.SceneError, match=r"cloth\[0\].mesh.prim: expected the absolute path of a prim in the stage"):
        wc.Simulator(wc.Scene(cloths=(wc.Cloth.from_mesh(shot, prim="/World/Nothing"),)), device="cpu")
    with pytest.raises(wc.SceneError, match=r"cloth\[0\].mesh.prim: expected no prim for an OBJ file"):
        wc.Simulator(wc.Scene(cloths=(wc.Cloth.from_mesh(path, prim="/World/Shirt"),)), device="cpu")


def test_a_scene_reads_no_mesh_when_made_and_is_checked_where_its_geometry_is_built(tmp_path):
    """The dataclasses check values only: a mesh is read, and the particles a pin selects found, when a scene
    file is loaded or a simulator (or batch) made, with the same one-line errors."""
    boxed = wc.Pin(region=wc.Box((5.0, 5.0, 5.0), (6.0, 6.0, 6.0)))
    scene = wc.Scene(cloths=(wc.Cloth.from_mesh(tmp_path / "quads.obj", pins=(boxed,)),))  # no such file yet
    with pytest.raises(wc.SceneError, match=r"^cloth\[0\]\.mesh: expected an existing, readable mesh file"):
        wc.Simulator(scene, device="cpu")
    grid_as_obj(tmp_path, GRID)
    with pytest.raises(wc.SceneError, match=r"^cloth\[0\]\.pins\[0\]\.region: expected a box containing"):
        wc.Simulator(scene, device="cpu")
    with pytest.raises(wc.SceneError, match=r"^scenes\[1\]\.cloth\[0\]\.pins\[0\]\.region: expected a box"):
        wc.Batch([wc.Scene(cloths=(GRID,)), scene], device="cpu")


def test_a_checkpoint_knows_the_mesh_it_was_made_with_not_only_its_path(tmp_path):
    from warp_cloth.checkpoint import scene_fingerprint

    path = grid_as_obj(tmp_path, GRID)
    scene = wc.Scene(cloths=(wc.Cloth.from_mesh(path),))
    before = scene_fingerprint(scene)
    text = path.read_text()
    path.write_text(text.replace("v 0.0 0.0 0.0", "v 0.0 0.0 0.001", 1))
    assert "v 0.0 0.0 0.001" in path.read_text()
    assert scene_fingerprint(wc.Scene(cloths=(wc.Cloth.from_mesh(path),))) != before


def test_pins_by_a_usd_group_a_subset_or_a_primvar(tmp_path):
    path = usd_shot(tmp_path / "shot.usda")
    stage = Usd.Stage.Open(str(path))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Shirt"))
    UsdGeom.Subset.CreateGeomSubset(mesh, "collar", UsdGeom.Tokens.point, [3, 4, 5])
    UsdGeom.Subset.CreateGeomSubset(mesh, "sleeve", UsdGeom.Tokens.face, [1])
    weights = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("pin_weight", Sdf.ValueTypeNames.FloatArray,
                                                      UsdGeom.Tokens.vertex)
    weights.Set([1.0, 0.0, 0.0, 0.0, 0.0, 0.5])
    stage.Save()
    for group, expected in (("collar", [3, 4, 5]), ("sleeve", [1, 2, 4, 5]), ("pin_weight", [0, 5])):
        cloth = wc.Cloth.from_mesh(path, prim="/World/Shirt", pins=(wc.Pin(group=group),))
        sim = wc.Simulator(wc.Scene(cloths=(cloth,)), device="cpu")
        assert sorted(sim.model.pins.index.tolist()) == expected, group
    with pytest.raises(wc.SceneError, match=r"pins\[0\].group: expected the name of a group of the cloth's mesh "
                                            r"\(a USD GeomSubset or point primvar, an OBJ g group: collar, pin_weight, "
                                            r"sleeve\)"):
        wc.Simulator(wc.Scene(cloths=(wc.Cloth.from_mesh(path, pins=(wc.Pin(group="hem"),)),)), device="cpu")


@pytest.mark.parametrize("fast", [True, False])
def test_pins_by_an_obj_group(tmp_path, fast):
    """``g`` statements name the faces after them; a group's vertices are those faces' (the bulk reader and
    the line by line one, which a comment line sends the file to, alike)."""
    points = [(x, y, 0.0) for y in range(3) for x in range(3)]
    faces = ["f 1 2 5 4", "f 2 3 6 5", "f 4 5 8 7", "f 5 6 9 8"]
    lines = [f"v {x} {y} {z}" for x, y, z in points] + ([] if fast else ["# groups"])
    lines += ["g body", faces[0], faces[1], "g collar hem", faces[2], "g collar", faces[3]]
    path = tmp_path / "groups.obj"
    path.write_text("\n".join(lines) + "\n")
    groups = wc.Cloth.from_mesh(path).surface().groups
    assert {name: v.tolist() for name, v in groups.items()} == \
        {"body": [0, 1, 2, 3, 4, 5], "collar": [3, 4, 5, 6, 7, 8], "hem": [3, 4, 6, 7]}
    cloth = wc.Cloth.from_mesh(path, pins=(wc.Pin(group="hem"),))
    assert sorted(wc.Simulator(wc.Scene(cloths=(cloth,)), device="cpu").model.pins.index.tolist()) == [3, 4, 6, 7]
