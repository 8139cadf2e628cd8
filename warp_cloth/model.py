"""A scene's cloths packed into one particle buffer (with a cloth id), as host arrays ready to upload
(warp_cloth/device_model.py uploads them).

Only what the scene declares is built: no pin arrays without pins, no limit lists without limits. The
model holds the scene's geometry and material as arrays; its settings (step, gravity, collision) stay in
the scene, which the simulator passes along with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_cloth.kernels import springs as spring_kernels

from . import surface_pairs
from .adjacency import Adjacency
from .cloth_grid import build_grid
from .cloth_mesh import BEND, SHEAR, STRUCTURAL, BendStencils, ClothMesh, enclosing_radii, rest_adjacent_pairs
from .keyed_motion import collider_keys, keyed_at, keyed_points
from .mesh_cloth import build_mesh_cloth
from .mesh_io import load_transform_motion, triangle_sides
from .pin_selection import select_pins
from .materials import REGIMES as MATERIAL_REGIMES
from .scene import Cloth, Collision, Scene, SpringRegime, TransformKey
from .seams import SewnPairs, sewn_neighbourhood, sewn_pairs
from .shot_clock import shot_clock
from .spring_paths import nearest_along_edges

# The spring kernels' regime bits (kernels/springs.py), which the host side sets and reads.
FLAG_ELASTIC_TENSION = int(spring_kernels.ELASTIC_TENSION)
FLAG_ELASTIC_COMPRESSION = int(spring_kernels.ELASTIC_COMPRESSION)
FLAG_DAMPING_TENSION = int(spring_kernels.DAMPING_TENSION)
FLAG_DAMPING_COMPRESSION = int(spring_kernels.DAMPING_COMPRESSION)


def regime_flags(acts: SpringRegime, damping_acts: SpringRegime) -> int:
    """The kernel's regime bits for a spring's elastic part and dashpot (see ``kernels/springs.py``)."""
    elastic = {"tension": FLAG_ELASTIC_TENSION, "compression": FLAG_ELASTIC_COMPRESSION,
               "both": FLAG_ELASTIC_TENSION | FLAG_ELASTIC_COMPRESSION}[acts]
    damping = {"tension": FLAG_DAMPING_TENSION, "compression": FLAG_DAMPING_COMPRESSION,
               "both": FLAG_DAMPING_TENSION | FLAG_DAMPING_COMPRESSION}[damping_acts]
    return elastic | damping


@dataclass(frozen=True)
class Springs:
    pairs: np.ndarray  # (s, 2)
    rest: np.ndarray  # (s,) float32
    stiffness: np.ndarray
    damping: np.ndarray
    flags: np.ndarray  # (s,) int32
    kind: np.ndarray  # (s,) int32: STRUCTURAL, SHEAR or BEND
    limit_min: np.ndarray  # (s,) shortest allowed length, 0 where the spring is not limited
    limit_max: np.ndarray  # (s,) longest allowed length, inf where not limited
    adjacency: Adjacency


@dataclass(frozen=True)
class Pins:
    index: np.ndarray  # (p,) int32 particle
    anchor: np.ndarray  # (p, 3) rest position
    amplitude: np.ndarray  # (p, 3) amplitude * unit axis, zero for fixed pins
    frequency: np.ndarray
    phase: np.ndarray
    moving: bool
    target: np.ndarray  # (p,) int32 the mesh collider each pinned particle follows, -1: none
    stiffness: np.ndarray  # (p,) float32 N/m of a soft pin's spring to where its motion puts it, 0: a hard pin
    damping: np.ndarray  # (p,) float32 N s/m of a soft pin's spring
    named: tuple[tuple[str, int, int], ...] = ()  # each named pin's name and rows, first to end

    @property
    def soft(self) -> np.ndarray:
        """(p,) bool: the soft pins' rows."""
        return self.stiffness > 0


