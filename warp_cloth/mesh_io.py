"""Surface meshes from the user's files: OBJ, and a ``Mesh`` prim of a USD stage (.usd, .usda, .usdc).

A mesh is read into world-space metres (a USD prim's transform and the stage's ``metersPerUnit`` applied, a
Z-up stage turned Y-up as the simulation's gravity is -Y) and checked as a cloth needs it: faces of three
or four vertices, none degenerate or repeated, every edge shared by at most two faces, every point on a
face. A problem is a ``SceneError`` naming the file (and prim) and what was expected; a conversion the
reader made is one of the mesh's ``notes``, for the run to say.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import SceneError

USD_SUFFIXES = (".usd", ".usda", ".usdc")
MESH_SUFFIXES = (".obj", *USD_SUFFIXES)
SAMPLED_VERTEX_BYTES = 48  # an animated mesh's vertex at one sample: read, then placed in the world (float64)


@dataclass(frozen=True)
class SurfaceMesh:
    points: np.ndarray  # (n, 3) float64, world metres
    face_counts: np.ndarray  # (f,) int64, 3 or 4
    face_indices: np.ndarray  # (sum of face_counts,) int64, each face's vertices in order
    uvs: np.ndarray | None  # (sum of face_counts, 2) float64 per face corner, or None
    prim: str | None  # the USD prim it came from
    notes: tuple[str, ...]  # conversions made on reading (units, up axis) and handled oddities
    shortest_edge: float = float("nan")  # metres, set by the checks
    key_times: np.ndarray | None = None  # (k,) seconds at which a USD mesh's points or transforms are keyed
    key_points: np.ndarray | None = None  # (k, n, 3) its world points then (None: static)
    groups: dict[str, np.ndarray] = field(default_factory=dict)  # named vertex sets (USD subsets, primvars)

    def triangles(self) -> np.ndarray:
        """(t, 3): each face fanned from its first vertex (a quad a, b, c, d: a b c, a c d)."""
        return fan_triangles(self.face_counts, self.face_indices)


def face_starts(face_counts: np.ndarray) -> np.ndarray:
    """Where each face's vertices begin in the face index list."""
    return np.concatenate([[0], np.cumsum(face_counts)[:-1]]).astype(np.int64)


def fan_triangles(face_counts: np.ndarray, face_indices: np.ndarray) -> np.ndarray:
    starts = face_starts(face_counts)
    first = face_indices[starts]
    parts = [np.stack([first, face_indices[starts + 1], face_indices[starts + 2]], axis=1)]
    quads = starts[face_counts == 4]
    parts.append(np.stack([face_indices[quads], face_indices[quads + 2], face_indices[quads + 3]], axis=1))
    return np.concatenate(parts).astype(np.int64)


def load_mesh(file: str | Path, prim: str | None = None) -> SurfaceMesh:
    """The checked surface mesh of ``file`` (OBJ or USD; for USD, the ``Mesh`` prim at ``prim``, or the
    stage's only one). Read once per file version: a cloth asks for its mesh more than once."""
    path = Path(file)
    where = f"{path}" + (f" at {prim}" if prim else "")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise SceneError("mesh", f"a mesh file ending in one of {', '.join(MESH_SUFFIXES)}", str(path))
    try:
        stat = path.stat()
    except OSError as exc:
        raise SceneError("mesh", f"an existing, readable mesh file ({exc.strerror})", str(path)) from None
    if not path.is_file():
        raise SceneError("mesh", "a mesh file (this is not a regular file)", str(path))
    return _load_cached(str(path.absolute()), prim, stat.st_mtime_ns, stat.st_size, where)


@functools.lru_cache(maxsize=32)
def _load_cached(path: str, prim: str | None, _mtime: int, _size: int, where: str) -> SurfaceMesh:
    if path.lower().endswith(".obj"):
        if prim is not None:
            raise SceneError("mesh.prim", "no prim for an OBJ file (prims are USD's)", prim)
        mesh = _read_obj(Path(path), where)
    else:
        mesh = _read_usd(Path(path), prim, where)
    return _checked(mesh, where)


def _read_obj(path: Path, where: str) -> SurfaceMesh:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError("mesh", f"a readable UTF-8 OBJ file ({exc})", has_got=False, source=where) from None
    lines = text.splitlines()
    return _read_obj_fast(lines) or _read_obj_lines(lines, where)


