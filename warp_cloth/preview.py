"""``warp-cloth preview OUT.usdc`` and ``warp-cloth run SCENE --preview``: the USD a run wrote, rendered, so
that what you see is what a DCC tool gets: a still of the last frame (PNG) and an animation of the run (MP4,
or a GIF where Blender has no video encoder), from a camera framed on the cloths and colliders (the still on
its frame, the animation on the whole run), lit, each cloth in its display colour and the colliders and
ground shaded apart.

The renderer is Blender's Cycles on the CPU, through Blender as a Python module (``pip install
'warp-cloth[preview]'``): Blender is the DCC tool the output targets, it runs headless on a machine without
a GPU, and its USD importer is the one a user's would be (a ``catmullClark`` cloth renders smooth). It runs
in a process of its own (``preview_blender.py``), since it carries its own USD libraries. The pictures are
written under staging names and put in place when all are made: a failed preview leaves the previous one.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from .errors import EXIT_BAD_INPUT, EXIT_OUTPUT_FAILED, SceneError
from .output import OutputLock, check_file_output, labelled, png_mark, refuse_replacing_unmarked_png
from .progress import Progress

STILL_RESOLUTION = (960, 540)
ANIMATION_RESOLUTION = (640, 360)
STILL_SAMPLES = 32
ANIMATION_SAMPLES = 16
STILL = "preview still"  # what the still is, in its mark and in messages


@dataclass(frozen=True)
class Preview:
    still: Path
    animation: Path | None
    pictures: int  # in the animation
    seconds: float


def blender_available() -> bool:
    return importlib.util.find_spec("bpy") is not None


def require_blender(key: str, source: str | None = "command line") -> None:
    if not blender_available():
        raise SceneError(key, "Blender as a Python module to render with (pip install 'warp-cloth[preview]'; its "
                              "wheels are for Python 3.11)", has_got=False, source=source)


def default_paths(usd: Path) -> tuple[Path, Path]:
    """``out/hanging.usdc`` -> ``out/hanging.preview.png`` and ``out/hanging.preview.mp4``."""
    stem = usd.name[:len(usd.name) - len(usd.suffix)]
    return usd.with_name(f"{stem}.preview.png"), usd.with_name(f"{stem}.preview.mp4")


def read_stage(usd: Path, key: str = "usd") -> dict:
    """What the renderer needs of a result: its frames, fps and each prim's role and display colour."""
    from pxr import Usd, UsdGeom

    from .writers.usd import COLLIDER_COLOR, ROLE_KEY

    if not usd.is_file():
        raise SceneError(key, "a USD file a run wrote", str(usd), source="command line")
    try:
        stage = Usd.Stage.Open(str(usd))
    except Exception as exc:  # pxr raises Tf.ErrorException for a file that is not USD
        raise SceneError(key, f"a USD file a run wrote (it does not open: {str(exc).strip().splitlines()[-1]})",
                         str(usd), source="command line") from None
    prims = {}
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Gprim):
            continue
        role = prim.GetCustomDataByKey(ROLE_KEY) or _role_of(prim)
        colors = UsdGeom.Gprim(prim).GetDisplayColorAttr().Get()
        color = list(colors[0]) if colors else ([0.7, 0.7, 0.7] if role == "cloth" else list(COLLIDER_COLOR))
        prims[prim.GetName()] = (role, [float(c) for c in color])
    if not any(role == "cloth" for role, _ in prims.values()):
        raise SceneError(key, "a USD file with a cloth mesh in it", str(usd), source="command line")
    start, end = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    return {"prims": prims, "start": start, "end": max(start, end), "fps": stage.GetFramesPerSecond() or 24.0}


def _role_of(prim) -> str:
    """A prim written without roles: the ground by its path, a mesh whose points move a cloth."""
    from pxr import UsdGeom

    from .writers.shot_layer import GROUND_PATH

    if str(prim.GetPath()) == GROUND_PATH:
        return "ground"
    if prim.IsA(UsdGeom.Mesh) and UsdGeom.Mesh(prim).GetPointsAttr().GetNumTimeSamples() > 1:
        return "cloth"
    return "collider"


