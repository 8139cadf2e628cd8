"""What a scene declares: cloths, their springs, limits and pins, colliders, time stepping, outputs.

Plain frozen dataclasses. A scene file (TOML) maps one to one onto them (see ``scene_file``); a scene built
in Python is checked by the same ``__post_init__`` rules. They check values and read no file: what needs
the scene's geometry (its mesh files, its particles, what its pins select) is checked by
``geometry_checks.validate``, which loading a scene file and making a ``Simulator`` run. Every effect that a
scene leaves out (``None`` or an empty tuple) costs the simulation nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from .checks import FLOAT32_MAX, check_fields, check_file_name, check_float32, check_identifier
from .errors import SceneError
from .materials import Material, along

Vec3 = tuple[float, float, float]

SpringRegime = Literal["tension", "compression", "both"]
Corner = Literal["bottom-left", "bottom-right", "top-left", "top-right", "boundary"]
Edge = Literal["bottom", "top", "left", "right", "boundary"]
BOUNDARY = "boundary"  # the corners or the edges of any cloth's boundary (pin_selection.py)
Integrator = Literal["explicit", "symplectic", "implicit"]
INTEGRATORS: tuple[str, ...] = ("explicit", "symplectic", "implicit")

MIN_CELL = 1e-4  # metres: the shortest spring rest length float32 positions resolve well

# Particle count above which a scene is refused before any memory is asked for: indices are int32 and
# a cloth of this size already needs gigabytes. The simulator checks the device's free memory as well.
MAX_PARTICLES = 64 * 1024 * 1024

MAX_EXTENT = 1e6  # metres: the largest coordinate or length (float32 resolves 6 cm there)
# A cloth's particles must lie within this many of its cells of the world origin: farther out, float32
# positions resolve less than 1/128 of a cell and its springs lose their lengths.
MAX_CELLS_FROM_ORIGIN = 2**16
# Bounds on the work of one frame, so that a typo cannot hang a run inside a frame (Ctrl-C stops between
# frames): substeps a frame, iterations of each pass a substep, and frames a run.
MAX_SUBSTEPS = 10_000
MAX_ITERATIONS = 1_000
MAX_FRAMES = 1_000_000
MAX_FPS = 10_000.0


def _require(ok: bool, key: str, expected: str, got: object = None, has_got: bool = True) -> None:
    if not ok:
        raise SceneError(key, expected, got, has_got=has_got)


def _positive(value: float, key: str) -> None:
    _require(value > 0, key, "a number > 0", value)


def _non_negative(value: float, key: str) -> None:
    _require(value >= 0, key, "a number >= 0", value)


def _unit_length(axis: Vec3, key: str) -> None:
    _require(math.hypot(*axis) > 1e-9, key, "a non-zero direction [x, y, z]", list(axis))


def _within_extent(values: tuple[float, ...] | float, key: str) -> None:
    vector = values if isinstance(values, tuple) else (values,)
    _require(all(abs(v) <= MAX_EXTENT for v in vector), key, f"metres of magnitude at most {MAX_EXTENT:g}",
             list(vector) if isinstance(values, tuple) else values)


def _whole_in(value: int, low: int, high: int, key: str) -> None:
    _require(low <= value <= high, key, f"a whole number in [{low}, {high}]", value)


@dataclass(frozen=True)
class Oscillation:
    """Motion ``offset(t) = amplitude * sin(2 pi frequency t + phase) * axis`` (axis normalised)."""

    axis: Vec3 = (1.0, 0.0, 0.0)
    amplitude: float = 1.0
    frequency: float = 1.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self)
        _unit_length(self.axis, "axis")
        _non_negative(self.amplitude, "amplitude")
        _within_extent(self.amplitude, "amplitude")
        _non_negative(self.frequency, "frequency")

    def unit_axis(self) -> Vec3:
        norm = math.hypot(*self.axis)
        return (self.axis[0] / norm, self.axis[1] / norm, self.axis[2] / norm)

    def offset(self, t: float) -> Vec3:
        s = self.amplitude * math.sin(2.0 * math.pi * self.frequency * t + self.phase)
        ax = self.unit_axis()
        return (s * ax[0], s * ax[1], s * ax[2])

    def velocity(self, t: float) -> Vec3:
        w = 2.0 * math.pi * self.frequency
        s = self.amplitude * w * math.cos(w * t + self.phase)
        ax = self.unit_axis()
        return (s * ax[0], s * ax[1], s * ax[2])


@dataclass(frozen=True)
class SpringKind:
    """One family of springs (structural, shear or bend).

    Force on particle 1 of a spring 1-2: ``-stiffness (l/L0 - 1) n - damping (n . v12) n``. The elastic
    part acts only in the regime ``acts`` names and the dashpot only in ``damping_acts``: the seed's
    structural and shear springs pull but never push (``acts = "tension"``) while their damping always
    acts; its bend springs push back only when compressed.
    """

    stiffness: float = 10.0
    damping: float = 1.0
    acts: SpringRegime = "tension"
    damping_acts: SpringRegime = "both"
    enabled: bool = True

    def __post_init__(self) -> None:
        check_fields(self)
        _positive(self.stiffness, "stiffness")
        _non_negative(self.damping, "damping")


SEED_STRUCTURAL = SpringKind(10.0, 1.0, "tension", "both")
SEED_SHEAR = SpringKind(10.0, 1.0, "tension", "both")
SEED_BEND = SpringKind(10.0, 1.0, "compression", "compression")


@dataclass(frozen=True)
class Limit:
    """Provot-style strain limit on structural and shear springs, as fractions of the rest length.

    With ``attachments``, each particle of a pinned cloth also stays within (1 + stretch) times its rest
    distance across the cloth from its nearest pin (long-range attachments, Kim, Chentanez and Mueller
    2012; on a mesh, the shortest path along its edges), projected in every limit pass: the limit's passes
    then hold a hanging cloth's length whatever its resolution, where springs alone pass a pull on one row
    per pass. The distance is measured around the world's spheres (the shortest way that stays outside
    each, shrunk by a spring's chord: kernels/wrapping.py), so a cloth that drapes over a sphere still hangs
    from its pins over it; meshes are not wrapped around (kernels/attachments.py).

    Use them for a cloth that hangs from pins (a curtain, a flag, a garment on a hanger): they hold the
    speed matrix's hanging 256^2 cloth at +10.1% with 10 substeps, 37 times faster than Newton's solver at
    equal quality (docs/benchmarks.md). They are off by default because they fight a kinematic collider
    that pushes the cloth out of their reach (the fast_sphere hard case reached 36 to 60 m/s and up to 23
    crossing triangle pairs with them, 23 to 30 m/s and none without).
    """

    stretch: float = 0.10
    compression: float = 0.10
    attachments: bool = False

    def __post_init__(self) -> None:
        check_fields(self)
        _require(0 < self.stretch <= 10, "stretch", "a fraction in (0, 10]", self.stretch)
        _require(0 < self.compression < 1, "compression", "a fraction in (0, 1)", self.compression)


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in world space (of the cloth's initial pose)."""

    min: Vec3
    max: Vec3

    def __post_init__(self) -> None:
        check_fields(self)
        _require(all(a <= b for a, b in zip(self.min, self.max)), "max", "every component >= min's",
                 list(self.max))