@dataclass(frozen=True)
class Worlds:
    """Independent scenes sharing the particle buffer (see warp_cloth/batch.py; a scene alone is one world):
    what each world has of its own beyond its cloths. Spheres and mesh colliders are in world order."""
    cloth_world: np.ndarray  # (cloths,) int32
    gravity: np.ndarray  # (w, 3) float32 m/s^2
    ground: np.ndarray  # (w,) int32: 1 where the world has a ground plane
    ground_height: np.ndarray  # (w,) float32: where the cloth rests (the plane raised by its thickness)
    ground_friction: np.ndarray  # (w,) float32
    sphere_start: np.ndarray  # (w + 1,) int32: world w's spheres are sphere_start[w] to [w + 1] - 1
    mesh_start: np.ndarray  # (w + 1,) int32: likewise its mesh colliders

    @classmethod
    def of_scene(cls, scene: Scene) -> "Worlds":
        ground = scene.ground
        return cls(np.zeros(len(scene.cloths), dtype=np.int32),
                   np.asarray([scene.simulation.gravity], dtype=np.float32),
                   np.asarray([ground is not None], dtype=np.int32),
                   np.asarray([ground.surface if ground is not None else 0.0], dtype=np.float32),
                   np.asarray([ground.friction if ground is not None else 0.0], dtype=np.float32),
                   np.asarray([0, len(scene.spheres)], dtype=np.int32),
                   np.asarray([0, len(scene.colliders)], dtype=np.int32))

    @property
    def count(self) -> int:
        return len(self.gravity)


@dataclass(frozen=True)
class PinAnimation:
    """Pinned particles carried along sampled positions: their keys or a USD prim's transform."""
    index: np.ndarray  # (m,) int32 particle
    key_times: np.ndarray  # (k,) seconds
    key_points: np.ndarray  # (k, m, 3) float32 where they are then
    soft: bool = False  # a soft pin's: the points are where its springs pull, not where its particles are


@dataclass(frozen=True)
class SeamEntries:
    """Where the sewn pairs are among the strain limits' incidences, and what the seams' pass (passes.CloseSeams)
    writes there each substep: the longest each may be, ``start_length`` shrunk to 0 over ``close_time``."""

    entry: np.ndarray  # (2k,) int32: the incidence (both ends of each pair)
    start_length: np.ndarray  # (2k,) float32
    close_time: np.ndarray  # (2k,) float32 seconds
    closes_at: np.ndarray  # (2k,) float32: the time on the run's clock it reaches 0
    residual_length: np.ndarray  # (incidences,) float32: what a sewn pair's violation is a fraction of (the
    # shortest edge of its cloths) where its allowed length is shorter, 0 for the springs


@dataclass(frozen=True)
class StrainLimits:
    """Limited (structural and shear) springs and sewn pairs as incidence lists with allowed length ranges,
    and each particle's long-range attachment: the nearest pin of its cloth (-1: none) and how far from it the
    particle may be. The attachment arrays are empty when no cloth has one."""

    offsets: np.ndarray
    other: np.ndarray
    min_length: np.ndarray
    max_length: np.ndarray  # a sewn pair's: where it starts (the seams' pass rewrites it every substep)
    attachment_pin: np.ndarray  # (n,) int32 or (0,)
    attachment_length: np.ndarray  # (n,) float32 or (0,)
    seams: SeamEntries | None = None


@dataclass(frozen=True)
class Spheres:
    center: np.ndarray  # (k, 3) centre of the motion
    initial_center: np.ndarray  # (k, 3) where the sphere is when the run begins
    radius: np.ndarray  # what the cloth is kept outside of: the radius and the thickness
    friction: np.ndarray
    angular_velocity: np.ndarray  # (k, 3) radians a second
    amplitude: np.ndarray  # (k, 3)
    frequency: np.ndarray
    phase: np.ndarray
    key_start: np.ndarray  # (k + 1,) int32: sphere s's keys are key_time[key_start[s]:key_start[s + 1]]
    key_time: np.ndarray  # float32 seconds
    key_offset: np.ndarray  # (keys, 3) float32: the translation from the centre then
    moving: bool


@dataclass(frozen=True)
class WindFaces:
    """Every cloth's faces, and each particle's, for the wind's forces."""

    faces: np.ndarray  # (f, 4) int32, -1 as a triangle's fourth
    offsets: np.ndarray  # (n + 1,) int32: particle i's faces are incident[offsets[i]:offsets[i + 1]]
    incident: np.ndarray  # int32 face indices


@dataclass(frozen=True)
class MeshColliders:
    """Each mesh collider's triangles in world space (its quads fanned into two)."""

    points: tuple[np.ndarray, ...]  # (v, 3) float32 each, where it starts
    triangles: tuple[np.ndarray, ...]  # (t, 3) int32 each
    thickness: np.ndarray  # (k,) float32
    friction: np.ndarray  # (k,) float32
    key_times: tuple[np.ndarray | None, ...]  # seconds at which an animated collider's points are keyed
    key_points: tuple[np.ndarray | None, ...]  # (keys, v, 3) float32 its points then; None: static

    @property
    def animated(self) -> bool:
        return any(keys is not None for keys in self.key_points)