def _read_obj_fast(lines: list[str]) -> SurfaceMesh | None:
    """The common OBJ, parsed in bulk: ``v x y z``, ``vt u v`` and ``f`` lines whose corners all have one
    form (``i``, ``i/t``, ``i/t/n`` or ``i//n``), positive indices in range, no comments or other statements
    but ``vn``, ``o``, ``g`` (groups), ``s``, ``usemtl``, ``mtllib``. None for anything else: the line by
    line reader then parses it, or says which line it cannot."""
    kinds: dict[str, list[str]] = {"v ": [], "vt": [], "f ": []}
    group_marks: list[tuple[int, list[str]]] = []
    for line in lines:
        head = line[:2]
        if head in kinds:
            kinds[head].append(line)
        elif head == "g " or line.rstrip() == "g":
            group_marks.append((len(kinds["f "]), line.split()[1:]))
        elif line.strip() and line.split(None, 1)[0] not in ("vn", "o", "s", "usemtl", "mtllib"):
            return None
    face_lines = kinds["f "]
    try:
        points = np.array(" ".join(line[2:] for line in kinds["v "]).split(), dtype=np.float64)
        texture = np.array(" ".join(line[3:] for line in kinds["vt"]).split(), dtype=np.float64)
        tokens = np.array(" ".join(line[2:] for line in face_lines).split())
    except ValueError:
        return None
    if len(points) != 3 * len(kinds["v "]) or len(texture) != 2 * len(kinds["vt"]) or not face_lines:
        return None
    counts = np.char.count(np.array(face_lines), " ").astype(np.int64)  # "f a b c": one space a corner
    slashes = np.char.count(tokens, "/")
    doubled = np.char.find(tokens, "//") >= 0
    if counts.sum() != len(tokens) or (slashes != slashes[0]).any() or (doubled != doubled[0]).any():
        return None
    form = int(slashes[0]), bool(doubled[0])
    try:
        fields = " ".join(tokens.tolist()).replace("//", " ").replace("/", " ").split()
        refs = np.array(fields, dtype=np.int64).reshape(len(tokens), -1)
    except ValueError:
        return None
    corners = refs[:, 0] - 1
    has_uv = form[0] >= 1 and not form[1]
    if corners.min(initial=0) < 0 or corners.max(initial=-1) >= len(kinds["v "]):
        return None
    uvs = None
    if has_uv and len(texture):
        uv_index = refs[:, 1] - 1
        if uv_index.min() < 0 or uv_index.max() >= len(kinds["vt"]):
            return None
        uvs = texture.reshape(-1, 2)[uv_index]
    return SurfaceMesh(points.reshape(-1, 3), counts, corners, uvs, None, (),
                       groups=_obj_groups(group_marks, counts, corners))