@dataclass(frozen=True)
class Near:
    """The particles within ``distance`` metres of a collider's surface where the cloth and the collider
    start: ``collider`` names a sphere, a mesh collider or ``"ground"``."""

    collider: str
    distance: float

    def __post_init__(self) -> None:
        check_fields(self)
        _require(bool(self.collider), "collider", "the name of a sphere, a [[collider]] or \"ground\"",
                 self.collider)
        _positive(self.distance, "distance")
        _within_extent(self.distance, "distance")


@dataclass(frozen=True)
class Pin:
    """Particles held in place, driven by an oscillation about their initial position, carried along
    ``keys`` (``[[cloth.pins.keys]]``: turned by ``rotate`` about where the pinned particles' centre
    starts, then moved by ``translate``, interpolated linearly between keys), or carried by a ``target``:
    the named mesh collider, each pinned particle held where it started relative to the collider's nearest
    face (a cape pinned to a moving character); or, for a cloth from a USD file, the path of a prim of that
    file (``"/World/Rig/Hand"``), whose world transform's motion carries the pinned particles. A ``name``
    lets a script drive the pin between frames (``Simulator.control``, warp_cloth/control.py).

    Selected by index (on a grid ``x + (nx + 1) y``), named corners and edges of the grid (left/right is
    the first grid direction, bottom/top the second), the ``"boundary"`` corners or edges of any cloth
    (pin_selection.py: every vertex of its boundary, or those where the boundary turns by more than
    ``pin_selection.CORNER_ANGLE`` degrees), a world-space box around the initial pose, the ``group`` of a
    mesh cloth (in USD a ``GeomSubset`` of its points or faces, or a primvar on its points that is non-zero
    where they belong; in OBJ a ``g`` group: the vertices of its faces), or the particles ``near`` a
    collider at the start. A pin selects the union of what its keys select.

    Without ``stiffness`` a pin is hard: its particles are moved, never pushed (inverse mass 0). With it
    (N/m, per particle) the pin is soft: each particle keeps its mass and is pulled toward where the pin's
    motion puts it by a spring of zero rest length, with ``damping`` (N s/m) on their relative velocity.
    """

    indices: tuple[int, ...] = ()
    corners: tuple[Corner, ...] = ()
    edges: tuple[Edge, ...] = ()
    region: Box | None = None
    group: str | None = None
    near: Near | None = None
    motion: Oscillation | None = None
    target: str | None = None
    keys: tuple[TransformKey, ...] = ()
    name: str | None = None
    stiffness: float | None = None
    damping: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self)
        if self.name is not None:
            check_identifier(self.name, "name")
        for k, index in enumerate(self.indices):
            _require(index >= 0, f"indices[{k}]", "a particle index >= 0", index)
        _require(bool(self.indices or self.corners or self.edges or self.region or self.group or self.near), "",
                 "at least one of indices, corners, edges, region, group, near", "none")
        _require(self.motion is None or self.target is None, "target", "either a motion or a target, not both",
                 self.target)
        _require(not (self.keys and (self.motion is not None or self.target is not None)), "keys",
                 "keys, a motion or a target, only one of them", has_got=False)
        _check_key_times(self.keys)
        if self.stiffness is not None:
            _positive(self.stiffness, "stiffness")
            check_float32(self.stiffness, "the stiffness", "stiffness", self.stiffness)
        _non_negative(self.damping, "damping")
        _require(self.damping == 0.0 or self.stiffness is not None, "damping",
                 "no damping on a hard pin (damping is a soft pin's, beside its stiffness)", self.damping)

    @property
    def soft(self) -> bool:
        return self.stiffness is not None


DEFAULT_CLOSE_TIME = 0.5  # seconds: a seam's default closing, a garment tool's few frames (12 at 24 fps)


@dataclass(frozen=True)
class SeamSide:
    """One side of a seam: particles of the cloth named ``cloth``, by ``indices`` (in the order given), by a
    grid's ``edge`` (along its first grid direction for bottom and top, its second for left and right), or by
    a mesh's ``group`` (the group's vertices on the mesh's boundary, which must form one open path along it:
    a USD GeomSubset of points or a point primvar names them exactly; an OBJ ``g`` group gives its faces'
    vertices, so a group of the faces along a side turns the corners too)."""

    cloth: str
    indices: tuple[int, ...] = ()
    edge: Edge | None = None
    group: str | None = None

    def __post_init__(self) -> None:
        check_fields(self)
        for k, index in enumerate(self.indices):
            _require(index >= 0, f"indices[{k}]", "a particle index >= 0", index)
        given = [key for key in ("indices", "edge", "group") if getattr(self, key)]
        _require(len(given) == 1, "", "one of indices, edge, group", " and ".join(given) or "none")


@dataclass(frozen=True)
class Seam:
    """Two sides sewn together (of one cloth or two), the k-th particle of ``a`` to the k-th of ``b``: over
    the first ``close_time`` seconds of the run each pair may be no farther apart than its start distance
    shrunk linearly to 0, and then no farther than 0, held as one (the strain-limit solve projects it:
    seams.py). Sides by edge or group are ordered along the boundary, ``b``'s way round the one that puts the
    pairs nearer at the start; sides by indices in the order given. Sewn pairs, and the particles that share
    a face with either of a pair, do not collide with each other."""

    a: SeamSide
    b: SeamSide
    close_time: float = DEFAULT_CLOSE_TIME

    def __post_init__(self) -> None:
        check_fields(self)
        _positive(self.close_time, "close_time")


