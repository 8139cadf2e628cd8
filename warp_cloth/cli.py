"""The ``warp-cloth`` command: list the built-in scenes, run a scene to USD and .poly files."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import os
import signal
import statistics
import sys
import threading
import time
import warnings
from pathlib import Path

from .errors import (EXIT_BAD_INPUT, EXIT_BROKEN_PIPE, EXIT_INTERRUPTED, EXIT_OUTPUT_FAILED, EXIT_SIGNAL_BASE,
                     EXIT_UNSTABLE, SceneError, UnstableSimulation)
from .progress import SlowStepNotice
from .scene import INTEGRATORS, Scene
from .shot_clock import shot_clock
from .wording import counted


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="warp-cloth", description="Mass-spring cloth on NVIDIA Warp (CPU or CUDA).")
    parser.add_argument("--version", action="version", version=_version())
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    commands.add_parser("scenes", help="list the built-in scenes", description="List the built-in scenes.")

    run = commands.add_parser("run", help="simulate a scene and write USD and .poly frames",
                              description="Simulate a scene (a built-in name or a TOML file) and write its "
                                          "frames as USD time samples and Houdini .poly files.")
    run.add_argument("scene", help="built-in scene name (see 'warp-cloth scenes') or path to a .toml file")
    run.add_argument("--device", help="cpu, cuda or cuda:N (default: cuda if available, else cpu)")
    run.add_argument("--frames", type=int, help="number of frames to simulate")
    run.add_argument("--start-frame", type=int, dest="start_frame", metavar="N",
                     help="the number of the first frame written, on the shot's clock (default: the scene's "
                          "simulation.start, else the start time code of the USD shot its colliders come from, "
                          "else 0)")
    run.add_argument("--preroll", type=int, metavar="N",
                     help="frames simulated before the first written frame, for the cloth to settle (default: "
                          "the scene's, else 0)")
    step = run.add_mutually_exclusive_group()
    step.add_argument("--substeps", type=_substeps, help="substeps per frame, or auto: chosen frame by frame")
    step.add_argument("--dt", type=float, help="time step in seconds (rounded to a whole number of substeps)")
    run.add_argument("--integrator", choices=INTEGRATORS, help="time integrator")
    run.add_argument("--limit-solve", choices=("fixed", "converged"), dest="limit_solve",
                     help="strain limits in the scene's limit_iterations passes a substep, or until within "
                          "limit_tolerance (at most limit_max_passes)")
    run.add_argument("--limit-max-passes", type=int, dest="limit_max_passes", metavar="N",
                     help="the converged limit solve's passes a substep at most (default: the scene's; where it "
                          "sets none, 200, or as many as keep a frame within 50,000 passes)")
    run.add_argument("--out", help="output folder (default: the scene's, 'out')")
    usd = run.add_mutually_exclusive_group()
    usd.add_argument("--usd", metavar="PATH", help="USD file to write (default: OUT/SCENE.usdc)")
    usd.add_argument("--no-usd", action="store_true", help="write no USD")
    poly = run.add_mutually_exclusive_group()
    poly.add_argument("--poly", metavar="DIR", help="folder for .poly files (default: OUT/SCENE/poly)")
    poly.add_argument("--no-poly", action="store_true", help="write no .poly files")
    run.add_argument("--resume", action="store_true",
                     help="continue the run that was stopped, killed or failed writing these outputs, from its "
                          "checkpoint (the scene and its settings must be unchanged)")
    run.add_argument("--no-graph", action="store_true",
                     help="launch a frame's kernels one by one instead of replaying the frame as a captured graph "
                          "(a CUDA graph on a GPU, a Warp CPU graph on the CPU): slower, for debugging")
    shown = run.add_mutually_exclusive_group()
    shown.add_argument("--quiet", action="store_true", help="no progress")
    shown.add_argument("--progress", action="store_true",
                       help="progress even with --check (by default a bar on a terminal; off one, as in a log or a "
                            "pipe, a line every 5 s once the run has taken that long)")
    run.add_argument("--check", action="store_true",
                     help="print, after every frame, the intersecting triangle pairs and the closest contact")
    run.add_argument("--preview", action="store_true",
                     help="render the USD the run wrote when it completes: a still of the last frame "
                          "(OUT/SCENE.preview.png) and an animation (.preview.mp4), with Blender (the preview extra)")
    run.add_argument("--metrics", metavar="FILE.csv",
                     help="write per-frame metrics (strain by edge kind, closest contact, energies, solver "
                          "iterations, wall time; crossing pairs with --check) to FILE.csv, and their plot to "
                          "FILE.png")

    plan = commands.add_parser("plan", help="print the passes of a scene's substep, in order",
                               description="Print the plan of a scene's substep: its passes in the order they "
                                           "run (fused passes named for what they fuse), as a run would build it.")
    plan.add_argument("scene", help="built-in scene name (see 'warp-cloth scenes') or path to a .toml file")
    plan.add_argument("--device", help="cpu, cuda or cuda:N (default: cuda if available, else cpu)")
    plan_step = plan.add_mutually_exclusive_group()
    plan_step.add_argument("--substeps", type=_substeps, help="substeps per frame, or auto: chosen frame by frame")
    plan_step.add_argument("--dt", type=float, help="time step in seconds (rounded to a whole number of substeps)")
    plan.add_argument("--integrator", choices=INTEGRATORS, help="time integrator")

    materials = commands.add_parser("materials", help="list the fabric presets a cloth's material may name",
                                    description="List the fabric presets a cloth's material may name "
                                                "(material = \"NAME\"), with their SI values and where they come "
                                                "from.")
    materials.add_argument("--json", metavar="PATH", help="also write them as JSON to PATH ('-': to standard output, "
                                                          "instead of the table)")

    commands.add_parser("bench", help="time whole runs, print a table and write JSON (see 'bench --help')",
                        add_help=False)
    commands.add_parser("study", help="what accuracy costs in time: error against a reference and wall time "
                                      "per integrator, step and resolution (see 'study --help')", add_help=False)
    commands.add_parser("sweep", help="run variants of a scene (--set KEY=V1,V2,...) as the worlds of batches, "
                                      "with a table of outcomes (see 'sweep --help')", add_help=False)
    commands.add_parser("drape-test", help="the Cusick drape test of a material: its drape coefficient against the "
                                           "published range (see 'drape-test --help')", add_help=False)
    commands.add_parser("preview", help="render a result's USD: a still of its last frame and an animation, with "
                                        "Blender (see 'preview --help')", add_help=False)
    return parser


def _substeps(text: str) -> int | str:
    """``--substeps``: a whole number, or ``auto``."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number or auto, got {text!r}") from None


