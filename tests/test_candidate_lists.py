"""Candidate lists that fill up (kernels/candidate_lists.py): a full list, the edge contacts' or the face
contacts' (a surface thickness's), keeps the nearest candidates; and the edge contacts' lists and hash hold
every candidate of a stack of layers."""

import numpy as np
import warp as wp

import warp_cloth as wc
from warp_cloth import face_contacts, passes, state
from warp_cloth.neighbour_lists import widest_reach
from warp_cloth.kernels import edge_collision, primitive_distances

QUADS = 8
HELD = 5  # entries an edge's list holds here: fewer than the candidates of most edges
THICKNESS = 0.0021  # metres: the surfaces' (a quarter of the particles' 8.4 mm contact distance)


@wp.kernel
def every_pair_gap(ends: wp.array(dtype=wp.vec2i), x: wp.array(dtype=wp.vec3), gap: wp.array2d(dtype=float)):
    e, f = wp.tid()
    gap[e, f] = edge_collision.pair_gap(ends, x, e, f)


def crossed_quads(sim: wc.Simulator, turned: bool) -> np.ndarray:
    """The one-quad cloths over each other, their corners at random heights within the edge lists' reach,
    each quad ``turned`` about a vertical axis through the middle by another angle (every edge's candidates
    are the other quads' edges it crosses, seen from above) or else moved along x by another 12 mm (most
    vertices lie over other quads' triangles), each candidate at another gap."""
    rng = np.random.default_rng(3)
    rest = sim.model.positions.reshape(QUADS, 4, 3)
    corners = rest - rest.mean(axis=1, keepdims=True)
    reach = widest_reach(sim.plan.lists.edges)
    x = np.empty_like(rest)
    for k in range(QUADS):
        turn = np.pi / 2 * k / QUADS if turned else 0.0
        c, s = np.cos(turn), np.sin(turn)
        x[k, :, 0] = c * corners[k, :, 0] - s * corners[k, :, 2] + (0.0 if turned else 0.012 * k)
        x[k, :, 2] = s * corners[k, :, 0] + c * corners[k, :, 2]
        x[k, :, 1] = rng.uniform(0.0, 0.8 * reach, 4)
    return x.reshape(-1, 3)


def crossed_quad_simulator(turned: bool) -> wc.Simulator:
    """The quads of ``crossed_quads``, their lists made there, their surfaces ``THICKNESS`` apart."""
    quads = tuple(wc.Cloth(name=f"q{k}", resolution=(1, 1), size=(0.1, 0.1), orientation="horizontal",
                           origin=(-0.05, float(k), 0.05), limit=wc.Limit()) for k in range(QUADS))
    scene = wc.Scene(name="crossed", cloths=quads,
                     collision=wc.Collision(radius=0.004, self_collision=False, thickness=THICKNESS))
    sim = wc.Simulator(scene, device="cpu", graph=False)
    sim.state.x.assign(crossed_quads(sim, turned))
    sim.plan.lists.remake_now(sim.state.x)
    return sim


def assert_nearest_kept(counts: np.ndarray, listed: np.ndarray, gap: np.ndarray, may_touch: np.ndarray,
                        reach: float) -> int:
    """Each owner's list (row) holds the ``HELD`` nearest of the entries it may touch within reach (columns
    of ``gap``); how many owners had more than that."""
    overfull = 0
    for owner in range(len(counts)):
        candidates = np.flatnonzero(may_touch[owner] & (gap[owner] < reach))
        nearest = candidates[np.argsort(gap[owner, candidates], kind="stable")][:HELD]
        assert sorted(listed[owner, :counts[owner]]) == sorted(nearest), owner
        overfull += len(candidates) > HELD
    return overfull


