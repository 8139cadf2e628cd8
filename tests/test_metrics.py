"""Per-frame metrics (``--metrics FILE.csv``, ``wc.MetricsWriter``): the worst strain by edge kind matches
what the USD's points give, the energies match free fall's closed form, the solver columns add up to the
run's solver stats, measuring changes nothing in the run, and the plot is made beside the CSV."""

import csv

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_cloth as wc
from conftest import lock_held_by_another_process, run_cli_in_process
from warp_cloth.metrics import COLUMNS, read_metrics
from warp_cloth.output import OutputLock


def grid_edges(nx: int, ny: int, dx: float, dy: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The structural and shear edges of an nx x ny grid of quads and their rest lengths, written out here
    from the grid's definition rather than read from the model."""
    index = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    rows = np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], axis=1)
    columns = np.stack([index[:-1].ravel(), index[1:].ravel()], axis=1)
    diagonals = np.concatenate([np.stack([index[:-1, :-1].ravel(), index[1:, 1:].ravel()], axis=1),
                                np.stack([index[:-1, 1:].ravel(), index[1:, :-1].ravel()], axis=1)])
    return {"structural": (np.concatenate([rows, columns]),
                           np.concatenate([np.full(len(rows), dx), np.full(len(columns), dy)])),
            "shear": (diagonals, np.full(len(diagonals), np.hypot(dx, dy)))}