# The lab's commands (warp_cloth/lab), each imported by its module's name when asked for: nothing of the
# product imports the lab (tests/test_architecture.py).
LAB_COMMANDS = {"bench": "warp_cloth.lab.bench", "study": "warp_cloth.lab.study"}

# A [simulation] key the command line sets, by the name argparse keeps its option under, where they differ.
OPTION_OF_KEY = {"start": "start_frame"}


def _version() -> str:
    """``warp-cloth 0.1.0 (warp-lang 1.9.0, Python 3.11.9)``: what a bug report needs, without importing Warp."""
    import importlib.metadata
    import platform

    from . import __version__

    try:
        warp = importlib.metadata.version("warp-lang")
    except importlib.metadata.PackageNotFoundError:
        warp = "not installed"
    return f"warp-cloth {__version__} (warp-lang {warp}, Python {platform.python_version()})"


def _with_step_overrides(scene: Scene, args: argparse.Namespace) -> Scene:
    """The scene with the command line's frames, clock, step, integrator and limit solve."""
    sim_changes = {k: getattr(args, OPTION_OF_KEY.get(k, k), None)
                   for k in ("frames", "start", "preroll", "integrator", "limit_solve", "limit_max_passes")
                   if getattr(args, OPTION_OF_KEY.get(k, k), None) is not None}
    if args.substeps is not None:
        sim_changes.update(substeps=args.substeps, dt=None)
    if args.dt is not None:
        sim_changes.update(dt=args.dt, substeps=None)
    try:
        return dataclasses.replace(scene, simulation=dataclasses.replace(scene.simulation, **sim_changes))
    except SceneError as exc:
        raise _from_option(OPTION_OF_KEY.get(exc.key, exc.key), exc) from None


def _from_option(option: str, exc: SceneError) -> SceneError:
    """``exc`` named as the command line's ``--option`` (an attribute's name, as argparse keeps it)."""
    return SceneError(f"--{option.replace('_', '-')}", exc.expected, exc.got, "command line", exc.has_got)