def test_a_full_edge_list_keeps_the_nearest_candidates(monkeypatch):
    """Eight one-quad cloths crossed over each other: an edge has up to 35 candidates within reach, its list
    holds 5, and holds the 5 nearest (by their gaps, worked out for every pair as the pass does), whatever
    order the hash finds them in."""
    monkeypatch.setattr(state, "EDGE_NEIGHBORS", HELD)
    monkeypatch.setattr(passes, "EDGE_NEIGHBORS", HELD)
    sim = crossed_quad_simulator(turned=True)
    ends = sim.device_model.contacts.edges.ends
    m = ends.shape[0]
    gap = wp.zeros((m, m), dtype=float, device="cpu")
    wp.launch(every_pair_gap, dim=(m, m), inputs=[ends, sim.state.x, gap], device="cpu")
    quad = ends.numpy()[:, 0] // 4
    overfull = assert_nearest_kept(sim.state.edges.counts.numpy(), sim.state.edges.neighbors.numpy().reshape(m, HELD),
                                   gap.numpy(), quad[:, None] != quad[None, :], widest_reach(sim.plan.lists.edges))
    assert overfull > m // 2 and sim.plan.lists.surface_dropped > 0


@wp.kernel
def every_vertex_triangle_gap(x: wp.array(dtype=wp.vec3), triangles: wp.array(dtype=wp.vec3i),
                              gap: wp.array2d(dtype=float)):
    v, t = wp.tid()
    corners = triangles[t]
    gap[v, t] = primitive_distances.point_triangle_distance(x[v], x[corners[0]], x[corners[1]], x[corners[2]])


def test_full_face_lists_keep_the_nearest_pairs(monkeypatch):
    """The quads moved over each other, with surface contacts: each vertex's list of triangles and
    each triangle's list of vertices hold 5, the 5 nearest (by the point-triangle distance)."""
    monkeypatch.setattr(face_contacts, "FACE_NEIGHBORS", HELD)
    sim = crossed_quad_simulator(turned=False)
    faces = sim.plan.faces
    n, t = sim.model.particle_count, faces.triangle_count
    gap = wp.zeros((n, t), dtype=float, device="cpu")
    wp.launch(every_vertex_triangle_gap, dim=(n, t), inputs=[sim.state.x, faces.args.triangles, gap], device="cpu")
    gap = gap.numpy()
    other_quad = (np.arange(n) // 4)[:, None] != sim.model.triangles[None, :, 0] // 4
    assert assert_nearest_kept(faces.args.vertex_counts.numpy(), faces.args.vertex_faces.numpy().reshape(n, HELD) >> 1,
                               gap, other_quad, widest_reach(faces)) >= n // 4
    assert assert_nearest_kept(faces.args.face_counts.numpy(), faces.args.face_vertices.numpy().reshape(t, HELD) >> 1,
                               gap.T, other_quad.T, widest_reach(faces)) >= t // 2

def stacked_sheets(sheets: int, n: int) -> wc.Scene:
    """``sheets`` horizontal 0.5 m sheets of n x n particles, 1 cm apart, their surfaces held ``THICKNESS``
    apart, over a sphere (tools/stacked_drape.py's case, small)."""
    cloths = tuple(wc.Cloth(name=f"sheet{k}", resolution=(n - 1, n - 1), size=(0.5, 0.5), orientation="horizontal",
                            origin=(-0.25, 0.3 + 0.01 * k, 0.25), limit=wc.Limit(0.05, 0.05),
                            pins=(wc.Pin(corners=("top-left", "top-right")),)) for k in range(sheets))
    return wc.Scene(name="stack", cloths=cloths, spheres=(wc.Sphere(name="ball", center=(0.0, 0.0, 0.0), radius=0.25),),
                    collision=wc.Collision(radius=0.004, thickness=THICKNESS),
                    simulation=wc.Simulation(fps=60.0, frames=3))


def test_a_stack_of_sheets_drops_no_edge_candidates():
    """Six sheets of 8^2 stacked: a cell of the edge hash (wider than a triangle's diagonal) holds some 12
    edges of each, 72 in all, every one of them in the hash (its buckets hold every edge, counted_hash.py),
    and the lists, at their chosen size, drop none."""
    sim = wc.Simulator(stacked_sheets(6, 8), device="cpu", graph=False)
    for _ in range(3):
        sim.step()
    edges = sim.plan.lists.edges
    assert sim.plan.lists.overflow == 0
    assert sorted(edges.hash.buckets.items.numpy()) == list(range(edges.m))
    assert edges.hash.buckets.count.numpy().max() >= 72
