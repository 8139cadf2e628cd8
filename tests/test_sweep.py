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
from pxr import Usd, UsdGeom

import warp_cloth as wc
from conftest import run_cli, run_cli_in_process
from warp_cloth.sweep import file_stem, spread

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
    assert "sweep sheet: 4 variants (0 done before) in 1 batch," in out.splitlines()[-1]
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
    assert "3 variants (2 done before) in 1 batch," in out
    assert sorted(r["settings"]["cloth.density"] for r in rows_of(tmp_path / "s")) == [0.1, 0.2, 0.3]


def test_an_interrupted_sweep_resumed_completes_each_variant_once(tmp_path):
    # A stable step (chosen by the scene); the first variant a fraction of a second, the second seconds: the
    # sweep is stopped once the second has begun writing its frames (a signal between batches lets the next
    # one run whole). The finer cloth at the file's 30 substeps blew up within a frame, and a sweep of
    # variants that stop at once could end before the interrupt arrived.
    slow = SCENE.replace("resolution = [8, 8]", "resolution = [12, 12]").replace("substeps = 30\n", "")
    (tmp_path / "sheet.toml").write_text(slow)
    frames = [24, 720, 48, 72]
    args = [sys.executable, "-m", "warp_cloth", "sweep", "sheet.toml", "--set",
            f"simulation.frames={','.join(map(str, frames))}", "--worlds", "1", "--out", "s"]
    process = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    second = tmp_path / "s" / f"{file_stem((('simulation.frames', 720),))}.incomplete.usdc"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not second.exists():
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
    assert sorted(r["settings"]["simulation.frames"] for r in rows) == sorted(frames)  # each once
    for row in rows:  # and run to its end: no row for the variant the interrupt cut short
        stage = Usd.Stage.Open(str(tmp_path / row["usd"]))
        points = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth")).GetPointsAttr()
        assert len(points.GetTimeSamples()) == row["settings"]["simulation.frames"] + 1, row["variant"]


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
def test_a_sweep_on_a_local_ray_cluster_gives_the_table_a_local_sweep_gives(tmp_path, monkeypatch):
    (tmp_path / "sheet.toml").write_text(SCENE)
    sets = ["--set", "cloth.density=0.1,0.2,0.3,0.4", "--set", "cloth.bend.stiffness=1,10", "--no-usd"]
    assert run_cli_in_process("sweep", "sheet.toml", *sets, "--out", "here", cwd=tmp_path)[0] == 0
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")  # another cluster's (gone): local starts a cluster of its own
    code, out, err = run_cli_in_process("sweep", "sheet.toml", *sets, "--out", "ray",
                                        "--cluster", "local", "--cluster-workers", "2", cwd=tmp_path)
    assert code == 0, err
    # none of Ray's log lines: off a terminal, only the sweep's own progress lines
    assert all(line.startswith("sweep sheet: ") for line in err.splitlines()), err
    assert "8 variants (0 done before) in 2 batches" in out  # one batch of 8 here, split for the two workers
    here = {r["variant"]: r for r in rows_of(tmp_path / "here")}
    there = rows_of(tmp_path / "ray")
    assert sorted(r["variant"] for r in there) == sorted(here)
    assert [r["batch_worlds"] for r in there] == [4] * 8
    for row in there:  # the same figures (batched 4 at a time there, all 8 together here)
        assert row["stretch"] == pytest.approx(here[row["variant"]]["stretch"], abs=1e-6)
        assert row["kinetic_energy"] == pytest.approx(here[row["variant"]]["kinetic_energy"], rel=1e-5)


def test_batches_are_split_until_each_worker_has_one_where_there_are_variants_enough():
    todo = [list("abcdefgh"), list("xy")]
    assert spread(todo, 1) == todo and spread(todo, 2) == todo
    assert spread(todo, 3) == [list("abcd"), list("efgh"), list("xy")]
    assert spread(todo, 4) == [list("ab"), list("cd"), list("efgh"), list("xy")]
    assert sorted(map(len, spread(todo, 64))) == [1] * 10  # no more batches than variants
    assert spread([list("abc")], 2) == [list("ab"), list("c")]


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


def test_a_second_sweep_into_the_same_folder_is_refused_at_once_and_the_first_completes(tmp_path):
    slow = SCENE.replace("frames = 6", "frames = 240").replace("resolution = [8, 8]", "resolution = [12, 12]")
    (tmp_path / "sheet.toml").write_text(slow)
    args = [sys.executable, "-m", "warp_cloth", "sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2",
            "--out", "s"]
    first = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and first.poll() is None and len(list((tmp_path / "s").glob(
                "*.incomplete.usdc"))) < 2:  # the batch's two worlds make their files one after the other
            time.sleep(0.05)
        in_progress = sorted((tmp_path / "s").glob("*.incomplete.usdc"))
        assert len(in_progress) == 2, "the first sweep was not seen writing"
        started = time.monotonic()
        code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2,0.3",
                                            "--out", "s", cwd=tmp_path)
        assert time.monotonic() - started < 10
        assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
        assert f"command line: --out: expected an output no other run is writing (the run with process id " \
               f"{first.pid} holds" in err
        assert all(path.exists() for path in in_progress)  # the first's frames are left alone
        stdout, stderr = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, stderr
    rows = rows_of(tmp_path / "s")
    assert sorted(r["settings"]["cloth.density"] for r in rows) == [0.1, 0.2]
    assert all((tmp_path / r["usd"]).is_file() for r in rows)