def test_the_worst_strain_by_kind_is_what_the_usd_points_give(tmp_path):
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "48", "--out", "out", "--no-poly", "--quiet",
                                        "--metrics", "out/m.csv", cwd=tmp_path)
    assert code == 0, err
    assert "out/m.csv, out/m.png" in out
    stage = Usd.Stage.Open(str(tmp_path / "out" / "hanging.usdc"))
    points = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth")).GetPointsAttr()
    metrics = read_metrics(tmp_path / "out" / "m.csv")
    assert list(metrics["frame"]) == list(range(49)) and list(points.GetTimeSamples()) == list(range(49))
    for kind, (pairs, rest) in grid_edges(10, 10, 1.0, 1.0).items():
        strain = np.array([np.linalg.norm(np.subtract(*np.asarray(points.Get(f), dtype=np.float64)[pairs.T]), axis=1)
                           / rest - 1.0 for f in range(49)])
        np.testing.assert_allclose(metrics[f"{kind}_stretch"], np.maximum(strain.max(axis=1), 0.0), atol=2e-6)
        np.testing.assert_allclose(metrics[f"{kind}_compression"], np.maximum(-strain.min(axis=1), 0.0), atol=2e-6)
    worst = max(metrics["structural_stretch"].max(), metrics["shear_stretch"].max())
    assert f"worst edge strain +{100 * worst:.1f}%" in out  # the summary line's figure, over every frame
    with open(tmp_path / "out" / "m.csv", newline="") as handle:
        assert tuple(next(csv.reader(handle))) == COLUMNS
    assert (tmp_path / "out" / "m.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_energies_of_a_free_fall_are_its_closed_form(tmp_path):
    # A cloth falling freely with explicit Euler: after n substeps of h, v = g n h and y = y0 - g h^2 n (n - 1) / 2
    # for every particle; no spring stretches, so the springs hold no energy.
    scene = wc.Scene(cloths=(wc.Cloth(resolution=(4, 4), size=(1.0, 1.0), mass=0.01, origin=(0.0, 5.0, 0.0),
                                      jitter=0.0),),
                     simulation=wc.Simulation(fps=24, frames=6, substeps=40, integrator="explicit"))
    sim = wc.Simulator(scene, device="cpu")
    y0 = sim.model.positions[:, 1].astype(np.float64)
    sim.run(6, writers=[wc.MetricsWriter(tmp_path / "m.csv", plot=False)])
    data = read_metrics(tmp_path / "m.csv")
    mass, g, h = 25 * 0.01, 9.81, 1.0 / 960
    for frame in range(7):
        n = 40 * frame
        np.testing.assert_allclose(data["kinetic_energy"][frame], 0.5 * mass * (g * n * h) ** 2, rtol=1e-5,
                                   atol=1e-9)
        height = y0 - g * h * h * n * (n - 1) / 2
        np.testing.assert_allclose(data["potential_energy"][frame], g * 0.01 * height.sum(), rtol=1e-5)
        assert data["spring_energy"][frame] < 1e-12  # float32 rest lengths' rounding
    assert np.isnan(data["limit_passes_mean"]).all() and np.isnan(data["closest_contact"]).all()
    assert not (tmp_path / "m.png").exists()


def test_solver_columns_add_up_to_the_run_and_measuring_changes_nothing(tmp_path):
    scene = wc.load_scene("fold")  # a converged limit solve and particle collision
    plain = wc.Simulator(scene, device="cpu")
    plain.run(12, writers=[wc.UsdWriter(tmp_path / "plain.usdc")])
    measured = wc.Simulator(scene, device="cpu")
    measured.run(12, writers=[wc.UsdWriter(tmp_path / "measured.usdc"), wc.MetricsWriter(tmp_path / "m.csv")])
    stages = [Usd.Stage.Open(str(tmp_path / f)) for f in ("plain.usdc", "measured.usdc")]
    cloths = [p for p in stages[0].Traverse() if p.GetCustomDataByKey("warpCloth:role") == "cloth"]
    assert cloths
    for prim in cloths:
        attrs = [UsdGeom.Mesh(s.GetPrimAtPath(prim.GetPath())).GetPointsAttr() for s in stages]
        assert len(attrs[0].GetTimeSamples()) == 13
        for t in attrs[0].GetTimeSamples():
            np.testing.assert_array_equal(np.asarray(attrs[0].Get(t)), np.asarray(attrs[1].Get(t)))
    data = read_metrics(tmp_path / "m.csv")
    total = measured.solver_stats(since_start=True)
    assert np.nanmax(data["limit_passes_most"]) == total.limit_passes
    np.testing.assert_allclose(np.nanmean(data["limit_passes_mean"]), total.limit_mean_passes, rtol=1e-6)
    contacts = data["closest_contact"]
    assert np.isfinite(contacts).all() and (contacts > 0.5).all()
    assert (tmp_path / "m.png").stat().st_size > 1000


def test_crossing_pairs_are_counted_where_the_run_checks(tmp_path):
    code, out, err = run_cli_in_process("run", "fold", "--frames", "3", "--out", "o", "--no-poly", "--no-usd",
                                        "--check", "--metrics", "m.csv", cwd=tmp_path)
    assert code == 0, err
    data = read_metrics(tmp_path / "m.csv")
    assert list(data["crossing_pairs"]) == [0, 0, 0, 0]
    code, out, err = run_cli_in_process("run", "fold", "--frames", "3", "--out", "o", "--no-poly", "--no-usd",
                                        "--metrics", "n.csv", cwd=tmp_path)
    assert code == 0 and np.isnan(read_metrics(tmp_path / "n.csv")["crossing_pairs"]).all()


@pytest.mark.parametrize("path, expected", [("m.txt", "a file name ending in .csv"),
                                            ("folder", "a file name ending in .csv")])
def test_a_bad_metrics_path_is_one_line_and_nothing_is_written(tmp_path, path, expected):
    (tmp_path / "folder").mkdir()
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", "o", "--metrics", path,
                                        cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--metrics" in err and expected in err, err
    assert not (tmp_path / "o").exists() and not (tmp_path / "m.txt").exists()


# Two runs never share a metrics file, and its plot never replaces a picture of the user's


def test_a_run_writing_metrics_another_run_writes_is_refused_at_once(tmp_path):
    with lock_held_by_another_process(OutputLock(tmp_path / "m.csv").path) as holder:
        code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", "o", "--quiet",
                                          "--metrics", "m.csv", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "--metrics" in err and f"process id {holder}" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.lock"]


def test_a_metrics_only_run_is_locked_and_checkpointed_like_other_outputs(tmp_path):
    """Without USD or .poly, the CSV is the run's output: its lock and checkpoint are named after it."""
    with lock_held_by_another_process(OutputLock(tmp_path / "m.csv").path):
        code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--no-usd", "--no-poly", "--quiet",
                                          "--metrics", "m.csv", cwd=tmp_path)
    assert code == 2 and "--metrics" in err, err
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--no-usd", "--no-poly", "--quiet",
                                      "--metrics", "m.csv", cwd=tmp_path)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv", "m.png"]


def test_the_metrics_plot_never_replaces_a_picture_of_the_users(tmp_path):
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "photo.png")
    photo = (tmp_path / "photo.png").read_bytes()
    code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", "o", "--quiet",
                                      "--metrics", "photo.csv", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "--metrics" in err and "photo.png" in err
    assert (tmp_path / "photo.png").read_bytes() == photo
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photo.png"]
    for _ in range(2):  # a plot of its own it replaces
        code, _, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", "o", "--quiet",
                                          "--metrics", "m.csv", cwd=tmp_path)
        assert code == 0, err
    assert len(read_metrics(tmp_path / "m.csv")["frame"]) == 3
