"""The accuracy/cost study: its numbers against exact ones (free fall), its convergence orders on the seed's
cloth, its instability reports, its files and its input errors."""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

import warp_cloth as wc
import warp_cloth.lab.study as study_module
from warp_cloth.limit_solve import SolveChoices, lab_hooks
from warp_cloth.lab.study import (StudyRun, Trajectory, converged_frames, main, pareto_front, run_study,
                              with_resolution)

G = 9.81
FPS = 24
OFF = wc.SpringKind(enabled=False)


def free_fall_scene() -> wc.Scene:
    cloth = wc.Cloth(resolution=(2, 2), size=(1.0, 1.0), orientation="horizontal", origin=(0.0, 1.0, 0.0),
                     structural=OFF, shear=OFF, bend=OFF)
    return wc.Scene(name="fall", cloths=(cloth,), simulation=wc.Simulation(fps=FPS, frames=12))


def test_free_fall_errors_drift_and_orders_are_the_exact_ones():
    # Forward Euler lags the exact fall by g h t / 2 and semi-implicit (and backward) Euler lead it by as much,
    # so against a symplectic reference at h_r each run is off by g (h -/+ h_r) t / 2 at every particle, and
    # the energy changes by m g^2 h t / 2: a drift of g h T / (2 y0) with the cloth starting at height y0 = 1.
    frames, substeps = 12, (4, 8, 16)
    study = run_study(free_fall_scene(), ("explicit", "symplectic", "implicit"), [1 / (FPS * s) for s in substeps],
                      frames=frames, device="cpu", reference_refinement=16, progress=False)
    h_ref = 1 / (FPS * 16 * substeps[-1])
    assert study.references[0].dt == pytest.approx(h_ref)
    times = np.arange(1, frames + 1) / FPS
    for run in study.runs:
        offset = run.dt + h_ref if run.integrator == "explicit" else run.dt - h_ref
        assert run.error_rms == pytest.approx(G * offset / 2 * np.sqrt(np.mean(times ** 2)), rel=2e-3)
        assert run.error_max == pytest.approx(G * offset / 2 * times[-1], rel=2e-3)
        assert run.energy_drift == pytest.approx(G * run.dt * times[-1] / 2, rel=2e-3)
        assert run.max_strain is None and run.unstable_frame is None and run.resolved
    dts = np.array([1 / (FPS * s) for s in substeps])
    for integrator, sign in (("explicit", 1), ("symplectic", -1), ("implicit", -1)):
        expected = np.polyfit(np.log(dts), np.log(dts + sign * h_ref), 1)[0]  # 0.967 and 1.035
        assert study.orders[integrator] == pytest.approx(expected, abs=0.01)
        assert abs(study.orders[integrator] - 1) < 0.05
    assert study.converged


def test_error_halves_with_dt_on_the_seed_cloth(tmp_path):
    # The seed's hanging cloth at 4x4 quads and 12 frames (before the strain limit holds the swing hard):
    # first order for all three integrators, within 0.15.
    out = tmp_path / "study"
    code = main(["hanging", "--resolutions", "4", "--frames", "12", "--dt", *(str(1 / (FPS * s)) for s in (8, 16, 32)),
                 "--reference-refinement", "8", "--device", "cpu", "--out", str(out)])
    assert code == 0
    data = json.loads((out / "study.json").read_text())
    for integrator in ("explicit", "symplectic", "implicit"):
        assert abs(data["orders"][integrator] - 1) < 0.15, data["orders"]
        errors = [r["error_rms"] for r in data["runs"] if r["integrator"] == integrator]
        assert errors == sorted(errors, reverse=True)
        assert 1.5 < errors[0] / errors[1] < 2.5
    assert all(0.07 < r["max_strain"] < 0.11 for r in data["runs"])
    check = data["reference"]["checks"][0]
    assert check["resolution"] == 4 and check["particles"] == 25
    assert check["difference_rms"] < min(r["error_rms"] for r in data["runs"])


def test_a_run_at_the_reference_step_differs_by_rounding_only_and_the_study_says_it_cannot_resolve_it():
    study = run_study("hanging", ["symplectic"], [0.0025], frames=6, device="cpu", reference_refinement=1,
                      progress=False)
    (run,) = study.runs
    assert run.dt == study.references[0].dt
    # the same steps; only the reference's compensated sums round differently (a few float32 ulps of 1 m)
    assert run.error_max < 2e-5 and run.error_rms < 0.01 * study.references[0].difference_rms
    assert run.resolved is False and not study.converged
    assert study.orders == {"symplectic": None}


def wc_scene_file_text(name: str) -> str:
    from warp_cloth.scene_file import resolve_scene_path

    return resolve_scene_path(name).read_text()