def _named_as_given(exc: SceneError, args: argparse.Namespace) -> SceneError:
    """A refusal of the scene as a whole (``exc``, without a source), named where its key's value came
    from: the command line's option that set it, or else the scene's file."""
    from .scene_file import resolve_scene_path

    key = exc.key.removeprefix("simulation.")
    option = OPTION_OF_KEY.get(key, key)
    if exc.key.startswith("simulation.") and getattr(args, option, None) is not None:
        return _from_option(option, exc)
    return exc.in_file(str(resolve_scene_path(args.scene)))


def _with_overrides(scene: Scene, args: argparse.Namespace) -> Scene:
    """``_with_step_overrides`` and the command line's outputs."""
    scene = _with_step_overrides(scene, args)
    output = scene.output
    if args.out is not None:
        output = dataclasses.replace(output, dir=args.out)
    if args.no_usd or args.usd:
        output = dataclasses.replace(output, usd=not args.no_usd)
    if args.no_poly or args.poly:
        output = dataclasses.replace(output, poly=not args.no_poly)
    return dataclasses.replace(scene, output=output)


def _cmd_scenes() -> int:
    from .scene_file import builtin_scene_names, load_scene

    names = builtin_scene_names()
    width = max(len(n) for n in names)
    for name in names:
        print(f"{name:<{width}}  {load_scene(name).description}")
    return 0


def _cmd_materials(args: argparse.Namespace) -> int:
    """The presets as a table, and as JSON where asked: numbers only, nothing of Warp loaded."""
    import json

    from .fabric_presets import PRESETS
    from .materials import Material

    presets = [{"name": name, "fabric": data.fabric, **Material(preset=name).values(), "source": data.source}
               for name, data in PRESETS.items()]
    for preset in presets:
        del preset["preset"]
    if args.json is not None:
        document = json.dumps({"units": MATERIAL_UNITS, "presets": presets}, indent=2) + "\n"
        if args.json == "-":
            sys.stdout.write(document)
            return 0
        try:
            Path(args.json).write_text(document)
        except OSError as exc:
            raise SceneError("--json", f"a file that can be written ({exc.strerror})", args.json,
                             "command line") from None
    rows = [("preset", "kg/m^2", "stretch N/m", "shear N/m", "bending uN m", "limits", "fabric")]
    for p in presets:
        limits = "-" if p["stretch_limit"] is None and p["compression_limit"] is None else \
            f"+{p['stretch_limit']} / -{p['compression_limit']}"
        rows.append((p["name"], f"{p['density']:.3f}", _pair(p["stretch"], "{:.0f}"), f"{p['shear']:.1f}",
                     _pair([1e6 * b for b in p["bending"]], "{:.1f}"), limits, p["fabric"]))
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]) - 1)]
    for row in rows:
        print("  ".join(f"{cell:<{w}}" for cell, w in zip(row, widths)) + "  " + row[-1])
    print("\nstretch and bending: warp / weft (the cloth's u / v); limits: stretch / compression fractions")
    print("sources:")
    for p in presets:
        print(f"  {p['name']}: {p['source']}")
    return 0


# The units of a material's values, as ``warp-cloth materials --json`` says them.
MATERIAL_UNITS = {"density": "kg/m^2", "stretch": "N/m, [warp, weft]", "shear": "N/m (per radian)",
                  "bending": "N m, [warp, weft]", "damping": "s", "friction": "coefficient",
                  "stretch_limit": "fraction", "compression_limit": "fraction"}


def _pair(values, form: str) -> str:
    return " / ".join(form.format(v) for v in values)


def _limit_solve(sim) -> str:
    """What the limit solve took over the run, for the summary line ('' where nothing is limited)."""
    if sim.plan.projection is None:
        fixed = sim.scene.simulation.limit_solve == "fixed" and sim.model.limits is not None
        return "; limit solve fixed: a set number of passes a substep, not solved to a tolerance" if fixed else ""
    stats = sim.solver_stats(since_start=True)
    cap = sim.limit_solve.max_passes
    ended = ("every solve ended within tolerance" if stats.limit_residual <= 1.0 else
             f"some reached the cap of {cap} passes at {stats.limit_residual:.3g} tolerances")
    return (f"; limit solve {stats.limit_mean_passes:.1f} passes a substep on average, {stats.limit_passes} at most, "
            f"{ended}")