def parse_frames(text: str | None, start: int, end: int, key: str = "--frames") -> tuple[int, int, int]:
    """``A:B`` or ``A:B:STEP`` (frames A to B, every STEP-th), within the result's frames; None: all."""
    if text is None:
        return start, end, 1
    parts = text.split(":")
    try:
        values = [int(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or values[0] > values[1] or (len(values) == 3 and values[2] < 1):
        raise SceneError(key, "FIRST:LAST or FIRST:LAST:STEP, whole frames, FIRST <= LAST, STEP >= 1", text,
                         source="command line")
    first, last, step = values[0], values[1], values[2] if len(values) == 3 else 1
    if first < start or last > end:
        raise SceneError(key, f"frames within the result's {start}:{end}", text, source="command line")
    return first, last, step


def render_preview(usd: str | Path, still: str | Path | None = None, animation: str | Path | None = None,
                   frames: tuple[int, int, int] | None = None, animate: bool = True,
                   resolution: tuple[int, int] = STILL_RESOLUTION,
                   animation_resolution: tuple[int, int] = ANIMATION_RESOLUTION, samples: int = STILL_SAMPLES,
                   animation_samples: int = ANIMATION_SAMPLES, progress: bool = True) -> Preview:
    """Render a result's USD: a still of the last frame of ``frames`` (first, last, step; default all) and,
    with ``animate``, one picture per frame of ``frames`` as an MP4 (or a GIF, by ``animation``'s suffix or
    where Blender has no video encoder). Paths default to ``default_paths(usd)``."""
    usd = Path(usd)
    require_blender("preview", source=None)
    info = read_stage(usd)
    default_still, default_animation = default_paths(usd)
    if still is None:
        refuse_replacing_unmarked_png(default_still, STILL, "preview", usd)
    still = Path(still) if still is not None else default_still
    animation = (Path(animation) if animation is not None else default_animation) if animate else None
    first, last, step = frames if frames is not None else (info["start"], info["end"], 1)
    count = len(range(first, last + 1, step))
    made = [still] + ([animation] if animation is not None else [])
    lock = OutputLock(still, claims=tuple(p for target in made for p in (target, _staging(target))))
    lock.acquire("preview")
    try:
        return _render(usd, info, still, animation, (first, last, step), count, resolution, animation_resolution,
                       samples, animation_samples, progress)
    finally:
        lock.release()


def _staging(target: Path) -> Path:
    return labelled(target, "incomplete", target.suffix)


def _render(usd: Path, info: dict, still: Path, animation: Path | None, frames: tuple[int, int, int], count: int,
            resolution: tuple[int, int], animation_resolution: tuple[int, int], samples: int,
            animation_samples: int, progress: bool) -> Preview:
    """``render_preview``'s pictures, made under the outputs' lock."""
    first, last, step = frames
    started = time.perf_counter()
    still.parent.mkdir(parents=True, exist_ok=True)
    if animation is not None:
        animation.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".preview-", dir=still.parent) as scratch:
        scratch = Path(scratch)
        job = {"usd": str(usd.absolute()), "prims": info["prims"], "fps": info["fps"],
               "frames": [first, last, step], "still_frame": last, "still": str(scratch / "still.png"),
               "resolution": list(resolution), "samples": samples,
               "animation_resolution": list(animation_resolution), "animation_samples": animation_samples}
        gif = animation is not None and animation.suffix.lower() == ".gif"
        if animation is not None:
            job["animation"] = {"format": "gif" if gif else "mp4",
                                "path": str(scratch / ("pictures" if gif else "animation.mp4"))}
        (scratch / "job.json").write_text(json.dumps(job))
        _run_blender(scratch / "job.json", count if animation is not None else 0, progress, still.name,
                     animation.name if animation is not None else None)
        _mark(scratch / "still.png")
        made = [(scratch / "still.png", still)]
        if animation is not None:
            if gif:
                _gif(sorted((scratch / "pictures").glob("frame_*.png")), scratch / "animation.gif",
                     info["fps"] / step)
            made.append((scratch / ("animation.gif" if gif else "animation.mp4"), animation))
        for source, target in made:
            shutil.move(source, _staging(target))
        for _, target in made:
            os.replace(_staging(target), target)
    return Preview(still, animation, count if animation is not None else 0, time.perf_counter() - started)


def _mark(png: Path) -> None:
    """The still, marked as a preview warp-cloth made (see ``output.png_mark``)."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    for key, value in png_mark(STILL).items():
        info.add_text(key, value)
    with Image.open(png) as image:
        image.load()
    image.save(png, pnginfo=info)


def _run_blender(job: Path, pictures: int, progress: bool, still: str, animation: str | None) -> None:
    """Blender's render of ``job``: the still (file name ``still``), then ``pictures`` frames of ``animation``,
    the progress saying which it is on."""
    script = Path(__file__).with_name("preview_blender.py")
    bar = Progress(1 + pictures, f"rendering {still}") if progress else None
    if bar:
        bar.update(0)  # the still comes first and takes longest: say so from the start
    process = subprocess.Popen([sys.executable, str(script), str(job)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    done = 0
    tail: list[str] = []
    try:
        for line in process.stdout:
            tail = (tail + [line.rstrip()])[-20:]
            if line.startswith(("STILL", "FRAME ", "RESTART")):
                done = 1 if line.startswith("RESTART") else done + 1
                if bar and animation is not None:
                    frame = line.split()[1] if line.startswith("FRAME ") else None
                    bar.update(done, f"rendering {animation}" + (f", frame {frame}" if frame else ""))
                elif bar:
                    bar.update(done)
        errors = process.stderr.read()
        process.wait()
    except BaseException:
        process.kill()
        raise
    finally:
        if bar:
            bar.close()
    if process.returncode != 0 or done < 1 + pictures:
        reason = (errors.strip().splitlines() or tail or ["no output"])[-1]
        raise RuntimeError(f"Blender's render ended after {done} of {1 + pictures} pictures: {reason}")


def _gif(pictures: list[Path], target: Path, fps: float) -> None:
    from PIL import Image

    frames = [Image.open(p).convert("RGB").quantize(colors=256) for p in pictures]
    frames[0].save(target, save_all=True, append_images=frames[1:], duration=round(1000 / fps), loop=0)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="warp-cloth preview",
                                     description="Render a result's USD with Blender: a still of its last frame "
                                                 "(PNG) and an animation of its frames (MP4, or GIF), framed on its "
                                                 "cloths and colliders. Needs the preview extra.")
    parser.add_argument("usd", help="a USD file a run wrote (out/SCENE.usdc)")
    parser.add_argument("--frames", metavar="FIRST:LAST[:STEP]", help="the frames to animate (default: all); "
                                                                     "the still shows LAST")
    parser.add_argument("--still", metavar="PATH.png", help="the still (default: beside the USD, .preview.png)")
    parser.add_argument("--animation", metavar="PATH.mp4|PATH.gif",
                        help="the animation (default: beside the USD, .preview.mp4)")
    parser.add_argument("--no-animation", action="store_true", help="the still only")
    parser.add_argument("--samples", type=int, default=STILL_SAMPLES, help=f"Cycles' samples for the still "
                                                                           f"(default {STILL_SAMPLES})")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def check_outputs(still: Path | None, animation: Path | None) -> None:
    if still is not None:
        check_file_output(still, (".png",), "--still", "command line")
    if animation is not None:
        check_file_output(animation, (".mp4", ".gif"), "--animation", "command line")


def describe(preview: Preview) -> str:
    made = f"{preview.still}" + (f" and {preview.animation} ({preview.pictures} pictures)" if preview.animation else "")
    return f"rendered {made} in {preview.seconds:.1f} s"


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    usd = Path(args.usd)
    try:
        require_blender("preview")
        if args.samples < 1:
            raise SceneError("--samples", "a number of samples >= 1", args.samples, source="command line")
        info = read_stage(usd, "usd")
        frames = parse_frames(args.frames, info["start"], info["end"])
        still, animation = default_paths(usd)
        still = Path(args.still) if args.still else still
        animation = None if args.no_animation else (Path(args.animation) if args.animation else animation)
        check_outputs(still, animation)
        preview = render_preview(usd, still if args.still else None, animation, frames,
                                 animate=animation is not None, samples=args.samples, progress=not args.quiet)
    except SceneError as exc:
        print(f"warp-cloth preview: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RuntimeError as exc:
        print(f"warp-cloth preview: error: {exc}; nothing in place was replaced", file=sys.stderr)
        return EXIT_OUTPUT_FAILED
    print(f"{usd.name}: {describe(preview)}")
    return 0
