"""``warp-cloth sweep``: the product of --set values run as the worlds of batches, a table whose figures are
those of each variant run alone, each variant once across interrupted and resumed sweeps, bad input
refused in one line."""

import dataclasses
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd

import warp_cloth as wc
from conftest import run_cli_in_process
from warp_cloth.sweep import file_stem

SCENE = """
name = "sheet"
[simulation]
fps = 24
frames = 6
substeps = 30
integrator = "symplectic"
limit_solve = "fixed"

[ground]
height = 0.0

[[cloth]]
resolution = [8, 8]
size = [1.0, 1.0]
orientation = "horizontal"
origin = [-0.5, 0.3, 0.5]
rotation = [25.0, 0.0, 0.0]
density = 0.2
limit = { stretch = 0.1, compression = 0.1 }
structural = { stiffness = 15.0, damping = 0.02 }
shear = { stiffness = 15.0, damping = 0.02 }
bend = { stiffness = 5.0, damping = 0.01, acts = "compression", damping_acts = "compression" }
"""


def rows_of(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "results.jsonl").read_text().splitlines()]


def test_a_sweep_runs_the_product_and_its_table_holds_each_variant_as_run_alone(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.bend.stiffness=1,10",
                                        "--set", "simulation.gravity=[0.0, -9.81, 0.0],[0.0, -3.0, 0.0]",
                                        "--out", "swept", cwd=tmp_path)
    assert code == 0, err
    assert "sweep sheet: 4 variants (0 done before) in 1 batches" in out.splitlines()[-1]
    rows = rows_of(tmp_path / "swept")
    assert sorted(r["variant"] for r in rows) == sorted(
        f"cloth.bend.stiffness={k} simulation.gravity={g}" for k in (1, 10)
        for g in ("[0.0, -9.81, 0.0]", "[0.0, -3.0, 0.0]"))
    table = (tmp_path / "swept" / "results.csv").read_text().splitlines()
    assert table[0].startswith("cloth.bend.stiffness,simulation.gravity,variant,stretch,compression")
    assert len(table) == 5
    base = wc.load_scene(tmp_path / "sheet.toml")
    for row in rows:
        stiffness, gravity = row["settings"]["cloth.bend.stiffness"], row["settings"]["simulation.gravity"]
        cloth = base.cloths[0]
        scene = wc.Scene(name="alone", cloths=(wc.Cloth(**{**cloth.__dict__, "bend": wc.SpringKind(
            float(stiffness), 0.01, "compression", "compression")}),), ground=base.ground,
            simulation=wc.Simulation(**{**base.simulation.__dict__, "gravity": tuple(gravity)}))
        sim = wc.Simulator(scene, device="cpu")
        monitor = wc.StrainMonitor()
        sim.run(6, writers=[monitor])
        report = monitor.report()
        assert row["stretch"] == pytest.approx(report.stretch, abs=1e-6)
        assert row["compression"] == pytest.approx(report.compression, abs=1e-6)
        v, m = sim.velocities().astype(np.float64), sim.model.masses.astype(np.float64)
        assert row["kinetic_energy"] == pytest.approx(0.5 * np.sum(m * np.sum(v * v, axis=1)), rel=1e-5)
        assert row["unstable_frame"] is None and row["batch_worlds"] == 4
        assert Path(tmp_path / row["usd"]).name == f"{file_stem(tuple(row['settings'].items()))}.usdc"
        assert (tmp_path / row["usd"]).is_file()


def test_implicit_variants_share_batches_and_each_runs_its_own_frames(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "simulation.integrator=symplectic,implicit",
                                        "--set", "cloth.density=0.1,0.2", "--set", "simulation.frames=3,5",
                                        "--out", "swept", cwd=tmp_path)
    assert code == 0, err
    assert "8 variants (0 done before) in 4 batches" in out.splitlines()[-1]
    base = wc.load_scene(tmp_path / "sheet.toml")
    for row in rows_of(tmp_path / "swept"):
        settings = row["settings"]
        assert row["batch_worlds"] == 2 and row["unstable_frame"] is None
        stage = Usd.Stage.Open(str(tmp_path / row["usd"]))
        assert stage.GetEndTimeCode() == settings["simulation.frames"]
        cloth = dataclasses.replace(base.cloths[0], density=settings["cloth.density"])
        simulation = dataclasses.replace(base.simulation, integrator=settings["simulation.integrator"],
                                         frames=settings["simulation.frames"])
        sim = wc.Simulator(dataclasses.replace(base, cloths=(cloth,), simulation=simulation), device="cpu")
        monitor = wc.StrainMonitor()
        sim.run(simulation.frames, writers=[monitor])
        assert row["stretch"] == pytest.approx(monitor.report().stretch, abs=1e-5)
        assert row["compression"] == pytest.approx(monitor.report().compression, abs=1e-5)


