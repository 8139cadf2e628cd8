"""``warp-cloth drape-test MATERIAL``: the Cusick drape test (BS 5058, ISO 9073-9) of a material, run on the
built-in scene ``drape_test`` (a 30 cm specimen over an 18 cm support disc, drape_geometry.py) until the
specimen comes to rest, and its drape coefficient compared with the published range of the preset's fabric
class (``fabric_presets.FabricData.drape``).

Coming to rest: the scene's air drag (the same for every fabric) takes the motion out; the specimen is
settled once its fastest particle has stayed below ``SETTLED_SPEED`` for ``SETTLED_FRAMES`` frames in a
row. A run that reaches the scene's frames first reports the coefficient with ``"settled": false``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import drape_geometry as geometry
from .errors import EXIT_BAD_INPUT, EXIT_OUTPUT_FAILED, EXIT_UNSTABLE, SceneError, UnstableSimulation
from .fabric_presets import PRESETS
from .materials import Material
from .scene import MAX_FRAMES, MeshSource, Scene

SCENE = "drape_test"
# m/s: the fastest particle, below which the specimen counts as at rest ... (measured on every preset at 30 and
# 60 cells: once the fastest is below 1.6 cm/s, the coefficient moves by at most 0.0005 in the next second;
# docs/guide/scene-reference.md)
SETTLED_SPEED = 0.01
SETTLED_FRAMES = 12  # ... for this many frames in a row (half a second at 24 fps)
MAX_RESOLUTION = 400
PICTURE = "drape test picture"  # what the top view is, in its PNG's mark


@dataclass(frozen=True)
class DrapeResult:
    material: str
    drape_coefficient: float
    published_range: tuple[float, float] | None
    source: str | None
    resolution: int
    seconds: float  # wall seconds of the simulation (building and compiling not counted)
    settled: bool
    frames: int
    simulated_seconds: float
    substeps: int
    fastest_speed: float  # m/s at the end
    worst_stretch: float  # of the specimen's edges at the end, fractions of their rest lengths
    worst_compression: float
    shadow_area: float  # m^2
    area_error: float  # m^2: the most the raster may be off by (drape_geometry.projected_area)
    coefficient_error: float  # what that makes of the coefficient
    particles: int
    device: str
    positions: np.ndarray = dataclasses.field(repr=False)
    triangles: np.ndarray = dataclasses.field(repr=False)

    def in_range(self) -> bool | None:
        if self.published_range is None:
            return None
        low, high = self.published_range
        return low <= self.drape_coefficient <= high

    def document(self) -> dict:
        """What ``--json`` writes."""
        return {"material": self.material, "drape_coefficient": round(self.drape_coefficient, 4),
                "published_range": list(self.published_range) if self.published_range else None,
                "source": self.source, "in_range": self.in_range(), "resolution": self.resolution,
                "seconds": round(self.seconds, 3), "settled": self.settled, "frames": self.frames,
                "simulated_seconds": round(self.simulated_seconds, 4), "substeps": self.substeps,
                "fastest_speed": self.fastest_speed, "worst_stretch": round(self.worst_stretch, 5),
                "worst_compression": round(self.worst_compression, 5), "shadow_area": self.shadow_area,
                "area_error": self.area_error, "coefficient_error": round(self.coefficient_error, 5),
                "particles": self.particles, "device": self.device,
                "settling": {"speed": SETTLED_SPEED, "frames": SETTLED_FRAMES}}

    def summary(self) -> str:
        said = f"{self.material}: drape coefficient {self.drape_coefficient:.3f} (+-{self.coefficient_error:.3f})"
        if self.published_range is not None:
            low, high = self.published_range
            said += f", published {low:.2f} to {high:.2f}: " + ("within" if self.in_range() else "outside")
        else:
            said += ", no published range"
        rest = "settled" if self.settled else f"NOT settled (fastest {self.fastest_speed:.3g} m/s)"
        return (f"{said}; {rest} after {self.frames} frames ({self.simulated_seconds:.2f} s), resolution "
                f"{self.resolution}, {self.particles} particles, {self.substeps} substeps on {self.device} in "
                f"{self.seconds:.1f} s; worst strain +{100 * self.worst_stretch:.1f}% / "
                f"-{100 * self.worst_compression:.1f}%")


def material_of(text: str) -> tuple[Material, str]:
    """MATERIAL: a preset's name, or a TOML file of a material's keys (as a cloth's ``material`` table gives
    them); the material and what to call it."""
    if text in PRESETS:
        return Material(preset=text), text
    path = Path(text)
    if not path.suffix == ".toml" or not path.is_file():
        raise SceneError("MATERIAL", "a preset (" + ", ".join(PRESETS) + ") or an existing .toml file of a "
                         "material's keys", text, "command line")
    import tomllib

    from .scene_file import table_as

    try:
        data = tomllib.loads(path.read_text())
        return table_as(data, Material), path.stem
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError) as exc:
        raise SceneError("MATERIAL", f"a readable TOML file ({exc})", text, "command line") from None
    except SceneError as exc:
        raise exc.in_file(str(path)) from None


def published(material: Material) -> tuple[tuple[float, float] | None, str | None]:
    """The published range of the preset a material is (unchanged), and its source; None for any other."""
    if material.preset is None or material != Material(preset=material.preset):
        return None, None
    drape = PRESETS[material.preset].drape
    return (None, None) if drape is None else (drape.range, drape.source)


def drape_scene(material: Material, resolution: int, folder: Path | None) -> Scene:
    """The built-in ``drape_test`` scene made of ``material``, its specimen meshed at ``resolution`` cells
    across (written into ``folder`` where it is not the built-in mesh's)."""
    from .scene_file import load_scene

    scene = load_scene(SCENE)
    (cloth,) = scene.cloths
    changes: dict[str, object] = {"material": material}
    if resolution != geometry.DEFAULT_RESOLUTION:
        mesh = geometry.specimen(resolution)
        path = Path(folder) / f"drape_specimen_{resolution}.obj"
        geometry.write_obj(path, f"The drape test's specimen in {resolution} cells across", mesh.points,
                           geometry.faces_of(mesh.face_counts, mesh.face_indices), mesh.uvs)
        changes["mesh"] = MeshSource(str(path))
    return dataclasses.replace(scene, cloths=(dataclasses.replace(cloth, **changes),))


def run_drape_test(material: Material, name: str, resolution: int = geometry.DEFAULT_RESOLUTION,
                   device: str | None = None, frames: int | None = None, progress=None) -> DrapeResult:
    """Simulate the test until the specimen settles (or ``frames``, default the scene's) and measure it.
    ``progress(frame, frames, fastest)`` is called after each frame."""
    from .simulator import Simulator

    with tempfile.TemporaryDirectory() as folder:
        scene = drape_scene(material, resolution, Path(folder))
        sim = Simulator(scene, device=device)
        sim.prepare()
    frames = scene.simulation.frames if frames is None else frames
    started = time.perf_counter()
    calm = done = 0
    fastest = math.inf
    substeps = 0
    while done < frames and calm < SETTLED_FRAMES:
        sim.step()
        substeps += sim.frame_substeps
        done += 1
        fastest = float(np.linalg.norm(sim.velocities(), axis=1).max())
        calm = calm + 1 if fastest < SETTLED_SPEED else 0
        if progress is not None:
            progress(done, frames, fastest)
    seconds = time.perf_counter() - started
    positions = sim.positions().astype(np.float64)
    mesh = geometry.specimen(resolution)
    triangles = mesh.triangles()
    projection = geometry.projected_area(positions, triangles)
    specimen_area = mesh.area
    coefficient = geometry.drape_coefficient(projection.area, specimen_area)
    stretch, compression = _worst_strain(sim.model, positions)
    low_high, source = published(material)
    return DrapeResult(name, coefficient, low_high, source, resolution, seconds, calm >= SETTLED_FRAMES, done,
                       done / scene.simulation.fps, substeps, fastest, stretch, compression, projection.area,
                       projection.error, projection.error / (specimen_area - geometry.SUPPORT_AREA),
                       len(positions), sim.device.alias, positions, triangles)


def _worst_strain(model, positions: np.ndarray) -> tuple[float, float]:
    """The most any structural or shear edge is stretched and compressed, as fractions of its rest length."""
    edges = model.edges
    lengths = np.linalg.norm(positions[edges[:, 1]] - positions[edges[:, 0]], axis=1)
    strain = lengths / model.edge_rest - 1.0
    return max(0.0, float(strain.max())), max(0.0, float(-strain.min()))


def top_view(result: DrapeResult, path: Path) -> None:
    """The draped specimen seen from above: its projection filled, the support's and the flat specimen's
    circles outlined."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from .output import png_mark

    figure, axes = plt.subplots(figsize=(5.2, 5.6), dpi=120)
    plan = result.positions[:, [0, 2]] * 100.0  # cm
    axes.add_collection(PolyCollection(plan[result.triangles], facecolors="#b8a98a", edgecolors="#8c7c5c",
                                       linewidths=0.15))
    for diameter, style in ((geometry.SPECIMEN_DIAMETER, ":"), (geometry.SUPPORT_DIAMETER, "-")):
        axes.add_patch(plt.Circle((0, 0), 50.0 * diameter, fill=False, linestyle=style, color="#303030"))
    limit = 50.0 * geometry.SPECIMEN_DIAMETER * 1.05
    axes.set_xlim(-limit, limit)
    axes.set_ylim(limit, -limit)  # looking down +Y: x right, z down the page
    axes.set_aspect("equal")
    axes.set_xlabel("x (cm, warp)")
    axes.set_ylabel("z (cm, weft)")
    where = ""
    if result.published_range is not None:
        where = f"\npublished {result.published_range[0]:.2f} to {result.published_range[1]:.2f}"
    axes.set_title(f"{result.material}: DC {result.drape_coefficient:.3f}, {result.resolution} cells across{where}",
                   fontsize=10)
    figure.tight_layout()
    figure.savefig(path, metadata=png_mark(PICTURE))
    plt.close(figure)


class _Parser(argparse.ArgumentParser):
    """Refusals in one line naming the argument, exit 2, as every other refusal of the command."""

    def error(self, message: str) -> None:
        print(f"warp-cloth drape-test: error: {message}", file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="warp-cloth drape-test",
                     description="The Cusick drape test of a material: a 30 cm specimen over an 18 cm support disc "
                                 "(the built-in scene drape_test), run until it settles; its drape coefficient "
                                 "against the published range of the preset's fabric class.")
    parser.add_argument("material", metavar="MATERIAL",
                        help="a preset (" + ", ".join(PRESETS) + ") or a .toml file of a material's keys")
    parser.add_argument("--device", help="cpu, cuda or cuda:N (default: cuda if available, else cpu)")
    parser.add_argument("--resolution", type=int, default=geometry.DEFAULT_RESOLUTION, metavar="N",
                        help=f"grid cells across the specimen's diameter (default {geometry.DEFAULT_RESOLUTION}: "
                             "1 cm cells)")
    parser.add_argument("--json", required=True, metavar="OUT", help="the JSON file to write the result to")
    parser.add_argument("--picture", metavar="PNG", help="also a top view of the draped specimen")
    parser.add_argument("--frames", type=int, metavar="N",
                        help="at most N frames, settled or not (default: the scene's)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    return parser


def main(argv: list[str] | None = None) -> int:
    from .output import check_file_output
    from .simulator import resolve_device

    args = _parser().parse_args(argv)
    try:
        material, name = material_of(args.material)
        if not 4 <= args.resolution <= MAX_RESOLUTION:
            raise SceneError("--resolution", f"a whole number of cells in [4, {MAX_RESOLUTION}]", args.resolution,
                             "command line")
        if args.frames is not None and not 1 <= args.frames <= MAX_FRAMES:
            raise SceneError("--frames", f"a whole number in [1, {MAX_FRAMES}]", args.frames, "command line")
        json_path = Path(args.json)
        check_file_output(json_path, (".json",), "--json", "command line")
        picture = Path(args.picture) if args.picture else None
        if picture is not None:
            check_file_output(picture, (".png",), "--picture", "command line")
        try:
            device = resolve_device(args.device).alias
        except SceneError as exc:
            raise SceneError("--device", exc.expected, exc.got, "command line") from None
    except SceneError as exc:
        print(f"warp-cloth drape-test: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT

    def progress(frame: int, frames: int, fastest: float) -> None:
        if not args.quiet and (frame % 24 == 0 or frame == frames):
            print(f"drape-test {name}: frame {frame}/{frames}, fastest particle {fastest:.3g} m/s", flush=True)

    try:
        result = run_drape_test(material, name, args.resolution, device, args.frames, progress)
    except UnstableSimulation as exc:
        print(f"warp-cloth drape-test: error: {name}: {exc}", file=sys.stderr)
        return EXIT_UNSTABLE
    try:
        json_path.write_text(json.dumps(result.document(), indent=2) + "\n")
        if picture is not None:
            top_view(result, picture)
    except OSError as exc:
        print(f"warp-cloth drape-test: error: {name}: could not write the result ({exc})", file=sys.stderr)
        return EXIT_OUTPUT_FAILED
    print(result.summary())
    return 0