def test_unstable_runs_are_reported_not_raised(tmp_path, capsys):
    # The seed's cloth blows up with explicit Euler at these steps (past max_speed); semi-implicit Euler at
    # 0.0208 s boils with springs 3x past the strain limit under the plain converged solve, while at 0.0104 s
    # that solve keeps it within the limit. (The solve's default Chebyshev acceleration holds the 0.0208 s
    # run to 37% instead, boiling but short of the guard's bound, and plain passes capped at the default
    # 1000 keep some run from blowing up within 24 frames: plain passes capped at 200 here.)
    out = tmp_path / "study"
    text = wc_scene_file_text("hanging")
    assert "\n[simulation]\n" in text
    scene = tmp_path / "hanging.toml"
    scene.write_text(text.replace("\n[simulation]\n", "\n[simulation]\nlimit_max_passes = 200\n", 1))
    plain = SolveChoices(chebyshev_rho=0.0, line_solve=False)  # plain Jacobi passes (the line rounds hold 0.0208 s)
    with lab_hooks(plain):
        code = main([str(scene), "--dt", "0.0208", "0.0104", "--frames", "24", "--device", "cpu", "--out", str(out)])
    assert code == 0
    with open(out / "study.csv") as handle:
        rows = list(csv.DictReader(handle))
    data = json.loads((out / "study.json").read_text())
    assert len(rows) == len(data["runs"]) == 6
    unstable = [r for r in data["runs"] if r["integrator"] == "explicit" or r["dt_requested"] == 0.0208]
    unstable = [r for r in unstable if r["integrator"] != "implicit"]
    assert len(unstable) == 3
    assert all(1 <= r["unstable_frame"] <= 24 and r["unstable_reason"] for r in unstable)
    assert all(r["error_rms"] is None and r["seconds_per_simulated_second"] is None for r in unstable)
    assert sum(bool(row["unstable_frame"]) for row in rows) == 3
    assert "strain" in next(r["unstable_reason"] for r in unstable if r["integrator"] == "symplectic")
    (held,) = [r for r in data["runs"] if r["integrator"] == "symplectic" and r["dt_requested"] == 0.0104]
    assert held["unstable_frame"] is None and held["max_strain"] <= 0.11
    implicit = [r for r in data["runs"] if r["integrator"] == "implicit"]
    assert all(r["unstable_frame"] is None and r["error_rms"] > 0 for r in implicit)
    assert all(r["seconds_per_simulated_second"] > 0 and math.isfinite(r["energy_drift"]) for r in implicit)
    assert data["device"] == "cpu" and data["environment"]["device_alias"] == "cpu" and data["environment"]["warp"]
    assert set(data["definitions"]) >= {"error_rms", "energy_drift", "max_strain", "unstable_frame"}
    pngs = [out / name for name in ("error_vs_time.png", "error_vs_dt.png", "time_vs_resolution.png")]
    stdout = capsys.readouterr().out
    assert "unstable at frame" in stdout and "6 runs (3 unstable) on cpu" in stdout
    assert all(png.stat().st_size > 1000 for png in pngs)


def test_resolution_keeps_size_and_total_mass():
    scene = wc.load_scene("hanging")  # mass per particle
    density = wc.Scene(cloths=(wc.Cloth(density=0.2),))
    for original in (scene, density):
        finer = with_resolution(original, 20)
        assert finer.cloths[0].resolution == (20, 20) and finer.cloths[0].size == original.cloths[0].size
        masses = [wc.Simulator(s, device="cpu").model.masses.sum() for s in (original, finer)]
        assert masses[1] == pytest.approx(masses[0], rel=1e-5)
    by_index = wc.Scene(cloths=(wc.Cloth(pins=(wc.Pin(indices=(0,)),)),))
    with pytest.raises(wc.SceneError, match="indices"):
        with_resolution(by_index, 4)


def test_pareto_front_keeps_only_unbeaten_runs():
    def run(seconds, error, unstable=None):
        return StudyRun("symplectic", None, 9, 0.01, 0.01, 4, 12, seconds, error, error, None, 0.0, unstable,
                        unstable and "test", True)

    fast, accurate, beaten, tied = run(1.0, 0.1), run(10.0, 0.01), run(20.0, 0.1), run(10.0, 0.01)
    blown = run(None, None, unstable=3)
    assert pareto_front([beaten, accurate, fast, blown, tied]) == [fast, accurate, tied]


@pytest.mark.parametrize("args", [["no_such_scene"], ["hanging", "--dt", "-0.01"], ["hanging", "--frames", "2"],
                                  ["hanging", "--resolutions", "0"], ["hanging", "--dt", "0.5"]])
