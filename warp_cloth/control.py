"""What a script drives between frames (``Simulator.control``, as Newton's ``Control``): named pins,
spheres and mesh colliders sent somewhere without keying the scene again.

``sim.control.pins["hand"].set_transform(translate=(0.2, 0, 0))`` sends a named pin's particles to their
initial pose turned and moved as a key of the pin's ``keys`` would (``rotate``: degrees about X, then Y, then
Z, about their centre, then ``translate``); ``set_positions`` sends each particle to a point of its own.
``sim.control.spheres["ball"].set_center(c)`` sends a sphere's centre, and
``sim.control.colliders["body"].set_transform(translate, rotate)`` a mesh collider's points (its mesh as
modelled turned about its own origin, then moved, as its ``keys`` do). What is sent moves in a straight line
from where it is to there over the next frame, at the speed that takes (a soft pin's target: where its
springs pull), and stays there, in place of the scene's motion, until sent again. The first send adds the
control's passes to the plan (a scene never controlled launches none); a checkpoint does not keep what was
sent.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warp_cloth.kernels import motion

from .cloth_grid import rotation_matrix
from .collider_kinds import Meshes, upload
from .pin_reach import sent_pins_past_reach
from .scene import Scene, Vec3

if TYPE_CHECKING:
    from .device_model import DeviceModel
    from .model import Model
    from .state import DeviceState


class ControlGroup:
    """Rows that a script sends somewhere: each one's point (a particle or a sphere), where it left from,
    where it goes, and the frame it goes over (-1: never sent, the scene moves it)."""

    def __init__(self, index: np.ndarray, device) -> None:
        count = len(index)
        self.index = upload(index, int, device)
        self.start = wp.zeros(count, dtype=wp.vec3, device=device)
        self.goal = wp.zeros(count, dtype=wp.vec3, device=device)
        self.first_frame = wp.full(count, -1, dtype=int, device=device)

    def send(self, rows: slice, now: np.ndarray, goal: np.ndarray, frame: int) -> None:
        """Rows ``rows``, now at ``now``, to ``goal`` over frame ``frame`` (arrays the graphs hold, rewritten)."""
        for array, values in ((self.start, now), (self.goal, goal)):
            host = array.numpy()
            host[rows] = values
            array.assign(host.astype(np.float32))
        first = self.first_frame.numpy()
        first[rows] = frame
        self.first_frame.assign(first)


class FollowControl:
    """A pass: the rows of a control group where they were sent, at the end of the substep (a mesh's BVH
    refitted after)."""

    def __init__(self, name: str, group: ControlGroup, model: DeviceModel, fps: float,
                 outputs: Callable[[DeviceState], list[wp.array]], mesh: wp.Mesh | None = None) -> None:
        self.name, self.group, self.model, self.fps, self.outputs = name, group, model, fps, outputs
        self.mesh = mesh

    def run(self, state: DeviceState) -> None:
        g = self.group
        substeps = round(1.0 / (self.fps * self.model.h))
        wp.launch(motion.follow_control, dim=g.index.shape[0],
                  inputs=[state.clock, substeps, 1.0 / self.fps, g.index, g.start, g.goal, g.first_frame],
                  outputs=self.outputs(state), device=state.device)
        if self.mesh is not None:
            self.mesh.refit()


class PinControl:
    """One named pin's particles, sent from Python (see the module's docstring)."""

    def __init__(self, name: str, control: Control, group: ControlGroup, rows: slice, rest: np.ndarray,
                 where: Callable[[], np.ndarray]) -> None:
        self.name, self._control, self._group, self._rows, self._where = name, control, group, rows, where
        self.rest = rest  # (m, 3) the particles in the cloth's initial pose

    @property
    def count(self) -> int:
        return len(self.rest)

    def set_transform(self, translate: Vec3 = (0.0, 0.0, 0.0), rotate: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """Send the particles to their initial pose turned by ``rotate`` (degrees about X, then Y, then Z,
        about their centre) and moved by ``translate`` (metres), over the next frame."""
        centre = self.rest.mean(axis=0)
        self.set_positions((self.rest - centre) @ rotation_matrix(tuple(rotate)).T + centre + np.asarray(translate))

    def set_positions(self, positions) -> None:
        """Send each particle to its own point, ``positions`` (m, 3) in the pin's particle order, over the
        next frame. A ValueError, nothing sent, where a hard pin would end farther from another hard pin of
        its cloth (where that one is, or is sent to, for the same frame) than the cloth's stretch limit
        lets it reach (``pin_reach.sent_pins_past_reach``)."""
        goal = np.asarray(positions, dtype=np.float64)
        if goal.shape != self.rest.shape or not np.isfinite(goal).all():
            raise ValueError(f"positions: finite points of shape {self.rest.shape} (the pin's particles), "
                             f"got shape {goal.shape}")
        problem = self._control.past_reach(self._group, self._rows, goal)
        if problem is not None:
            raise ValueError(f"pin {self.name!r} sent too far: {problem}")
        self._control.send(self._group, self._rows, self._where()[self._rows], goal)


class SphereControl:
    """One sphere, sent from Python (see the module's docstring)."""

    def __init__(self, control: Control, group: ControlGroup, row: int, where: Callable[[], np.ndarray]) -> None:
        self._control, self._group, self._row, self._where = control, group, row, where

    def set_center(self, center: Vec3) -> None:
        """Send the sphere's centre to ``center`` over the next frame."""
        goal = np.asarray(center, dtype=np.float64).reshape(1, 3)
        if not np.isfinite(goal).all():
            raise ValueError(f"center: a finite point [x, y, z], got {center!r}")
        rows = slice(self._row, self._row + 1)
        self._control.send(self._group, rows, self._where()[rows], goal)


class ColliderControl:
    """One mesh collider, sent from Python (see the module's docstring)."""

    def __init__(self, control: Control, group: ControlGroup, points: np.ndarray, mesh: wp.Mesh) -> None:
        self._control, self._group, self._mesh = control, group, mesh
        self.points = points  # (v, 3) the mesh as modelled

    def set_transform(self, translate: Vec3 = (0.0, 0.0, 0.0), rotate: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """Send the mesh as modelled turned by ``rotate`` (degrees about X, then Y, then Z, about its own
        origin) and moved by ``translate``, over the next frame."""
        goal = self.points @ rotation_matrix(tuple(rotate)).T + np.asarray(translate, dtype=np.float64)
        if not np.isfinite(goal).all():
            raise ValueError(f"translate and rotate: finite numbers, got {translate!r}, {rotate!r}")
        self._control.send(self._group, slice(None), self._mesh.points.numpy(), goal)


class Named(dict):
    """Controls by name; a missing name's error lists the names there are."""

    def __init__(self, kind: str, items: dict) -> None:
        super().__init__(items)
        self.kind = kind

    def __missing__(self, name: str):
        raise KeyError(f"no {self.kind} named {name!r} (" + (", ".join(self) or f"no {self.kind} has a name") + ")")


class Control:
    """The pins with a ``name`` (``pins``), the spheres (``spheres``) and the mesh colliders (``colliders``)
    a script can send, by name. ``scene``: the model's (its spheres and colliders in the model's order);
    ``frame`` says which frame comes next;
    ``on_first_send`` is called before the first send (the simulator then builds its plan again with
    ``passes()``)."""

    def __init__(self, model: Model, device_model: DeviceModel, state: DeviceState, scene: Scene,
                 frame: Callable[[], int], on_first_send: Callable[[], None]) -> None:
        self._fps, self._frame = scene.simulation.fps, frame
        self._scene, self._model, self._state = scene, model, state
        self._on_first_send = on_first_send
        self.started = False
        self._groups: dict[str, ControlGroup] = {}
        self._meshes: dict[str, wp.Mesh] = {}
        pins, device = model.pins, device_model.device
        rest_all = np.concatenate([g.positions for g in model.cloths])
        controls = {}
        for soft in (False, True):
            named = [(name, first, end) for name, first, end in (pins.named if pins is not None else ())
                     if bool(pins.soft[first]) == soft]
            if not named:
                continue
            index = np.concatenate([pins.index[first:end] for _, first, end in named])
            group = self._groups["soft pins" if soft else "pins"] = ControlGroup(index, device)
            where = (lambda: device_model.soft_pins.target_x.numpy()) if soft else (lambda: state.x.numpy())
            row = 0
            for name, first, end in named:
                rows = slice(row, row + end - first)
                controls[name] = PinControl(name, self, group, rows, rest_all[pins.index[first:end]],
                                            lambda where=where, index=index: where()[index])
                row += end - first
        self.pins = Named("pin", controls)
        spheres = {}
        if model.spheres is not None:
            group = self._groups["spheres"] = ControlGroup(np.arange(len(model.spheres.radius)), device)
            spheres = {name: SphereControl(self, group, s, lambda: state.sphere_center.numpy())
                       for s, name in enumerate(s.name for s in scene.spheres)}
        self.spheres = Named("sphere", spheres)
        colliders = {}
        for collider, mesh in zip(scene.colliders, device_model.collider_kinds[Meshes].meshes):
            points = collider.surface().points
            group = self._groups[f"collider {collider.name}"] = ControlGroup(np.arange(len(points)), device)
            self._meshes[f"collider {collider.name}"] = mesh
            colliders[collider.name] = ColliderControl(self, group, points, mesh)
        self.colliders = Named("collider", colliders)

    @property
    def moves_meshes(self) -> bool:
        """Whether it can send mesh colliders (whose BVHs its passes then refit every substep)."""
        return bool(self._meshes)

    def past_reach(self, group: ControlGroup, rows: slice, goal: np.ndarray) -> str | None:
        """Where ``group``'s ``rows`` are hard pins sent to ``goal``: what is wrong if they would end out of
        their cloth's reach of its other hard pins, those sent for the coming frame taken where they go."""
        if group is not self._groups.get("pins"):
            return None
        where = self._state.x.numpy().astype(np.float64)
        index = group.index.numpy()
        coming = group.first_frame.numpy() == self._frame()
        where[index[coming]] = group.goal.numpy()[coming]
        where[index[rows]] = goal
        return sent_pins_past_reach(self._scene, self._model, index[rows], where)

    def send(self, group: ControlGroup, rows: slice, now: np.ndarray, goal: np.ndarray) -> None:
        if not self.started:
            self._on_first_send()
            self.started = True
        group.send(rows, now, goal, self._frame())

    def passes(self, model: DeviceModel) -> dict[str, list[FollowControl]]:
        """The control's passes by where the plan puts them: ``"colliders"`` (spheres and meshes, after the
        colliders' motion), ``"soft pins"`` (before the step), ``"pins"`` (after the pins' motion)."""
        outputs = {"spheres": lambda state: [state.sphere_center, state.sphere_velocity],
                   "soft pins": lambda state: [model.soft_pins.target_x, model.soft_pins.target_v],
                   "pins": lambda state: [state.x, state.v]}
        by_place: dict[str, list[FollowControl]] = {}
        for kind, group in self._groups.items():
            mesh = self._meshes.get(kind)
            output = outputs[kind] if mesh is None else (lambda state, mesh=mesh: [mesh.points, mesh.velocities])
            place = kind if kind in ("soft pins", "pins") else "colliders"
            by_place.setdefault(place, []).append(FollowControl(f"{kind}:control", group, model, self._fps, output,
                                                                mesh))
        return by_place
