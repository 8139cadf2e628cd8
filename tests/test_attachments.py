"""Long-range attachments: each particle of a pinned, limited cloth stays within (1 + stretch) times its
rest distance from its nearest pin, which holds a hanging cloth's length at any resolution."""

import dataclasses

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
from conftest import spring_strains
from warp_cloth.lab.bench import matrix_scene
from warp_cloth.lab.bench_meshes import as_mesh_cloth
from warp_cloth.model import _nearest_on_grid
from warp_cloth.lab.newton_compare import grid_strain
from warp_cloth.kernels.wrapping import way_around_sphere
from warp_cloth.spring_paths import nearest_along_edges


def with_attachments(scene: wc.Scene, on: bool) -> wc.Scene:
    cloths = tuple(dataclasses.replace(c, limit=dataclasses.replace(c.limit, attachments=on)) for c in scene.cloths)
    return dataclasses.replace(scene, cloths=cloths)


@pytest.mark.parametrize("seed", range(4))
def test_nearest_pin_on_grid_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    nx, ny, dx, dy = 17, 11, 0.3, 0.7
    gx, gy = np.arange((nx + 1) * (ny + 1)) % (nx + 1), np.arange((nx + 1) * (ny + 1)) // (nx + 1)
    pins = rng.choice(len(gx), size=rng.integers(1, 30), replace=False)
    nearest, distance = _nearest_on_grid(gx, gy, gx[pins], gy[pins], dx, dy)
    all_d = np.hypot((gx[:, None] - gx[pins][None]) * dx, (gy[:, None] - gy[pins][None]) * dy)
    np.testing.assert_allclose(distance, all_d.min(axis=1), rtol=1e-12)
    np.testing.assert_allclose(all_d[np.arange(len(gx)), nearest], all_d.min(axis=1), rtol=1e-12)


def test_hanging_cloth_stays_within_reach_of_its_pins():
    # The speed matrix's 64 x 64 cloth: soft springs and two limit passes a substep. Without attachments
    # its top rows stretch ~19 % (the limit passes a pull on one row per pass); with them every particle
    # stays within 1.1 times its rest distance from its pin, and no edge stretches much past 10 %.
    n = 64
    strains = {}
    for on in (True, False):
        sim = wc.Simulator(with_attachments(matrix_scene("hanging", n, "symplectic"), on), device="cpu")
        sim.run(48)
        x = sim.positions()
        strains[on] = grid_strain(x, n)[0]
        if on:
            limits = sim.model.limits
            attached = limits.attachment_pin >= 0
            reach = np.linalg.norm(x[attached] - x[limits.attachment_pin[attached]], axis=1)
            assert (reach <= limits.attachment_length[attached] * (1 + 1e-5)).all()
            # the pull reaches the bottom: the cloth hangs at nearly its full allowed length
            assert x[:, 1].min() < -0.9
    assert strains[True] <= 0.105
    assert strains[False] > 0.15


def test_attachments_go_to_the_nearest_pin_of_the_same_cloth_only():
    cloth = wc.Cloth(resolution=(4, 4), size=(4.0, 4.0), limit=wc.Limit(attachments=True),
                     pins=(wc.Pin(corners=("top-left",)),))
    other = dataclasses.replace(cloth, name="other", origin=(10.0, 0.0, 0.0), pins=(wc.Pin(corners=("top-right",)),))
    model = wc.Simulator(wc.Scene(cloths=(cloth, other)), device="cpu").model
    pin, length = model.limits.attachment_pin, model.limits.attachment_length
    top_left, top_right = 4 * 5, 4 * 5 + 4
    assert pin[top_left] == -1 and pin[25 + top_right] == -1
    assert pin[0] == top_left and length[0] == pytest.approx(1.1 * 4.0)  # bottom-left, 4 m below its pin
    assert pin[25 + 0] == 25 + top_right and length[25] == pytest.approx(1.1 * np.hypot(4.0, 4.0))
    assert set(pin[:25][pin[:25] >= 0]) == {top_left} and set(pin[25:][pin[25:] >= 0]) == {25 + top_right}


def test_without_pins_or_with_attachments_off_nothing_is_allocated():
    free = wc.Simulator(wc.Scene(cloths=(wc.Cloth(resolution=(3, 3), limit=wc.Limit(attachments=True)),)),
                        device="cpu")
    assert free.model.limits.attachment_pin.shape == (0,) and free.device_model.attachments is None
    pinned = wc.Simulator(wc.load_scene("hanging"), device="cpu")  # off by default
    assert pinned.model.pins is not None and pinned.model.limits.attachment_pin.shape == (0,)
    assert pinned.device_model.attachments is None and "attachments" not in str(pinned.plan)