def test_variants_whose_chosen_steps_differ_each_run_at_their_own(tmp_path):
    """The scene sets no step: each density is given the one chosen for it alone (a batch of its own), not
    the finest of the sweep's, and its row is that of its scene alone."""
    (tmp_path / "sheet.toml").write_text(SCENE.replace("substeps = 30\n", ""))
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1,0.4",
                                        "--set", "simulation.gravity=[0.0, -9.81, 0.0],[0.0, -3.0, 0.0]",
                                        "--frames", "12", "--out", "swept", "--no-usd", cwd=tmp_path)
    assert code == 0, err
    base = wc.load_scene(tmp_path / "sheet.toml")
    steps = set()
    for row in rows_of(tmp_path / "swept"):
        settings = row["settings"]
        cloth = dataclasses.replace(base.cloths[0], density=settings["cloth.density"])
        simulation = dataclasses.replace(base.simulation, gravity=tuple(settings["simulation.gravity"]), frames=12)
        sim = wc.Simulator(dataclasses.replace(base, cloths=(cloth,), simulation=simulation), device="cpu")
        steps.add(sim.substeps_per_frame)
        monitor = wc.StrainMonitor()
        sim.run(12, writers=[monitor])
        assert row["stretch"] == pytest.approx(monitor.report().stretch, abs=1e-6), row["variant"]
        assert row["compression"] == pytest.approx(monitor.report().compression, abs=1e-6), row["variant"]
        v, m = sim.velocities().astype(np.float64), sim.model.masses.astype(np.float64)
        assert row["kinetic_energy"] == pytest.approx(0.5 * np.sum(m * np.sum(v * v, axis=1)), rel=1e-5), row["variant"]
        assert row["unstable_frame"] is None
    assert len(steps) == 2 and [row["batch_worlds"] for row in rows_of(tmp_path / "swept")] == [2] * 4
    assert "4 variants (0 done before) in 2 batches" in out.splitlines()[-1]


def test_a_variant_whose_step_cannot_be_chosen_is_refused_in_one_line_before_anything_runs(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE.replace("substeps = 30\n", ""))
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.2,1e-8", "--out", "s",
                                        cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "variant cloth.density=1e-08" in err and "simulation.substeps: expected a scene whose stable step" in err
    assert not (tmp_path / "s").exists()


def test_a_sweep_started_again_runs_only_what_its_table_lacks(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    assert run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2", "--out", "s",
                              "--no-usd", cwd=tmp_path)[0] == 0
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2,0.3", "--out", "s",
                                        "--no-usd", cwd=tmp_path)
    assert code == 0, err
    assert "3 variants (2 done before) in 1 batches" in out
    assert sorted(r["settings"]["cloth.density"] for r in rows_of(tmp_path / "s")) == [0.1, 0.2, 0.3]


def test_an_interrupted_sweep_resumed_completes_each_variant_once(tmp_path):
    # A stable step (chosen by the scene) and seconds a variant: time to stop the sweep after the first. The
    # finer cloth at the file's 30 substeps blew up within a frame, and a sweep of variants that stop at once
    # could end before the interrupt arrived.
    slow = SCENE.replace("frames = 6", "frames = 720").replace("resolution = [8, 8]", "resolution = [12, 12]")
    slow = slow.replace("substeps = 30\n", "")
    (tmp_path / "sheet.toml").write_text(slow)
    args = [sys.executable, "-m", "warp_cloth", "sweep", "sheet.toml", "--set", "cloth.density=0.1,0.15,0.2,0.25",
            "--worlds", "1", "--out", "s"]
    process = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    results = tmp_path / "s" / "results.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (results.exists() and results.read_text().strip()):
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    stopped, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    first = rows_of(tmp_path / "s")
    assert f"interrupted by SIGINT after {len(first)} of 4 variants" in stopped
    assert 1 <= len(first) < 4  # stopped part way
    assert all(row["unstable_frame"] is None for row in first)
    resumed = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"4 variants ({len(first)} done before)" in resumed.stdout
    rows = rows_of(tmp_path / "s")
    assert sorted(r["settings"]["cloth.density"] for r in rows) == [0.1, 0.15, 0.2, 0.25]  # each once


