"""The Newton comparison builds the benchmark's scenes (sizes, pins, gravity, sphere) in each Newton solver."""

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("newton")

import warp_cloth as wc  # noqa: E402
from warp_cloth.lab.bench import matrix_scene  # noqa: E402
from warp_cloth.lab.newton_compare import (SOLVERS, SPHERE_CENTER, SPHERE_RADIUS, NewtonCloth, grid_strain,  # noqa: E402
                                       time_newton)

N = 16


def run(cloth: NewtonCloth, frames: int) -> np.ndarray:
    for _ in range(frames):
        cloth.frame()
    return cloth.positions()


@pytest.mark.parametrize("solver", SOLVERS)
def test_the_scene_is_the_benchmarks(solver):
    cloth = NewtonCloth("sphere", N, solver, "cpu")
    model = cloth.model
    x = cloth.positions()
    assert model.particle_count == N * N
    ours = wc.Simulator(matrix_scene("sphere", N, "symplectic"), device="cpu").positions()
    np.testing.assert_allclose(x, ours, atol=1e-5)  # the same particles in the same order, swung back
    np.testing.assert_allclose(x.max(axis=0), [10.0, 10.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(x.min(axis=0), [0.0, 10.0 - 10.0 * np.cos(np.radians(20.0)),
                                               -10.0 * np.sin(np.radians(20.0))], atol=1e-5)
    np.testing.assert_allclose(model.gravity.numpy()[0], [0.0, -9.81, 0.0], rtol=1e-6)
    inv_mass = model.particle_inv_mass.numpy()
    pinned = inv_mass == 0.0
    assert pinned.sum() == N and np.allclose(x[pinned, 1], 10.0)  # the whole top row, nothing else
    np.testing.assert_allclose(model.particle_mass.numpy()[~pinned], 2.5 / N**2, rtol=1e-6)
    assert cloth.dt == pytest.approx(1.0 / 240.0)
    assert model.shape_count == 1
    np.testing.assert_allclose(model.shape_transform.numpy()[0][:3], SPHERE_CENTER)
    assert model.shape_scale.numpy()[0][0] == pytest.approx(SPHERE_RADIUS)


@pytest.mark.parametrize("solver", SOLVERS)
def test_the_cloth_hangs_from_its_pins(solver):
    cloth = NewtonCloth("hanging", N, solver, "cpu")
    x0 = cloth.positions()
    x = run(cloth, 12)
    top = x0[:, 1] == 10.0
    np.testing.assert_array_equal(x[top], x0[top])
    assert np.isfinite(x).all()
    assert x[~top, 1].mean() < x0[~top, 1].mean() - 1e-3  # it sags under gravity...
    assert x[:, 1].min() > -3.0  # ...but hangs: the bottom edge (y = 0 at rest) stays within 30 % stretch
    assert np.abs(x[:, 2]).max() < 1e-3  # gravity lies in its plane: nothing pushes it out of it
    assert np.abs(cloth.state_0.particle_qd.numpy()).max() < 20.0


@pytest.mark.parametrize("solver", SOLVERS)
def test_the_cloth_swings_onto_the_sphere(solver):
    cloth = NewtonCloth("sphere", N, solver, "cpu")
    x0 = cloth.positions()
    center = np.array(SPHERE_CENTER)
    assert np.linalg.norm(x0 - center, axis=1).min() > SPHERE_RADIUS + 1.0  # it starts clear of the sphere
    closest = []
    for _ in range(30):
        x = run(cloth, 1)
        closest.append(np.linalg.norm(x - center, axis=1).min())
    assert min(closest[:12]) > SPHERE_RADIUS + 0.5  # it swings...
    assert min(closest) < SPHERE_RADIUS + 0.3  # ...onto the sphere (contact keeps it a particle radius off)...
    assert min(closest) > 0.95 * SPHERE_RADIUS  # ...which keeps it out
    top = np.isclose(x0[:, 1], 10.0)
    assert top.sum() == N
    np.testing.assert_array_equal(x[top], x0[top])


@pytest.mark.parametrize("solver", SOLVERS)
def test_time_newton_reports_a_finite_graphed_run(solver):
    result = time_newton("self", N, solver, "cpu", frames=2, repeats=2)
    assert result["particles"] == N * N and result["n"] == N and result["device"] == "cpu"
    assert result["finite"] and result["graph"] and result["self_contact"]
    assert result["median_seconds"] > 0.0
    assert result["ms_per_frame"] == pytest.approx(1e3 * result["median_seconds"] / 2)
    assert result["particle_substeps_per_second"] == pytest.approx(N * N * 10 * 2 / result["median_seconds"])
    assert "self contact" in result["notes"]


def test_time_newton_measures_strain_over_every_frame_as_ours_is():
    result = time_newton("sphere", N, "semi_implicit", "cpu", frames=3, repeats=2)
    cloth = NewtonCloth("sphere", N, "semi_implicit", "cpu")
    per_frame = [grid_strain(run(cloth, 1), N) for _ in range(2 + 2 * 3)]
    assert result["strain_frames"] == 8
    assert result["stretch"] == pytest.approx(max(s for s, _ in per_frame), abs=1e-6)
    assert result["compression"] == pytest.approx(max(c for _, c in per_frame), abs=1e-6)
    assert result["max_strain"] == max(result["stretch"], result["compression"])
    assert result["max_strain"] > max(per_frame[-1])  # the swing onto the sphere stretches more than the end


def test_unknown_names_are_refused():
    with pytest.raises(ValueError):
        NewtonCloth("drape", N, "vbd", "cpu")
    with pytest.raises(ValueError):
        NewtonCloth("hanging", N, "style3d", "cpu")


def test_the_module_imports_without_newton():
    code = ("import sys; sys.modules['newton'] = None; import warp_cloth.lab.newton_compare as m; "
            "print(m.newton_available())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("False")


@pytest.mark.parametrize("solver", SOLVERS)
def test_self_contact_is_on_only_in_the_self_variant(solver):
    for variant in ("sphere", "self"):
        cloth = NewtonCloth(variant, N, solver, "cpu")
        on = (cloth.solver.particle_enable_self_contact if solver == "vbd"
              else cloth.model.particle_grid is not None and cloth.model.particle_max_radius > 0.0)
        assert on == (variant == "self") == cloth.self_contact