def _lists_full(sim) -> str:
    """Contact candidates that did not fit their lists or hash buckets over the run, for the summary line
    ('' where none): the particles' went unchecked, so contacts may have been missed; the surfaces' (with a
    thickness) were the farthest of full lists, held from crossing by the bounds, which read the nearest, but
    not a thickness apart."""
    from warp_cloth.kernels.spatial_hash import DROPPED_MOST

    lists = sim.plan.lists
    if lists is None:
        return ""
    said = []
    for dropped, what in ((lists.overflow, "contact lists full: {} dropped, their contacts unchecked"),
                          (lists.surface_dropped, "surface lists full: {} left out (the farthest: kept from "
                           "crossing, not held a thickness apart)")):
        if dropped:
            at_least = "at least " if dropped >= DROPPED_MOST else ""
            said.append("; " + what.format(at_least + counted(dropped, "candidate")))
    return "".join(said)


def _measured_again(sim, summary) -> str:
    """How often the run measured the displacement bounds again inside a substep, where the solve held
    particles at them (with a thickness), for the summary line ('' where never)."""
    bounds = sim.plan.bounds
    stats = bounds.read_stats() if bounds is not None else None
    if stats is None or not stats.measured_again or not summary.substeps:
        return ""
    said = f"; bounds measured again {stats.measured_again / summary.substeps:.3g} times a substep on average"
    if stats.left_held:
        said += (f", {counted(stats.left_held, 'particle')} left held at them with the "
                 f"{bounds.settings.again} rounds spent (steps cut short)")
    return said


def _cmd_plan(args: argparse.Namespace) -> int:
    _quiet_warp()
    from .scene_file import load_scene
    from .simulator import Simulator

    scene = _with_step_overrides(load_scene(args.scene), args)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a step past the bound is for a run to warn of
        sim = Simulator(scene, device=args.device)
    substeps = sim.substeps_per_frame
    said = f"substeps: auto (starting at {substeps}, the stable floor)" if sim.auto is not None else \
        f"{counted(substeps, 'substep')} a frame"
    print(f"{scene.name} on {sim.device.alias}, {said}; {sim.plan}")
    return 0


def _writers(scene: Scene, args: argparse.Namespace) -> list:
    """The run's output writers (USD, .poly, metrics), their paths checked (before anything is simulated or
    written)."""
    from .writers import PolyWriter, UsdWriter

    out = Path(scene.output.dir)
    usd = Path(args.usd) if args.usd else out / f"{scene.name}.usdc"
    poly = Path(args.poly) if args.poly else out / scene.name / "poly"
    writers = []
    try:
        if scene.output.usd:
            writers.append(UsdWriter(usd, scene.output.subdivision, resume=args.resume))
        if scene.output.poly:
            writers.append(PolyWriter(poly, resume=args.resume))
        if args.metrics is not None:
            from .metrics import MetricsWriter

            writers.append(MetricsWriter(args.metrics, resume=args.resume))
    except SceneError as exc:
        raise _output_error(exc, args) from None
    return writers


def _output_error(exc: SceneError, args: argparse.Namespace) -> SceneError:
    """A writer's refusal of its path (key ``usd`` or ``poly``), named as the user gave the path: its own
    option, ``--out``, or the scene file's ``output.dir``."""
    from .scene_file import resolve_scene_path

    if getattr(args, exc.key, None):
        key, source = f"--{exc.key}", "command line"
    elif args.out is not None:
        key, source = "--out", "command line"
    else:
        key, source = "output.dir", str(resolve_scene_path(args.scene))
    return SceneError(key, exc.expected, exc.got, source, exc.has_got)


def _prepare(writers: list, args: argparse.Namespace) -> None:
    """Take every output's lock, or release those taken and refuse."""
    try:
        for w in writers:
            w.prepare()
    except SceneError as exc:
        _release(writers)
        raise _output_error(exc, args) from None
    except BaseException:
        _release(writers)
        raise


def _release(writers: list) -> None:
    """Give back the outputs' locks, last taken first, so that the folders made for them go too."""
    for w in reversed(writers):
        w.lock.release()