@pytest.mark.parametrize("sets, expected", [
    (["cloth.bend.stiffnes=1,2"], "bend.stiffnes"),
    (["cloth.density=light"], "cloth[0].density"),
    (["cloth.density=0.1:0.2"], "cloth[0].density: expected a number, got '0.1:0.2'"),  # a range needs --random
    (["cloth.density"], "--set: expected KEY=V1,V2,..."),
    (["cloth[3].density=1"], "--set cloth[3].density: expected an index below 1 for cloth"),
])
def test_bad_sweep_input_is_one_line_and_nothing_is_written(tmp_path, sets, expected):
    (tmp_path / "sheet.toml").write_text(SCENE)
    args = [a for s in sets for a in ("--set", s)]
    code, out, err = run_cli_in_process("sweep", "sheet.toml", *args, "--out", "s", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
    assert not (tmp_path / "s").exists()


def test_random_variants_draw_from_the_ranges_and_lists_the_same_way_for_a_seed(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    drawn = []
    for out in ("a", "b"):
        code, _, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1:0.3",
                                          "--set", "cloth.bend.stiffness=1,5", "--random", "5", "--seed", "3",
                                          "--no-usd", "--out", out, cwd=tmp_path)
        assert code == 0, err
        drawn.append(sorted((r["settings"]["cloth.density"], r["settings"]["cloth.bend.stiffness"])
                            for r in rows_of(tmp_path / out)))
    assert drawn[0] == drawn[1] and len(drawn[0]) == 5
    assert all(0.1 <= d <= 0.3 and k in (1, 5) for d, k in drawn[0])


def ray_task_processes() -> list[int]:
    """The processes running a sweep's batch as a Ray task (Ray titles them after the task)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and (entry / "cmdline").read_bytes().startswith(b"ray::run_batch"):
                found.append(int(entry.name))
        except OSError:
            continue
    return found


needs_ray = pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                               reason="Ray (the cluster extra) is not installed")


@needs_ray
def test_a_sweep_on_a_local_ray_cluster_gives_the_table_a_local_sweep_gives(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    sets = ["--set", "cloth.density=0.1,0.2,0.3,0.4", "--set", "cloth.bend.stiffness=1,10", "--no-usd"]
    assert run_cli_in_process("sweep", "sheet.toml", *sets, "--out", "here", cwd=tmp_path)[0] == 0
    code, out, err = run_cli_in_process("sweep", "sheet.toml", *sets, "--out", "ray", "--worlds", "3",
                                        "--cluster", "local", "--cluster-workers", "2", cwd=tmp_path)
    assert code == 0, err
    assert "8 variants (0 done before) in 3 batches" in out
    here = {r["variant"]: r for r in rows_of(tmp_path / "here")}
    there = rows_of(tmp_path / "ray")
    assert sorted(r["variant"] for r in there) == sorted(here)
    for row in there:  # the same figures (batched 3 at a time there, all 8 together here)
        assert row["stretch"] == pytest.approx(here[row["variant"]]["stretch"], abs=1e-6)
        assert row["kinetic_energy"] == pytest.approx(here[row["variant"]]["kinetic_energy"], rel=1e-5)


@needs_ray
def test_a_sweep_whose_ray_worker_is_killed_still_runs_each_variant_once(tmp_path):
    slow = SCENE.replace("frames = 6", "frames = 120").replace("resolution = [8, 8]", "resolution = [20, 20]")
    (tmp_path / "sheet.toml").write_text(slow)
    args = [sys.executable, "-m", "warp_cloth", "sweep", "sheet.toml", "--set",
            "cloth.density=0.1,0.12,0.14,0.16,0.18,0.2,0.22,0.24", "--worlds", "1", "--out", "s",
            "--cluster", "local", "--cluster-workers", "2"]
    process = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    deadline = time.monotonic() + 180
    while killed is None and time.monotonic() < deadline and process.poll() is None:
        running = ray_task_processes()
        if running:
            killed = running[0]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    out, err = process.communicate(timeout=600)
    assert killed is not None, "no Ray task was seen running"
    assert process.returncode == 0, err
    assert "8 variants (0 done before) in 8 batches" in out
    densities = sorted(r["settings"]["cloth.density"] for r in rows_of(tmp_path / "s"))
    assert densities == [0.1, 0.12, 0.14, 0.16, 0.18, 0.2, 0.22, 0.24]  # each once, the killed one run again
    assert all((tmp_path / r["usd"]).is_file() for r in rows_of(tmp_path / "s"))


def test_a_cluster_address_that_does_not_answer_is_refused_in_one_line(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, _, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s",
                                      "--cluster", "127.0.0.1:1", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "--cluster: expected the address of a running Ray cluster, HOST:PORT, or local" in err
    assert not (tmp_path / "s").exists()
