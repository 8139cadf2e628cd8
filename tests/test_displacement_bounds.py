"""The lab's displacement bounds (warp_cloth/displacement_bounds.py): the nearest vertex-triangle and edge-edge
distances found through the hash against all pairs in numpy, and a step that crosses two cloths unbounded and
does not bounded."""

import dataclasses

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
from warp_cloth.diagnostics import TriangleIntersections
from warp_cloth.displacement_bounds import BoundSettings, DisplacementBounds, lab_hooks, mesh_primitives


def point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances from points p (k, 3) to segments a-b (k, 3 each)."""
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def point_triangle(p, a, b, c) -> np.ndarray:
    """Distances from p to triangles a, b, c: the plane's foot where its barycentric coordinates (from the
    normal equations) are all at least 0, else the nearest edge."""
    e0, e1, d = b - a, c - a, p - a
    g00, g01, g11 = (np.einsum("ij,ij->i", u, w) for u, w in ((e0, e0), (e0, e1), (e1, e1)))
    r0, r1 = np.einsum("ij,ij->i", d, e0), np.einsum("ij,ij->i", d, e1)
    det = g00 * g11 - g01 * g01
    s = (g11 * r0 - g01 * r1) / det
    t = (g00 * r1 - g01 * r0) / det
    foot = np.linalg.norm(d - s[:, None] * e0 - t[:, None] * e1, axis=1)
    edges = np.minimum(np.minimum(point_segment(p, a, b), point_segment(p, b, c)), point_segment(p, c, a))
    return np.where((s >= 0) & (t >= 0) & (s + t <= 1), foot, edges)


def segment_segment(p0, p1, q0, q1) -> np.ndarray:
    """Distances between segments: the lines' closest points where both lie within the segments, else the
    nearest end to the other segment."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, b = (np.einsum("ij,ij->i", u, w) for u, w in ((d1, d1), (d2, d2), (d1, d2)))
    c, f = np.einsum("ij,ij->i", d1, r), np.einsum("ij,ij->i", d2, r)
    det = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s, t = (b * f - c * e) / det, (a * f - b * c) / det
    inner = np.linalg.norm(p0 + s[:, None] * d1 - q0 - t[:, None] * d2, axis=1)
    ends = np.minimum(np.minimum(point_segment(p0, q0, q1), point_segment(p1, q0, q1)),
                      np.minimum(point_segment(q0, p0, p1), point_segment(q1, p0, p1)))
    return np.where((det > 1e-12 * a * e) & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1), np.minimum(inner, ends), ends)


def brute_force_nearest(x: np.ndarray, triangles: np.ndarray, ends: np.ndarray, radius: float) -> np.ndarray:
    """Each vertex's least distance over every vertex-triangle and edge-edge pair sharing no vertex that it
    belongs to, at most ``radius``."""
    x = x.astype(np.float64)
    nearest = np.full(len(x), radius)
    v, t = (a.ravel() for a in np.meshgrid(np.arange(len(x)), np.arange(len(triangles)), indexing="ij"))
    keep = (triangles[t] != v[:, None]).all(axis=1)
    v, t = v[keep], t[keep]
    d = point_triangle(x[v], *(x[triangles[t, k]] for k in range(3)))
    for members in (v, triangles[t, 0], triangles[t, 1], triangles[t, 2]):
        np.minimum.at(nearest, members, d)
    e, f = (a.ravel() for a in np.meshgrid(np.arange(len(ends)), np.arange(len(ends)), indexing="ij"))
    keep = (e < f) & (ends[e][:, :, None] != ends[f][:, None, :]).all(axis=(1, 2))
    e, f = e[keep], f[keep]
    d = segment_segment(x[ends[e, 0]], x[ends[e, 1]], x[ends[f, 0]], x[ends[f, 1]])
    for members in (ends[e, 0], ends[e, 1], ends[f, 0], ends[f, 1]):
        np.minimum.at(nearest, members, d)
    return nearest