def _read_obj_lines(lines: list[str], where: str) -> SurfaceMesh:
    points: list[list[float]] = []
    texture: list[list[float]] = []
    counts: list[int] = []
    corners: list[int] = []
    corner_uvs: list[int] = []  # -1 where a corner has none
    group_marks: list[tuple[int, list[str]]] = []
    for number, line in enumerate(lines, start=1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        try:
            if words[0] == "v":
                points.append([float(w) for w in words[1:4]])
                if len(points[-1]) != 3:
                    raise ValueError("a vertex needs x y z")
            elif words[0] == "vt":
                texture.append([float(w) for w in words[1:3]] + [0.0] * max(0, 3 - len(words)))
            elif words[0] == "f":
                counts.append(len(words) - 1)
                for word in words[1:]:
                    refs = word.split("/")
                    corners.append(_obj_index(refs[0], len(points)))
                    has_uv = len(refs) > 1 and refs[1] != ""
                    corner_uvs.append(_obj_index(refs[1], len(texture)) if has_uv else -1)
            elif words[0] == "g":
                group_marks.append((len(counts), words[1:]))
            elif words[0] in ("l", "p"):
                raise ValueError("lines and points are not a surface")
        except (ValueError, IndexError) as exc:
            raise SceneError("mesh", f"OBJ statements v, vt and f (line {number}: {exc})", line.strip(),
                             source=where) from None
    uvs = None
    if texture and corner_uvs and min(corner_uvs) >= 0:
        uvs = np.asarray(texture, dtype=np.float64)[np.asarray(corner_uvs)]
    counts_array, corners_array = np.asarray(counts, dtype=np.int64), np.asarray(corners, dtype=np.int64)
    return SurfaceMesh(np.asarray(points, dtype=np.float64).reshape(-1, 3), counts_array, corners_array, uvs, None,
                       (), groups=_obj_groups(group_marks, counts_array, corners_array))


def _obj_groups(marks: list[tuple[int, list[str]]], counts: np.ndarray, corners: np.ndarray) -> dict[str, np.ndarray]:
    """The vertices of each OBJ group: ``marks`` are the ``g`` statements, each with the number of faces
    before it and the names it makes current for the faces after it (until the next)."""
    starts = np.concatenate([[0], np.cumsum(counts)])
    members: dict[str, list[np.ndarray]] = {}
    for k, (first, names) in enumerate(marks):
        last = marks[k + 1][0] if k + 1 < len(marks) else len(counts)
        for name in names:
            members.setdefault(name, []).append(corners[starts[first]:starts[last]])
    return {name: np.unique(np.concatenate(parts)) for name, parts in members.items()}


def _obj_index(word: str, count: int) -> int:
    """OBJ's 1-based index (negative: from the end) as a 0-based one."""
    index = int(word)
    resolved = index - 1 if index > 0 else count + index
    if index == 0 or not 0 <= resolved < count:
        raise ValueError(f"index {index} refers to none of the {count} defined so far")
    return resolved


def _read_usd(path: Path, prim_path: str | None, where: str) -> SurfaceMesh:
    from pxr import Usd, UsdGeom  # usd-core: imported where USD is read, as the writers do

    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises its own Tf.ErrorException for unreadable layers
        raise SceneError("mesh", f"a USD file that opens ({str(exc).strip().splitlines()[-1]})", has_got=False,
                         source=where) from None
    if prim_path is None:
        meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
        if len(meshes) != 1:
            names = ", ".join(str(p.GetPath()) for p in meshes[:5])
            raise SceneError("mesh.prim", "the path of the Mesh prim to use (the stage has "
                             + (f"{len(meshes)}: {names})" if meshes else "none)"), has_got=False, source=where)
        prim = meshes[0]
    else:
        prim = stage.GetPrimAtPath(prim_path) if prim_path.startswith("/") else Usd.Prim()
        if not prim:
            raise SceneError("mesh.prim", "the absolute path of a prim in the stage", prim_path, source=where)
        if not prim.IsA(UsdGeom.Mesh):
            raise SceneError("mesh.prim", "a Mesh prim", f"a {prim.GetTypeName() or 'typeless'} prim", source=where)
    mesh = UsdGeom.Mesh(prim)
    time = Usd.TimeCode.EarliestTime()
    local = np.asarray(mesh.GetPointsAttr().Get(time) or [], dtype=np.float64).reshape(-1, 3)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(time) or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(time) or [], dtype=np.int64)
    if counts.sum() != len(indices):
        raise SceneError("mesh", "faceVertexCounts that add up to the length of faceVertexIndices",
                         f"{int(counts.sum())} vs {len(indices)}", source=where)
    meters = UsdGeom.GetStageMetersPerUnit(stage)
    z_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z

    def world_at(time, points) -> np.ndarray:
        matrix = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
        world = (points @ matrix[:3, :3] + matrix[3, :3]) * meters  # USD's row vectors
        return world @ Z_UP_TO_Y_UP.T if z_up else world

    notes = []
    if meters != 1.0:
        notes.append(f"{where}: units of {meters:g} m converted to metres")
    if z_up:
        notes.append(f"{where}: Z-up stage turned Y-up (the simulation's gravity is -Y)")
    key_times, key_points = None, None
    codes = _animation_codes(prim, set(mesh.GetPointsAttr().GetTimeSamples()))
    if codes:
        need = len(codes) * len(local) * SAMPLED_VERTEX_BYTES
        free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        if need > free:
            raise SceneError("mesh", f"an animation that fits in memory: {len(local)} points at {len(codes)} time "
                                     f"codes need about {need / 2**30:.1f} GiB, {free / 2**30:.1f} GiB is free",
                             has_got=False, source=where)
        frames = []
        for code in codes:
            points = np.asarray(mesh.GetPointsAttr().Get(code) or [], dtype=np.float64).reshape(-1, 3)
            if len(points) != len(local):
                raise SceneError("mesh", "points that keep their number over the animation",
                                 f"{len(points)} at time code {code:g}, {len(local)} at the first", source=where)
            frames.append(world_at(Usd.TimeCode(code), points))
        key_times = np.asarray(codes, dtype=np.float64) / stage.GetTimeCodesPerSecond()
        key_points = np.stack(frames)
    return SurfaceMesh(world_at(time, local), counts, indices, _usd_uvs(mesh, counts, indices, time),
                       str(prim.GetPath()), tuple(notes), key_times=key_times, key_points=key_points,
                       groups=_usd_groups(mesh, counts, indices, len(local), time))