@dataclass(frozen=True)
class ContactEdges:
    """The triangle edges that edge contacts keep apart (kernels/edge_collision.py)."""

    ends: np.ndarray  # (m, 2) int32, particles
    incidence: Adjacency  # each particle's edges (its ``spring`` entries are edge numbers)
    longest: float  # the longest an edge may get: at its cloth's stretch limit, with a margin (the hash's least cells)


@dataclass(frozen=True)
class ParticleContacts:
    """What particle collision needs: each particle's sphere radius and, only where some cloth's
    strain limit cannot keep the particles of a face apart, those pairs to skip."""

    radius: np.ndarray  # (n,) float32
    exclude_adjacent: np.ndarray | None  # (cloths,) int32, 1 where rest-adjacent pairs are skipped
    rest_adjacent: Adjacency | None  # particles that share a face, both ways, each list sorted
    edges: ContactEdges | None = None  # where the scene asks for edge contacts
    sewn: Adjacency | None = None  # pairs a seam keeps from colliding (seams.sewn_neighbourhood), each list sorted
    rest_apart: np.ndarray | None = None  # (cloths,) float32 with a surface thickness: a pair of one cloth's
    # surfaces nearer than this at rest is no contact (surface_pairs.py)

    @property
    def max_radius(self) -> float:
        return float(self.radius.max())


@dataclass(frozen=True)
class Model:
    cloths: tuple[ClothMesh, ...]
    offsets: tuple[int, ...]  # first particle of each cloth, plus the total at the end
    positions: np.ndarray  # (n, 3) float32
    velocities: np.ndarray
    masses: np.ndarray
    inv_mass: np.ndarray  # 0 for hard-pinned particles
    cloth_id: np.ndarray  # (n,) int32
    springs: Springs | None
    limits: StrainLimits | None
    pins: Pins | None
    spheres: Spheres | None
    contacts: ParticleContacts | None
    edges: np.ndarray  # (e, 2) int32: every cloth's structural and shear edges, springs or not
    edge_rest: np.ndarray  # (e,) float32: their rest lengths
    edge_kind: np.ndarray  # (e,) int32: STRUCTURAL or SHEAR
    mesh_colliders: MeshColliders | None = None
    wind_faces: WindFaces | None = None
    pin_animations: tuple[PinAnimation, ...] = ()
    worlds: Worlds | None = None  # None: the scene is one world (``Worlds.of_scene``)
    friction: np.ndarray | None = None  # (n,) float32 each particle's cloth's material's coefficient, 0 where it
    # sets none; None: no cloth's material sets one
    sewn: SewnPairs | None = None  # the seams' pairs; None: no seam
    bending: BendStencils | None = None  # the materials' bending stencils, every cloth's; None: none

    @property
    def particle_world(self) -> np.ndarray:
        """(n,) int32 each particle's world."""
        if self.worlds is None:
            return np.zeros(self.particle_count, dtype=np.int32)
        return self.worlds.cloth_world[self.cloth_id]

    @property
    def world_start(self) -> np.ndarray:
        """(worlds + 1,) where each world's particles start: a world's particles are contiguous."""
        count = 1 if self.worlds is None else self.worlds.count
        return np.searchsorted(self.particle_world, np.arange(count + 1))

    @property
    def particle_count(self) -> int:
        return self.offsets[-1]

    def cloth_slice(self, c: int) -> slice:
        return slice(self.offsets[c], self.offsets[c + 1])

    @property
    def triangles(self) -> np.ndarray:
        """(t, 3) int32 every cloth's triangles, in the model's particle numbers."""
        return np.concatenate([g.triangles + self.offsets[c] for c, g in enumerate(self.cloths)]).astype(np.int32)


