"""The rigid collider kinds in one table, ``KINDS``: each kind uploads its arrays, fills its fields of the
kernels' ``RigidColliders`` (empty ones where a pass ends with no colliders), gives the pass that moves it
each substep where it moves, and measures how deep particles start inside it. The device side is
kernels/colliders.py: a kind's fields in ``RigidColliders`` and its ``collide_<kind>``, one loop a kind
(a Warp kernel cannot dispatch on Python objects)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warp_cloth.kernels import motion
from warp_cloth.kernels.colliders import RigidColliders, depth_in_mesh

from .model import Model, Worlds
from .scene import Scene

if TYPE_CHECKING:
    from .state import DeviceState


def upload(values: np.ndarray, dtype, device) -> wp.array:
    """A host array on the device (the device model's uploads and its collider kinds')."""
    return wp.array(values, dtype=dtype, device=device)


class Ground:
    """Each world's ground plane (a scene's ``ground``)."""

    def __init__(self, model: Model, scene: Scene, worlds: Worlds, device, h: float) -> None:
        self.present = bool(worlds.ground.any())
        self.motion = None
        self.worlds = worlds
        self._arrays = (upload(worlds.ground, int, device), upload(worlds.ground_height, float, device),
                        upload(worlds.ground_friction, float, device))

    def fill(self, colliders: RigidColliders, state: DeviceState) -> None:
        colliders.ground, colliders.ground_height, colliders.ground_friction = self._arrays

    @staticmethod
    def fill_none(colliders: RigidColliders, device) -> None:
        colliders.ground = wp.zeros(0, dtype=int, device=device)
        colliders.ground_height = colliders.ground_friction = wp.zeros(0, dtype=float, device=device)

    def start_depths(self, x: np.ndarray, model: Model, allowed: np.ndarray) -> list[tuple[int, np.ndarray, str]]:
        """(the first particle, how deep each from it on starts inside, what it starts inside), as below."""
        worlds, world = self.worlds, model.particle_world
        if not worlds.ground.any():
            return []
        return [(0, np.where(worlds.ground[world] != 0, worlds.ground_height[world] - x[:, 1], -np.inf),
                 "the ground")]


class SphereMotion:
    """Puts moving spheres where their motion has them at the end of the substep, with its velocity."""

    name = "spheres:move"

    def __init__(self, spheres, device, h: float) -> None:
        self.h = h
        self.center, self.key_start = upload(spheres.center, wp.vec3, device), upload(spheres.key_start, int, device)
        self.key_time, self.key_offset = upload(spheres.key_time, float, device), upload(spheres.key_offset,
                                                                                          wp.vec3, device)
        self.amplitude = upload(spheres.amplitude, wp.vec3, device)
        self.frequency, self.phase = upload(spheres.frequency, float, device), upload(spheres.phase, float, device)

    def run(self, state: DeviceState) -> None:
        wp.launch(motion.move_spheres, dim=state.sphere_center.shape[0],
                  inputs=[state.clock, self.h, self.center, self.key_start, self.key_time, self.key_offset,
                          self.amplitude, self.frequency, self.phase],
                  outputs=[state.sphere_center, state.sphere_velocity], device=state.device)


class Spheres:
    """Spheres, still, spinning or moving; where they are is the state's (``sphere_center``, ``sphere_velocity``),
    which starts at ``initial_center``."""

    def __init__(self, model: Model, scene: Scene, worlds: Worlds, device, h: float) -> None:
        spheres = model.spheres
        self.present = spheres is not None
        self.scene, self.worlds, self.spheres = scene, worlds, spheres
        self.initial_center = None if spheres is None else spheres.initial_center  # host: the state starts there
        self.motion = None if spheres is None or not spheres.moving else SphereMotion(spheres, device, h)
        self._start = upload(worlds.sphere_start, int, device)
        self._radius = upload(spheres.radius if spheres is not None else np.zeros(0), float, device)
        self._friction = upload(spheres.friction if spheres is not None else np.zeros(0), float, device)
        self._spin = upload(spheres.angular_velocity if spheres is not None else np.zeros((0, 3)), wp.vec3, device)

    def fill(self, colliders: RigidColliders, state: DeviceState) -> None:
        colliders.sphere_start = self._start
        colliders.center, colliders.velocity = state.sphere_center, state.sphere_velocity
        colliders.radius, colliders.friction = self._radius, self._friction
        colliders.angular_velocity = self._spin

    @staticmethod
    def fill_none(colliders: RigidColliders, device) -> None:
        colliders.sphere_start = wp.zeros(0, dtype=int, device=device)
        colliders.center = colliders.velocity = colliders.angular_velocity = wp.zeros(0, dtype=wp.vec3, device=device)
        colliders.radius = colliders.friction = wp.zeros(0, dtype=float, device=device)

    def start_depths(self, x: np.ndarray, model: Model, allowed: np.ndarray) -> list[tuple[int, np.ndarray, str]]:
        """Static spheres only: a moving one may start in a cloth, a moment of its motion."""
        if self.spheres is None:
            return []
        sphere_world = np.repeat(np.arange(self.worlds.count), np.diff(self.worlds.sphere_start))
        depths = []
        for s, sphere in enumerate(self.scene.spheres):
            if sphere.motion is not None and sphere.motion.amplitude > 0 and sphere.motion.frequency > 0:
                continue
            first, end = model.world_start[sphere_world[s]], model.world_start[sphere_world[s] + 1]
            distance = np.linalg.norm(x[first:end] - self.spheres.initial_center[s], axis=1)
            depths.append((first, float(self.spheres.radius[s]) - distance, f"sphere[{s}] '{sphere.name}'"))
        return depths


class MeshAnimation:
    """Puts animated mesh colliders where their keys have them at the end of the substep, with their
    vertices' velocities, and refits their BVHs."""

    name = "mesh colliders:move"

    def __init__(self, animated: tuple[tuple[wp.Mesh, wp.array, wp.array], ...], h: float) -> None:
        self.animated, self.h = animated, h  # (BVH, key times (k,), keys (k, v) vec3) each

    def run(self, state: DeviceState) -> None:
        for mesh, key_times, keys in self.animated:
            wp.launch(motion.place_keyed_points, dim=mesh.points.shape[0],
                      inputs=[state.clock, self.h, key_times, keys], outputs=[mesh.points, mesh.velocities],
                      device=state.device)
            mesh.refit()