def _usd_groups(mesh, counts: np.ndarray, indices: np.ndarray, n: int, time) -> dict[str, np.ndarray]:
    """Named vertex sets of a USD mesh: each GeomSubset (of points, or of faces: their vertices), and each
    numeric primvar on its points (vertex or varying), the points where it is non-zero (a DCC tool's
    vertex group or weight map)."""
    from pxr import UsdGeom

    groups: dict[str, np.ndarray] = {}
    starts = face_starts(counts)
    for subset in UsdGeom.Subset.GetAllGeomSubsets(mesh):
        members = np.asarray(subset.GetIndicesAttr().Get(time) or [], dtype=np.int64)
        if subset.GetElementTypeAttr().Get() == UsdGeom.Tokens.face:
            members = members[(members >= 0) & (members < len(counts))]
            members = np.concatenate([indices[starts[f]:starts[f] + counts[f]] for f in members]) if len(members) \
                else members
        groups[subset.GetPrim().GetName()] = np.unique(members[(members >= 0) & (members < n)])
    for primvar in UsdGeom.PrimvarsAPI(mesh).GetPrimvars():
        if primvar.GetInterpolation() not in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            continue
        try:
            values = np.asarray(primvar.ComputeFlattened(time), dtype=np.float64)
        except (TypeError, ValueError):
            continue  # not numbers (names, paths)
        if values.ndim == 1 and len(values) == n:
            groups.setdefault(primvar.GetPrimvarName(), np.nonzero(values)[0])
    return groups


def _animation_codes(prim, codes: set[float]) -> list[float]:
    """The time codes to sample an animated prim at: ``codes`` (its points' keys, for a mesh) and those at
    which a transform of it or above it is keyed, and every whole one between (USD interpolates a keyed
    rotation's angle, while the simulation interpolates points linearly between samples: between keys a
    quarter turn apart, points would cut the corner by 30%, between frames by 0.06%). None for a static
    prim."""
    from pxr import UsdGeom

    codes = set(codes)
    node = prim
    while node and not node.IsPseudoRoot():
        xformable = UsdGeom.Xformable(node)
        if xformable:
            for op in xformable.GetOrderedXformOps():
                codes.update(op.GetAttr().GetTimeSamples())
        node = node.GetParent()
    if len(codes) < 2:
        return []
    first, last = min(codes), max(codes)
    codes.update(float(c) for c in range(math.ceil(first), math.floor(last) + 1))
    return sorted(codes)


Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # (x, y, z) -> (x, z, -y)


def load_transform_motion(file: str | Path, prim_path: str) -> tuple[np.ndarray, np.ndarray] | None:
    """How a USD prim's world transform moves what starts with it: (times in seconds, (k, 4, 4) matrices
    in USD's row-vector convention taking a point of the simulation's world at the stage's earliest time (where
    a mesh of the stage is read) to where the transform carries it then), sampled as an animated mesh is; None
    for a prim that does not move. Read once per file version: the scene's checks ask, then the model."""
    try:
        stat = Path(file).stat()
    except OSError:  # opening it says why, in the error's terms
        return _transform_motion(str(file), prim_path)
    return _transform_motion_cached(str(file), prim_path, str(Path(file).absolute()), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=32)
def _transform_motion_cached(file: str, prim_path: str, _absolute: str, _mtime: int, _size: int):
    return _transform_motion(file, prim_path)