def build_model(scene: Scene, worlds: Worlds | None = None) -> Model:
    """The scene's arrays; ``worlds``: where the scene packs several (see warp_cloth/batch.py)."""
    meshes = tuple(build_grid(c) if c.mesh is None else build_mesh_cloth(c) for c in scene.cloths)
    offsets = [0]
    for g in meshes:
        offsets.append(offsets[-1] + len(g.positions))
    n = offsets[-1]
    positions = np.concatenate([g.positions for g in meshes]).astype(np.float32)
    velocities = np.concatenate([np.tile(np.asarray(c.velocity, dtype=np.float32), (len(g.positions), 1))
                                 for c, g in zip(scene.cloths, meshes)])
    masses = np.concatenate([g.masses for g in meshes]).astype(np.float32)
    cloth_id = np.concatenate([np.full(len(g.positions), c, dtype=np.int32) for c, g in enumerate(meshes)])
    selections = select_pins(scene)
    pins = _pins(scene, meshes, offsets, selections)
    inv_mass = (1.0 / masses).astype(np.float32)
    begins = shot_clock(scene).first_time  # everything that moves starts where it is then
    if pins is not None:
        inv_mass[pins.index[~pins.soft]] = 0.0
        # A driven pin starts where its motion puts it, with that motion's velocity.
        omega = 2.0 * np.pi * pins.frequency[:, None]
        angle = omega * begins + pins.phase[:, None]
        positions[pins.index] = pins.anchor + pins.amplitude * np.sin(angle)
        velocities[pins.index] = pins.amplitude * omega * np.cos(angle)
    pin_animations = _pin_animations(scene, meshes, offsets, selections)
    for animation in pin_animations:
        positions[animation.index] = keyed_at(animation.key_times, animation.key_points, begins)
    springs = _springs(scene, meshes, offsets, n)
    edges, edge_rest, edge_kind = _edges(meshes, offsets)
    sewn = sewn_pairs(scene, positions, offsets, [float(g.rest_lengths[g.is_edge].min()) for g in meshes], begins)
    limits = _limits(springs, n, _attachments(scene, meshes, offsets, selections), sewn)
    return Model(meshes, tuple(offsets), positions, velocities, masses, inv_mass, cloth_id, springs, limits,
                 pins, _spheres(scene, begins), _contacts(scene, meshes, sewn), edges, edge_rest, edge_kind,
                 _mesh_colliders(scene, begins), _wind_faces(meshes, offsets) if scene.wind is not None else None,
                 pin_animations, worlds, _friction(scene, meshes), sewn, _bending(meshes, offsets))


def _bending(meshes, offsets) -> BendStencils | None:
    """Every cloth's bending stencils (a material's), numbered as the model's particles."""
    parts = [g.derived.bending.shifted(offset) for g, offset in zip(meshes, offsets)
             if g.derived is not None and g.derived.bending is not None]
    return BendStencils.joined(parts) if parts else None


def _friction(scene: Scene, meshes) -> np.ndarray | None:
    """Each particle's cloth's friction coefficient, where some cloth's material sets one."""
    coefficients = [c.material.friction if c.material is not None else None for c in scene.cloths]
    if all(f is None for f in coefficients):
        return None
    return np.concatenate([np.full(len(g.positions), f or 0.0, dtype=np.float32) for f, g in zip(coefficients, meshes)])


