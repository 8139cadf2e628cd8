"""Writes the built-in `tablecloth` scene's meshes into a folder:

    python tools/make_scene_meshes.py scenes

- tablecloth.obj: a flat disc of 1.2 m radius made of nearly equilateral triangles in 12 rings (ring k has
  6 k vertices at radius k / 12 of the disc's), in the XZ plane facing +Y, with UVs from its plan view;
- table.obj: a closed round table, a cylinder of 0.6 m radius from the floor to 0.9 m in 48 sides (quads),
  its top and bottom fans of triangles, every face outward;
- turntable.usda: a USD shot at 24 fps, Y-up, in metres: the same kind of cylinder, 0.8 m in radius and
  0.6 m high, under an Xform keyed to turn once about +Y from frame 0 to frame 96;
- cape.usda: a USD shot at 24 fps, Y-up, in metres: a character's body (a closed elliptic cylinder from
  the hips to the shoulders, 0.4 x 0.24 m across) under an Xform keyed to walk 1.6 m along -Z in 2 s
  (speeding up over the first half second, slowing down over the last), then turn a quarter turn left in
  the next 2 s (likewise); behind its back a cape, a 0.56 x 0.9 m quad mesh of
  20 x 30 cells with UVs, whose top row is the point subset "collar";
- garment.usda: a USD shot at 24 fps, Y-up, in metres: a torso (a closed elliptic cylinder from 0.5 m to
  1.4 m, 0.34 x 0.24 m across) under an Xform keyed to stand still for the first second (while the seams
  close), then turn 30 degrees left, 30 degrees right and back; around it a skirt's two panels, front and
  back, quad meshes of 16 x 16 cells with UVs, each curved round half the torso: the waist row 1 cm off the
  body, meeting the other panel's at the sides, the rows below flaring out to 6 cm off it and narrowing to
  150 degrees of the 180 each covers, so that the sides stand open to a hem's gap of a 30-degree arc.
  Each panel's side edges are the point subsets "side_left" and "side_right" (the body's left, +X, and
  right: it faces +Z).
- drape_specimen.obj and drape_support.obj: the Cusick drape test's specimen (30 cells across) and support
  disc, as warp_cloth/drape_geometry.py makes them (warp-cloth drape-test makes the specimen again at the
  resolution it is asked for).
"""

import argparse
import math


def disc(radius: float, rings: int) -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    points = [(0.0, 0.0, 0.0)]
    first = [0]  # index of each ring's first vertex
    for k in range(1, rings + 1):
        first.append(len(points))
        r = radius * k / rings
        points += [(r * math.cos(2 * math.pi * i / (6 * k)), 0.0, -r * math.sin(2 * math.pi * i / (6 * k)))
                   for i in range(6 * k)]
    faces = []
    for k in range(1, rings + 1):
        inner_count, outer_count = max(6 * (k - 1), 1), 6 * k
        inner, outer = first[k - 1], first[k]
        # Walk both rings around together, always advancing the one that is behind in angle.
        i = j = 0
        while i < inner_count or j < outer_count:
            a = inner + i % inner_count
            b = outer + j % outer_count
            advance_outer = i >= inner_count or (j < outer_count and (j + 1) / outer_count <= (i + 1) / inner_count)
            if k == 1 or advance_outer:
                faces.append((a, b, outer + (j + 1) % outer_count))
                j += 1
                if k == 1 and j >= outer_count:
                    break
            else:
                faces.append((a, b, inner + (i + 1) % inner_count))
                i += 1
    return points, faces


def table(radius: float, height: float, sides: int):
    """A closed cylinder on the floor: ring 0 at y = 0, ring 1 at the top, then the two caps' centres."""
    ring = [(radius * math.cos(2 * math.pi * i / sides), 0.0, -radius * math.sin(2 * math.pi * i / sides))
            for i in range(sides)]
    points = ring + [(x, height, z) for x, _, z in ring] + [(0.0, 0.0, 0.0), (0.0, height, 0.0)]
    bottom, top = 2 * sides, 2 * sides + 1
    faces = []
    for i in range(sides):
        j = (i + 1) % sides
        faces.append((i, j, sides + j, sides + i))  # counter-clockwise seen from outside
        faces.append((sides + i, sides + j, top))
        faces.append((j, i, bottom))
    return points, faces