def test_the_plan_shows_the_limit_passes_that_hold_to_the_pins():
    sim = wc.Simulator(with_attachments(wc.load_scene("hanging"), True), device="cpu")
    assert sim.device_model.attachments is not None
    iteration = [line.strip() for line in str(sim.plan).splitlines()]
    start = iteration.index("each iteration:")
    assert iteration[start + 1:start + 3] == ["limits+attachments", "limits+attachments"]


def shortest_paths_by_relaxation(n, pairs, lengths, sources):
    """Bellman-Ford: every edge relaxed until nothing changes (the reference for the banded Dijkstra)."""
    distance = np.full(n, np.inf)
    distance[sources] = 0.0
    while True:
        through = np.concatenate([distance[pairs[:, 0]] + lengths, distance[pairs[:, 1]] + lengths])
        ends = np.concatenate([pairs[:, 1], pairs[:, 0]])
        relaxed = distance.copy()
        np.minimum.at(relaxed, ends, through)
        if np.array_equal(relaxed, distance):
            return distance
        distance = relaxed


@pytest.mark.parametrize("seed", range(6))
def test_paths_along_edges_are_the_shortest(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 200))
    pairs = rng.integers(0, n, (int(rng.integers(n, 4 * n)), 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    lengths = rng.uniform(0.05, 2.0, len(pairs))
    sources = rng.choice(n, int(rng.integers(1, 5)), replace=False)
    nearest, distance = nearest_along_edges(n, pairs, lengths, sources)
    expected = shortest_paths_by_relaxation(n, pairs, lengths, sources)
    np.testing.assert_allclose(distance, expected, rtol=1e-12)
    reached = np.isfinite(expected)
    assert np.isin(nearest[reached], sources).all() and (nearest[~reached] == -1).all()
    for s in sources:  # the source named is one at that distance
        alone = shortest_paths_by_relaxation(n, pairs, lengths, [s])
        np.testing.assert_allclose(alone[reached & (nearest == s)], distance[reached & (nearest == s)], rtol=1e-12)


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
@pytest.mark.parametrize("triangles", [False, True], ids=["quads", "triangles"])
def test_a_mesh_cloth_is_attached_along_its_edges_and_hangs_within_its_limit(triangles, device):
    # The matrix's hanging cloth read back from an OBJ, its limit solved to tolerance: each particle is
    # attached to its nearest pin with the shortest path along the mesh's edges, at least the grid's
    # straight distance and at most the longest detour a path of the mesh's edges makes (8.2% along quads
    # and both their diagonals, at 22.5 degrees; a factor sqrt(2) across triangles' diagonals, which all
    # run one way); it hangs within reach of its pins, every limited edge within its limit. The quads are
    # the grid's cloth and hang as it does; the triangles lack one diagonal's springs and shear further.
    n = 48
    grid_scene = matrix_scene("hanging", n, "symplectic")
    grid_scene = dataclasses.replace(grid_scene,
                                     simulation=dataclasses.replace(grid_scene.simulation, limit_solve="converged"))
    mesh_scene = as_mesh_cloth(grid_scene, triangles=triangles)
    grid, mesh = (wc.Simulator(s, device=device) for s in (grid_scene, mesh_scene))
    for sim in (grid, mesh):
        sim.run(24)
    g, m = grid.model.limits, mesh.model.limits
    attached = g.attachment_pin >= 0
    np.testing.assert_array_equal(attached, m.attachment_pin >= 0)
    ratio = m.attachment_length[attached] / g.attachment_length[attached]
    assert ratio.min() >= 1 - 1e-6
    assert ratio.max() <= (1.0824 if not triangles else np.sqrt(2.0)) + 1e-6
    x = mesh.positions()
    reach = np.linalg.norm(x[attached] - x[m.attachment_pin[attached]], axis=1)
    tolerance = mesh.scene.simulation.limit_tolerance  # of each allowed length, attachments' too
    assert (reach <= m.attachment_length[attached] * (1 + tolerance)).all()
    limited = np.isfinite(mesh.model.springs.limit_max)
    assert np.abs(spring_strains(mesh)[limited]).max() <= 0.1 + tolerance * 1.1
    assert mesh.solver_stats().limit_residual <= 1.0  # every solve ended within it
    lowest = x[:, 1].min()
    assert lowest >= 10.0 - 10.0 * 1.1 * 1.005
    if not triangles:
        assert lowest == pytest.approx(grid.positions()[:, 1].min(), abs=1e-3)


def way_around_circle(a, p, c, r, samples=4001):
    """The shortest way from a to p outside the ball (c, r), found by brute force in the plane of the three:
    over every pair of points on the great circle, each seen from its end (the straight piece to it leaves
    the ball outward), the two straight pieces and the arc between them; or the straight line if it misses."""
    a, p, c = (np.asarray(v, dtype=np.float64) for v in (a, p, c))
    straight = np.linalg.norm(p - a)
    t = np.clip(np.dot(c - a, p - a) / straight**2, 0.0, 1.0)
    if np.linalg.norm(a + t * (p - a) - c) >= r:
        return straight
    e1 = (a - c) / np.linalg.norm(a - c)
    e2 = (p - c) - np.dot(p - c, e1) * e1
    e2 = e2 / np.linalg.norm(e2)
    angles = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    points = c + r * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)

    def seen(end):
        return np.einsum("ij,ij->i", points - c, end - points) >= -1e-12

    from_a, to_p = seen(a), seen(p)
    arc = np.abs(angles[:, None] - angles[None, :])
    arc = r * np.minimum(arc, 2 * np.pi - arc)
    total = np.linalg.norm(points - a, axis=1)[:, None] + arc + np.linalg.norm(points - p, axis=1)[None, :]
    total[~from_a, :] = np.inf
    total[:, ~to_p] = np.inf
    return total.min()


@wp.kernel
def ways_around(a: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3), centre: wp.vec3, radius: float,
                length: wp.array(dtype=float), direction: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    d, towards = way_around_sphere(a[i], p[i], centre, radius)
    length[i] = d
    direction[i] = towards


def kernel_ways_around(a, p, centre, radius):
    n = len(a)
    length, direction = wp.zeros(n, dtype=float, device="cpu"), wp.zeros(n, dtype=wp.vec3, device="cpu")
    wp.launch(ways_around, dim=n, inputs=[wp.array(a, dtype=wp.vec3, device="cpu"),
                                          wp.array(p, dtype=wp.vec3, device="cpu"), wp.vec3(*centre), radius],
              outputs=[length, direction], device="cpu")
    return length.numpy().astype(np.float64), direction.numpy().astype(np.float64)


def test_the_way_around_a_sphere_is_the_shortest_and_grows_along_its_direction():
    rng = np.random.default_rng(3)
    centre, radius = np.array([0.5, -1.0, 2.0]), 1.5
    a = centre + rng.normal(size=(40, 3)) * 2.5
    p = centre + rng.normal(size=(40, 3)) * 2.5
    outside = (np.linalg.norm(a - centre, axis=1) > radius * 1.05) & (np.linalg.norm(p - centre, axis=1) > radius * 1.05)
    a, p = a[outside], p[outside]
    length, direction = kernel_ways_around(a, p, centre, radius)
    reference = np.array([way_around_circle(ai, pi, centre, radius) for ai, pi in zip(a, p)])
    wrapped = reference > np.linalg.norm(p - a, axis=1) + 1e-6
    assert 5 <= wrapped.sum() < len(a)  # both kinds of pair are tested
    np.testing.assert_allclose(length, reference, rtol=2e-4)  # the brute force's angle step: 1.6e-3 rad
    # the direction is the gradient of the length as p moves (central differences of the brute force)
    for i in np.nonzero(wrapped)[0][:3]:
        step = 1e-3
        gradient = [(way_around_circle(a[i], p[i] + step * e, centre, radius)
                     - way_around_circle(a[i], p[i] - step * e, centre, radius)) / (2 * step) for e in np.eye(3)]
        np.testing.assert_allclose(direction[i], gradient, atol=5e-3)
    # an end inside the sphere: the straight distance
    length, _ = kernel_ways_around(centre[None] + 0.5, p[:1], centre, radius)
    np.testing.assert_allclose(length, np.linalg.norm(p[:1] - (centre + 0.5), axis=1), rtol=1e-6)


def test_attachments_hold_the_cloth_below_a_sphere_around_it():
    # The speed matrix's sphere cloth swings onto the sphere, which pokes through the plane it hangs in: the
    # straight lines from the pinned top edge to the rows below the sphere run through it. Each attachment
    # is held around the sphere instead (shrunk by a spring's chord, through which the cloth's path cannot
    # cut), so the rows below hang within reach of their pins along the way over it.
    n = 64
    sim = wc.Simulator(matrix_scene("sphere", n, "symplectic"), device="cpu")
    limits = sim.model.limits
    attached = limits.attachment_pin >= 0
    pins, reach = limits.attachment_pin[attached], limits.attachment_length[attached].astype(np.float64)
    sphere = sim.scene.spheres[0]
    chord_half = 0.5 * float(limits.max_length.max())
    shrunk = np.sqrt(sphere.radius**2 - chord_half**2)
    held_only_around = 0
    for _ in range(12):
        sim.run(5)
        x = sim.positions().astype(np.float64)
        straight = np.linalg.norm(x[attached] - x[pins], axis=1)
        around, _ = kernel_ways_around(x[pins], x[attached], sphere.center, shrunk)
        assert (around <= reach * (1 + 1e-4)).all()
        held_only_around = max(held_only_around, int(((around > 0.999 * reach) & (straight < 0.99 * reach)).sum()))
    assert held_only_around > n  # more than a row of particles hangs taut from its pin over the sphere
