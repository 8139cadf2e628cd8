"""The rendered preview (``warp-cloth run --preview``, ``warp-cloth preview``): a still whose pixels show the
cloth in its colour where the camera looks, an animation of one picture per frame asked, in place only when
all of it is made; bad input refused in one line. Skipped where Blender (bpy) is not installed."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli_in_process

needs_blender = pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="bpy (Blender) is not installed")

GREEN = (0.15, 0.75, 0.2)


def green_hanging(folder: Path) -> Path:
    """The built-in hanging scene with a cloth of a colour nothing else in the picture has."""
    from warp_cloth.scene_file import resolve_scene_path

    text = resolve_scene_path("hanging").read_text().replace('name = "cloth"', f'name = "cloth"\ncolor = {list(GREEN)}')
    path = folder / "green.toml"
    path.write_text(text)
    return path


def cloth_pixels(png: Path) -> np.ndarray:
    """Where the picture is the cloth's green (lit or shaded: green well above red and blue)."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB"), dtype=np.float64) / 255.0
    return (rgb[..., 1] > rgb[..., 0] + 0.1) & (rgb[..., 1] > rgb[..., 2] + 0.1)


@pytest.fixture
def small_pictures(monkeypatch):
    """Blender renders 96 x 54 pictures at one sample (a second each, where the default still takes half a
    minute on two cores): for tests of which pictures are made and where, not of how they look."""
    from warp_cloth import preview

    real = preview._run_blender

    def run_blender(job: Path, *args) -> None:
        settings = json.loads(job.read_text())
        settings.update(resolution=[96, 54], samples=1, animation_resolution=[96, 54], animation_samples=1)
        job.write_text(json.dumps(settings))
        real(job, *args)

    monkeypatch.setattr(preview, "_run_blender", run_blender)


def movie_pictures(path: Path) -> int:
    """The pictures in a video, as Blender reads it (in its own process: it carries its own USD)."""
    code = f"import bpy; print('PICTURES', bpy.data.movieclips.load({str(path)!r}).frame_duration)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout
    return int(out.split("PICTURES")[1].split()[0])


@needs_blender
def test_run_preview_renders_the_cloth_in_its_colour_and_a_picture_per_frame(tmp_path):
    scene = green_hanging(tmp_path)
    code, out, err = run_cli_in_process("run", str(scene), "--frames", "12", "--out", "out", "--no-poly", "--quiet",
                                        "--preview", cwd=tmp_path)
    assert code == 0, err
    still, movie = tmp_path / "out" / "green.preview.png", tmp_path / "out" / "green.preview.mp4"
    assert f"{Path('out/green.preview.png')}, {Path('out/green.preview.mp4')} (rendered in" in out
    cloth = cloth_pixels(still)
    assert cloth.shape == (540, 960)
    assert cloth.mean() > 0.03  # the cloth fills a good part of the picture ...
    rows, columns = np.nonzero(cloth)
    assert 540 * 0.2 < rows.mean() < 540 * 0.8 and 960 * 0.2 < columns.mean() < 960 * 0.8  # ... where it looks
    assert not cloth[:20, :20].any() and not cloth[-20:, -20:].any()  # and the background is not the cloth
    assert movie_pictures(movie) == 13
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["green.preview.mp4", "green.preview.png",
                                                                     "green.usdc"]


@needs_blender
def test_preview_of_a_result_animates_the_frames_asked_and_replaces_only_when_done(tmp_path, small_pictures):
    from PIL import Image

    scene = green_hanging(tmp_path)
    assert run_cli_in_process("run", str(scene), "--frames", "12", "--out", "out", "--no-poly", "--quiet",
                              cwd=tmp_path)[0] == 0
    usd = tmp_path / "out" / "green.usdc"
    code, out, err = run_cli_in_process("preview", str(usd), "--frames", "2:11:3", "--animation", "anim.gif",
                                        "--still", "still.png", "--quiet", cwd=tmp_path)
    assert code == 0, err
    assert Image.open(tmp_path / "anim.gif").n_frames == 4  # frames 2, 5, 8 and 11
    assert cloth_pixels(tmp_path / "still.png").mean() > 0.03
    before = (tmp_path / "still.png").read_bytes()
    code, out, err = run_cli_in_process("preview", str(usd), "--frames", "2:30", "--still", "still.png",
                                        cwd=tmp_path)
    assert code == 2 and "--frames: expected frames within the result's 0:12" in err
    assert (tmp_path / "still.png").read_bytes() == before
    assert not list(tmp_path.glob("*.incomplete*")) and not list(tmp_path.glob(".preview-*"))