def write_obj(path: str, title: str, points, faces, uv_radius: float | None = None) -> None:
    with open(path, "w") as out:
        out.write(f"# {title} (tools/make_scene_meshes.py)\n")
        for x, y, z in points:
            out.write(f"v {x:.6f} {y:.6f} {z:.6f}\n")
        if uv_radius is None:
            out.writelines("f " + " ".join(str(i + 1) for i in face) + "\n" for face in faces)
            return
        for x, _, z in points:
            out.write(f"vt {0.5 + x / (2 * uv_radius):.6f} {0.5 - z / (2 * uv_radius):.6f}\n")
        out.writelines("f " + " ".join(f"{i + 1}/{i + 1}" for i in face) + "\n" for face in faces)


def new_shot(path: str, documentation: str):
    """A USD stage of 96 frames at 24 fps, Y-up, in metres, with /World its default prim."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(24.0)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(96)
    stage.GetRootLayer().documentation = f"{documentation} (tools/make_scene_meshes.py)"
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    return stage


def define_mesh(stage, path: str, points, faces):
    from pxr import Gf, UsdGeom

    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    mesh.CreateFaceVertexCountsAttr([len(f) for f in faces])
    mesh.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    return mesh


def write_turntable(path: str) -> None:
    from pxr import UsdGeom

    stage = new_shot(path, "A turntable that turns once in 4 s")
    turn = UsdGeom.Xform.Define(stage, "/World/Turntable").AddRotateYOp()
    turn.Set(0.0, 0)
    turn.Set(360.0, 96)
    define_mesh(stage, "/World/Turntable/Top", *table(0.8, 0.6, 48))
    stage.GetRootLayer().Save()


def elliptic_body(half_width: float, half_depth: float, bottom: float, top: float, sides: int, rings: int):
    """A closed elliptic cylinder about +Y, its sides in ``rings`` bands of quads, capped by fans."""
    points = [(half_width * math.cos(2 * math.pi * i / sides), bottom + (top - bottom) * k / rings,
               -half_depth * math.sin(2 * math.pi * i / sides)) for k in range(rings + 1) for i in range(sides)]
    points += [(0.0, bottom, 0.0), (0.0, top, 0.0)]
    low, high = len(points) - 2, len(points) - 1
    faces = []
    for k in range(rings):
        for i in range(sides):
            j = (i + 1) % sides
            faces.append((k * sides + i, k * sides + j, (k + 1) * sides + j, (k + 1) * sides + i))
    for i in range(sides):
        j = (i + 1) % sides
        faces.append((rings * sides + i, rings * sides + j, high))
        faces.append((j, i, low))
    return points, faces


def write_cape(path: str) -> None:
    from pxr import Gf, Sdf, UsdGeom, Vt

    stage = new_shot(path, "A cape on a character that walks, then turns")
    character = UsdGeom.Xform.Define(stage, "/World/Character")
    walk, turn = character.AddTranslateOp(), character.AddRotateYOp()
    for frame, z in ((0, 0.0), (12, -0.2), (36, -1.4), (48, -1.6)):  # speeding up, walking, slowing down
        walk.Set(Gf.Vec3d(0.0, 0.0, z), frame)
    for frame, angle in ((0, 0.0), (48, 0.0), (60, 15.0), (84, 75.0), (96, 90.0)):
        turn.Set(angle, frame)
    define_mesh(stage, "/World/Character/Body", *elliptic_body(0.2, 0.12, 0.9, 1.5, 32, 6))
    columns, rows = 20, 30
    width, length, top, back = 0.56, 0.9, 1.48, 0.15
    cape = UsdGeom.Mesh.Define(stage, "/World/Cape")
    cape.CreatePointsAttr([Gf.Vec3f(width * (i / columns - 0.5), top - length * k / rows, back)
                           for k in range(rows + 1) for i in range(columns + 1)])
    cape.CreateFaceVertexCountsAttr([4] * (columns * rows))
    cape.CreateFaceVertexIndicesAttr([v for k in range(rows) for i in range(columns)
                                      for v in (k * (columns + 1) + i, (k + 1) * (columns + 1) + i,
                                                (k + 1) * (columns + 1) + i + 1, k * (columns + 1) + i + 1)])
    st = UsdGeom.PrimvarsAPI(cape).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    st.Set(Vt.Vec2fArray([Gf.Vec2f(i / columns, 1.0 - k / rows) for k in range(rows + 1) for i in range(columns + 1)]))
    UsdGeom.Subset.CreateGeomSubset(cape, "collar", UsdGeom.Tokens.point, Vt.IntArray(list(range(columns + 1))))
    stage.GetRootLayer().Save()


def skirt_panel(front: bool, half_width: float, half_depth: float, waist: float, length: float,
                columns: int, rows: int) -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int, int]]]:
    """One panel of ``columns`` x ``rows`` quads round half the elliptic torso, row 0 at the waist: a
    point of row k stands off the ellipse along its normal by 1 cm at the waist, flaring to 6 cm at the
    hem (as the square root of k / rows, so that only the waist row is within 1.5 cm of the body), and
    covers 180 degrees at the waist narrowing to 150 at the hem. Column 0 is at the body's left (+X: it
    faces +Z), on either panel."""
    points = []
    for k in range(rows + 1):
        t = k / rows
        offset = 0.01 + 0.05 * math.sqrt(t)
        half_span = math.radians(90.0 - 15.0 * t)
        for i in range(columns + 1):
            theta = half_span * (1.0 - 2.0 * i / columns)  # from the left side round to the right
            if not front:
                theta = math.pi - theta
            # the ellipse x = a cos(phi), z = b sin(phi), phi measured from +X towards +Z
            phi = math.pi / 2 - theta
            x, z = half_width * math.cos(phi), half_depth * math.sin(phi)
            nx, nz = half_depth * math.cos(phi), half_width * math.sin(phi)
            norm = math.hypot(nx, nz)
            points.append((x + offset * nx / norm, waist - length * t, z + offset * nz / norm))
    faces = [(k * (columns + 1) + i, (k + 1) * (columns + 1) + i, (k + 1) * (columns + 1) + i + 1,
              k * (columns + 1) + i + 1) for k in range(rows) for i in range(columns)]
    if front:  # outward faces: the front panel's columns run the other way round it
        faces = [tuple(reversed(f)) for f in faces]
    return points, faces


def write_garment(path: str) -> None:
    from pxr import Gf, Sdf, UsdGeom, Vt

    stage = new_shot(path, "A skirt of two panels sewn round a torso that turns")
    turn = UsdGeom.Xform.Define(stage, "/World/Character").AddRotateYOp()
    for frame, angle in ((0, 0.0), (24, 0.0), (48, 30.0), (72, -30.0), (96, 0.0)):
        turn.Set(angle, frame)
    half_width, half_depth = 0.17, 0.12
    define_mesh(stage, "/World/Character/Body", *elliptic_body(half_width, half_depth, 0.5, 1.4, 32, 6))
    columns, rows = 16, 16
    for name, front in (("Front", True), ("Back", False)):
        points, faces = skirt_panel(front, half_width, half_depth, 1.05, 0.5, columns, rows)
        panel = define_mesh(stage, f"/World/{name}", points, faces)
        st = UsdGeom.PrimvarsAPI(panel).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                      UsdGeom.Tokens.vertex)
        st.Set(Vt.Vec2fArray([Gf.Vec2f(i / columns, 1.0 - k / rows)
                              for k in range(rows + 1) for i in range(columns + 1)]))
        left = [k * (columns + 1) for k in range(rows + 1)]
        right = [k * (columns + 1) + columns for k in range(rows + 1)]
        for side, indices in (("side_left", left), ("side_right", right)):
            UsdGeom.Subset.CreateGeomSubset(panel, side, UsdGeom.Tokens.point, Vt.IntArray(indices))
    stage.GetRootLayer().Save()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder")
    args = parser.parse_args()
    points, faces = disc(1.2, 12)
    write_obj(f"{args.folder}/tablecloth.obj", "A disc of radius 1.2 m in 12 rings", points, faces, uv_radius=1.2)
    points, faces = table(0.6, 0.9, 48)
    write_obj(f"{args.folder}/table.obj", "A round table of radius 0.6 m, 0.9 m high, in 48 sides", points, faces)
    write_turntable(f"{args.folder}/turntable.usda")
    write_cape(f"{args.folder}/cape.usda")
    write_garment(f"{args.folder}/garment.usda")
    write_drape_test(args.folder)


def write_drape_test(folder: str) -> None:
    from warp_cloth import drape_geometry as geometry

    specimen = geometry.specimen()
    geometry.write_obj(f"{folder}/drape_specimen.obj", "The Cusick drape test specimen: a disc of 0.30 m in 30 cells "
                       "across (warp_cloth/drape_geometry.py)", specimen.points,
                       geometry.faces_of(specimen.face_counts, specimen.face_indices), specimen.uvs)
    points, faces = geometry.support()
    geometry.write_obj(f"{folder}/drape_support.obj", "The Cusick drape test support: a disc of 0.18 m, 1 cm thick, "
                       "its top at y = 0 (warp_cloth/drape_geometry.py)", points, faces)


if __name__ == "__main__":
    main()