def _take_back(checkpoint, scene: Scene, writers: list) -> None:
    """Give each writer back the frames the checkpointed run left (under the staging name, in place, or
    beside it as failed or interrupted)."""
    from .writers.checkpoint import frames_at

    for w in writers:
        location = frames_at(checkpoint.extra, w.target)
        if location is None:
            raise SceneError("--resume", f"a checkpoint of a run that wrote {w.target} (it did not)", has_got=False,
                             source="command line")
        w.take_back(location, checkpoint.frame, [c.name for c in scene.cloths], shot_clock(scene).start)


def _resume_hint(checkpointer) -> str:
    """Said where a run that did not complete left a checkpoint to go on from."""
    return "; continue it with --resume" if checkpointer is not None and checkpointer.saved else ""


def _kept(writers: list) -> str:
    return ", ".join(f"{p}" for w in writers for p in w.outputs) or "nothing"


def _simulator(scene: Scene, device: str, args: argparse.Namespace):
    """The scene's simulator with its kernels compiled, and the seconds that took (the model built, the
    kernels compiled or loaded); says first the step it takes, and warns of a step set past the stable bound."""
    from .simulator import Simulator
    from .stability import UnstableStepWarning

    started = time.perf_counter()
    # Building the plan compiles some kernels, prepare() the others: seconds of silence on a first run.
    with SlowStepNotice("compiling kernels") if not args.quiet else contextlib.nullcontext():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UnstableStepWarning)
            try:
                sim = Simulator(scene, device=device, graph=not args.no_graph)
            except SceneError as exc:  # checks of the scene as a whole (overlaps, colliders, size, work)
                raise (_named_as_given(exc, args) if exc.source is None else exc) from None
        sim.prepare()
    seconds = time.perf_counter() - started
    print(f"{scene.name}: {sim.step_choice.describe()}", flush=True)
    meshes = [("cloth", c) for c in scene.cloths if c.mesh is not None] + [("collider", c) for c in scene.colliders]
    for kind, item in meshes:  # what reading a user's mesh converted or let pass
        for note in item.surface().notes:
            print(f"warp-cloth: note: {kind} {item.name!r}: {note}", file=sys.stderr, flush=True)
    step_source = "command line" if args.substeps is not None or args.dt is not None else args.scene
    for w in caught:
        if issubclass(w.category, UnstableStepWarning):
            print(f"warp-cloth: warning: {step_source}: {w.message}", file=sys.stderr, flush=True)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return sim, seconds


def _quiet_warp() -> None:
    """Warp's messages of modules loaded and compiled are not for a user of the command."""
    import warp as wp

    wp.config.log_level = wp.LOG_ERROR


