"""Checkpoints: what a simulation needs to go on from a frame exactly as if it had never stopped.

A checkpoint is one ``.npz`` file: every device array that a substep reads before it writes it
(``Simulator.carried``: the state's positions, velocities, substep clock, order of the next line round,
spheres' centres and collision lists, and the plan's, such as the face contacts' lists), with the frame, the
substep count, with substeps auto the next frame's substeps and the counts that missed lately
(``auto_substeps.SubstepChoice.carried``), and a fingerprint of the scene. The frame and the substeps are on
the shot's clock (``warp_cloth.shot_clock``), as the simulator's are: a checkpoint of a run that starts at
1001 after a preroll of 24 frames may be at frame 990, of its preroll. It is written
under a temporary name and renamed, so a kill leaves the previous one whole.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from .errors import SceneError
from .output import fsync_path, temporary_path

FORMAT = 3  # 3: the plan's carried arrays and the line rounds' order too; 2: the state's arrays by name
_META_FIELDS = {"format": int, "frame": int, "substeps": int, "scene": str}  # what the metadata must hold


def scene_fingerprint(scene) -> str:
    """A hash of everything that decides the frames: the scene without its frame count and output
    settings (a resumed run may ask for more frames), the step it runs at, the meshes that mesh cloths
    were read from (their content, not only their paths) and this package's version. The scene is taken
    as a simulator runs it, with what it leaves to the simulator chosen (the step, the limit solve's cap),
    so that a scene file read again and the simulator's scene give the same hash; its clock's start is the
    one its shot gives where the scene sets none."""
    from . import __version__
    from .shot_clock import with_start
    from .stability import scene_with_step

    scene = with_start(scene_with_step(scene))
    fields = dataclasses.asdict(scene)
    del fields["simulation"]["frames"]
    for key in ("dir", "usd", "poly"):
        del fields["output"][key]
    digest = hashlib.sha256(f"{__version__}|{scene.simulation.time_step!r}|{fields!r}".encode())
    for cloth in scene.cloths:
        if cloth.mesh is not None:
            surface = cloth.surface()
            for array in (surface.points, surface.face_counts, surface.face_indices):
                digest.update(array.tobytes())
    return digest.hexdigest()


@dataclasses.dataclass
class Checkpoint:
    frame: int
    substeps: int
    scene: str  # the scene's fingerprint
    arrays: dict[str, np.ndarray]
    extra: dict  # what the writer of the checkpoint keeps with it (the CLI: where each output's frames are)
    substeps_choice: dict | None = None  # with substeps auto: ``SubstepChoice.carried()``


def save_checkpoint(sim, path: str | Path, extra: dict | None = None) -> None:
    arrays = {name: array.numpy() for name, array in sim.carried().items()}
    choice = sim.auto.carried() if sim.auto is not None else None
    _write(Path(path), Checkpoint(sim.frame, sim.substep_count, scene_fingerprint(sim.scene), arrays, extra or {},
                                  choice))


def rewrite_extra(path: Path, extra: dict) -> None:
    """The checkpoint at ``path`` with ``extra`` in place of what it kept."""
    checkpoint = load_checkpoint(path)
    checkpoint.extra = extra
    _write(path, checkpoint)


def _write(path: Path, checkpoint: Checkpoint) -> None:
    meta = {"format": FORMAT, "frame": checkpoint.frame, "substeps": checkpoint.substeps, "scene": checkpoint.scene,
            "extra": checkpoint.extra}
    if checkpoint.substeps_choice is not None:
        meta["substeps_choice"] = checkpoint.substeps_choice
    arrays = checkpoint.arrays
    temporary = temporary_path(path)
    with open(temporary, "wb") as f:
        np.savez(f, meta=np.array(json.dumps(meta)), **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(temporary, path)
    fsync_path(path.parent)


def load_checkpoint(path: str | Path) -> Checkpoint:
    """The checkpoint at ``path``; one cut short, of another format or lacking a field is refused naming it."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {name: data[name] for name in data.files if name != "meta"}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise SceneError("checkpoint", "a whole checkpoint written by warp-cloth (an .npz file; this one is cut short "
                                       f"or is not one: {exc})", has_got=False, source=str(path)) from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        got = meta.get("format") if isinstance(meta, dict) else meta
        raise SceneError("checkpoint", f"a checkpoint of format {FORMAT}", got, str(path))
    for name, kind in _META_FIELDS.items():
        if not isinstance(meta.get(name), kind) or isinstance(meta.get(name), bool):
            *others, last = _META_FIELDS
            found = "is missing" if name not in meta else f"is {meta[name]!r}"
            raise SceneError("checkpoint.meta", f"the fields {', '.join(others)} and {last} ({name} {found})",
                             has_got=False, source=str(path))
    return Checkpoint(meta["frame"], meta["substeps"], meta["scene"], arrays, meta.get("extra", {}),
                      meta.get("substeps_choice"))


def check_scene(checkpoint: Checkpoint, scene, source: str) -> None:
    if checkpoint.scene != scene_fingerprint(scene):
        raise SceneError("scene", "the scene and settings the checkpoint was made with (they changed since; "
                                  "run without --resume to start over)", has_got=False, source=source)


def restore(sim, checkpoint: Checkpoint, source: str = "checkpoint") -> None:
    check_scene(checkpoint, sim.scene, source)
    arrays = sim.carried()
    if set(arrays) != set(checkpoint.arrays):
        raise SceneError("checkpoint", "the arrays of this simulator", sorted(checkpoint.arrays), source)
    for name, array in arrays.items():
        values = checkpoint.arrays[name]
        if values.shape != array.numpy().shape:
            raise SceneError(f"checkpoint.{name}", f"shape {array.numpy().shape}", values.shape, source)
        array.assign(values)
    sim.frame = checkpoint.frame
    sim.substep_count = checkpoint.substeps