def _edges(meshes, offsets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The structural and shear edges of every cloth, whose strain is what the strain limit bounds, their
    rest lengths and kinds."""
    chosen = [g.is_edge for g in meshes]
    edges = np.concatenate([g.springs[c] + offset for g, c, offset in zip(meshes, chosen, offsets)])
    rest = np.concatenate([g.rest_lengths[c] for g, c in zip(meshes, chosen)])
    kind = np.concatenate([g.spring_kind[c] for g, c in zip(meshes, chosen)])
    return edges.astype(np.int32).reshape(-1, 2), rest.astype(np.float32), kind.astype(np.int32)


def _springs(scene: Scene, meshes, offsets, n: int) -> Springs | None:
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("pairs", "rest", "k", "b", "flags", "kind", "lo", "hi")}
    for c, (cloth, mesh) in enumerate(zip(scene.cloths, meshes)):
        for kind_id, kind in ((STRUCTURAL, cloth.structural), (SHEAR, cloth.shear), (BEND, cloth.bend)):
            if not kind.enabled:
                continue
            sel = mesh.spring_kind == kind_id
            if mesh.derived is not None and mesh.derived.stenciled is not None:
                sel &= ~mesh.derived.stenciled  # bent by its stencils instead
            count = int(sel.sum())
            rest = mesh.rest_lengths[sel]
            derived = mesh.derived
            parts["pairs"].append(mesh.springs[sel] + offsets[c])
            parts["rest"].append(rest)
            parts["k"].append(np.full(count, kind.stiffness) if derived is None else derived.stiffness[sel])
            parts["b"].append(np.full(count, kind.damping) if derived is None else derived.damping[sel])
            regimes = (kind.acts, kind.damping_acts) if derived is None else MATERIAL_REGIMES[kind_id]
            parts["flags"].append(np.full(count, regime_flags(*regimes), dtype=np.int32))
            parts["kind"].append(np.full(count, kind_id, dtype=np.int32))
            limit = cloth.strain_limit
            if limit is None or kind_id not in (STRUCTURAL, SHEAR):
                parts["lo"].append(np.zeros(count))
                parts["hi"].append(np.full(count, np.inf))
                continue
            stretch, compression = limit.stretch, limit.compression  # a material's: each spring's by its direction
            if derived is not None and derived.stretch_limit is not None:
                stretch = derived.stretch_limit[sel]
            if derived is not None and derived.compression_limit is not None:
                compression = derived.compression_limit[sel]
            parts["lo"].append(rest * (1.0 - compression))
            parts["hi"].append(rest * (1.0 + stretch))
    if not parts["pairs"]:
        return None
    pairs = np.concatenate(parts["pairs"])
    f32 = lambda key: np.concatenate(parts[key]).astype(np.float32)  # noqa: E731
    return Springs(pairs, f32("rest"), f32("k"), f32("b"), np.concatenate(parts["flags"]), np.concatenate(parts["kind"]),
                   f32("lo"), f32("hi"),
                   Adjacency.of(pairs, n))


def _limits(springs: Springs | None, n: int, attachments: tuple[np.ndarray, np.ndarray],
            sewn: SewnPairs | None) -> StrainLimits | None:
    """The limited springs, and the sewn pairs after them, as incidence lists."""
    if springs is None:
        pairs, lo, hi = np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=np.float32), np.zeros(0, dtype=np.float32)
    else:
        limited = np.isfinite(springs.limit_max)
        pairs, lo, hi = springs.pairs[limited], springs.limit_min[limited], springs.limit_max[limited]
    if len(pairs) == 0 and sewn is None:
        return None
    if sewn is None:
        adjacency = Adjacency.of(pairs, n)
        return StrainLimits(adjacency.offsets, adjacency.other, lo[adjacency.spring], hi[adjacency.spring],
                            *attachments)
    first = len(pairs)  # the sewn pairs' numbers start here
    adjacency = Adjacency.of(np.concatenate([pairs, sewn.pairs]), n)
    lo = np.concatenate([lo, np.zeros(len(sewn.pairs), dtype=np.float32)])
    hi = np.concatenate([hi, sewn.start_length])
    entry = np.nonzero(adjacency.spring >= first)[0]
    seam = adjacency.spring[entry] - first
    residual = np.concatenate([np.zeros(first, dtype=np.float32), sewn.scale])[adjacency.spring]
    seams = SeamEntries(entry.astype(np.int32), sewn.start_length[seam], sewn.close_time[seam], sewn.closes_at[seam],
                        residual.astype(np.float32))
    return StrainLimits(adjacency.offsets, adjacency.other, lo[adjacency.spring], hi[adjacency.spring], *attachments,
                        seams)


def _attachments(scene: Scene, meshes, offsets: list[int],
                 selections: list[list[np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Per particle, the nearest pin of its cloth across the cloth at rest and (1 + stretch) times the rest
    distance to it (empty arrays when no limited, pinned cloth asks for attachments): on a grid, flat and
    convex at rest, the straight distance; on a mesh, which may be curved, the shortest path along its
    structural and shear edges."""
    n = offsets[-1]
    pin_of = np.full(n, -1, dtype=np.int32)
    length = np.zeros(n, dtype=np.float32)
    attached = False
    for c, (cloth, chosen_per_pin) in enumerate(zip(scene.cloths, selections)):
        if cloth.strain_limit is None or not cloth.strain_limit.attachments or not chosen_per_pin:
            continue
        attached = True
        count = offsets[c + 1] - offsets[c]
        pinned = np.unique(np.concatenate(chosen_per_pin))
        if cloth.mesh is None:
            nx, ny = cloth.resolution
            gx, gy = np.arange(count) % (nx + 1), np.arange(count) // (nx + 1)
            nearest, distance = _nearest_on_grid(gx, gy, gx[pinned], gy[pinned], cloth.size[0] / nx,
                                                 cloth.size[1] / ny)
            nearest = pinned[nearest]
        else:
            mesh = meshes[c]
            nearest, distance = nearest_along_edges(count, mesh.springs[mesh.is_edge], mesh.rest_lengths[mesh.is_edge],
                                                    pinned)
        free = np.ones(count, dtype=bool)
        free[pinned] = False
        free &= nearest >= 0  # a piece of the mesh with no pin of its own is not attached
        sl = slice(offsets[c], offsets[c + 1])
        pin_of[sl] = np.where(free, nearest + offsets[c], -1)
        length[sl] = np.where(free, (1.0 + cloth.strain_limit.stretch) * distance, 0.0)
    if not attached:
        return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)
    return pin_of, length


