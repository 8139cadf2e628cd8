"""Materials in SI units, and the masses and springs that make a cloth of one at any resolution, on any mesh.

A ``Material`` says what a fabric is: its areal density (kg/m^2); its stretch stiffness along the warp (the
cloth's u: a grid's first direction, a mesh's UV u) and the weft (v), in N/m, the tension per unit width per
unit strain of a strip pulled along that direction and free to narrow, as a tensile test measures it; its
shear stiffness G (N/m, the shear force per unit width per radian of shear angle); its bending stiffness
along warp and weft (N m, the bending moment per unit width per unit curvature); damping, friction and
strain limits. A preset (``fabric_presets.py``) gives measured values; a table may name one and replace
some of them.

What a cloth of it is made of, derived from the continuum so that the same material behaves the same at any
resolution (``derive_springs``; a spring's force is k (l/L - 1), k in N, see kernels/springs.py):

Masses. Each particle owns an equal share of each of its faces' area: m = density x that area
(``cloth_mesh.lumped_masses``), so the cloth weighs density x its area exactly.

Stretch and shear. A membrane of stiffness E carries the tension E eps per unit width; a spring standing for
a strip of it of area A along its length L carries k eps with k = E A / L. Each face shares its area among
its sides, a quad half of it to each, a triangle all of it (Van Gelder 1998), so that a grid's springs across
any cut stand for the cells they cross. The sides and diagonals pull and push, as a membrane does.
A quad's two diagonals (length d, across a cell of area A) carry its shear: at a shear angle gamma one is
stretched and the other shortened by gamma sin t cos t (on a rectangle, sin t cos t = A / d^2); their energy
equals the membrane's 1/2 G gamma^2 A for k = G d^3 / (2 A). They also stiffen the cell along u by G c^2/s^2
(c/s the cell's side ratio) and couple u to v by G, so its sides stand for a stiffness a_u (and a_v) chosen
so that a strip free to narrow carries E_u: a_u - G^2 / a_v = E_u and a_v - G^2 / a_u = E_v, that is
a_u = E_u (1 + sqrt(1 + 4 G^2 / (E_u E_v))) / 2, a_v = a_u E_v / E_u, less G c^2/s^2 (a cell too long for
that, of a fabric whose G nears its E, a knit's, gets no less than zero: stiffer than its material along u).
A triangle has no diagonal: its sides carry stretch and shear, each side at angle t to the warp with
the modulus 1/E(t) = c^4/E_u + s^4/E_v + c^2 s^2 (1/G - 1/E_u - 1/E_v) (c = cos t, s = sin t; at most the
largest of E_u, E_v, 4 G), E_u and E_v along the threads and 4 G on the bias, so that a grid of right
triangles is pulled and sheared exactly as the material says (its diagonals turning freely, as a
pantograph's). A quad's side takes c^2 a_u + s^2 a_v.

Bending. Linear in the curvature, M = B kappa at every curvature, wherever a bend spring spans a row straight
at rest (a grid's, and a mesh's across an edge between two quads of one row; not one between two triangles,
which the particles' fits bend, below): the spring's two ends p, q and the particle m between them (joined to
both by sides, on the segment p-q) make a stencil (kernels/bending.py). With spacings L1 = |m - p| and
L2 = |q - m|, the weights w = 2 (1/(L1 (L1 + L2)), -1/(L1 L2), 1/(L2 (L1 + L2))) make d = w_p x_p + w_m x_m + w_q x_q
the second derivative of the row along its length, which for a row bent to a curvature kappa (unstretched) is
kappa times the row's normal, and zero for any straight row, however it lies. The stencil stands for the area
A of its middle particle (on a grid a cell: its width across the row times the length it owns along it; half
of one along the border), so its energy 1/2 k |d|^2 equals the plate's 1/2 B kappa^2 A for k = B A: a bend of
kappa in the row's direction costs 1/2 B kappa^2 per unit area, the moment per unit width M = B kappa,
whatever the resolution or the curvature. Rows across (a grid's columns) bend the other direction; a twist
bends no straight row, so it costs nothing (as it cost the springs nothing). A dashpot of ``damping`` seconds
(c = damping x k) damps its rate. Along a direction at angle t to the warp, B = c^2 B_u + s^2 B_v.

Between two triangles flat at rest (a mesh of triangles, the drape specimen's rim) no row need run: the bend
spring joining their far corners goes, and each particle of such triangles that no row runs through along the
warp (or the weft) is bent along it by its fit (bend_fits.py): the weights that read the curvature along u
from the quadratic fitting the particle and its neighbours at rest, exact for every quadratic on any mesh (on
a free border, taking the curvature across it as zero; where its neighbours are fewer points than a
quadratic has coefficients, from theirs too), stand in a stencil as a row's do, k = B_u A (B_v A along v),
A the particle's area. Bent round a cylinder, a grid of right triangles stores the plate's energy
but half a cell at the two ends along the bend, converging as the cell squared (0.9934, 0.9983, 0.9996 at 1,
0.5, 0.25 cm), its points moved by up to a fifth of a cell 0.987 to 0.991; a twist costs nothing and lets no
bend off, and Peirce's cantilever of triangles sags as the elastica within 0.4%, 0.08%, 0.02% at 10, 20, 40
cells, as the rows' do (tests/test_bending_fits.py). Bergou's hinges, which bent these triangles before, read
across a side of a cell the bend plus the twist between the cell's rows, so a strip that twisted a little bent
for 0.75 to 0.79 of B and sagged 6 to 16% too far, the further the finer. The model takes the rest state flat,
as every cloth here is but the garment's panels (quads curved as modelled, which keep their springs): two
triangles turned more than 1e-4 rad at rest keep their bend spring, and a particle whose fit reads a curvature
at rest (its neighbours not flat) has no fit.

Where a bend spring has neither (across an edge beside a quad with no straight row under it, or between
faces curved as modelled, for which fixed weights would not be at rest), it stays a spring: it spans two
edges of length L/2 across an edge; bent to a curvature kappa along it, an unstretched row shortens it by
the strain eps = L^2 kappa^2 / 32 (the chord of two edges turned kappa L/2 apart), so its energy 1/2 k L eps^2 per
area A it stands for gives the moment M = k L^5 kappa^3 / (512 A). Springs that only push back when
shortened cannot give M = B kappa at every curvature; k makes the slope of M over 0.5 to 1.5 1/cm, the range
in which the Kawabata tester (KES-FB2) measures B, equal B: k = 512 B A / (L^5 S), S = k1^2 + k1 k2 + k2^2
of that range's ends. Then M = B kappa^3 / S whatever the resolution: at a fold of 3 cm radius about 1/29
of B, at 1 cm about 1/3, so that gentle folds were left to the mesh (the drape coefficient moved by 2 to 8
points from 30 to 60 cells, docs/guide/scene-reference.md). A spring stands for the mean of its ends'
areas (on a grid of triangles, now bent by the fits, whose bend springs ran three ways, the three together
bent an eighth stiffer than B).

Damping. Each spring's dashpot is ``damping`` seconds of its elastic response: b = damping x k / L
(stiffness-proportional, Rayleigh's), a strain rate then pulls as that much strain would.

Strain limits. A limited spring at angle t to the warp may stretch c^2 s_u + s^2 s_v and likewise shorten.

Directions. Angles are measured at rest in each face's frame, from the 3D direction in which its UV's u grows
(on a grid, the first direction). A mesh without UVs has no warp: it is made isotropic, every side taking
the mean of the warp's and the weft's stiffness (a triangle's (E_u + E_v) / 2, so that its shear is then
its sides', far stiffer than a fabric's: give a garment's mesh UVs), every bend spring and limit the mean.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .checks import check_fields
from .adjacency import Adjacency
from .bend_fits import fitted_stencils, flat_triangle_bends
from .cloth_mesh import BEND, SHEAR, STRUCTURAL, BendStencils, ClothMesh, DerivedSprings, lumped_masses
from .errors import SceneError
from .fabric_presets import PRESETS
from .mesh_io import face_areas, face_edges, face_starts, pair_keys

PerDirection = float | tuple[float, float]

# The curvatures (1/m) over which KES-FB2 takes the bending stiffness, 0.5 and 1.5 1/cm (Kawabata 1980).
KES_CURVATURES = (50.0, 150.0)
# What the bend springs' moment's slope over that range is made equal to B by: k1^2 + k1 k2 + k2^2.
_KES_SLOPE = KES_CURVATURES[0] ** 2 + KES_CURVATURES[0] * KES_CURVATURES[1] + KES_CURVATURES[1] ** 2
# Bounds within which every derived spring constant and its ratio to a particle's mass is finite in float32.
_RANGES = {"density": (1e-6, 1e3, "kg/m^2"), "stretch": (1e-3, 1e8, "N/m"), "shear": (1e-3, 1e8, "N/m"),
           "bending": (1e-12, 10.0, "N m"), "damping": (0.0, 1.0, "s"), "friction": (0.0, 10.0, "")}
_REQUIRED = ("density", "stretch", "shear", "bending")
# In which regime a material's springs act, elastic part and dashpot (the kernels' regimes, model.regime_flags):
# sides and diagonals both ways, as a membrane does; bend springs (those no stencil replaces) only when
# shortened, as the seed's.
REGIMES = {STRUCTURAL: ("both", "both"), SHEAR: ("both", "both"), BEND: ("compression", "compression")}


@dataclass(frozen=True)
class Material:
    """A fabric in SI units (see the module's docstring): ``preset`` names one of ``fabric_presets.PRESETS``,
    whose values fill the keys left out. ``stretch`` and ``bending`` are one number or [warp, weft] (along
    u and v); ``stretch_limit`` and ``compression_limit`` likewise, fractions of a spring's rest length
    (left out: no strain limit from the material; the cloth's ``limit`` may set one). ``damping`` (s) is
    each spring's dashpot as that many seconds of its stiffness; ``friction`` the coefficient of the cloth's
    contacts (left out: the colliders' and the collision table's own)."""

    preset: str | None = None
    density: float | None = None
    stretch: PerDirection | None = None
    shear: float | None = None
    bending: PerDirection | None = None
    damping: float = 0.0
    friction: float | None = None
    stretch_limit: PerDirection | None = None
    compression_limit: PerDirection | None = None

    @classmethod
    def from_string(cls, name: str) -> "Material":
        """``material = "cotton"``: the preset, its errors keyed by the material itself."""
        try:
            return cls(preset=name)
        except SceneError as exc:
            raise SceneError("", exc.expected, exc.got, has_got=exc.has_got) from None

    def __post_init__(self) -> None:
        check_fields(self)
        if self.preset is not None:
            if self.preset not in PRESETS:
                raise SceneError("preset", "a preset (one of " + ", ".join(PRESETS) + ")", self.preset)
            data = PRESETS[self.preset]
            for key in _REQUIRED:
                if getattr(self, key) is None:
                    object.__setattr__(self, key, getattr(data, key))
        for key in _REQUIRED:
            if getattr(self, key) is None:
                raise SceneError(key, f"a number in {_RANGES[key][2]} (a material without a preset gives density, "
                                      "stretch, shear and bending)", has_got=False)
        for key, (low, high, unit) in _RANGES.items():
            value = getattr(self, key)
            values = () if value is None else value if isinstance(value, tuple) else (value,)
            if not all(low <= v <= high for v in values):
                raise SceneError(key, f"a number in [{low:g}, {high:g}]" + (f" {unit}" if unit else "")
                                 + (", or [warp, weft] such numbers" if key in ("stretch", "bending") else ""),
                                 _shown(value))
        if self.stretch_limit is not None and not all(0.0 < v <= 10.0 for v in along(self.stretch_limit)):
            raise SceneError("stretch_limit", "a fraction in (0, 10], or [warp, weft] such fractions",
                             _shown(self.stretch_limit))
        if self.compression_limit is not None and not all(0.0 < v < 1.0 for v in along(self.compression_limit)):
            raise SceneError("compression_limit", "a fraction in (0, 1), or [warp, weft] such fractions",
                             _shown(self.compression_limit))

    @property
    def has_limits(self) -> bool:
        return self.stretch_limit is not None or self.compression_limit is not None

    def values(self) -> dict[str, object]:
        """The material's keys and values, as a scene file or ``warp-cloth materials --json`` gives them."""
        return {f.name: _shown(getattr(self, f.name)) for f in fields(self)}


def _shown(value: PerDirection) -> object:
    return list(value) if isinstance(value, tuple) else value


def along(value: PerDirection) -> tuple[float, float]:
    """(warp, weft) of a value given once for both or per direction."""
    return value if isinstance(value, tuple) else (value, value)


def derive_springs(material: Material, rest_points: np.ndarray, mesh: ClothMesh) -> DerivedSprings:
    """The springs of ``mesh`` made of ``material`` (see the module's docstring); ``rest_points`` is the cloth
    as its rest lengths have it (a grid flat, a mesh as modelled)."""
    pairs, kinds, rests = mesh.springs, mesh.spring_kind, mesh.rest_lengths
    counts, indices = mesh.face_counts, mesh.face_indices
    tensors = _warp_tensors(rest_points, counts, indices, mesh.uvs)
    warp = np.nan_to_num(_warp_share(tensors, rest_points, pairs), nan=0.5)  # no direction: warp and weft's mean
    stiffness = np.zeros(len(pairs))
    sides = kinds == STRUCTURAL
    stiffness[sides] = _side_stiffness(material, tensors, rest_points, counts, indices, pairs[sides])
    diagonals = kinds == SHEAR
    stiffness[diagonals] = material.shear * rests[diagonals] ** 3 / (
        2.0 * _quad_areas(rest_points, counts, indices, pairs[diagonals]))
    bends = kinds == BEND
    bend_u, bend_v = along(material.bending)
    bending = warp[bends] * bend_u + (1 - warp[bends]) * bend_v
    stiffness[bends] = 512.0 * bending * _bend_areas(rest_points, counts, indices, pairs[bends]) / (
        rests[bends] ** 5 * _KES_SLOPE)
    fitted, in_triangles = flat_triangle_bends(rest_points, counts, indices, pairs[bends])
    middle = np.where(fitted, -1, _straight_middles(rest_points, pairs[sides], pairs[bends]))
    straight = middle >= 0
    rows = _stencils(rest_points, counts, indices, pairs[bends][straight], middle[straight], bending[straight],
                     material.damping)
    row_directions = (middle[straight], rest_points[pairs[bends][straight, 1]] - rest_points[pairs[bends][straight, 0]])
    fits = fitted_stencils(rest_points, counts, indices, pairs[sides], tensors, in_triangles, row_directions,
                           along(material.bending), material.damping)
    stenciled = np.zeros(len(pairs), dtype=bool)
    stenciled[np.nonzero(bends)[0][straight | fitted]] = True
    parts = [part for part in (rows, fits) if len(part.stiffness)]

    stretch_limit = compression_limit = None
    if material.stretch_limit is not None:
        s_u, s_v = along(material.stretch_limit)
        stretch_limit = warp * s_u + (1 - warp) * s_v
    if material.compression_limit is not None:
        c_u, c_v = along(material.compression_limit)
        compression_limit = warp * c_u + (1 - warp) * c_v
    return DerivedSprings(stiffness, material.damping * stiffness / rests, stretch_limit, compression_limit,
                          BendStencils.joined(parts) if parts else None, stenciled)


def _straight_middles(points, sides, bends) -> np.ndarray:
    """For each bend spring p-q, a particle m joined to both by sides and on the segment p-q at rest (within
    1e-6 of its length); -1 where there is none."""
    n = len(points)
    adjacency = Adjacency.of(sides, n)
    side_keys = np.sort(pair_keys(sides, n))
    p, q = bends[:, 0], bends[:, 1]
    degree = adjacency.offsets[p + 1] - adjacency.offsets[p]
    owner = np.repeat(np.arange(len(bends)), degree)
    entry = np.repeat(adjacency.offsets[p] - np.cumsum(degree) + degree, degree) + np.arange(int(degree.sum()))
    m = adjacency.other[entry].astype(np.int64)
    ends = np.stack([m, q[owner]], axis=1)
    found = np.searchsorted(side_keys, pair_keys(ends, n))
    joined = side_keys[np.minimum(found, len(side_keys) - 1)] == pair_keys(ends, n)
    chord = points[q[owner]] - points[p[owner]]
    offset = points[m] - points[p[owner]]
    length2 = np.einsum("si,si->s", chord, chord)
    along = np.einsum("si,si->s", offset, chord)
    off_line = np.linalg.norm(np.cross(chord, offset), axis=1)
    on_segment = joined & (along > 0) & (along < length2) & (off_line <= 1e-6 * length2)
    middle = np.full(len(bends), -1, dtype=np.int64)
    middle[owner[on_segment][::-1]] = m[on_segment][::-1]  # the first found, where several are
    return middle


def _stencils(points, counts, indices, bends, middle, bending, damping: float) -> BendStencils:
    """The stencils p, m, q of the straight bend springs (see the module's docstring)."""
    p, q = bends[:, 0], bends[:, 1]
    l1 = np.linalg.norm(points[middle] - points[p], axis=1)
    l2 = np.linalg.norm(points[q] - points[middle], axis=1)
    weights = 2.0 * np.stack([1.0 / (l1 * (l1 + l2)), -1.0 / (l1 * l2), 1.0 / (l2 * (l1 + l2))], axis=1)
    stiffness = bending * lumped_masses(points, counts, indices, 1.0)[middle]
    return BendStencils.of_table(np.stack([p, middle, q], axis=1), weights, np.ones(weights.shape, dtype=bool),
                                 stiffness, damping * stiffness)


def _side_stiffness(material: Material, tensors, points, counts, indices, wanted) -> np.ndarray:
    """Each side's stiffness, summed over the faces beside it (see the module's docstring)."""
    e_u, e_v = along(material.stretch)
    g = material.shear
    a_u = 0.5 * e_u * (1.0 + np.sqrt(1.0 + 4.0 * g * g / (e_u * e_v)))  # a quad cell's C_uu that leaves E_u
    a_v = a_u * e_v / e_u
    edges = face_edges(counts, indices)
    length = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)
    starts = np.repeat(face_starts(counts), counts)
    position, corners = np.arange(len(indices)) - starts, np.repeat(counts, counts)
    across = 0.5 * (length[starts + (position - 1) % corners] + length[starts + (position + 1) % corners])
    area = np.repeat(face_areas(points, counts, indices), counts)
    c2 = _warp_share(tensors, points, edges)
    known = ~np.isnan(c2)
    c2 = np.where(known, c2, 0.5)
    in_quad = np.where(known, c2 * a_u + (1 - c2) * a_v, 0.5 * (a_u + a_v)) - g * (length / across) ** 2
    compliance = c2 * c2 / e_u + (1 - c2) ** 2 / e_v + c2 * (1 - c2) * (1.0 / g - 1.0 / e_u - 1.0 / e_v)
    compliance = np.maximum(compliance, 1.0 / max(e_u, e_v, 4.0 * g))
    in_triangle = np.where(known, 1.0 / compliance, 0.5 * (e_u + e_v))
    share = np.where(corners == 4, 0.5 * area * np.maximum(in_quad, 0.0), area * in_triangle) / length
    return _summed_by_pair(edges, share, wanted, len(points))


def _summed_by_pair(pairs: np.ndarray, values: np.ndarray, wanted: np.ndarray, n: int) -> np.ndarray:
    """For each pair of ``wanted``, the sum of ``values`` over the equal pairs of ``pairs``."""
    keys, owner = np.unique(pair_keys(pairs, n), return_inverse=True)
    sums = np.bincount(owner, weights=values, minlength=len(keys))
    return sums[np.searchsorted(keys, pair_keys(wanted, n))]


def _quad_areas(points, counts, indices, wanted) -> np.ndarray:
    """The area of the quad each diagonal crosses."""
    starts = face_starts(counts)[counts == 4]
    diagonals = np.concatenate([np.stack([indices[starts], indices[starts + 2]], axis=1),
                                np.stack([indices[starts + 1], indices[starts + 3]], axis=1)])
    areas = face_areas(points, counts, indices)[counts == 4]
    return _summed_by_pair(diagonals, np.concatenate([areas, areas]), wanted, len(points))


def _bend_areas(points, counts, indices, bends) -> np.ndarray:
    """The area each bend spring stands for: the mean of its ends' areas (on a grid, a cell; half of one
    along the border)."""
    area = lumped_masses(points, counts, indices, 1.0)
    return 0.5 * (area[bends[:, 0]] + area[bends[:, 1]])


def _warp_tensors(points, counts, indices, uvs) -> np.ndarray | None:
    """(n, 3, 3) at each particle, the sum of u u^T over its faces, u the 3D direction in which the face's UV
    u grows (from its first triangle): summed as u u^T so that UV islands mirrored across a seam agree.
    None without UVs."""
    if uvs is None:
        return None
    starts = face_starts(counts)
    corner_uvs = uvs if len(uvs) == len(indices) else uvs[indices]  # a grid's are per particle
    a, b, c = indices[starts], indices[starts + 1], indices[starts + 2]
    e1, e2 = points[b] - points[a], points[c] - points[a]
    t1, t2 = corner_uvs[starts + 1] - corner_uvs[starts], corner_uvs[starts + 2] - corner_uvs[starts]
    det = t1[:, 0] * t2[:, 1] - t2[:, 0] * t1[:, 1]
    grows = (e1 * t2[:, 1:2] - e2 * t1[:, 1:2]) / np.where(det != 0, det, np.inf)[:, None]
    length = np.linalg.norm(grows, axis=1, keepdims=True)
    grows = grows / np.where(length > 0, length, 1.0)  # degenerate UVs: zero, no direction
    tensors = np.zeros((len(points), 3, 3))
    np.add.at(tensors, indices, np.repeat(grows[:, :, None] * grows[:, None, :], counts, axis=0))
    return tensors


def _warp_share(tensors, points, pairs) -> np.ndarray:
    """cos^2 of each pair's angle to the warp at rest, from its two ends' tensors; NaN where there is no
    direction (no UVs, or degenerate ones)."""
    if tensors is None:
        return np.full(len(pairs), np.nan)
    ends = tensors[pairs[:, 0]] + tensors[pairs[:, 1]]
    edge = points[pairs[:, 1]] - points[pairs[:, 0]]
    along_warp = np.einsum("si,sij,sj->s", edge, ends, edge)
    total = np.trace(ends, axis1=1, axis2=2) * np.einsum("si,si->s", edge, edge)
    return np.where(total > 0, along_warp / np.where(total > 0, total, 1.0), np.nan)