def _transform_motion(file: str, prim_path: str) -> tuple[np.ndarray, np.ndarray] | None:
    from pxr import Usd, UsdGeom

    where = f"{file} at {prim_path}"
    try:
        stage = Usd.Stage.Open(str(file))
    except Exception as exc:  # pxr raises its own Tf.ErrorException for unreadable layers
        raise SceneError("target", f"a USD file that opens ({str(exc).strip().splitlines()[-1]})", has_got=False,
                         source=where) from None
    prim = stage.GetPrimAtPath(prim_path)
    if not prim or not prim.IsA(UsdGeom.Xformable):
        raise SceneError("target", "the path of a transformable prim (an Xform, a mesh) in the cloth's USD file",
                         prim_path, source=str(file))
    codes = _animation_codes(prim, set())
    if not codes:
        return None
    to_simulation = np.eye(4)
    to_simulation[:3, :3] = UsdGeom.GetStageMetersPerUnit(stage) * (
        Z_UP_TO_Y_UP.T if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z else np.eye(3))

    def world(code) -> np.ndarray:
        return np.asarray(UsdGeom.XformCache(code).GetLocalToWorldTransform(prim), dtype=np.float64)

    start = np.linalg.inv(to_simulation) @ np.linalg.inv(world(Usd.TimeCode.EarliestTime()))
    matrices = np.stack([start @ world(Usd.TimeCode(code)) @ to_simulation for code in codes])
    return np.asarray(codes, dtype=np.float64) / stage.GetTimeCodesPerSecond(), matrices


def shot_start_seconds(file: str | Path) -> float | None:
    """When the shot in a USD file starts: its stage's start time code in seconds (None where it sets none).
    Read once per file version."""
    stat = Path(file).stat()
    return _shot_start_cached(str(Path(file).absolute()), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=32)
def _shot_start_cached(path: str, _mtime: int, _size: int) -> float | None:
    from pxr import Usd

    stage = Usd.Stage.Open(path, Usd.Stage.LoadNone)
    if not stage.HasAuthoredMetadata("startTimeCode"):
        return None
    return stage.GetStartTimeCode() / stage.GetTimeCodesPerSecond()


def _usd_uvs(mesh, counts: np.ndarray, indices: np.ndarray, time) -> np.ndarray | None:
    """The ``st`` primvar per face corner, whatever its interpolation (None where the mesh has none)."""
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    if not primvar or not primvar.HasValue():
        return None
    values = np.asarray(primvar.ComputeFlattened(time), dtype=np.float64).reshape(-1, 2)
    interpolation = primvar.GetInterpolation()
    if interpolation == UsdGeom.Tokens.faceVarying and len(values) == len(indices):
        return values
    if interpolation in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying) and len(values) > indices.max(initial=-1):
        return values[indices]
    if interpolation == UsdGeom.Tokens.uniform and len(values) == len(counts):
        return np.repeat(values, counts, axis=0)
    return None  # constant or malformed: nothing a texture could use


