"""The benchmark's cloth scenes run in Newton's cloth solvers, timed the way ``bench.py`` times ours.

Scene (as ours): an n x n particle cloth, 10 m x 10 m, in the XY plane (Y up) at z = 0 with x and y in
[0, 10], its whole top row pinned, gravity (0, -9.81, 0), 2.5 kg spread evenly (2.5 / n^2 a particle),
10 substeps a frame at 24 fps. ``hanging`` is the cloth alone; ``sphere`` adds a static, frictionless
sphere of radius 2 m at (5, 5, 1.5), which pokes through the plane the cloth hangs in, so there the cloth
starts swung back 20 degrees about its top edge (bottom edge at z = -3.4), clear of the sphere, and
swings onto it; ``self`` adds self contact to ``sphere``.

Settings (m = particle mass, dt = 1/240 s; chosen so that every solver stays finite at every n):

* ``semi_implicit`` (``SolverSemiImplicit``, symplectic Euler) and ``xpbd`` (``SolverXPBD``, 10
  iterations) share one mass-spring cloth, like ours: ``add_springs`` puts springs along every triangle
  edge (structural, one diagonal) and across every bending flap (the other diagonal, bend), with
  ``spring_ke = 0.1 m/dt^2``, ``spring_kd = 0.01 m/dt`` and weak dihedral bending
  (``edge_ke = 0.05 m/dt^2 cell^2``). Neither can take more at this step: the explicit step, or XPBD's
  Jacobi sweep (corrections summed over ~12 springs a particle, no averaging), blew up at 0.2-0.5 m/dt^2
  with n = 32. Newton's FEM triangles, the semi-implicit example's choice, blew up once stretched (n >= 64
  at the stiffness the step allows), so they are not used. Since m/dt^2 falls as 1/n^2, the cloth is
  softer as n grows: hanging, it stretches ~2 % at n = 32, ~10 % at n = 64 and to nearly three times
  its length at n = 256. These rows time the same work per spring, not an equally stiff cloth.
  Sphere contact: a penalty spring (``ke = 0.2 m/dt^2``, ``kd = 0.01 m/dt``) for semi-implicit, a
  position projection for XPBD.
* ``vbd`` (``SolverVBD``, 10 iterations, as Newton's examples): Neo-Hookean membrane triangles
  ``tri_ke = tri_ka = 1e3`` (a stiff cloth: hanging, its bottom edge sags ~2 cm at n = 32),
  ``tri_kd = 1``, dihedral bending ``1e-2``; sphere contact an implicit penalty
  (``soft_contact_ke = 1e4``, ``kd = 1``).

Self contact (``self`` only): VBD's vertex-triangle and edge-edge self contact, its BVH rebuilt once a
frame as the examples do; the two spring solvers' particle-particle contact (spheres found through a hash
grid, as ours; off in the other variants). Particles are spheres of our collision radius, 0.25 x cell
diagonal x 1.1, which is also how far Newton keeps them off the sphere (ours projects their centres onto
its surface). Semi-implicit's brute-force particle-triangle contact is left off.
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np
import warp as wp

VARIANTS = ("hanging", "sphere", "self")
SOLVERS = ("semi_implicit", "xpbd", "vbd")
SIZE = 10.0
TOTAL_MASS = 2.5
SPHERE_CENTER = (5.0, 5.0, 1.5)
SPHERE_RADIUS = 2.0
SWING_DEGREES = 20.0  # how far the sphere scenes' cloth starts swung back from hanging straight down
FPS = 24
FORMULATION = {"semi_implicit": "springs 0.1 m/dt^2 (explicit limit), penalty sphere contact",
               "xpbd": "distance constraints 0.1 m/dt^2 (Jacobi limit), projected sphere contact",
               "vbd": "Neo-Hookean triangles 1e3, implicit penalty sphere contact"}


def newton_available() -> bool:
    try:
        import newton  # noqa: F401
    except ImportError:
        return False
    return True


class NewtonCloth:
    """One scene built for one Newton solver; ``frame()`` runs a frame's substeps the examples' way
    (clear forces, collide, step, swap states)."""

    def __init__(self, variant: str, n: int, solver: str, device: str, substeps: int = 10,
                 worlds: int = 1) -> None:
        import newton

        if variant not in VARIANTS or solver not in SOLVERS:
            raise ValueError(f"variant must be one of {VARIANTS} and solver one of {SOLVERS}")
        self.variant, self.solver_name, self.substeps = variant, solver, substeps
        self.self_contact = variant == "self"
        self.dt = 1.0 / (FPS * substeps)
        cell = SIZE / (n - 1)
        mass = TOTAL_MASS / n**2
        k_limit = mass / self.dt**2
        self.radius = 0.25 * cell * 2**0.5 * 1.1

        if solver == "vbd":
            material = dict(tri_ke=1.0e3, tri_ka=1.0e3, tri_kd=1.0, edge_ke=1.0e-2, edge_kd=0.0)
            contact_ke, contact_kd = 1.0e4, 1.0
        else:
            material = dict(add_springs=True, spring_ke=0.1 * k_limit, spring_kd=0.01 * mass / self.dt,
                            tri_ke=0.0, tri_ka=0.0, tri_kd=0.0, edge_ke=0.05 * k_limit * cell**2, edge_kd=0.0)
            contact_ke, contact_kd = 0.2 * k_limit, 0.01 * mass / self.dt
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
        swing = SWING_DEGREES if variant != "hanging" else 0.0
        builder.add_cloth_grid(pos=wp.vec3(*swung_origin(swing)),
                               rot=wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), float(np.radians(swing))),
                               vel=wp.vec3(0.0, 0.0, 0.0),
                               dim_x=n - 1, dim_y=n - 1, cell_x=cell, cell_y=cell, mass=mass, fix_top=True,
                               particle_radius=self.radius, **material)
        if variant != "hanging":
            builder.add_shape_sphere(-1, xform=wp.transform(wp.vec3(*SPHERE_CENTER), wp.quat_identity()),
                                     radius=SPHERE_RADIUS,
                                     cfg=newton.ModelBuilder.ShapeConfig(ke=contact_ke, kd=contact_kd, mu=0.0))
        if worlds > 1:  # copies as Newton's worlds, side by side
            world, builder = builder, newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
            builder.replicate(world, worlds, spacing=(2.0 * SIZE, 0.0, 0.0))
        self.n, self.worlds = n, worlds
        if solver == "vbd":
            builder.color(include_bending=True)
        model = builder.finalize(device=device)
        # Newton mixes the model's and the shape's contact parameters: make them the same
        model.soft_contact_ke, model.soft_contact_kd, model.soft_contact_mu = contact_ke, contact_kd, 0.0
        model.particle_ke, model.particle_kd, model.particle_mu = contact_ke, contact_kd, 0.0
        if solver != "vbd" and not self.self_contact:
            # no grid (and a zero max radius, which XPBD checks): no particle-particle contact
            model.particle_grid = None
            model.particle_max_radius = 0.0

        if solver == "semi_implicit":
            model.tri_count = 0  # add_cloth_grid's triangles carry no stiffness here: don't evaluate them
            self.solver = newton.solvers.SolverSemiImplicit(model, enable_tri_contact=False)
        elif solver == "xpbd":
            self.solver = newton.solvers.SolverXPBD(model, iterations=10)
        else:
            self.solver = newton.solvers.SolverVBD(
                model, iterations=10, particle_enable_self_contact=self.self_contact,
                particle_self_contact_margin=2.0 * self.radius, particle_self_contact_gap=self.radius)
        self.model = model
        self.state_0, self.state_1 = model.state(), model.state()
        self.control = model.control()
        self.pipeline = newton.CollisionPipeline(model)
        self.contacts = self.pipeline.contacts()

    @property
    def notes(self) -> str:
        notes = [FORMULATION[self.solver_name]]
        if self.self_contact:
            notes.append("self contact: vertex-triangle + edge-edge" if self.solver_name == "vbd"
                         else "self contact: particle-particle spheres (hash grid)")
        return "; ".join(notes)

    def frame(self) -> None:
        if self.solver_name == "vbd" and self.self_contact:
            self.solver.rebuild_bvh(self.state_0)
        for i in range(self.substeps):
            self.state_0.clear_forces()
            self.pipeline.collide(self.state_0, self.contacts)
            self.solver.step(self.state_0, self.state_1, self.control, self.contacts, self.dt)
            if self.substeps % 2 == 1 and i == self.substeps - 1:
                self.state_0.assign(self.state_1)  # a replayed graph must end in the arrays it starts from
            else:
                self.state_0, self.state_1 = self.state_1, self.state_0

    def positions(self) -> np.ndarray:
        return self.state_0.particle_q.numpy().copy()  # on the CPU numpy() is a view of the live state

    def finite(self) -> bool:
        return bool(np.isfinite(self.positions()).all() and np.isfinite(self.state_0.particle_qd.numpy()).all())


def swung_origin(degrees: float) -> tuple[float, float, float]:
    """Where the cloth's corner (0, 0) goes when the cloth, rotated ``degrees`` about X, keeps its top
    edge at y = SIZE, z = 0: its bottom edge is then at z = -SIZE sin(degrees)."""
    angle = np.radians(degrees)
    return 0.0, float(SIZE * (1.0 - np.cos(angle))), float(-SIZE * np.sin(angle))


def grid_strain(positions: np.ndarray, n: int) -> tuple[float, float]:
    """The worst stretch and compression (a positive fraction) of the structural (row and column) and shear
    (both diagonals) edges of n x n cloths of this module's size, one after another: the edges ours limits
    and ``StrainMonitor`` measures; particles in row-major grid order, as both engines number them."""
    grid = positions.reshape(-1, n, n, 3)
    cell = SIZE / (n - 1)
    edges = ((grid[:, :, 1:], grid[:, :, :-1], cell), (grid[:, 1:], grid[:, :-1], cell),
             (grid[:, 1:, 1:], grid[:, :-1, :-1], cell * 2**0.5), (grid[:, 1:, :-1], grid[:, :-1, 1:], cell * 2**0.5))
    strains = [np.linalg.norm(a - b, axis=3) / rest - 1.0 for a, b, rest in edges]
    return max(0.0, float(max(s.max() for s in strains))), max(0.0, float(-min(s.min() for s in strains)))


def strain_over_run(variant: str, n: int, solver: str, device: str, frames: int, substeps: int = 10,
                    worlds: int = 1) -> tuple[float, float]:
    """The worst stretch and compression (``grid_strain``) over every frame of a fresh run of ``frames``
    frames, as ours is measured (inf once a position is not finite)."""
    cloth = NewtonCloth(variant, n, solver, device, substeps, worlds)
    stretch = compression = 0.0
    for _ in range(frames):
        cloth.frame()
        x = cloth.positions()
        if not np.isfinite(x).all():
            return np.inf, np.inf
        frame_stretch, frame_compression = grid_strain(x, n)
        stretch, compression = max(stretch, frame_stretch), max(compression, frame_compression)
    return stretch, compression


def time_newton(variant: str, n: int, solver: str, device: str, frames: int = 24, substeps: int = 10,
                repeats: int = 3, worlds: int = 1) -> dict[str, Any]:
    """Median wall time of ``frames`` frames of one scene in one Newton solver (as ``worlds`` copies, its
    worlds), after 2 warm-up frames, replaying one frame captured as a graph where the solver allows it.
    Repeats continue the same run, as bench's warmed cases do. ``build_seconds`` (not timed) is Newton's
    Python model build. The strain is measured over every frame of a second run as long as the timed one
    (2 + ``repeats`` x ``frames`` frames from the start): ``strain_over_run``."""
    started = time.perf_counter()
    cloth = NewtonCloth(variant, n, solver, device, substeps, worlds)
    build_seconds = time.perf_counter() - started
    dev = cloth.model.device
    notes = cloth.notes
    for _ in range(2):
        cloth.frame()
    graph = None
    states = cloth.state_0, cloth.state_1
    try:
        with wp.ScopedCapture(device=dev) as capture:
            cloth.frame()
        graph = capture.graph
    except Exception as error:  # e.g. a solver that reads back to the host inside its step
        cloth.state_0, cloth.state_1 = states  # capture swapped them without running anything
        notes += f"; no graph ({type(error).__name__}: {error})"
    step = (lambda: wp.capture_launch(graph)) if graph is not None else cloth.frame
    seconds = []
    for _ in range(repeats):
        wp.synchronize_device(dev)
        started = time.perf_counter()
        for _ in range(frames):
            step()
        wp.synchronize_device(dev)
        seconds.append(time.perf_counter() - started)
    median = statistics.median(seconds)
    particles = cloth.model.particle_count
    strain_frames = 2 + repeats * frames  # the warm-up and timed frames, from the start
    stretch, compression = strain_over_run(variant, n, solver, device, strain_frames, substeps, worlds)
    return {"solver": solver, "variant": variant, "n": n, "worlds": worlds, "particles": particles,
            "device": str(dev),
            "substeps": substeps, "frames": frames, "median_seconds": median, "ms_per_frame": 1e3 * median / frames,
            "particle_substeps_per_second": particles * substeps * frames / median, "graph": graph is not None,
            "self_contact": cloth.self_contact, "finite": cloth.finite(), "build_seconds": build_seconds,
            "max_strain": max(stretch, compression), "stretch": stretch, "compression": compression,
            "strain_frames": strain_frames, "notes": notes}