class Meshes:
    """The user's meshes, static or animated by keys; the BVHs are kept here (the kernels hold only their
    ids). ``reach``: how far past its thickness a mesh looks for particles."""

    def __init__(self, model: Model, scene: Scene, worlds: Worlds, device, h: float) -> None:
        colliders = model.mesh_colliders
        self.present = colliders is not None
        self.scene, self.worlds, self.device = scene, worlds, device
        self._start = upload(worlds.mesh_start, int, device)
        self._reach = float(model.edge_rest.max()) if len(model.edge_rest) else 0.0
        self.motion = None
        if colliders is None:
            self.meshes: tuple[wp.Mesh, ...] = ()
            self._ids = wp.zeros(0, dtype=wp.uint64, device=device)
            self._thickness = self._friction = wp.zeros(0, dtype=float, device=device)
            return
        self.meshes = tuple(wp.Mesh(points=upload(points, wp.vec3, device),
                                    indices=upload(triangles.ravel(), int, device),
                                    velocities=wp.zeros(len(points), dtype=wp.vec3, device=device))
                            for points, triangles in zip(colliders.points, colliders.triangles))
        animated = tuple((mesh, upload(times, float, device), upload(keys, wp.vec3, device))
                         for mesh, times, keys in zip(self.meshes, colliders.key_times, colliders.key_points)
                         if keys is not None)
        self.motion = MeshAnimation(animated, h) if animated else None
        self._ids = wp.array(np.array([m.id for m in self.meshes], dtype=np.uint64), dtype=wp.uint64, device=device)
        self._thickness = upload(colliders.thickness, float, device)
        self._friction = upload(colliders.friction, float, device)

    def fill(self, colliders: RigidColliders, state: DeviceState) -> None:
        colliders.mesh_start = self._start
        colliders.meshes, colliders.mesh_thickness = self._ids, self._thickness
        colliders.mesh_friction, colliders.mesh_reach = self._friction, self._reach

    @staticmethod
    def fill_none(colliders: RigidColliders, device) -> None:
        colliders.mesh_start = wp.zeros(0, dtype=int, device=device)
        colliders.meshes = wp.zeros(0, dtype=wp.uint64, device=device)
        colliders.mesh_thickness = colliders.mesh_friction = wp.zeros(0, dtype=float, device=device)
        colliders.mesh_reach = 0.0

    def start_depths(self, x: np.ndarray, model: Model, allowed: np.ndarray) -> list[tuple[int, np.ndarray, str]]:
        """Where each mesh starts, animated or not (inside: behind its nearest face, or within its thickness);
        pinned particles are left out (pins on a target start where they are attached, on its surface)."""
        depths = []
        mesh_world = np.repeat(np.arange(self.worlds.count), np.diff(self.worlds.mesh_start))
        reach = float(np.ptp(x, axis=0).max()) + float(allowed.max())
        free = model.inv_mass > 0
        points = upload(x, wp.vec3, self.device)
        for k, (mesh, thickness, collider) in enumerate(zip(self.meshes, self._thickness.numpy().tolist(),
                                                              self.scene.colliders)):
            depth = wp.zeros(len(x), dtype=float, device=self.device)
            wp.launch(depth_in_mesh, dim=len(x), inputs=[mesh.id, thickness, reach, points], outputs=[depth],
                      device=self.device)
            depths.append((0, np.where(free & (model.particle_world == mesh_world[k]),
                                       depth.numpy().astype(np.float64), 0.0), f"collider[{k}] '{collider.name}'"))
        return depths


KINDS = (Ground, Spheres, Meshes)  # in the order kernels/colliders.collide_particle runs them