def test_a_variant_whose_output_another_run_is_writing_is_one_line(tmp_path):
    """An error inside the sweep (a variant's USD locked by a ``warp-cloth run`` writing it) is reported as
    ``run`` reports it."""
    (tmp_path / "sheet.toml").write_text(SCENE)
    stem = file_stem((("cloth.density", 0.1),))
    (tmp_path / "s").mkdir()
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(tmp_path / "s" / f"{stem}.lock")],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s",
                                            cwd=tmp_path)
    finally:
        holder.kill()
        holder.wait()
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"usd: expected an output no other run is writing (the run with process id {holder.pid} holds" in err


HOLD_LOCK = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)
fcntl.flock(fd, fcntl.LOCK_EX)
os.write(fd, f"{os.getpid()}\\n".encode())
print("held", flush=True)
time.sleep(120)
"""


@pytest.mark.parametrize("sets, expected", [
    (["cloth.density=0.02,0.02"], "command line: --set cloth.density: expected each value once (0.02 is there "
                                  "twice), got '0.02,0.02'"),
    (["cloth.bend.stiffness=1,5,1.0"], "--set cloth.bend.stiffness: expected each value once (1.0 is there twice)"),
    (["cloth.density=0.1,0.2", "cloth.density=0.3"], "command line: --set cloth.density: expected each key once"),
])
def test_a_value_or_key_given_twice_is_refused_in_one_line(tmp_path, sets, expected):
    (tmp_path / "sheet.toml").write_text(SCENE)
    args = [a for s in sets for a in ("--set", s)]
    code, out, err = run_cli_in_process("sweep", "sheet.toml", *args, "--out", "s", cwd=tmp_path)
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1 and expected in err, err
    assert not (tmp_path / "s").exists()


def test_random_draws_of_a_list_that_repeat_a_variant_run_it_once(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.bend.stiffness=1,5", "--random",
                                        "6", "--no-usd", "--out", "s", cwd=tmp_path)
    assert code == 0, err
    assert sorted(r["settings"]["cloth.bend.stiffness"] for r in rows_of(tmp_path / "s")) == [1, 5]
    assert "sweep sheet: 2 variants (0 done before) in 1 batch," in out


def test_random_values_are_rounded_to_six_digits_in_the_name_and_in_the_run(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, _, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1:0.3", "--random", "3",
                                      "--no-usd", "--out", "s", cwd=tmp_path)
    assert code == 0, err
    for row in rows_of(tmp_path / "s"):
        density = row["settings"]["cloth.density"]
        assert density == float(f"{density:.6g}") and 0.1 <= density <= 0.3
        assert row["variant"] == f"cloth.density={density}" and len(row["variant"]) <= len("cloth.density=0.123456")
    table = (tmp_path / "s" / "results.csv").read_text().splitlines()
    assert all(len(line.split(",")[0]) <= 8 for line in table[1:])


def test_the_summary_says_one_variant_and_one_batch_in_the_singular(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--no-usd", "--out",
                                        "s", cwd=tmp_path)
    assert code == 0, err
    assert out.splitlines()[-1].startswith("sweep sheet: 1 variant (0 done before) in 1 batch, ")


def test_the_sweep_help_reads_without_markup():
    result = subprocess.run([sys.executable, "-m", "warp_cloth", "sweep", "--help"], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert "``" not in result.stdout and "--set KEY=V1,V2,..." in result.stdout
    assert "pip install 'warp-cloth[cluster]'" in result.stdout


@pytest.mark.parametrize("out, expected", [
    ("notes.txt", "command line: --out: expected a folder (this is a file), got 'notes.txt'"),
    ("notes.txt/s", "command line: --out: expected a path whose folders can be made ("),
    ("o" * 300, "command line: --out: expected a path the file system can hold"),
])
def test_a_sweep_output_the_file_system_refuses_is_one_line(tmp_path, out, expected):
    (tmp_path / "sheet.toml").write_text(SCENE)
    (tmp_path / "notes.txt").write_text("mine")
    code, stdout, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", out,
                                           cwd=tmp_path)
    assert (code, stdout) == (2, "") and len(err.strip().splitlines()) == 1 and expected in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "sheet.toml"]
    assert (tmp_path / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("stray, expected", [
    ("42", "expected a row of a sweep's table (an object with variant, settings, stretch"),
    ('{"variant": "cloth.density=0.3"}', "expected a row of a sweep's table (an object with variant, settings"),
    ("not json", "expected a row of a sweep's table"),
])
def test_a_stray_line_in_a_sweeps_table_is_refused_naming_the_file_and_the_line(tmp_path, stray, expected):
    (tmp_path / "sheet.toml").write_text(SCENE)
    sweep = ["sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2", "--no-usd", "--out", "s"]
    assert run_cli_in_process(*sweep, cwd=tmp_path)[0] == 0
    results = tmp_path / "s" / "results.jsonl"
    lines = results.read_text().splitlines()
    edited = "\n".join([lines[0], stray, lines[1]]) + "\n"
    results.write_text(edited)
    code, out, err = run_cli_in_process(*sweep, cwd=tmp_path)
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
    assert f"warp-cloth sweep: error: {Path('s') / 'results.jsonl'}: line 2: {expected}" in err
    assert results.read_text() == edited


def test_a_last_row_cut_short_by_a_kill_is_run_again(tmp_path):
    (tmp_path / "sheet.toml").write_text(SCENE)
    sweep = ["sweep", "sheet.toml", "--set", "cloth.density=0.1,0.2", "--worlds", "1", "--no-usd", "--out", "s"]
    assert run_cli_in_process(*sweep, cwd=tmp_path)[0] == 0
    results = tmp_path / "s" / "results.jsonl"
    whole = results.read_text()
    first, second = whole.splitlines()
    results.write_text(f"{first}\n{second[:len(second) // 2]}")  # killed as it wrote the second row
    code, out, err = run_cli_in_process(*sweep, cwd=tmp_path)
    assert code == 0, err
    assert f"{Path('s') / 'results.jsonl'}: line 2 was cut short" in err
    assert "2 variants (1 done before) in 1 batch," in out
    rows = rows_of(tmp_path / "s")  # every line a whole row again
    assert [r["variant"] for r in rows] == [json.loads(first)["variant"], json.loads(second)["variant"]]


def test_a_cluster_address_where_a_web_server_answers_is_refused_in_seconds(tmp_path):
    import http.server
    import threading

    (tmp_path / "sheet.toml").write_text(SCENE)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    address = f"127.0.0.1:{server.server_address[1]}"
    try:
        started = time.monotonic()
        result = run_cli("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s", "--cluster", address,
                         cwd=tmp_path, timeout=60)
        elapsed = time.monotonic() - started
    finally:
        server.shutdown()
        server.server_close()
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert ("--cluster: expected the address of a running Ray cluster, HOST:PORT, or local (an HTTP server "
            "answered: HTTP/1.0 501") in result.stderr
    assert f"got '{address}'" in result.stderr
    assert elapsed < 30  # seconds of Python's and Warp's imports; the probe itself takes a moment
    assert not (tmp_path / "s").exists()


def test_an_address_where_a_grpc_server_answers_passes_the_check():
    """Ray's GCS (HOST:6379) and client server (ray://HOST:10001) speak gRPC, whose server opens each
    connection with an HTTP/2 SETTINGS frame."""
    import socket
    import threading

    from warp_cloth.sweep import check_cluster_address

    listener = socket.create_server(("127.0.0.1", 0))

    def answer() -> None:
        connection, _ = listener.accept()
        connection.sendall(bytes.fromhex("000006040000000000") + bytes.fromhex("000300000064"))
        time.sleep(1)
        connection.close()

    threading.Thread(target=answer, daemon=True).start()
    try:
        check_cluster_address(f"127.0.0.1:{listener.getsockname()[1]}")
    finally:
        listener.close()


def test_a_cluster_that_fails_to_start_names_no_table_that_is_not_there(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")

    def refuse(*args, **kwargs):
        raise ConnectionError("the cluster went away")

    monkeypatch.setattr(ray, "init", refuse)
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s",
                                        "--cluster", "local", cwd=tmp_path)
    assert code == 4 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("warp-cloth sweep: error: --cluster: could not start a Ray cluster here (ConnectionError: "
                          "the cluster went away); nothing ran"), err
    assert "results.jsonl" not in err
    assert not (tmp_path / "s").exists()


def test_a_cluster_sweep_without_ray_names_the_extra_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails, as where it is not installed
    (tmp_path / "sheet.toml").write_text(SCENE)
    code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s",
                                        "--cluster", "local", cwd=tmp_path)
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
    assert "command line: --cluster: expected Ray installed (it is not: pip install 'warp-cloth[cluster]')" in err
    assert not (tmp_path / "s").exists()


def test_a_cluster_address_where_nothing_answers_is_refused_in_seconds(tmp_path):
    import socket

    (tmp_path / "sheet.toml").write_text(SCENE)
    listener = socket.create_server(("127.0.0.1", 0))  # connections wait in its backlog, never answered
    address = f"127.0.0.1:{listener.getsockname()[1]}"
    try:
        started = time.monotonic()
        code, out, err = run_cli_in_process("sweep", "sheet.toml", "--set", "cloth.density=0.1", "--out", "s",
                                            "--cluster", address, cwd=tmp_path)
        elapsed = time.monotonic() - started
    finally:
        listener.close()
    assert (code, out) == (2, "") and len(err.strip().splitlines()) == 1, err
    assert f"(nothing answered there as Ray does within 5 s), got '{address}'" in err
    assert elapsed < 15
    assert not (tmp_path / "s").exists()
