"""USD output: one stage, a Mesh per cloth with points and extent as time samples, spheres and ground.

Conventions (see DESIGN.md): ``/World`` default prim, Y up, metres, timeCodesPerSecond = fps, time code =
frame number on the shot's clock (``warp_cloth.shot_clock``): the first written frame, at the stage's start
time code, is the clock's start (0 for a scene of no shot), mesh colliders keep their shot's time codes.

The run writes a binary stage under a staging name beside the output (see ``warp_cloth.output``) and saves
it when the simulator syncs its writers (every few seconds, with a checkpoint), not after every frame: each
save of a ``.usdc`` appends the whole structure again. A completed run exports the stage once, compact,
to the output's own format (``.usda`` too) and moves it into place.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, Vt

from .. import output
from ..errors import SceneError
from ..output import (INCOMPLETE, OutputError, RunOutcome, StagedOutput, check_file_output, first_free, fsync_path,
                      labelled)
from .shot_layer import GROUND_PATH, layer_path, prim_paths, shot_files, write_shot_layer

USD_SUFFIXES = (".usd", ".usda", ".usdc")
COLLIDER_COLOR = (0.55, 0.6, 0.7)  # display colour of spheres and mesh colliders
ROLE_KEY = "warpCloth:role"  # customData of each prim written: "cloth", "collider" or "ground" (for previews)
# A save appends the new samples and the whole structure again: small, but with every sample's time.
SAVE_MARGIN_BYTES = 64 * 1024
BYTES_PER_SAMPLE_TIME = 16
# Frames are saved early where they would take more than this fraction of the free space.
EARLY_SAVE_FRACTION = 1 / 8


class UsdWriter(StagedOutput):
    """Writes ``path`` (.usd, .usda or .usdc). ``resume``: go on with the frames of an earlier run of the same
    scene, found under the staging name, from the simulator's frame (see ``Simulator.restore``)."""

    key = "usd"
    kind = "file"
    suffix = ".usdc"

    def __init__(self, path: str | Path, subdivision: str = "none", resume: bool = False) -> None:
        self.path = Path(path)
        check_file_output(self.path, USD_SUFFIXES, "usd")
        super().__init__(self.path, labelled(self.path, INCOMPLETE, self.suffix), resume)
        self.subdivision = subdivision
        self.saved_through = -1  # the last frame the file on disk holds
        self.stage: Usd.Stage | None = None
        self._last_frame = -1
        self._pending_bytes = 0
        self._points: list[Usd.Attribute] = []
        self._extents: list[Usd.Attribute] = []
        self._sphere_translates: list[Usd.Attribute] = []
        self.layer: Path | None = None  # the shot layer, once a completed run with meshes from USD wrote it

    def _names_made(self) -> list[str]:
        layer = layer_path(self.path)
        return [*super()._names_made(), layer.name, labelled(layer, "exporting", layer.suffix).name]

    def _copy_to_staging(self, location: Path) -> None:
        if not Sdf.Layer.FindOrOpen(str(location)).Export(str(self.staging)):
            raise OutputError(f"could not copy {location} to {self.staging}")

    def begin(self, sim) -> None:
        self.prepare()
        if self.resume:
            self._reopen(sim)
            return
        stage = Usd.Stage.CreateNew(str(self.staging))
        self.stage = stage
        fps = sim.scene.simulation.fps
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(fps)
        stage.SetFramesPerSecond(fps)
        stage.SetStartTimeCode(sim.clock.start)
        stage.SetEndTimeCode(sim.clock.start)
        self._last_frame = self.saved_through = sim.clock.start - 1
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        stage.GetRootLayer().documentation = f"warp-cloth scene '{sim.scene.name}'"
        paths = prim_paths(sim.scene)
        for c, cloth in enumerate(sim.scene.cloths):
            self._define_cloth(sim, c, cloth, paths.cloths[c])
        moving = sim.model.spheres is not None and sim.model.spheres.moving
        for sphere, path in zip(sim.scene.spheres, paths.spheres):
            prim = UsdGeom.Sphere.Define(stage, _with_parents(stage, path))
            prim.CreateRadiusAttr(sphere.radius)
            r = sphere.radius
            prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-r, -r, -r), Gf.Vec3f(r, r, r)]))
            prim.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*COLLIDER_COLOR)]))
            prim.GetPrim().SetCustomDataByKey(ROLE_KEY, "collider")
            translate = prim.AddTranslateOp()
            if moving:
                self._sphere_translates.append(translate.GetAttr())
            else:
                translate.Set(Gf.Vec3d(*sphere.center))
        for k, collider in enumerate(sim.scene.colliders):
            self._define_mesh_collider(collider, paths.colliders[k], sim.model.mesh_colliders.key_times[k],
                                       sim.model.mesh_colliders.key_points[k])
        if sim.scene.ground is not None:
            self._define_ground(sim)
        self._save()

    def _reopen(self, sim) -> None:
        """The staging stage of the run being resumed, cut back to the simulator's frame."""
        if not self.staging.exists():
            raise SceneError("usd", f"the frames of the run to resume in {self.staging}", has_got=False)
        self.stage = stage = Usd.Stage.Open(str(self.staging))
        paths = prim_paths(sim.scene)
        self._points = [stage.GetPrimAtPath(path).GetAttribute("points") for path in paths.cloths]
        self._extents = [stage.GetPrimAtPath(path).GetAttribute("extent") for path in paths.cloths]
        if sim.model.spheres is not None and sim.model.spheres.moving:
            self._sphere_translates = [UsdGeom.Sphere(stage.GetPrimAtPath(path)).GetOrderedXformOps()[0].GetAttr()
                                       for path in paths.spheres]
        # a checkpoint in the preroll comes before any frame written
        written = sim.frame if sim.clock.writes(sim.frame) else sim.clock.start - 1
        last = max(self._points[0].GetTimeSamples(), default=sim.clock.start - 1)
        if last < written:
            raise SceneError("usd", f"frames up to the checkpoint's frame {sim.frame} in {self.staging}",
                             f"frames up to {last:g}")
        for attr in self._points + self._extents + self._sphere_translates:
            for t in attr.GetTimeSamples():
                if t > written:
                    attr.ClearAtTime(t)
        stage.SetEndTimeCode(max(written, sim.clock.start))
        self._last_frame = self.saved_through = written
        self._save()

    def _define_cloth(self, sim, c: int, cloth, path: str) -> None:
        faces = sim.model.cloths[c]
        mesh = UsdGeom.Mesh.Define(self.stage, _with_parents(self.stage, path))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(faces.face_counts.astype(np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.face_indices.astype(np.int32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark if self.subdivision == "catmullClark"
                                         else UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*cloth.color)]))
        mesh.GetPrim().SetCustomDataByKey(ROLE_KEY, "cloth")
        if faces.uvs is not None:
            per_corner = len(faces.uvs) == len(faces.face_indices)  # a grid's are per particle
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                "st", Sdf.ValueTypeNames.TexCoord2fArray,
                UsdGeom.Tokens.faceVarying if per_corner else UsdGeom.Tokens.vertex)
            st.Set(Vt.Vec2fArray.FromNumpy(faces.uvs.astype(np.float32)))
        self._points.append(mesh.CreatePointsAttr())
        self._extents.append(mesh.CreateExtentAttr())

    def _define_mesh_collider(self, collider, path: str, key_times, key_points) -> None:
        """A mesh collider: world-space points (sampled where it moves), its faces."""
        surface = collider.surface()
        mesh = UsdGeom.Mesh.Define(self.stage, _with_parents(self.stage, path))
        points = surface.points.astype(np.float32)
        attr = mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
        if key_points is not None:  # animated: its samples, at the frames of their times
            fps = self.stage.GetFramesPerSecond()
            for t, keyed in zip(key_times, key_points.astype(np.float32)):
                attr.Set(Vt.Vec3fArray.FromNumpy(keyed), Usd.TimeCode(t * fps))
            points = key_points.reshape(-1, 3).astype(np.float32)
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(surface.face_counts.astype(np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(surface.face_indices.astype(np.int32)))
        mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*points.min(axis=0).tolist()),
                                             Gf.Vec3f(*points.max(axis=0).tolist())]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*COLLIDER_COLOR)]))
        mesh.GetPrim().SetCustomDataByKey(ROLE_KEY, "collider")

    def _define_ground(self, sim) -> None:
        ground = sim.scene.ground
        positions = sim.model.positions
        center = (positions.min(axis=0) + positions.max(axis=0)) / 2.0
        half = ground.size / 2.0 if ground.size > 0 else float(np.ptp(positions, axis=0).max()) + 5.0
        cx, cz, y = float(center[0]), float(center[2]), ground.height
        corners = [(cx - half, y, cz - half), (cx - half, y, cz + half), (cx + half, y, cz + half),
                   (cx + half, y, cz - half)]
        mesh = UsdGeom.Mesh.Define(self.stage, GROUND_PATH)
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in corners]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
        mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(cx - half, y, cz - half), Gf.Vec3f(cx + half, y, cz + half)]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.35, 0.35, 0.33)]))
        mesh.GetPrim().SetCustomDataByKey(ROLE_KEY, "ground")

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
        self._last_frame = frame
        self._pending_bytes += positions.nbytes + 32 * (len(sim.scene.cloths) + len(sim.scene.spheres))
        if self._pending_bytes > EARLY_SAVE_FRACTION * output.free_bytes(self.staging.parent):
            self._save()  # the disk is filling up: keep what fits now

    def sync(self, sim) -> None:
        """Save the frames so far (a killed run keeps them, with the checkpoint saved alongside)."""
        self._save()

    def _save(self) -> None:
        # A save that runs out of space leaves the crate file unreadable (and the stage unusable), so it is
        # checked first; where the frames so far do not all fit, those that do are saved.
        pending = self._last_frame - self.saved_through
        free = output.free_bytes(self.staging.parent)
        attributes = len(self._points) + len(self._extents) + len(self._sphere_translates)
        samples = max(0, self._last_frame + 1 - int(self.stage.GetStartTimeCode()))
        margin = SAVE_MARGIN_BYTES + BYTES_PER_SAMPLE_TIME * attributes * samples
        shortfall = 2 * self._pending_bytes + margin - free
        if shortfall > 0:
            fit = max(0, (free - margin) // max(1, 2 * self._pending_bytes // max(1, pending)))
            self._drop_frames_after(self.saved_through + min(pending, fit))
            if fit > 0:
                self._write()
            raise OutputError(f"not enough free space in {self.staging.parent} to save {self.staging}: about "
                              f"{output.describe_size(shortfall)} more needed")
        self._write()

    def _drop_frames_after(self, last: int) -> None:
        for attr in self._points + self._extents + self._sphere_translates:
            for t in attr.GetTimeSamples():
                if t > last:
                    attr.ClearAtTime(t)
        self.stage.SetEndTimeCode(max(last, self.stage.GetStartTimeCode()))
        self._last_frame = last
        self._pending_bytes = 0

    def _write(self) -> None:
        try:
            self.stage.Save()
        except Tf.ErrorException as exc:
            self.stage = None
            raise OutputError(f"could not save {self.staging}: {str(exc).strip().splitlines()[-1]}") from None
        fsync_path(self.staging)
        self.saved_through = self._last_frame
        self._pending_bytes = 0

    def finish(self, sim, frames_written: int) -> None:
        """Save, export compactly in the output's format and put the result in place."""
        self._save()
        size = os.path.getsize(self.staging)
        text = self.path.suffix.lower() == ".usda"
        exported = labelled(self.path, "exporting", self.path.suffix)
        if output.free_bytes(self.path.parent) < (4 if text else 1) * size + SAVE_MARGIN_BYTES:
            if text:
                raise OutputError(f"not enough free space in {self.path.parent} to write {self.path} "
                                  f"(about {output.describe_size(4 * size)} of text)")
            exported = self.staging  # already binary: put in place as it is
        else:
            try:
                if not self.stage.GetRootLayer().Export(str(exported)):
                    raise OutputError(f"could not write {exported}")
            except Tf.ErrorException as exc:
                exported.unlink(missing_ok=True)
                raise OutputError(f"could not write {exported}: {str(exc).strip().splitlines()[-1]}") from None
        layer = self._export_layer(sim)
        os.replace(exported, self.path)
        if layer is not None:
            self.layer = layer_path(self.path)
            os.replace(layer, self.layer)
        fsync_path(self.path.parent)
        if exported != self.staging:
            self.staging.unlink()
        self._end(self.path)

    def _export_layer(self, sim) -> Path | None:
        """The shot layer of a scene with meshes from USD, written under its exporting name (see
        ``shot_layer``); None for a scene without."""
        shots = shot_files(sim.scene)
        if not shots:
            return None
        exporting = labelled(layer_path(self.path), "exporting", ".usda")
        try:
            write_shot_layer(exporting, self.path, self.stage, shots, prim_paths(sim.scene).cloths,
                             (sim.clock.start, max(self._last_frame, sim.clock.start)), sim.scene.simulation.fps)
        except Tf.ErrorException as exc:
            exporting.unlink(missing_ok=True)
            raise OutputError(f"could not write {exporting}: {str(exc).strip().splitlines()[-1]}") from None
        return exporting

    def abandon(self, sim, frames_written: int, outcome: RunOutcome) -> None:
        """Keep the frames so far: in place if the run was stopped and there is nothing to replace, else
        beside the output as ``<name>.interrupted.usdc`` or ``<name>.failed.usdc``."""
        if self.stage is not None:
            try:
                self._save()
            except OutputError:
                pass  # the file keeps the frames of the last save
        if not self.staging.exists():
            self.stage = None
            self.lock.release()
            return
        if outcome.interrupted and not self.path.exists():
            try:
                self.finish(sim, frames_written)
                return
            except OutputError:
                pass
        target = first_free(self.path, outcome.label, self.suffix)
        os.replace(self.staging, target)
        self._end(target)

    def _end(self, location: Path) -> None:
        self.stage = None
        super()._end(location)

    @property
    def outputs(self) -> list[Path]:
        return [*super().outputs, *([self.layer] if self.layer is not None else [])]


def _with_parents(stage, path: str) -> str:
    """``path``, its parents defined as transforms where nothing defines them yet: a prim of a shot's path
    (/World/Character/Body) under a parent of no type is taken out of the hierarchy by Blender's importer,
    which then misses the Y-up turn that /World gives its children."""
    for parent in Sdf.Path(path).GetParentPath().GetPrefixes():
        if not stage.GetPrimAtPath(parent).IsValid():
            UsdGeom.Xform.Define(stage, parent)
    return path