@dataclass(frozen=True)
class MeshSource:
    """Where a cloth's mesh comes from: an OBJ file, or a ``Mesh`` prim of a USD file (``prim``: its path;
    left out, the stage's only mesh). A scene file may give the file alone: ``mesh = "garment.obj"``; a
    relative path is taken from the scene file's folder."""

    file: str
    prim: str | None = None

    def __post_init__(self) -> None:
        check_fields(self)
        _require(bool(self.file), "file", "the path of an OBJ or USD file", self.file)

    @classmethod
    def from_string(cls, file: str) -> "MeshSource":
        return cls(file)


def _surface_of(source: MeshSource):
    """A mesh source's checked mesh, its errors keyed ``mesh`` with the mesh file named after the scene's."""
    from .mesh_io import load_mesh

    try:
        return load_mesh(source.file, source.prim)
    except SceneError as exc:
        expected = f"{exc.expected} (in {exc.source})" if exc.source else exc.expected
        raise SceneError(exc.key, expected, exc.got, has_got=exc.has_got) from None


@dataclass(frozen=True)
class Cloth:
    """A rectangular grid of ``resolution`` quads, ``(nx + 1) * (ny + 1)`` particles, or the user's own
    ``mesh`` (``Cloth.from_mesh``).

    Built in its local (u, v) plane, laid ``vertical`` (u along +X, v along +Y, facing +Z) or
    ``horizontal`` (u along +X, v along -Z, facing +Y), then rotated by ``rotation`` (degrees about X,
    then Y, then Z) about its corner (0, 0), which is put at ``origin``. ``mass`` is per particle;
    ``density`` (kg/m^2) instead gives each particle the area around it. ``jitter`` moves particles out of
    plane by up to that fraction of a cell (the seed used 0.05), reproducibly from ``seed``. ``twist``
    (degrees) starts the cloth twisted about its middle line along v, the far edge turned that much:
    the springs keep the flat grid's rest lengths, so the cloth springs back.

    A mesh cloth (triangles and quads, cloth_mesh.py) takes its particles, faces and UVs from the mesh as
    modelled, rotated by ``rotation`` about the mesh's own origin and moved by ``origin``; the grid's keys
    (resolution, size, orientation, jitter, twist) do not apply to it, nor do the grid's named corners and
    edges (its ``"boundary"`` ones do).
    ``density`` gives each particle a share of its faces' area.

    A ``material`` (materials.py: a preset's name or a table of SI values) gives the cloth its masses and
    springs, the same at any resolution; such a cloth sets none of ``mass``, ``density``, ``structural``,
    ``shear`` and ``bend`` (the seed's numbers, which change meaning with resolution), nor a ``limit`` where
    its material sets strain limits.
    """

    name: str = "cloth"
    resolution: tuple[int, int] = (10, 10)
    size: tuple[float, float] = (10.0, 10.0)
    origin: Vec3 = (0.0, 0.0, 0.0)
    orientation: Literal["vertical", "horizontal"] = "vertical"
    rotation: Vec3 = (0.0, 0.0, 0.0)
    mass: float | None = None
    density: float | None = None
    velocity: Vec3 = (0.0, 0.0, 0.0)
    jitter: float = 0.0
    twist: float = 0.0
    seed: int = 0
    structural: SpringKind = SEED_STRUCTURAL
    shear: SpringKind = SEED_SHEAR
    bend: SpringKind = SEED_BEND
    limit: Limit | None = None
    pins: tuple[Pin, ...] = ()
    color: Vec3 = (0.75, 0.32, 0.22)
    mesh: MeshSource | None = None
    material: Material | None = None

    GRID_KEYS = ("resolution", "size", "orientation", "jitter", "twist", "seed")

    @classmethod
    def from_mesh(cls, file: str, prim: str | None = None, **settings) -> "Cloth":
        """A cloth made of the mesh in ``file`` (OBJ or USD, see ``MeshSource``), with any other settings."""
        return cls(mesh=MeshSource(str(file), prim), **settings)

    def __post_init__(self) -> None:
        check_fields(self)
        check_identifier(self.name, "name")
        _require(all(0 <= c <= 1 for c in self.color), "color", "[r, g, b] each in [0, 1]", list(self.color))
        if self.mass is not None:
            _positive(self.mass, "mass")
        if self.density is not None:
            _positive(self.density, "density")
        _require(not (self.mass is not None and self.density is not None), "density",
                 "either mass (per particle) or density (kg/m^2), not both", self.density)
        if self.material is not None:
            self._check_material_alone()
        if self.mesh is not None:
            self._check_mesh_settings()
        else:
            self._check_grid()
            self.check_placement(self.shortest_edge(), max(self.size))
        if not self.masses_from_mesh:
            self.check_masses(*self.mass_range())

    def _check_material_alone(self) -> None:
        """A material gives the masses, the springs and (where it sets them) the strain limits: no raw ones
        beside it. A spring kind counts as set where it is not the seed's default object itself."""
        for key in ("mass", "density"):
            _require(getattr(self, key) is None, key, f"no {key} on a cloth with a material (its density is the "
                     "material's: material.density)", getattr(self, key))
        for key, seed in (("structural", SEED_STRUCTURAL), ("shear", SEED_SHEAR), ("bend", SEED_BEND)):
            _require(getattr(self, key) is seed, key, f"no {key} springs on a cloth with a material (its springs "
                     "come from the material; leave the material out to set springs)", has_got=False)
        _require(self.limit is None or not self.material.has_limits, "limit",
                 "no limit on a cloth whose material sets strain limits (material.stretch_limit, "
                 "material.compression_limit): one or the other", has_got=False)

    def _check_mesh_settings(self) -> None:
        for key in self.GRID_KEYS:
            _require(getattr(self, key) == getattr(Cloth, key), key, "no grid setting on a mesh cloth (its "
                     "particles are the mesh's)", getattr(self, key))
        for p, pin in enumerate(self.pins):
            for key in ("corners", "edges"):
                names = getattr(pin, key)
                _require(all(name == BOUNDARY for name in names), f"pins[{p}].{key}",
                         f"[\"{BOUNDARY}\"] on a mesh cloth (the named ones are a grid's)", list(names))

    def _check_grid(self) -> None:
        for p, pin in enumerate(self.pins):
            _require(pin.group is None, f"pins[{p}].group", "no group on a grid cloth (groups are a mesh's)",
                     pin.group)
        nx, ny = self.resolution
        _require(nx >= 1 and ny >= 1, "resolution", "[nx, ny] quads, each >= 1", list(self.resolution))
        _require(nx < 65535 and ny < 32767, "resolution", "at most [65534, 32766] quads", list(self.resolution))
        _require((nx + 1) * (ny + 1) <= MAX_PARTICLES, "resolution",
                 f"at most {MAX_PARTICLES} particles per cloth", list(self.resolution))
        _require(self.size[0] > 0 and self.size[1] > 0, "size", "[width, height] in metres, each > 0",
                 list(self.size))
        _within_extent(self.size, "size")
        _require(min(self.size[0] / nx, self.size[1] / ny) >= MIN_CELL, "size",
                 f"cells of at least {MIN_CELL:g} m (size / resolution; float32 positions cannot resolve "
                 "smaller springs)", list(self.size))
        _require(0 <= self.jitter <= 0.5, "jitter", "a fraction of a cell in [0, 0.5]", self.jitter)
        _require(self.seed >= 0, "seed", "a whole number >= 0", self.seed)

    def surface(self):
        """A mesh cloth's checked mesh (``mesh_io.SurfaceMesh``, read once per file version, when first asked
        for: by ``geometry_checks.validate``); its errors name this cloth's ``mesh`` key."""
        return _surface_of(self.mesh)

    def usd_file(self) -> str | None:
        """The USD file the cloth's mesh comes from (None: a grid, an OBJ)."""
        from .mesh_io import USD_SUFFIXES

        if self.mesh is None or not self.mesh.file.lower().endswith(USD_SUFFIXES):
            return None
        return self.mesh.file

    def shortest_edge(self) -> float:
        """The shortest rest length of an edge (a grid's shorter cell side)."""
        if self.mesh is None:
            return min(self.size[0] / self.resolution[0], self.size[1] / self.resolution[1])
        return self.surface().shortest_edge

    def check_placement(self, cell: float, extent: float) -> None:
        """The cloth's particles near enough the world origin for float32 to resolve its springs: ``cell`` is
        its shortest edge, ``extent`` the longest side of the box around it as modelled."""
        farthest = max(abs(c) for c in self.origin) + extent
        _require(farthest <= MAX_CELLS_FROM_ORIGIN * cell, "origin",
                 f"a cloth within {MAX_CELLS_FROM_ORIGIN * cell:.4g} m of the world origin ({MAX_CELLS_FROM_ORIGIN} "
                 f"of its {cell:.3g} m cells: float32 positions farther out cannot resolve its springs)",
                 list(self.origin))

    @property
    def masses_from_mesh(self) -> bool:
        """Whether the particles' masses come from the mesh's faces (``density`` on a mesh cloth): then only
        ``geometry_checks.validate`` knows them."""
        return self.mesh is not None and self.areal_density is not None

    @property
    def areal_density(self) -> float | None:
        """The cloth's kg/m^2, its material's or its ``density``; None: a mass per particle."""
        return self.material.density if self.material is not None else self.density

    @property
    def strain_limit(self) -> Limit | None:
        """The strain limit the cloth is held to: its ``limit``, or its material's (the largest of its
        directions' fractions; each spring's own by its direction: materials.derive_springs)."""
        if self.material is None or not self.material.has_limits:
            return self.limit
        stretch, compression = self.material.stretch_limit, self.material.compression_limit
        return Limit(max(along(stretch)) if stretch is not None else Limit.stretch,
                     max(along(compression)) if compression is not None else Limit.compression)

    def mass_key(self) -> tuple[str, float | None]:
        """The key that sets the particles' masses, and its value."""
        if self.material is not None:
            return "material.density", self.material.density
        return ("density", self.density) if self.density is not None else ("mass", self.mass)

    def check_masses(self, lightest: float, heaviest: float) -> None:
        """Every particle's mass (then its inverse too) and stiffness / mass (the springs', the soft pins'), as the
        device holds them in float32.
        A material's ranges keep its springs' stiffness / mass finite (materials._RANGES)."""
        key, value = self.mass_key()
        check_float32(lightest, "the lightest particle's mass", key, value)
        check_float32(heaviest, "the heaviest particle's mass", key, value)
        for p, pin in enumerate(self.pins):
            if pin.soft:
                field = "damping" if pin.damping > pin.stiffness else "stiffness"
                _require(getattr(pin, field) / lightest <= FLOAT32_MAX, f"pins[{p}].{field}",
                         f"a soft pin's stiffness and damping / the lightest particle's mass ({lightest:.3g} kg) at "
                         f"most {FLOAT32_MAX:.3g} (float32)", getattr(pin, field))
        if self.material is not None:
            return
        for kind in ("structural", "shear", "bend"):
            spring = getattr(self, kind)
            field = "damping" if spring.damping > spring.stiffness else "stiffness"
            _require(getattr(spring, field) / lightest <= FLOAT32_MAX, f"{kind}.{field}",
                     f"stiffness and damping / the lightest particle's mass ({lightest:.3g} kg) at most "
                     f"{FLOAT32_MAX:.3g} (float32)", getattr(spring, field))

    def mass_range(self) -> tuple[float, float]:
        """The lightest and the heaviest particle's mass (kg): with ``density``, a corner has a quarter cell."""
        uniform = self.particle_mass()
        if uniform is not None:
            return uniform, uniform
        if self.mesh is not None:
            from .cloth_mesh import lumped_masses

            surface = self.surface()
            masses = lumped_masses(surface.points, surface.face_counts, surface.face_indices, self.areal_density)
            return float(masses.min()), float(masses.max())
        cell_area = self.size[0] / self.resolution[0] * self.size[1] / self.resolution[1]
        return self.areal_density * cell_area / 4.0, self.areal_density * cell_area

    @property
    def particle_count(self) -> int:
        if self.mesh is not None:
            return len(self.surface().points)
        return (self.resolution[0] + 1) * (self.resolution[1] + 1)

    def particle_mass(self) -> float | None:
        """The uniform per-particle mass, or None when a density (the cloth's or its material's) lumps area per
        particle."""
        if self.areal_density is not None:
            return None
        return 0.025 if self.mass is None else self.mass