def _nearest_on_grid(gx: np.ndarray, gy: np.ndarray, px: np.ndarray, py: np.ndarray, dx: float,
                     dy: float) -> tuple[np.ndarray, np.ndarray]:
    """For grid points (gx, gy), the index into (px, py) of the nearest point in the metric of cells dx by
    dy, and the distance. Points are grouped into grid lines (rows or columns, whichever are fewer) and
    the nearest of each line found by bisection, so an edge of pins costs one sweep."""
    if len(np.unique(py)) > len(np.unique(px)):  # fewer columns than rows: swap the axes
        return _nearest_on_grid(gy, gx, py, px, dy, dx)
    best = np.full(len(gx), np.inf)
    best_index = np.zeros(len(gx), dtype=np.int64)
    for row in np.unique(py):
        in_row = np.nonzero(py == row)[0]
        order = in_row[np.argsort(px[in_row])]
        xs = px[order]
        right = np.clip(np.searchsorted(xs, gx), 0, len(xs) - 1)
        left = np.clip(right - 1, 0, len(xs) - 1)
        across = ((gy - row) * dy) ** 2
        for side in (left, right):
            d2 = ((gx - xs[side]) * dx) ** 2 + across
            closer = d2 < best
            best[closer] = d2[closer]
            best_index[closer] = order[side[closer]]
    return best_index, np.sqrt(best)


def _pins(scene: Scene, meshes, offsets, selections: list[list[np.ndarray]]) -> Pins | None:
    index, amplitude, frequency, phase, target, stiffness, damping = [], [], [], [], [], [], []
    named, rows = [], 0
    collider_of = {c.name: k for k, c in enumerate(scene.colliders)}
    for c, (cloth, chosen_per_pin) in enumerate(zip(scene.cloths, selections)):
        for pin, chosen in zip(cloth.pins, chosen_per_pin):
            target.append(np.full(len(chosen), collider_of.get(pin.target, -1), dtype=np.int32))
            motion = pin.motion
            amp = np.zeros(3) if motion is None else np.asarray(motion.unit_axis()) * motion.amplitude
            index.append(chosen + offsets[c])
            amplitude.append(np.tile(amp, (len(chosen), 1)))
            frequency.append(np.full(len(chosen), 0.0 if motion is None else motion.frequency))
            phase.append(np.full(len(chosen), 0.0 if motion is None else motion.phase))
            stiffness.append(np.full(len(chosen), pin.stiffness or 0.0))
            damping.append(np.full(len(chosen), pin.damping))
            if pin.name is not None:
                named.append((pin.name, rows, rows + len(chosen)))
            rows += len(chosen)
    if not index:
        return None
    idx = np.concatenate(index).astype(np.int32)
    positions = np.concatenate([g.positions for g in meshes])
    amplitude_all = np.concatenate(amplitude).astype(np.float32)
    return Pins(idx, positions[idx].astype(np.float32), amplitude_all,
                np.concatenate(frequency).astype(np.float32), np.concatenate(phase).astype(np.float32),
                moving=bool(np.any(amplitude_all != 0.0)), target=np.concatenate(target),
                stiffness=np.concatenate(stiffness).astype(np.float32),
                damping=np.concatenate(damping).astype(np.float32),
                named=tuple(named))