def crumpled_cloths() -> wc.Scene:
    """Two small cloths, one over the other, that random moves will crumple into each other."""
    cloths = (wc.Cloth(name="a", resolution=(6, 5), size=(0.3, 0.25), orientation="horizontal", jitter=0.1),
              wc.Cloth(name="b", resolution=(5, 5), size=(0.25, 0.25), orientation="horizontal",
                       origin=(0.02, 0.03, 0.01), jitter=0.1, seed=3))
    return wc.Scene(name="crumpled", cloths=cloths)


@pytest.mark.parametrize("seed, radius", [(0, 0.02), (1, 0.05), (2, 0.2)])
def test_nearest_distances_match_all_pairs(seed, radius):
    sim = wc.Simulator(crumpled_cloths(), device="cpu")
    bounds = DisplacementBounds(sim.model, sim.device_model, BoundSettings(radius=radius))
    rng = np.random.default_rng(seed)
    x = (sim.model.positions + rng.normal(0.0, 0.03, sim.model.positions.shape)).astype(np.float32)
    bounds.measure_at(wp.array(x, dtype=wp.vec3, device="cpu"))
    triangles, ends = mesh_primitives(sim.model)
    expected = brute_force_nearest(x, triangles, ends, radius)
    assert (expected < radius).sum() > len(x) // 4  # the case has pairs within the radius to find
    np.testing.assert_allclose(bounds.nearest.numpy(), expected, rtol=1e-4, atol=1e-6)


def falling_onto_sheet() -> wc.Scene:
    """A vertical sheet whose lower edge is 1 cm above a horizontal one, falling 5 cm in its first substep."""
    below = wc.Cloth(name="below", resolution=(4, 4), size=(0.4, 0.4), orientation="horizontal",
                     origin=(-0.2, 0.0, 0.2))
    falling = wc.Cloth(name="falling", resolution=(4, 4), size=(0.2, 0.2), orientation="vertical",
                       origin=(-0.07, 0.01, 0.03), velocity=(0.0, -18.0, 0.0))
    return wc.Scene(name="falling", cloths=(below, falling), simulation=wc.Simulation(fps=60.0, substeps=6))


@pytest.mark.parametrize("rounds", [1, 3])
def test_bounded_step_does_not_cross(rounds):
    unbounded = wc.Simulator(falling_onto_sheet(), device="cpu")
    with lab_hooks(BoundSettings(radius=0.02, rounds=rounds)):
        bounded = wc.Simulator(falling_onto_sheet(), device="cpu")
    counts = []
    for sim in (unbounded, bounded):
        crossings = TriangleIntersections(sim)
        assert crossings(sim) == 0
        sim.substep()
        counts.append(crossings(sim))
    assert counts[0] > 0 and counts[1] == 0
    stats = bounded.plan.bounds.read_stats()
    assert stats.held_short[0] > 0 and stats.held_back > 0.0
    surfaces = DisplacementBounds(bounded.model, bounded.device_model, BoundSettings(radius=0.02))
    surfaces.measure_at(bounded.state.x)
    assert surfaces.nearest.numpy().min() > 0.0
    # the held particles' velocities are their clamped steps over the substep
    start, x, v = bounded.model.positions, bounded.positions(), bounded.velocities()
    moved = np.linalg.norm(x - start, axis=1) > 0
    np.testing.assert_allclose(v[moved], (x[moved] - start[moved]) / bounded.device_model.h, rtol=1e-3, atol=1e-4)


def test_query_radius_widens_to_the_longest_free_step():
    """Measured with the step's targets, the query radius is the longest step of a free particle over gamma
    (with the kernel's 1.001 slack) where that exceeds the settings' radius, and the distances are all pairs'
    within it; measured without targets (the start check, the tools), the settings' radius."""
    sim = wc.Simulator(crumpled_cloths(), device="cpu")
    settings = BoundSettings(radius=0.02)
    bounds = DisplacementBounds(sim.model, sim.device_model, settings)
    x = sim.model.positions.astype(np.float32)
    step = np.zeros_like(x)
    step[7] = (0.0, 0.045, 0.0)  # gamma r = 0.0405 at r = 0.09
    target = (x + step).astype(np.float32)
    bounds.measure_at(wp.array(x, dtype=wp.vec3, device="cpu"), wp.array(target, dtype=wp.vec3, device="cpu"))
    radius = float(bounds.query.numpy()[0])
    assert radius == pytest.approx(1.001 * 0.045 / settings.gamma, rel=1e-6)
    triangles, ends = mesh_primitives(sim.model)
    np.testing.assert_allclose(bounds.nearest.numpy(), brute_force_nearest(x, triangles, ends, radius),
                               rtol=1e-4, atol=1e-6)
    bounds.measure_at(wp.array(x, dtype=wp.vec3, device="cpu"))
    assert bounds.query.numpy()[0] == np.float32(settings.radius)