@dataclass(frozen=True)
class Ground:
    """The plane y = ``height``; ``size`` is only how large it is drawn in the USD (0: fit the scene). Cloth
    rests ``thickness`` metres above it, so that a renderer sees a cloth lying on the ground, not in it."""

    height: float = 0.0
    friction: float = 0.0
    size: float = 0.0
    thickness: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self)
        _within_extent(self.height, "height")
        _non_negative(self.friction, "friction")
        _non_negative(self.size, "size")
        _within_extent(self.size, "size")
        _non_negative(self.thickness, "thickness")
        _within_extent(self.thickness, "thickness")

    @property
    def surface(self) -> float:
        """Where the cloth's particles are kept above: the plane raised by the thickness."""
        return self.height + self.thickness


@dataclass(frozen=True)
class TransformKey:
    """Where a keyed collider is at ``time`` (seconds): turned by ``rotate`` (degrees about X, then Y, then
    Z, about the mesh's own origin), then moved by ``translate``."""

    time: float = 0.0
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        check_fields(self)
        _non_negative(self.time, "time")
        _within_extent(self.translate, "translate")


def _check_key_times(keys: tuple[TransformKey, ...]) -> None:
    for k in range(1, len(keys)):
        _require(keys[k].time > keys[k - 1].time, f"keys[{k}].time",
                 f"times in increasing order (after keys[{k - 1}]'s {keys[k - 1].time:g} s)", keys[k].time)