def test_bad_input_is_one_line_and_exit_code_2(args, capsys, tmp_path):
    assert main([*args, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("warp-cloth study: error: ") and "\n" not in err
    assert not (tmp_path / "x").exists()


def test_a_reference_past_the_substep_bound_is_refused_naming_the_option(capsys, tmp_path):
    # 0.0001 s is 413 substeps a frame at 24 fps (dt may be 1% over); its reference, 16x finer and checked
    # at half that step, would need 13216 substeps a frame.
    assert main(["hanging", "--dt", "0.0001", "--reference-refinement", "16", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("warp-cloth study: error: command line: --reference-refinement: expected a reference of "
                          "at most 10000 substeps a frame") and "13216 asked" in err
    assert not (tmp_path / "x").exists()


def test_a_study_step_too_small_for_any_reference_is_refused_naming_the_option(capsys, tmp_path):
    # 0.00001 s is over 4000 substeps a frame: the coarsest reference tried, 2x finer and checked at half
    # its step, would need over 16000.
    assert main(["hanging", "--dt", "0.00001", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("warp-cloth study: error: command line: --dt: expected a smallest step of at least 1.67e-05 s "
                   "(the reference is 4 times finer, at most 10000 substeps a frame), got 1e-05")
    assert not (tmp_path / "x").exists()


def converged_hanging() -> wc.Scene:
    scene = wc.load_scene("hanging")
    return dataclasses.replace(scene, simulation=dataclasses.replace(
        scene.simulation, limit_solve="converged", limit_tolerance=1e-4, limit_max_passes=20))


def test_the_reference_stops_refining_where_its_difference_from_half_its_step_grows(monkeypatch):
    # Each candidate reference is compared with the one at half its step; past some step rounding can
    # outgrow truncation, and the study keeps the refinement whose difference was the smallest.
    differences = iter([0.0, 4.0, 2.0, 3.0, 1.0])  # the first: the coarsest candidate, compared with nothing
    tried = []

    def fake_reference_run(scene, device, frames, substeps, tick, compared_with=None):
        tried.append(substeps)
        run = Trajectory(dt=1.0 / substeps, substeps=substeps, particles=1, frames=frames)
        run.frame_squared_errors = [next(differences) ** 2] * frames
        return run

    monkeypatch.setattr(study_module, "_reference_run", fake_reference_run)
    refinement, reference, half = study_module._check_reference(None, "cpu", 3, 10, (2, 4, 8, 16, 32),
                                                                lambda frames: None)
    assert tried == [20, 40, 80, 160]  # stopped once 8's half step (160) differed more than 4's (80)
    assert refinement == 4 and reference.substeps == 40 and half.substeps == 80


def test_with_compensated_sums_the_hanging_reference_converges_to_the_finest_step_tried():
    # Without compensation the float32 positions' rounding outgrew truncation below about 0.15 ms here and
    # the study stopped at 8; with it the difference from half the step keeps halving, so the study goes on
    # to 32, and that reference is closer than the one at 16 (measured 0.61 of it: not quite the halving of
    # truncation alone, since the velocities and the limit's passes still round).
    study = run_study(converged_hanging(), ["symplectic"], [0.0025, 0.00125], frames=12, device="cpu",
                      progress=False)
    assert study.reference_refinements == [32]
    fixed = run_study(converged_hanging(), ["symplectic"], [0.0025, 0.00125], frames=12, device="cpu",
                      reference_refinement=16, progress=False)
    assert study.references[0].difference_rms < 0.75 * fixed.references[0].difference_rms
    for chosen, given in zip(study.runs, fixed.runs):  # the runs themselves do not depend on the reference
        assert chosen.dt == given.dt and chosen.substeps == given.substeps


def _trajectory(frame_errors) -> Trajectory:
    run = Trajectory(dt=0.001, substeps=1, particles=1, frames=len(frame_errors))
    run.frame_squared_errors = list(frame_errors)
    return run


def test_converged_frames_are_the_most_first_frames_over_which_every_run_is_resolved():
    check = _trajectory([1.0, 1.0, 1.0, 100.0])
    # over frames 1..3 both runs' summed squared errors are >= 10^2 times the check's; over 1..4 the second
    # run's (100 + 100 + 100 + 100) is not 100 times (1 + 1 + 1 + 100)
    runs = [_trajectory([200.0, 100.0, 100.0, 1e6]), _trajectory([100.0, 100.0, 100.0, 100.0])]
    assert converged_frames(check, runs) == 3
    unstable = _trajectory([0.0])
    unstable.unstable_frame = 1
    assert converged_frames(check, runs + [unstable]) == 3  # unstable runs have no error to resolve
    assert converged_frames(check, [_trajectory([50.0] * 4)]) == 0
    assert converged_frames(_trajectory([0.0] * 4), [_trajectory([1.0] * 4)]) == 4