def _checked(mesh: SurfaceMesh, where: str) -> SurfaceMesh:
    """The mesh, or a SceneError for what no cloth can be made of."""
    n, counts, indices = len(mesh.points), mesh.face_counts, mesh.face_indices

    def refuse(expected: str, got: object = None, has_got: bool = True) -> None:
        raise SceneError("mesh", expected, got, has_got=has_got, source=where)

    if len(counts) == 0:
        refuse("a surface mesh with faces", f"{n} points and no faces")
    if not np.isfinite(mesh.points).all():
        refuse("finite point coordinates", has_got=False)
    bad = np.nonzero((counts < 3) | (counts > 4))[0]
    if len(bad):
        refuse("faces of 3 or 4 vertices (triangles and quads)", f"face {bad[0]} with {counts[bad[0]]}")
    if indices.min() < 0 or indices.max() >= n:
        refuse(f"face vertex indices in [0, {n - 1}]", int(indices.min() if indices.min() < 0 else indices.max()))
    corners = face_table(counts, indices)  # (f, 4), -1 past a triangle's third vertex
    for a in range(4):
        for b in range(a + 1, 4):
            repeated = np.nonzero((corners[:, a] == corners[:, b]) & (corners[:, a] >= 0))[0]
            if len(repeated):
                refuse("faces with distinct vertices", f"face {repeated[0]}: {corners[repeated[0]].tolist()}")
    areas = face_areas(mesh.points, counts, indices)
    scale = float(np.ptp(mesh.points, axis=0).max())
    flat = np.nonzero(areas <= 1e-12 * scale * scale)[0]
    if len(flat):
        refuse("faces of non-zero area", f"face {flat[0]} (vertices {corners[flat[0]][corners[flat[0]] >= 0].tolist()})"
                                         " is degenerate")
    keys = np.sort(np.where(corners < 0, n, corners), axis=1)
    key = ((keys[:, 0] * (n + 1) + keys[:, 1]) * (n + 1) + keys[:, 2]) * (n + 1) + keys[:, 3] if n < 40_000 \
        else None  # 4 indices in one int64 only below that: larger meshes compare rows
    _, first, seen = np.unique(key if key is not None else keys, axis=None if key is not None else 0,
                               return_index=True, return_counts=True)
    if (seen > 1).any():
        repeat = np.nonzero(seen > 1)[0][0]
        refuse("each face once", f"face {first[repeat]} is repeated")
    unique_edges, uses = unique_pairs(face_edges(counts, indices), n)
    if (uses > 2).any():
        e = unique_edges[np.nonzero(uses > 2)[0][0]]
        refuse("a manifold surface (every edge in at most two faces)", f"edge {e[0]}-{e[1]} in {uses.max()} faces")
    unused = np.setdiff1d(np.arange(n), indices)
    if len(unused):
        refuse("every point on some face", f"{len(unused)} points on none, the first {unused[0]}")
    pieces = count_pieces(n, unique_edges)
    notes = mesh.notes + ((f"{where}: {pieces} separate pieces, simulated as one cloth",) if pieces > 1 else ())
    shortest = float(edge_lengths(mesh.points, counts, indices).min())
    return SurfaceMesh(mesh.points, counts, indices, mesh.uvs, mesh.prim, notes, shortest, mesh.key_times,
                       mesh.key_points, mesh.groups)


def face_table(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(f, 4) vertex table, -1 as a triangle's fourth."""
    starts = face_starts(counts)
    table = np.full((len(counts), 4), -1, dtype=np.int64)
    for k in range(4):
        has = counts > k
        table[has, k] = indices[starts[has] + k]
    return table


def face_edges(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(sum of counts, 2): each face's boundary edges, in face order."""
    starts = np.repeat(face_starts(counts), counts)
    position = np.arange(len(indices)) - starts
    following = starts + (position + 1) % np.repeat(counts, counts)
    return np.stack([indices, indices[following]], axis=1)


def edge_lengths(points: np.ndarray, counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """The length of each face's each edge (an edge shared by two faces twice)."""
    edges = face_edges(counts, indices)
    return np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)


def face_areas(points: np.ndarray, counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Each face's area (a quad's as its two fan triangles')."""
    triangles = fan_triangles(counts, indices)
    a, b, c = (points[triangles[:, k]] for k in range(3))
    tri_area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    owner = np.concatenate([np.arange(len(counts)), np.nonzero(counts == 4)[0]])
    return np.bincount(owner, weights=tri_area, minlength=len(counts))


def pair_keys(pairs: np.ndarray, n: int) -> np.ndarray:
    """Each unordered pair of vertices below n as one int64, the same either way round."""
    return np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64) * n + np.maximum(pairs[:, 0], pairs[:, 1])


def unique_pairs(pairs: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct unordered pairs of vertices below n, sorted, and how often each occurs."""
    keys, uses = np.unique(pair_keys(pairs, n), return_counts=True)
    return np.stack([keys // n, keys % n], axis=1), uses


def triangle_sides(triangles: np.ndarray, n: int) -> np.ndarray:
    """(m, 2) the distinct sides of ``triangles`` (t, 3) over vertices below n, each once, sorted."""
    sides = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return unique_pairs(sides, n)[0]


def count_pieces(n: int, edges: np.ndarray) -> int:
    """Connected components of a graph of n vertices: every vertex hooked to the smallest label across its
    edges, then labels followed to their roots, until nothing changes (a few dozen rounds on a mesh)."""
    label = np.arange(n)
    a, b = edges[:, 0], edges[:, 1]
    while True:
        low = np.minimum(label[a], label[b])
        hooked = label.copy()
        np.minimum.at(hooked, label[a], low)
        np.minimum.at(hooked, label[b], low)
        while True:  # follow each label to its root
            jumped = hooked[hooked]
            if np.array_equal(jumped, hooked):
                break
            hooked = jumped
        if np.array_equal(hooked, label):
            return len(np.unique(label))
        label = hooked