@dataclass(frozen=True)
class Sphere:
    """A rigid sphere collider, static or moving about ``center``: along ``keys`` (``[[sphere.keys]]``:
    translations from ``center`` at times, interpolated linearly in between, held before the first and
    after the last), plus the oscillation ``motion``. ``spin`` turns it about its centre: the axis
    [x, y, z] scaled to degrees a second (the right-hand rule); friction then acts against the cloth's
    speed relative to the sphere's surface there, so a spinning sphere carries what rests on it round.
    Cloth is kept ``thickness`` metres off its surface (the sphere is drawn at ``radius``)."""

    name: str = "sphere"
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = 1.0
    friction: float = 0.0
    motion: Oscillation | None = None
    spin: Vec3 = (0.0, 0.0, 0.0)
    keys: tuple[TransformKey, ...] = ()
    thickness: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self)
        check_identifier(self.name, "name")
        _within_extent(self.center, "center")
        _positive(self.radius, "radius")
        _within_extent(self.radius, "radius")
        _non_negative(self.friction, "friction")
        _non_negative(self.thickness, "thickness")
        _within_extent(self.thickness, "thickness")
        _check_key_times(self.keys)
        for k, key in enumerate(self.keys):
            _require(key.rotate == (0.0, 0.0, 0.0), f"keys[{k}].rotate",
                     "no rotation on a sphere's key (a sphere turns by spin)", list(key.rotate))

    @property
    def surface_radius(self) -> float:
        """What the cloth's particles are kept outside of: the radius grown by the thickness."""
        return self.radius + self.thickness

    def keyed_offset(self, t: float) -> Vec3:
        """Where ``keys`` have moved the sphere from ``center`` at ``t`` seconds."""
        if not self.keys:
            return (0.0, 0.0, 0.0)
        after = next((k for k, key in enumerate(self.keys) if key.time > t), len(self.keys))
        if after in (0, len(self.keys)):
            return self.keys[min(after, len(self.keys) - 1)].translate
        a, b = self.keys[after - 1], self.keys[after]
        w = (t - a.time) / (b.time - a.time)
        return tuple(p + w * (q - p) for p, q in zip(a.translate, b.translate))

    def angular_velocity(self) -> Vec3:
        """``spin`` in radians a second."""
        return (math.radians(self.spin[0]), math.radians(self.spin[1]), math.radians(self.spin[2]))


@dataclass(frozen=True)
class MeshCollider:
    """A rigid collider made of the user's mesh (OBJ, or a USD ``Mesh`` prim with its transform), found
    through a BVH. Cloth is kept ``thickness`` metres off the side its faces face (for a closed mesh,
    outside), so that a draped cloth rests a visible distance off the surface, and ``friction`` acts as on
    the other colliders. It moves with its USD time samples, or along ``keys`` (``[[collider.keys]]``:
    translations and rotations at times, interpolated linearly in between, held before the first and
    after the last). A scene file may give the file alone: ``mesh = "table.obj"``."""

    name: str = "collider"
    mesh: MeshSource | None = None
    thickness: float = 0.01
    friction: float = 0.0
    keys: tuple[TransformKey, ...] = ()

    def __post_init__(self) -> None:
        check_fields(self)
        check_identifier(self.name, "name")
        _require(self.mesh is not None, "mesh", "the collider's mesh (a file, or { file, prim })", has_got=False)
        _non_negative(self.thickness, "thickness")
        _within_extent(self.thickness, "thickness")
        _non_negative(self.friction, "friction")
        _check_key_times(self.keys)

    def surface(self):
        """The collider's checked mesh (``mesh_io.SurfaceMesh``, read when first asked for: by
        ``geometry_checks.validate``); its errors name this collider's ``mesh``."""
        return _surface_of(self.mesh)


@dataclass(frozen=True)
class WindKey:
    """The wind's velocity (m/s) at ``time`` (seconds)."""

    time: float = 0.0
    velocity: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        check_fields(self)
        _non_negative(self.time, "time")
        _within_extent(self.velocity, "velocity")


@dataclass(frozen=True)
class Wind:
    """Air moving at ``velocity`` (m/s), or along ``keys`` (``[[wind.keys]]``: velocities at times,
    interpolated linearly in between, held before the first and after the last), acting on every face of
    every cloth through aerodynamic drag (``drag``: the coefficient of the pressure across a face) and lift
    (``lift``: across the flow, for a face tilted to it), in air of ``air_density`` (kg/m^3);
    ``turbulence`` adds noise of that fraction of the wind's speed, varying over ``scale`` metres and
    seconds (kernels/wind.py has the formulas)."""

    velocity: Vec3 = (0.0, 0.0, 0.0)
    turbulence: float = 0.0
    scale: float = 1.0
    air_density: float = 1.2
    drag: float = 1.0
    lift: float = 0.3
    keys: tuple[WindKey, ...] = ()

    def __post_init__(self) -> None:
        check_fields(self)
        _within_extent(self.velocity, "velocity")
        _check_key_times(self.keys)
        _require(not (self.keys and self.velocity != (0.0, 0.0, 0.0)), "velocity",
                 "a velocity or keys, not both", list(self.velocity))
        _non_negative(self.turbulence, "turbulence")
        _positive(self.scale, "scale")
        _non_negative(self.air_density, "air_density")
        _non_negative(self.drag, "drag")
        _non_negative(self.lift, "lift")


