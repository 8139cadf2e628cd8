"""USD output: one stage, a Mesh per cloth with points and extent as time samples, spheres and ground.

Conventions (see DESIGN.md): ``/World`` default prim, Y up, metres, timeCodesPerSecond = fps, time code =
frame number with the initial state at 0. The stage is saved after every frame (``.usdc`` appends), so an
interrupted run keeps every finished frame.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, Vt


def prim_name(name: str) -> str:
    return Tf.MakeValidIdentifier(name)


class UsdWriter:
    def __init__(self, path: str | Path, subdivision: str = "none") -> None:
        self.path = Path(path)
        self.partial = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self.subdivision = subdivision
        self.stage: Usd.Stage | None = None
        self._points: list[Usd.Attribute] = []
        self._extents: list[Usd.Attribute] = []
        self._sphere_translates: list[Usd.Attribute] = []

    def begin(self, sim) -> None:
        self.partial.parent.mkdir(parents=True, exist_ok=True)
        if self.partial.exists():
            self.partial.unlink()
        stage = Usd.Stage.CreateNew(str(self.partial))
        self.stage = stage
        fps = sim.scene.simulation.fps
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(fps)
        stage.SetFramesPerSecond(fps)
        stage.SetStartTimeCode(sim.frame)
        stage.SetEndTimeCode(sim.frame)
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        stage.GetRootLayer().documentation = f"warp-cloth scene '{sim.scene.name}'"
        for c, cloth in enumerate(sim.scene.cloths):
            self._define_cloth(sim, c, cloth)
        moving = sim.model.spheres is not None and sim.model.spheres.moving
        for s, sphere in enumerate(sim.scene.spheres):
            prim = UsdGeom.Sphere.Define(stage, f"/World/{prim_name(sphere.name)}")
            prim.CreateRadiusAttr(sphere.radius)
            r = sphere.radius
            prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-r, -r, -r), Gf.Vec3f(r, r, r)]))
            prim.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.55, 0.6, 0.7)]))
            translate = prim.AddTranslateOp()
            if moving:
                self._sphere_translates.append(translate.GetAttr())
            else:
                translate.Set(Gf.Vec3d(*sphere.center))
        if sim.scene.ground is not None:
            self._define_ground(sim)

    def _define_cloth(self, sim, c: int, cloth) -> None:
        grid = sim.model.grids[c]
        mesh = UsdGeom.Mesh.Define(self.stage, f"/World/{prim_name(cloth.name)}")
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4] * len(grid.quads)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(grid.quads.astype(np.int32).ravel()))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark if self.subdivision == "catmullClark"
                                         else UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*cloth.color)]))
        st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                     UsdGeom.Tokens.vertex)
        st.Set(Vt.Vec2fArray.FromNumpy(grid.uvs.astype(np.float32)))
        self._points.append(mesh.CreatePointsAttr())
        self._extents.append(mesh.CreateExtentAttr())

    def _define_ground(self, sim) -> None:
        ground = sim.scene.ground
        positions = sim.model.positions
        center = (positions.min(axis=0) + positions.max(axis=0)) / 2.0
        half = ground.size / 2.0 if ground.size > 0 else float(np.ptp(positions, axis=0).max()) + 5.0
        cx, cz, y = float(center[0]), float(center[2]), ground.height
        corners = [(cx - half, y, cz - half), (cx - half, y, cz + half), (cx + half, y, cz + half),
                   (cx + half, y, cz - half)]
        mesh = UsdGeom.Mesh.Define(self.stage, "/World/ground")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in corners]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
        mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(cx - half, y, cz - half), Gf.Vec3f(cx + half, y, cz + half)]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.35, 0.35, 0.33)]))

    def write_frame(self, sim, frame: int) -> None:
        code = Usd.TimeCode(frame)
        positions = sim.positions()
        for c in range(len(sim.scene.cloths)):
            points = np.ascontiguousarray(sim.cloth_positions(c, positions), dtype=np.float32)
            self._points[c].Set(Vt.Vec3fArray.FromNumpy(points), code)
            lo, hi = points.min(axis=0), points.max(axis=0)
            self._extents[c].Set(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]), code)
        if self._sphere_translates:
            for attr, center in zip(self._sphere_translates, sim.sphere_centers().tolist()):
                attr.Set(Gf.Vec3d(*center), code)
        self.stage.SetEndTimeCode(frame)
        self.stage.Save()

    def finish(self, sim, frames_written: int) -> None:
        if self.stage is None:
            return
        self.stage.Save()
        self.stage = None
        os.replace(self.partial, self.path)

    @property
    def outputs(self) -> list[Path]:
        return [self.path]