def _cmd_run(args: argparse.Namespace) -> int:
    _quiet_warp()
    from .checkpoint import check_scene, load_checkpoint
    from .output import OutputError, check_folder_output, checkpoint_path
    from .scene_file import load_scene
    from .simulator import resolve_device
    from .writers import CheckpointWriter
    from .writers.checkpoint import strain_at

    scene = _with_overrides(load_scene(args.scene), args)
    try:
        device = resolve_device(args.device)
    except SceneError as exc:
        raise SceneError("--device", exc.expected, exc.got, source="command line") from None
    if args.out is not None:
        check_folder_output(Path(args.out), "--out", "command line")
    writers = _writers(scene, args)
    if args.preview:
        from .output import refuse_replacing_unmarked_png
        from .preview import STILL, default_paths, require_blender

        require_blender("--preview")
        if not scene.output.usd:
            raise SceneError("--preview", "a run that writes USD (the preview renders it)", "--no-usd",
                             source="command line")
        usd_target = writers[0].target
        try:
            refuse_replacing_unmarked_png(default_paths(usd_target)[0], STILL, "--preview", usd_target)
        except SceneError as exc:
            raise SceneError(exc.key, exc.expected, exc.got, "command line") from None
    checkpoint_file = checkpoint_path(writers[0].target) if writers else None
    checkpoint = None
    if args.resume:
        if checkpoint_file is None:
            raise SceneError("--resume", "outputs to go on with (a run without USD, .poly or metrics keeps no "
                                         "checkpoint)",
                             has_got=False, source="command line")
        if not checkpoint_file.exists():
            raise SceneError("--resume", f"a checkpoint of an earlier run at {checkpoint_file}", has_got=False,
                             source="command line")
        checkpoint = load_checkpoint(checkpoint_file)
        check_scene(checkpoint, scene, str(checkpoint_file))
        clock = shot_clock(scene)
        if clock.end <= checkpoint.frame:
            raise SceneError("--frames", f"more frames than the checkpoint's {checkpoint.frame - clock.start} to "
                                         "resume", scene.simulation.frames, "command line")
    _prepare(writers, args)
    try:
        sim, building = _simulator(scene, device.alias, args)
        if checkpoint is not None:
            sim.restore(checkpoint)
            _take_back(checkpoint, scene, writers)
    except BaseException:
        _release(writers)
        raise
    if sim.start_projection is not None:  # a fresh run's, not a resumed one's
        print(f"{scene.name}: {sim.start_projection.describe()}", flush=True)
    from .metrics import MetricsWriter
    from .strain import StrainMonitor

    outputs = list(writers)
    strain = StrainMonitor(strain_at(checkpoint.extra) if checkpoint is not None else None)
    check = None
    if args.check:
        from .diagnostics import CheckReport

        check = CheckReport(sys.stdout, strain)
    metrics = [w for w in outputs if isinstance(w, MetricsWriter)]
    for w in metrics:
        w.check = check
    # The metrics read the check's count of the frame, and the checkpoint saves what every other writer
    # holds at its frame: they come last.
    writers = [w for w in outputs if w not in metrics] + [strain] + ([check] if check else []) + metrics
    checkpointer = None
    if checkpoint_file is not None:
        checkpointer = CheckpointWriter(checkpoint_file, outputs, strain)
        writers.append(checkpointer)
    frames = sim.clock.end - sim.frame
    try:
        summary = sim.run(frames, writers=writers, progress=args.progress or not (args.quiet or args.check))
    except UnstableSimulation as exc:
        kept = (f"frames {sim.clock.start} to {exc.frame - 1}" if sim.clock.writes(exc.frame - 1)
                else "no frame (it was in the preroll)")
        print(f"warp-cloth: error: {scene.name}: {exc} Kept {kept} in {_kept(outputs)}; "
              "nothing in place was replaced.", file=sys.stderr)
        return EXIT_UNSTABLE
    except (OutputError, OSError) as exc:
        print(f"warp-cloth: error: {scene.name}: could not write the output ({exc}). Kept the frames so far in "
              f"{_kept(outputs)}{_resume_hint(checkpointer)}; nothing in place was replaced.", file=sys.stderr)
        return EXIT_OUTPUT_FAILED
    except KeyboardInterrupt:  # a second Ctrl-C, SIGTERM or SIGHUP: the frame in progress is lost
        print(f"warp-cloth: {scene.name}: stopped at once; kept the finished frames in {_kept(outputs)}"
              f"{_resume_hint(checkpointer)}.", file=sys.stderr)
        return EXIT_INTERRUPTED
    sim_settings = scene.simulation
    wrote = _kept(outputs)
    if summary.interrupted:
        name = signal.Signals(summary.stop_signal).name
        status = (f"interrupted after {summary.frames} of {sim_settings.preroll + sim_settings.frames} frames by "
                  f"{name}")
        wrote += _resume_hint(checkpointer)
    else:
        status = counted(summary.frames, "frame")
    if sim.clock.start or sim.clock.preroll:
        status += f" (frames {sim.clock.start} to {sim.clock.end} of the shot" + \
                  (f", after a preroll of {sim.clock.preroll})" if sim.clock.preroll else ")")
    if checkpoint is not None:
        status += f" (resumed at frame {checkpoint.frame})"
    older = sum(getattr(w, "older_frames_left", 0) for w in outputs)
    if older:
        wrote += f" ({older} older .poly files of other frames left there)"
    if args.preview and not summary.interrupted:
        wrote += _preview(outputs, args)
    print(f"{scene.name}: {status} ({_substeps_said(summary, sim)}, "
          f"{sim_settings.integrator}) of {summary.particles} particles on {sim.device.alias} in "
          f"{summary.wall_seconds:.2f} s (+{building + summary.prepare_seconds:.1f} s building and compiling; "
          f"{summary.particle_substeps_per_second:.3g} particle-substeps/s); "
          f"wrote {wrote}; {_strain(strain)}{_limit_solve(sim)}{_measured_again(sim, summary)}{_lists_full(sim)}" +
          (f"; {check.summary()}" if check else ""))
    return EXIT_SIGNAL_BASE + summary.stop_signal if summary.interrupted else 0