@dataclass(frozen=True)
class Collision:
    """Self and cloth-cloth collision between particles, found through a hash grid.

    Particles are spheres: by default of radius 0.25 x rest diagonal x (1 + stretch limit), the seed's
    rule, so that no sphere fits through a quad stretched to its limit; ``radius`` (metres) overrides it
    for every cloth. Two particles are kept ``separation`` radii apart (the mean of their radii).
    ``iterations`` Jacobi passes push overlapping pairs apart, then the approaching part of their
    relative velocity is removed, and ``friction`` takes tangential relative speed in proportion.
    Scenes of at most 512 particles find the pairs by checking all of them, where that is faster than
    building the grid. The strain limits (see ``Simulation.limit_solve``) are projected with the contacts:
    for a substep's first 200 passes jointly, one Jacobi kernel doing both (each particle moves by its
    limits' mean correction and its pushes' mean, no limit correction pulling into a contact: a launch less
    a pass, contacts held closer), then sequentially, the limit and then the separation on what it left (a
    chain of springs pulled taut over a contact converges only so; docs/notebook/strain-solve.md). Each
    particle's candidate pairs are listed within 1.5 contact distances and the lists remade once some
    particle has moved half the margin that leaves, so that no pair left out can touch before. With ``simulation.limit_solve = "converged"`` the passes go on
    (``iterations`` is not used) until no candidate pair is more than ``tolerance`` of its contact distance
    inside it, and the strain limits hold to theirs.

    ``thickness`` (metres; None: off) holds surfaces, not points, that far apart whatever the mesh's
    resolution (issue 34): every triangle edge and every vertex-triangle pair sharing no vertex
    (kernels/edge_collision.py, kernels/face_collision.py), in the converged solve, whose check then reads
    those pairs too, and each substep's displacements clamped to bounds under which no step makes a crossing
    (warp_cloth/displacement_bounds.py), with ``friction`` on those pairs too. The particles' default radius
    is then at most ``thickness / separation``, so that particle contacts reach no farther than the
    surfaces'; layers that start closer than the thickness are refused. A cloth's own pairs nearer at rest
    than thickness / (1 - its compression limit) are none (warp_cloth/surface_pairs.py), so its triangles may
    be finer than the thickness. Every cloth needs a strain limit (the edge hash's cells are sized by how far
    it lets an edge stretch).
    """

    self_collision: bool = field(default=True, metadata={"toml": "self"})
    between_cloths: bool = True
    radius: float | None = None
    separation: float = 2.1
    iterations: int = 2
    friction: float = 0.0
    max_neighbors: int = 32
    tolerance: float = 0.05
    thickness: float | None = None

    def __post_init__(self) -> None:
        check_fields(self)
        _require(self.self_collision or self.between_cloths, "self", "self or between_cloths to be true "
                 "(leave [collision] out for no particle collision)", self.self_collision)
        if self.radius is not None:
            _positive(self.radius, "radius")
            _within_extent(self.radius, "radius")
        _require(1.0 <= self.separation <= 4.0, "separation", "a number of radii in [1, 4]", self.separation)
        _whole_in(self.iterations, 1, MAX_ITERATIONS, "iterations")
        _non_negative(self.friction, "friction")
        _require(4 <= self.max_neighbors <= 256, "max_neighbors", "a whole number in [4, 256]", self.max_neighbors)
        _require(0.0 < self.tolerance <= 0.5, "tolerance", "a fraction of the contact distance in (0, 0.5]",
                 self.tolerance)
        if self.thickness is not None:
            _positive(self.thickness, "thickness")
            _within_extent(self.thickness, "thickness")


@dataclass(frozen=True)
class ImplicitSolver:
    """Settings of the ``implicit`` integrator (backward Euler). One Newton step is Baraff & Witkin's
    linearised step; more steps solve the nonlinear backward Euler equations until the residual (RMS over
    free particles of |M (v - v0) - h f| / m, in m/s) is below ``newton_tolerance``. Each step is solved
    by conjugate gradient to ``cg_tolerance`` (relative to the right-hand side, in the preconditioned norm)
    or ``cg_max_iterations``, in a conditional loop on the device (inside the captured graph); a single step
    starts from the last substep's solution."""

    newton_iterations: int = 1
    newton_tolerance: float = 1e-4
    cg_tolerance: float = 1e-4
    cg_max_iterations: int = 200

    def __post_init__(self) -> None:
        check_fields(self)
        _require(1 <= self.newton_iterations <= 100, "newton_iterations", "a whole number in [1, 100]",
                 self.newton_iterations)
        _non_negative(self.newton_tolerance, "newton_tolerance")
        _require(0 < self.cg_tolerance < 1, "cg_tolerance", "a number in (0, 1)", self.cg_tolerance)
        _require(1 <= self.cg_max_iterations <= 100000, "cg_max_iterations", "a whole number in [1, 100000]",
                 self.cg_max_iterations)


