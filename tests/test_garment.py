"""The built-in `garment` scene: a skirt's two panels sewn round a torso that turns (scenes/garment.toml,
its shot scenes/garment.usda). Over its first 36 frames (the seams shut by frame 12, the body turning from
frame 24): the seams stay shut, no particle is inside the body, no two triangles cross, and every edge is
within its 10% limit, solved to the limit solve's tolerance."""

from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_cloth as wc
from warp_cloth.diagnostics import TriangleIntersections

SHOT = Path(__file__).resolve().parent.parent / "scenes" / "garment.usda"
FRAMES = 36


class ConvexBody:
    """The shot's body, a convex closed mesh: a point's signed distance to it at a time code is the largest of
    its distances above the faces' planes (exact inside, where it is negative; a lower bound outside)."""

    def __init__(self, shot: Path, prim: str = "/World/Character/Body") -> None:
        self.stage = Usd.Stage.Open(str(shot))  # kept: a prim does not keep its stage open
        self.prim = self.stage.GetPrimAtPath(prim)
        mesh = UsdGeom.Mesh(self.prim)
        points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
        counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
        indices = np.array(mesh.GetFaceVertexIndicesAttr().Get())
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        a, b, c = (points[indices[starts + k]] for k in range(3))
        normals = np.cross(b - a, c - a)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        inward = np.einsum("ij,ij->i", normals, points.mean(axis=0) - a) > 0
        self.normals = np.where(inward[:, None], -normals, normals)
        self.offsets = np.einsum("ij,ij->i", self.normals, a)

    def signed_distance(self, world_points: np.ndarray, time_code: float) -> np.ndarray:
        to_world = np.array(UsdGeom.Xformable(self.prim).ComputeLocalToWorldTransform(Usd.TimeCode(time_code)))
        local = (np.c_[world_points, np.ones(len(world_points))] @ np.linalg.inv(to_world))[:, :3]
        return (local @ self.normals.T - self.offsets).max(axis=1)


def measure(frames: int, device: str = "cpu") -> tuple[list[dict], float, wc.Simulator]:
    """Each frame's largest seam gap, closest particle to the body, crossing triangle pairs and worst strain;
    the contact distance; the simulator after ``frames`` frames."""
    sim = wc.Simulator(wc.load_scene("garment"), device=device)
    body, crossings = ConvexBody(SHOT), TriangleIntersections(sim)
    pairs, edges, rest = sim.model.sewn.pairs, sim.model.edges, sim.model.edge_rest
    measured = []
    for frame in range(1, frames + 1):
        sim.step()
        x = sim.positions().astype(np.float64)
        strain = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) / rest - 1.0
        measured.append({"frame": frame, "seam_gap": float(np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1).max()),
                         "body_distance": float(body.signed_distance(x, frame).min()),
                         "crossings": crossings(sim), "stretch": float(strain.max()),
                         "compression": float(-strain.min())})
    contact = sim.scene.collision.separation * float(sim.model.contacts.radius.max())
    return measured, contact, sim


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.cuda)])
def test_garment_seams_shut_outside_the_body_without_crossings_within_its_limit(device):
    measured, contact, sim = measure(FRAMES, device)
    close_frame = round(0.5 * sim.scene.simulation.fps)  # the seams' default close_time, 0.5 s
    tolerance = sim.scene.simulation.limit_tolerance
    for m in measured:
        if m["frame"] >= close_frame:
            # held as one by the limit solve, within its tolerance of the cloths' shortest edge (measured:
            # under 0.1 um), far under the contact distance (2.8 cm) the contacts would otherwise hold it at
            assert m["seam_gap"] < contact / 100, m
        # the collider keeps the cloth its thickness (5 mm) off the body (measured: 4.95 mm at the closest),
        # a margin larger than any solve's tolerance or float32's rounding: no tolerance needed
        assert m["body_distance"] >= 0.0, m
        assert m["crossings"] == 0, m
        limit = sim.scene.cloths[0].limit  # both panels' (10%)
        assert m["stretch"] <= (1 + limit.stretch) * (1 + tolerance) - 1 + 1e-6, m
        assert m["compression"] <= 1 - (1 - limit.compression) * (1 - tolerance) + 1e-6, m
    assert measured[0]["seam_gap"] > 0.02  # pulled shut over close_time, not snapped
    stats = sim.solver_stats(since_start=True)
    assert stats.limit_residual <= tolerance