def _substeps_said(summary, sim) -> str:
    """The run's substeps, for the summary line: with substeps auto, those a frame took and what was made
    again."""
    if sim.auto is None:
        return f"{counted(summary.substeps, 'substep')} of {sim.dt * 1e3:.3g} ms"
    chosen = summary.frame_substeps
    if not chosen:
        return f"{counted(summary.substeps, 'substep')}, auto"
    said = (f"{counted(summary.substeps, 'substep')}, auto: substeps a frame: min {min(chosen)}, median "
            f"{statistics.median(chosen):g}, max {max(chosen)}")
    again = summary.substeps - sum(chosen)
    if again:
        said += f"; {again} in frames made again with more"
    if summary.kept_missing:
        said += (f"; {counted(summary.kept_missing, 'frame')} kept at the most, {sim.auto.most}, with a solve "
                 "missing its tolerance or the guard's flag")
    if summary.kept_stalled:
        said += (f"; {counted(summary.kept_stalled, 'frame')} kept with a solve missing its tolerance that twice "
                 "the substeps did not bring closer (what it holds cannot all be held: pins or colliders past "
                 "the strain limit)")
    return said


def _strain(monitor) -> str:
    """What the run's frames strained, for the summary line."""
    report = monitor.report()
    return report.describe() if report is not None else "no frame written (stopped in the preroll)"


def _preview(outputs: list, args: argparse.Namespace) -> str:
    """Render the run's USD (``--preview``); what it wrote, for the summary line."""
    from .preview import render_preview
    from .writers import UsdWriter

    (usd,) = [w.path for w in outputs if isinstance(w, UsdWriter)]
    try:
        preview = render_preview(usd, progress=not args.quiet)
    except SceneError as exc:
        print(f"warp-cloth: error: --preview: {exc}", file=sys.stderr)
        return " (no preview: refused)"
    except RuntimeError as exc:
        print(f"warp-cloth: error: --preview: {exc}", file=sys.stderr)
        return " (no preview: its render failed)"
    return f", {preview.still}, {preview.animation} (rendered in {preview.seconds:.1f} s)"


class _StoppedBySignal(KeyboardInterrupt):
    """SIGTERM or SIGHUP before a run's frames (a run turns them into a stop after a frame)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_stopped(signum: int, frame) -> None:
    raise _StoppedBySignal(signum)


def main(argv: list[str] | None = None) -> int:
    """The ``warp-cloth`` command. Ctrl-C, SIGTERM and SIGHUP before a run (while Warp loads and compiles)
    end it with one line and nothing left behind, and a reader that closes the pipe (``warp-cloth scenes |
    head -1``) ends it without a traceback."""
    stop_signals = [s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s]
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {number: signal.signal(number, _raise_stopped) for number in stop_signals}
    try:
        code = _main(argv)
        sys.stdout.flush()  # so that a closed pipe shows here rather than at exit
        return code
    except _StoppedBySignal as exc:
        print(f"warp-cloth: stopped by {signal.Signals(exc.signum).name}", file=sys.stderr)
        return EXIT_SIGNAL_BASE + exc.signum
    except KeyboardInterrupt:
        print("warp-cloth: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # Python flushes stdout once more at exit: leave it nothing to fail on.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _main(argv: list[str] | None) -> int:
    args, rest = _parser().parse_known_args(argv)
    if args.command in LAB_COMMANDS:
        return importlib.import_module(LAB_COMMANDS[args.command]).main(rest)
    if args.command == "sweep":
        from .sweep import main as sweep_main

        return sweep_main(rest)
    if args.command == "drape-test":
        from .drape_test import main as drape_test_main

        return drape_test_main(rest)
    if args.command == "preview":
        from .preview import main as preview_main

        return preview_main(rest)
    if rest:
        _parser().error(f"unrecognized arguments: {' '.join(rest)}")
    try:
        if args.command == "scenes":
            return _cmd_scenes()
        if args.command == "plan":
            return _cmd_plan(args)
        if args.command == "materials":
            return _cmd_materials(args)
        return _cmd_run(args)
    except SceneError as exc:
        print(f"warp-cloth: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