@dataclass(frozen=True)
class Simulation:
    """Time stepping. ``substeps = "auto"``, or neither ``substeps`` nor ``dt``: the simulator chooses the
    substeps frame by frame (``warp_cloth.auto_substeps``), starting at the stable step of the scene's own
    springs and masses (``warp_cloth.stability``), taking more where a frame's solves miss their tolerance
    within their caps or the blow-up guard flags it, fewer (never below that start) where they converge
    with room. A number of ``substeps`` per frame or a step ``dt`` fixes the step; the simulator warns before
    the run where it is past the stable bound. The step used is ``1 / (fps * substeps)``
    so that frames fall on exact times: for ``dt`` that is the largest such step at most 1% over ``dt``
    (so the seed's 0.0052, 0.0104, 0.0208 and 0.04165 s at 24 fps become 1/8, 1/4, 1/2 and 1 frame).
    ``drag`` is a linear air drag rate in 1/s (acceleration ``-drag * v``). A run stops as unstable when
    a particle's state is not finite or faster than ``max_speed`` (m/s).

    The strain limits (with particle collision, together with the contacts; with the rigid colliders in
    every pass) are projected in Jacobi passes: ``limit_solve = "converged"`` (the default) runs them in
    pairs until no limited spring is more than ``limit_tolerance`` of its
    allowed length outside it (and no pair of particles more than ``collision.tolerance`` of their
    contact distance inside it), at most ``limit_max_passes`` a substep (``Simulator.solver_stats()``
    says how many it took; unset: 1000, or as many as keep a frame within the simulator's bound on a frame's
    passes at its substeps). Each pair of passes is accelerated by Chebyshev's semi-iterative method with a
    spectral radius the solver adjusts (lowered where a pair leaves the residual growing, back up from solve
    to solve). ``"fixed"``, a fast mode to be
    chosen explicitly, runs ``limit_iterations`` passes a substep, however far that leaves the cloth from its
    limits (the run's summary says how far).

    ``compensated`` adds each explicit or symplectic step's move to the positions by Kahan's compensated
    summation: positions are float32, so far from the origin a small step's move loses its low bits, and
    over thousands of substeps that loss outgrows the step's own error (the study's references use it;
    one more vector read and written a particle a substep).

    The run keeps its shot's clock: ``start`` is the frame number of its first written frame (the initial
    state, unless there is a preroll), so that its frames and the time of every motion and key in the scene
    are the shot's (time = frame / fps seconds). Left out, it is the start time code of the USD shot the scene
    reads its colliders (else its cloths) from, where that sets one (1001 in a film pipeline), else 0.
    ``preroll`` frames are simulated before ``start`` and not written, for the cloth to settle before the shot
    begins: the colliders meanwhile run from the shot's earlier keys, or are held at their first key where it
    has none (``warp_cloth.shot_clock``)."""

    fps: float = 24.0
    frames: int = 240
    start: int | None = None
    preroll: int = 0
    substeps: int | Literal["auto"] | None = None
    dt: float | None = None
    integrator: Integrator = "symplectic"
    gravity: Vec3 = (0.0, -9.81, 0.0)
    drag: float = 0.0
    limit_iterations: int = 4
    limit_solve: Literal["fixed", "converged"] = "converged"
    limit_tolerance: float = 0.005
    limit_max_passes: int | None = None
    max_speed: float = 1000.0
    compensated: bool = False

    def __post_init__(self) -> None:
        check_fields(self)
        _require(0 < self.fps <= MAX_FPS, "fps", f"a number in (0, {MAX_FPS:g}]", self.fps)
        _whole_in(self.frames, 1, MAX_FRAMES, "frames")
        if self.start is not None:
            _whole_in(self.start, -MAX_FRAMES, MAX_FRAMES, "start")
        _whole_in(self.preroll, 0, MAX_FRAMES, "preroll")
        _require(not (self.substeps is not None and self.dt is not None), "dt",
                 "either substeps or dt, not both", self.dt)
        if isinstance(self.substeps, int):
            _require(1 <= self.substeps <= MAX_SUBSTEPS, "substeps",
                     f"a whole number in [1, {MAX_SUBSTEPS}] or \"auto\"", self.substeps)
        if self.dt is not None:
            _positive(self.dt, "dt")
            _require(self.dt <= 1.0 / self.fps * 1.01, "dt", f"at most one frame (1/fps = {1 / self.fps:g} s)",
                     self.dt)
            shortest = 0.99 / (self.fps * MAX_SUBSTEPS)
            _require(self.dt >= shortest, "dt", f"a step of at least {shortest:.3g} s (at most {MAX_SUBSTEPS} "
                                                f"substeps a frame at {self.fps:g} fps)", self.dt)
        if self.time_step is not None:  # else chosen by the simulator, within the same substep bound
            check_float32(self.time_step, "the step 1 / (fps x substeps)", "fps", self.fps)
        _non_negative(self.drag, "drag")
        _positive(self.max_speed, "max_speed")
        _whole_in(self.limit_iterations, 1, MAX_ITERATIONS, "limit_iterations")
        _require(0.0 < self.limit_tolerance <= 0.1, "limit_tolerance", "a fraction of an allowed length in (0, 0.1]",
                 self.limit_tolerance)
        if self.limit_max_passes is not None:
            _whole_in(self.limit_max_passes, 2, MAX_ITERATIONS, "limit_max_passes")
        _require(not self.compensated or self.integrator != "implicit", "compensated",
                 "false with the implicit integrator (it sums the explicit and symplectic steps' moves)",
                 self.compensated)

    @property
    def substeps_per_frame(self) -> int | None:
        """The substeps a frame that ``substeps`` or ``dt`` set; None under ``auto_substeps``: the simulator
        then chooses them frame by frame (``Simulator.substeps_per_frame``, see ``stability.choose_step`` and
        ``warp_cloth.auto_substeps``)."""
        if isinstance(self.substeps, int):
            return self.substeps
        if self.dt is None:
            return None
        return max(1, math.ceil(0.99 / (self.fps * self.dt)))

    @property
    def auto_substeps(self) -> bool:
        """Whether the simulator chooses the substeps frame by frame: ``substeps = "auto"``, or neither
        ``substeps`` nor ``dt`` set."""
        return self.substeps_per_frame is None

    @property
    def time_step(self) -> float | None:
        """The time step that ``substeps`` or ``dt`` set, in seconds (None: chosen by the simulator). (Not
        ``step``: ``Simulator.step()`` advances a frame.)"""
        substeps = self.substeps_per_frame
        return None if substeps is None else 1.0 / (self.fps * substeps)


@dataclass(frozen=True)
class Output:
    """What a run writes: a USD stage and/or Houdini .poly files, under ``dir``."""

    dir: str = "out"
    usd: bool = True
    poly: bool = True
    subdivision: Literal["none", "catmullClark"] = "none"

    def __post_init__(self) -> None:
        check_fields(self)
        _require(bool(self.dir) and "\0" not in self.dir, "dir", "a folder path", self.dir)


RESERVED_NAME = "ground"  # the ground's prim: no cloth or sphere may take it