@needs_blender
def test_a_preview_never_replaces_a_picture_of_the_users_nor_renders_beside_another(tmp_path, small_pictures):
    from PIL import Image

    from conftest import lock_held_by_another_process
    from warp_cloth.output import OutputLock

    scene = green_hanging(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    mine = out / "green.preview.png"
    Image.new("RGB", (4, 4), (200, 10, 10)).save(mine)
    picture = mine.read_bytes()
    code, _, err = run_cli_in_process("run", str(scene), "--frames", "2", "--out", "out", "--no-poly", "--quiet",
                                      "--preview", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--preview" in err and "green.preview.png" in err
    assert sorted(p.name for p in out.iterdir()) == ["green.preview.png"]  # refused before simulating
    assert run_cli_in_process("run", str(scene), "--frames", "2", "--out", "out", "--no-poly", "--quiet",
                              cwd=tmp_path)[0] == 0
    code, _, err = run_cli_in_process("preview", "out/green.usdc", "--no-animation", "--quiet", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "green.preview.png" in err, err
    assert mine.read_bytes() == picture
    with lock_held_by_another_process(OutputLock(mine).path) as holder:
        code, _, err = run_cli_in_process("preview", "out/green.usdc", "--no-animation", "--still", "s.png",
                                          "--quiet", cwd=tmp_path)
    assert code == 0, err  # a still named elsewhere takes its own lock
    with lock_held_by_another_process(OutputLock(tmp_path / "s.png").path) as holder:
        code, _, err = run_cli_in_process("preview", "out/green.usdc", "--no-animation", "--still", "s.png",
                                          "--quiet", cwd=tmp_path)
    assert code == 2 and f"process id {holder}" in err, err
    mine.unlink()
    for _ in range(2):  # its own still, it replaces
        code, _, err = run_cli_in_process("preview", "out/green.usdc", "--no-animation", "--quiet", cwd=tmp_path)
        assert code == 0, err
    assert cloth_pixels(mine).mean() > 0.03


@pytest.mark.parametrize("args, expected", [
    (["missing.usdc"], "usd: expected a USD file a run wrote, got 'missing.usdc'"),
    (["not_usd.usdc"], "usd: expected a USD file a run wrote (it does not open"),
    (["out/green.usdc", "--frames", "5"], "--frames: expected FIRST:LAST or FIRST:LAST:STEP"),
    (["out/green.usdc", "--frames", "5:2"], "--frames: expected FIRST:LAST or FIRST:LAST:STEP"),
    (["out/green.usdc", "--still", "still.jpg"], "--still: expected a file name ending in .png"),
    (["out/green.usdc", "--animation", "a.avi"], "--animation: expected a file name ending in .mp4, .gif"),
])
@needs_blender
def test_bad_preview_input_is_one_line_and_nothing_is_written(tmp_path, args, expected):
    scene = green_hanging(tmp_path)
    assert run_cli_in_process("run", str(scene), "--frames", "2", "--out", "out", "--no-poly", "--quiet",
                              cwd=tmp_path)[0] == 0
    (tmp_path / "not_usd.usdc").write_text("not a stage")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code, out, err = run_cli_in_process("preview", *args, cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_without_blender_preview_is_refused_in_one_line_before_anything_runs(tmp_path, monkeypatch):
    from warp_cloth import preview

    monkeypatch.setattr(preview, "blender_available", lambda: False)
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", "out", "--preview", cwd=tmp_path)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--preview: expected Blender as a Python module" in err and "pip install 'warp-cloth[preview]'" in err
    assert not (tmp_path / "out").exists()
    code, out, err = run_cli_in_process("preview", "anything.usdc", cwd=tmp_path)
    assert code == 2 and "preview: expected Blender as a Python module" in err


class _Terminal:
    def __init__(self) -> None:
        self.text = ""

    def isatty(self) -> bool:
        return True

    def write(self, text: str) -> None:
        self.text += text

    def flush(self) -> None:
        pass


def test_render_progress_says_which_picture_it_is_on(tmp_path, monkeypatch):
    """Blender (faked: its lines after each picture) makes the still, then frames 1 to 3: the progress names
    the still's file, then the animation's with its frame, never the still's for all of them."""
    import io

    import warp_cloth.preview as preview

    class Blender:
        def __init__(self, *args, **kwargs) -> None:
            self.stdout = io.StringIO("STILL\nFRAME 1\nFRAME 2\nFRAME 3\n")
            self.stderr = io.StringIO("")
            self.returncode = 0

        def wait(self) -> int:
            return 0

    labels = []
    real_update = preview.Progress.update

    def update(bar, done, label=None):
        real_update(bar, done, label)
        labels.append(bar.label)

    monkeypatch.setattr(preview.subprocess, "Popen", Blender)
    monkeypatch.setattr(preview.Progress, "update", update)
    monkeypatch.setattr(sys, "stderr", _Terminal())
    preview._run_blender(tmp_path / "job.json", 3, True, "h.preview.png", "h.preview.mp4")
    assert labels == ["rendering h.preview.png", "rendering h.preview.mp4", "rendering h.preview.mp4, frame 1",
                      "rendering h.preview.mp4, frame 2", "rendering h.preview.mp4, frame 3"]
    shown = sys.stderr.text
    assert shown.startswith("\rrendering h.preview.png [") and "4/4" in shown and "eta" in shown


BOX_OBJ = """v -1 0 -1\nv 1 0 -1\nv 1 0.4 -1\nv -1 0.4 -1\nv -1 0 1\nv 1 0 1\nv 1 0.4 1\nv -1 0.4 1
f 1 4 3 2\nf 5 6 7 8\nf 1 5 8 4\nf 2 3 7 6\nf 4 8 7 3\nf 1 2 6 5
"""

SHADING = """
import json
import sys
sys.path.insert(0, sys.argv[1])
import preview_blender
meshes, roles = preview_blender.import_result({"usd": sys.argv[2], "prims": json.loads(sys.argv[3])})
for obj in meshes:
    mesh = obj.data
    flat = all((mesh.corner_normals[k].vector - p.normal).length < 1e-4 for p in mesh.polygons for k in p.loop_indices)
    print("SHADED", roles[obj.name], "flat" if flat else "rounded", all(p.use_smooth for p in mesh.polygons))
"""


@needs_blender
def test_a_box_collider_renders_with_flat_faces_and_the_cloth_smooth(tmp_path):
    """A box's faces meet at 90 degrees: shaded smooth across them it looks like a pill. Colliders are
    shaded smooth only across edges flatter than 30 degrees; the cloth smooth."""
    (tmp_path / "box.obj").write_text(BOX_OBJ)
    (tmp_path / "box.toml").write_text(
        '[simulation]\nfps = 24\nframes = 1\n\n[[collider]]\nname = "box"\nmesh = "box.obj"\n\n'
        '[[cloth]]\nname = "cloth"\nresolution = [4, 4]\nsize = [1.0, 1.0]\norientation = "horizontal"\n'
        'origin = [-0.5, 0.8, -0.5]\nmass = 0.01\n')
    code, out, err = run_cli_in_process("run", "box.toml", "--out", "out", "--no-poly", "--quiet", cwd=tmp_path)
    assert code == 0, err
    import warp_cloth
    from warp_cloth.preview import read_stage

    usd = tmp_path / "out" / "box.usdc"
    result = subprocess.run([sys.executable, "-c", SHADING, str(Path(warp_cloth.__file__).parent), str(usd),
                             json.dumps(read_stage(usd)["prims"])], capture_output=True, text=True, timeout=120)
    shaded = {line.split()[1]: line.split()[2:] for line in result.stdout.splitlines() if line.startswith("SHADED")}
    # the box's corners take their faces' normals; the cloth is shaded smooth (flat here: it has not bent yet)
    assert shaded["collider"][0] == "flat" and shaded["cloth"][1] == "True", result.stdout + result.stderr