def _pin_animations(scene: Scene, meshes, offsets, selections: list[list[np.ndarray]]) -> tuple[PinAnimation, ...]:
    """Pins carried along keys (turned about their particles' centre) or by a USD prim's transform."""
    animations = []
    for c, (cloth, chosen_per_pin) in enumerate(zip(scene.cloths, selections)):
        for pin, chosen in zip(cloth.pins, chosen_per_pin):
            start = meshes[c].positions[chosen]
            if pin.keys:
                centre = start.mean(axis=0)
                times, placed = keyed_points(start - centre, pin.keys, scene.simulation.fps)
                placed = placed + centre
            elif pin.target is not None and pin.target.startswith("/"):
                motion = load_transform_motion(cloth.usd_file(), pin.target)
                if motion is None:
                    continue  # a prim that does not move: fixed pins
                times, matrices = motion
                placed = np.einsum("pi,kij->kpj", start, matrices[:, :3, :3]) + matrices[:, None, 3, :3]
            else:
                continue
            animations.append(PinAnimation((chosen + offsets[c]).astype(np.int32), times,
                                           placed.astype(np.float32), pin.soft))
    return tuple(animations)


def _spheres(scene: Scene, begins: float) -> Spheres | None:
    """The scene's spheres, starting where their motion has them at ``begins`` seconds."""
    if not scene.spheres:
        return None
    amp = [np.zeros(3) if s.motion is None else np.asarray(s.motion.unit_axis()) * s.motion.amplitude
           for s in scene.spheres]
    f32 = lambda xs: np.asarray(xs, dtype=np.float32)  # noqa: E731
    initial = [np.add(s.center, s.keyed_offset(begins)) + (0.0 if s.motion is None else s.motion.offset(begins))
               for s in scene.spheres]
    keys = [s.keys or (TransformKey(),) for s in scene.spheres]  # unkeyed: held where it is
    return Spheres(f32([s.center for s in scene.spheres]), f32(initial), f32([s.surface_radius for s in scene.spheres]),
                   f32([s.friction for s in scene.spheres]), f32([s.angular_velocity() for s in scene.spheres]),
                   f32(amp),
                   f32([0.0 if s.motion is None else s.motion.frequency for s in scene.spheres]),
                   f32([0.0 if s.motion is None else s.motion.phase for s in scene.spheres]),
                   np.cumsum([0] + [len(k) for k in keys]).astype(np.int32),
                   f32([key.time for k in keys for key in k]), f32([key.translate for k in keys for key in k]),
                   moving=any((s.motion is not None and s.motion.amplitude > 0) or len(s.keys) > 1
                              for s in scene.spheres))


def _wind_faces(meshes, offsets) -> WindFaces:
    faces = np.concatenate([np.where(m.face_table() < 0, -1, m.face_table() + o) for m, o in zip(meshes, offsets)])
    corners = faces.ravel()
    face = np.repeat(np.arange(len(faces)), 4)[corners >= 0]
    particle = corners[corners >= 0]
    order = np.lexsort((face, particle))
    first = np.zeros(offsets[-1] + 1, dtype=np.int32)
    np.cumsum(np.bincount(particle, minlength=offsets[-1]), out=first[1:])
    return WindFaces(faces.astype(np.int32), first, face[order].astype(np.int32))


def _mesh_colliders(scene: Scene, begins: float) -> MeshColliders | None:
    """The scene's mesh colliders, starting where their keys have them at ``begins`` seconds."""
    if not scene.colliders:
        return None
    surfaces = [c.surface() for c in scene.colliders]
    animations = [collider_keys(c, scene.simulation.fps) for c in scene.colliders]
    return MeshColliders(tuple((s.points if p is None else keyed_at(t, p, begins)).astype(np.float32)
                               for s, (t, p) in zip(surfaces, animations)),
                         tuple(s.triangles().astype(np.int32) for s in surfaces),
                         np.array([c.thickness for c in scene.colliders], dtype=np.float32),
                         np.array([c.friction for c in scene.colliders], dtype=np.float32),
                         tuple(t for t, _ in animations),
                         tuple(None if p is None else p.astype(np.float32) for _, p in animations))


def collision_radii(cloth: Cloth, mesh: ClothMesh, radius_override: float | None) -> np.ndarray:
    """Each particle's sphere: the seed's rule made general, half the widest of its faces (the smallest
    circle around a face's triangle) stretched to the limit, so that a particle sphere cannot pass through
    a face; on a square grid a quarter of the rest diagonal, the face's centre two radii from its corners."""
    if radius_override is not None:
        return np.full(len(mesh.positions), radius_override)
    stretch = cloth.strain_limit.stretch if cloth.strain_limit is not None else 0.0
    return 0.5 * (1.0 + stretch) * enclosing_radii(mesh.positions, mesh.face_counts, mesh.face_indices)