@dataclass(frozen=True)
class Scene:
    name: str = "scene"
    description: str = ""
    simulation: Simulation = Simulation()
    output: Output = Output()
    implicit: ImplicitSolver = ImplicitSolver()
    cloths: tuple[Cloth, ...] = field(default=(), metadata={"toml": "cloth"})
    ground: Ground | None = None
    spheres: tuple[Sphere, ...] = field(default=(), metadata={"toml": "sphere"})
    colliders: tuple[MeshCollider, ...] = field(default=(), metadata={"toml": "collider"})
    collision: Collision | None = None
    wind: Wind | None = None
    seams: tuple[Seam, ...] = field(default=(), metadata={"toml": "seam"})

    def __post_init__(self) -> None:
        check_fields(self)
        check_file_name(self.name, "name")
        _require(len(self.cloths) >= 1, "cloth", "at least one [[cloth]]", len(self.cloths))
        self._check_names_unique()
        self._check_pin_targets()
        self._check_motion_in_bounds()
        self._check_edge_contacts_limited()
        self._check_seam_sides()

    def _check_names_unique(self) -> None:
        """Cloths, spheres and mesh colliders are prims side by side under /World, beside the ground's, and
        cloths name .poly files: names are compared ignoring case, as file names are on some systems."""
        taken = {RESERVED_NAME: "the ground's prim"}
        for kind, items in (("cloth", self.cloths), ("sphere", self.spheres), ("collider", self.colliders)):
            for k, item in enumerate(items):
                other = taken.setdefault(item.name.casefold(), f"{kind}[{k}]")
                _require(other == f"{kind}[{k}]", f"{kind}[{k}].name",
                         f"a name that no other cloth, sphere or collider has, nor the ground (ignoring case; {other} "
                         "has it)", item.name)

    def _check_edge_contacts_limited(self) -> None:
        """A surface thickness's edge contacts find their pairs among edges as long as the stretch limit lets
        them get; its contacts are held, and checked, in the converged solve."""
        if self.collision is None or self.collision.thickness is None:
            return
        key, got = "collision.thickness", self.collision.thickness
        for c, cloth in enumerate(self.cloths):
            _require(cloth.strain_limit is not None, key,
                     f"no thickness, or a strain limit on every cloth (cloth[{c}] "
                     "has none: edge contacts size their search by how far the limit lets an edge stretch)", got)
        _require(self.simulation.limit_solve == "converged", key,
                 "no thickness, or simulation.limit_solve = \"converged\" (surface contacts are held, and checked, "
                 "in the converged solve)", got)

    def _check_seam_sides(self) -> None:
        """Each side names a cloth of the scene, with a selection that kind of cloth has."""
        names = {c.name: c for c in self.cloths}
        for k, seam in enumerate(self.seams):
            for side_key, side in (("a", seam.a), ("b", seam.b)):
                key = f"seam[{k}].{side_key}"
                _require(side.cloth in names, f"{key}.cloth", "the name of a [[cloth]] (" + ", ".join(names) + ")",
                         side.cloth)
                mesh = names[side.cloth].mesh is not None
                _require(side.edge is None or not mesh, f"{key}.edge", "no edge on a mesh cloth's side (edges are "
                         "a grid's: use group or indices)", side.edge)
                _require(side.group is None or mesh, f"{key}.group", "no group on a grid cloth's side (groups are a "
                         "mesh's: use edge or indices)", side.group)

    def _check_pin_targets(self) -> None:
        colliders = [c.name for c in self.colliders]
        near = [s.name for s in self.spheres] + colliders + ([RESERVED_NAME] if self.ground is not None else [])
        named: dict[str, str] = {}
        for c, cloth in enumerate(self.cloths):
            for p, pin in enumerate(cloth.pins):
                if pin.name is not None:
                    other = named.setdefault(pin.name, f"cloth[{c}].pins[{p}]")
                    _require(other == f"cloth[{c}].pins[{p}]", f"cloth[{c}].pins[{p}].name",
                             f"a name no other pin has ({other} has it)", pin.name)
                if pin.near is not None:
                    _require(pin.near.collider in near, f"cloth[{c}].pins[{p}].near.collider",
                             "the name of a sphere, a [[collider]] or the ground (" + (", ".join(near) or
                                                                                     "the scene has none") + ")",
                             pin.near.collider)
                key = f"cloth[{c}].pins[{p}].target"
                if pin.target is not None and pin.target.startswith("/"):  # the prim: geometry_checks.validate
                    _require(cloth.usd_file() is not None, key, "the name of a [[collider]] (a prim path is for "
                             "a cloth from a USD file)", pin.target)
                    continue
                _require(pin.target is None or pin.target in colliders, key,
                         "the name of a [[collider]] (" + (", ".join(colliders) or "the scene has none") + ")"
                         + ", or for a cloth from a USD file a prim's path", pin.target)

    def _check_motion_in_bounds(self) -> None:
        """Start-up speeds and forces that the device holds in float32 and the blow-up guard accepts."""
        sim = self.simulation
        for c, cloth in enumerate(self.cloths):
            if not cloth.masses_from_mesh:
                self.check_weight(c, cloth.mass_range()[1])
            _require(math.hypot(*cloth.velocity) < sim.max_speed, f"cloth[{c}].velocity",
                     f"a speed below simulation.max_speed = {sim.max_speed:g} m/s", list(cloth.velocity))
            for p, pin in enumerate(cloth.pins):
                if pin.motion is None:
                    continue
                speed = pin.motion.amplitude * 2.0 * math.pi * pin.motion.frequency
                _require(speed < sim.max_speed, f"cloth[{c}].pins[{p}].motion",
                         f"a peak speed (amplitude x 2 pi frequency = {speed:.3g} m/s) below simulation.max_speed "
                         f"= {sim.max_speed:g} m/s", has_got=False)

    def check_weight(self, c: int, heaviest: float) -> None:
        """Cloth ``c``'s heaviest particle (``heaviest`` kg) of a weight finite in float32, as the device holds it."""
        cloth = self.cloths[c]
        weight = heaviest * math.hypot(*self.simulation.gravity)
        key, value = cloth.mass_key()
        _require(weight <= FLOAT32_MAX, f"cloth[{c}].{key}",
                 f"a mass whose weight (mass x |gravity| = {weight:.3g} N) is finite in float32", value)