def free_fall_scene(thickness: float | None) -> wc.Scene:
    """A 1 m sheet of 8^2 cells falling from rest through empty air, at the fold's 24 fps and 17 substeps."""
    sheet = wc.Cloth(name="sheet", resolution=(8, 8), size=(1.0, 1.0), orientation="horizontal",
                     origin=(-0.5, 2.0, 0.5), limit=wc.Limit())
    return wc.Scene(name="falling", cloths=(sheet,), collision=wc.Collision(radius=0.002, thickness=thickness),
                    simulation=wc.Simulation(fps=24, frames=12, substeps=17))


def test_a_thickness_does_not_slow_a_free_fall():
    """Twelve frames (0.5 s) of free fall with a 4 mm thickness: the displacement bounds hold no particle
    short, the sheet falls as without a thickness (positions equal to float32's rounding near 2 m) and by
    g t^2 / 2 to within the substeps' semi-implicit Euler (g h t / 2, 6 mm). A fixed query radius of 2.5
    thicknesses capped the fall at gamma r = 4.5 mm a substep, 1.84 m/s, at most 0.92 m in 0.5 s against
    1.23 m."""
    heights = []
    for thickness in (None, 0.004):
        sim = wc.Simulator(free_fall_scene(thickness), device="cpu")
        for _ in range(12):
            sim.step()
        heights.append(sim.positions()[:, 1])
        if thickness is not None:
            stats = sim.plan.bounds.read_stats()
            assert sum(stats.held_short) == 0 and stats.held_back == 0.0 and stats.measured_again == 0
    np.testing.assert_allclose(heights[1], heights[0], rtol=0.0, atol=1e-6)
    t, h = 0.5, 1.0 / (24 * 17)
    drop = 2.0 - heights[1]
    assert np.all(np.abs(drop - 9.81 * t * t / 2) < 9.81 * h * t / 2 + 1e-4)


def test_the_fold_landing_on_itself_at_a_thickness_holds_its_limit_and_its_layers_apart():
    """The built-in fold with a 4 mm thickness: its 32^2 cloth falls from 4 m and lands on its own layers at
    some 8 m/s (frames 19 to 23). With the bounds held inside the solve every edge ends within the limit's
    tolerance (10% + 0.5%; measured +10.4% / -10.4% over 48 frames) and every vertex-triangle and edge-edge pair
    of the cloth at least 0.9 of the thickness apart (0.951 at frame 25), with no crossing pair. With the clamp
    after the solve alone it landed at +15.3% / -19.6%, its surfaces 0.62 of the thickness apart."""
    base = wc.load_scene("fold")
    frames = 26
    scene = dataclasses.replace(base, collision=dataclasses.replace(base.collision, thickness=0.004),
                                simulation=dataclasses.replace(base.simulation, frames=frames))
    sim = wc.Simulator(scene, device="cpu")
    strain, crossings = wc.StrainMonitor(), TriangleIntersections(sim)
    strain.begin(sim)
    surfaces = DisplacementBounds(sim.model, sim.device_model, BoundSettings(radius=0.004))
    closest, most_crossings = [], 0
    for frame in range(1, frames + 1):
        sim.step()
        strain.write_frame(sim, frame)
        most_crossings = max(most_crossings, crossings(sim))
        surfaces.measure_at(sim.state.x)
        closest.append(float(surfaces.nearest.numpy().min()))
    report = strain.report()
    assert most_crossings == 0
    assert report.stretch <= 0.105 and report.compression <= 0.105, (report.stretch, report.compression)
    assert min(closest) >= 0.9 * 0.004, closest