def particle_radii(cloth: Cloth, mesh: ClothMesh, collision: Collision) -> np.ndarray:
    """The scene's radii (``collision_radii``); with a surface ``thickness`` and no radius set, the rule's
    capped at thickness / separation: the edge and face contacts keep faces apart, particle contacts then
    reach no farther than they do, and layers a thickness apart start clear of both at any resolution."""
    radii = collision_radii(cloth, mesh, collision.radius)
    if collision.radius is not None or collision.thickness is None:
        return radii
    return np.minimum(radii, collision.thickness / collision.separation)


def needs_adjacent_exclusion(cloth: Cloth, positions: np.ndarray, pairs: np.ndarray, radii: np.ndarray,
                             separation: float) -> bool:
    """True unless the strain limit alone keeps every pair of particles that share a face (``pairs``, from
    ``rest_adjacent_pairs``) farther apart than their contact distance: with the seed's rule and a 10%
    limit, grid neighbours stay >= 0.9 of a cell apart while contact needs 0.82 of a (square) cell, so they
    never touch and need no exclusion."""
    if cloth.strain_limit is None:
        return True
    rest = np.linalg.norm(positions[pairs[:, 0]] - positions[pairs[:, 1]], axis=1)
    contact = separation * 0.5 * (radii[pairs[:, 0]] + radii[pairs[:, 1]])
    return bool(np.any((1.0 - cloth.strain_limit.compression) * rest <= contact))


def triangle_edges_at_limit(cloth: Cloth, mesh: ClothMesh) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) the cloth's triangle edges and their lengths at the stretch limit."""
    pairs = triangle_sides(mesh.triangles, len(mesh.positions))
    a, b = pairs[:, 0], pairs[:, 1]
    return pairs, (1.0 + cloth.strain_limit.stretch) * np.linalg.norm(mesh.positions[a] - mesh.positions[b], axis=1)


EDGE_OVERSHOOT = 1.1  # the hash's least cells allow edges this much past their stretch limit (a solve's tolerance)


def _contact_edges(scene: Scene, meshes, offsets: np.ndarray) -> ContactEdges | None:
    """The edges that a surface thickness's edge contacts hold apart: every triangle edge (surfaces held
    apart, not points)."""
    found = [triangle_edges_at_limit(c, m) for c, m in zip(scene.cloths, meshes)]
    ends = np.concatenate([pairs + o for (pairs, _), o in zip(found, offsets)]).astype(np.int32)
    if len(ends) == 0:
        return None
    longest = EDGE_OVERSHOOT * max(float(length.max()) for _, length in found if len(length))
    return ContactEdges(ends, Adjacency.of(ends, int(offsets[-1])), longest)


def _contacts(scene: Scene, meshes, sewn: SewnPairs | None) -> ParticleContacts | None:
    collision = scene.collision
    if collision is None:
        return None
    radii = [particle_radii(c, m, collision) for c, m in zip(scene.cloths, meshes)]
    radius = np.concatenate(radii).astype(np.float32)
    offsets = np.cumsum([0] + [len(m.positions) for m in meshes])
    edges = _contact_edges(scene, meshes, offsets) if collision.thickness is not None else None
    adjacent = [rest_adjacent_pairs(m.face_counts, m.face_indices) for m in meshes]
    exclude = np.array([needs_adjacent_exclusion(c, m.positions, a, r, collision.separation)
                        and collision.self_collision
                        for c, m, a, r in zip(scene.cloths, meshes, adjacent, radii)], dtype=np.int32)
    sewn_apart = None if sewn is None else Adjacency.of(
        sewn_neighbourhood(sewn, [m.face_counts for m in meshes], [m.face_indices for m in meshes], list(offsets)),
        int(offsets[-1]))
    apart = None if collision.thickness is None else surface_pairs.rest_apart(scene.cloths, collision.thickness)
    if not exclude.any():
        return ParticleContacts(radius, None, None, edges, sewn_apart, apart)
    pairs = np.concatenate([a + o for a, o in zip(adjacent, offsets)])
    return ParticleContacts(radius, exclude, Adjacency.of(pairs, int(offsets[-1])), edges, sewn_apart, apart)
