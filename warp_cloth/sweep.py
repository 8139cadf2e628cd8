"""``warp-cloth sweep``: many variants of a scene, packed as the worlds of batches, with a table of outcomes.

    warp-cloth sweep drape --set cloth.bend.stiffness=1,5,10 --set simulation.integrator=symplectic,implicit
    warp-cloth sweep drape --set cloth.density=0.1:0.4 --random 64 --seed 7

A ``--set KEY=V1,V2,...`` names a key of the scene file by its path (``cloth.bend.stiffness`` sets it on
every cloth, ``cloth[1].bend.stiffness`` on the second) and its values, each a TOML value (a bare word is
a string), each key and value once; the sweep runs the cartesian product. With ``--random N``,
``KEY=LOW:HIGH`` draws a number uniformly in the range (to 6 significant digits, the value the variant's
name and run both have) and a list draws one of its values, N times from ``--seed``; a variant drawn
twice runs once.

Variants that can share a step (see ``batch.step_key``) run together as the worlds of one batch, at most
``--worlds`` at a time; those with another step (another integrator, substeps, solve settings, or where
the scene sets no step, another one chosen for stability: a density, a stiffness) or another number of
frames in batches of their own, so that each variant runs at the step it would take alone. Each writes
its USD, named by its settings, into the output folder, and one row of ``results.jsonl`` as its batch
ends: its settings, its worst edge stretch and compression over every frame, its kinetic energy and
closest contact at the end, the frame it blew up in if it did, and the wall time. ``results.csv`` holds
the same table. A sweep started again over the same folder skips the variants the table already has, so
an interrupted sweep goes on where it stopped, and nothing is computed twice; a row cut short by a kill is
run again. The folder is locked while a sweep runs (``results.lock``): a second sweep into it is refused.

With ``--cluster ADDRESS`` (a running Ray cluster's, or ``local`` for one started on this machine with
``--cluster-workers`` workers), each batch is a Ray task: two at a time on each GPU where the cluster has
them (one builds its model while the other runs), else one a CPU; batches are split until each such slot
has one, where there are variants enough. A task whose worker is lost runs again on another
(``--retries``). The tasks write their USD files into the output folder, which every worker must reach
(shared storage on a real cluster); the table is written here as their results come back. An address
where no Ray cluster answers is refused within seconds; Ray's own log lines show with ``--verbose``. Ray is the ``cluster`` extra:
``pip install 'warp-cloth[cluster]'``.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import csv
import hashlib
import itertools
import json
import logging
import os
import re
import signal
import socket
import sys
import time
import tomllib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import EXIT_BAD_INPUT, EXIT_SIGNAL_BASE, SceneError
from .output import OutputLock, check_folder_output, check_names_fit, file_system_refusals, lock_path
from .progress import Progress
from .wording import counted

EXIT_FAILED = 4
DEFAULT_WORLDS = 1024
RESULTS = "results.jsonl"
TABLE = "results.csv"
COLUMNS = ("variant", "settings", "stretch", "compression", "kinetic_energy", "closest_contact", "unstable_frame",
           "batch_worlds", "batch_seconds", "usd")
# Two workers share a GPU: one builds its batch's model on the host while the other's runs on the GPU
# (alone, a GPU idled for the build, a fifth of a 256^2 batch: docs/benchmarks.md).
TASKS_PER_GPU = 2
SIGNIFICANT_DIGITS = 6  # of a number drawn in a range: its variant's name, row and run all have this value
PROBE_SECONDS = 5.0  # how long a --cluster address has to answer as Ray does


@dataclass(frozen=True)
class SweepKey:
    """A ``--set``: the key's path and its values (or, for ``--random``, a range)."""
    path: str
    values: tuple[Any, ...] = ()
    low: float | None = None
    high: float | None = None


def _value(text: str) -> Any:
    """A TOML value, or the text itself where it is none (a bare word: a string)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _split_values(text: str) -> list[str]:
    """Values separated by commas outside brackets and quotes (``[1, 2],[3, 4]`` is two arrays)."""
    parts, depth, quote, current = [], 0, "", ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(current)
            current = ""
            continue
        current += ch
    return [*parts, current]


def parse_set(text: str, random: bool) -> SweepKey:
    key, sep, values = text.partition("=")
    if not sep or not key or not values:
        raise SceneError("--set", "KEY=V1,V2,... (or KEY=LOW:HIGH with --random)", text, source="command line")
    if random and re.fullmatch(r"[^,:\[\]]+:[^,:\[\]]+", values):
        low, high = (_value(v) for v in values.split(":"))
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (low, high)) or low > high:
            raise SceneError(f"--set {key}", "a range LOW:HIGH of two numbers, LOW <= HIGH", values,
                             source="command line")
        return SweepKey(key, low=float(low), high=float(high))
    texts = _split_values(values)
    parsed = tuple(_value(v) for v in texts)
    for k, value in enumerate(parsed):
        if value in parsed[:k]:  # by ==: 1 and 1.0 are one value (and would be one run)
            raise SceneError(f"--set {key}", f"each value once ({texts[k].strip()} is there twice)", values,
                             source="command line")
    return SweepKey(key, parsed)


def check_keys_once(keys: Sequence[SweepKey]) -> None:
    paths = [k.path for k in keys]
    for k, path in enumerate(paths):
        if path in paths[:k]:
            raise SceneError(f"--set {path}", "each key once (all its values in one --set)", has_got=False,
                             source="command line")


def settings_of(keys: Sequence[SweepKey], random: int | None, seed: int) -> list[tuple[tuple[str, Any], ...]]:
    """Each variant's settings, (key, value) in the order the keys were given."""
    if random is None:
        product = itertools.product(*[[(k.path, v) for v in k.values] for k in keys])
        return [tuple(p) for p in product]
    rng = np.random.default_rng(seed)
    variants, names = [], set()
    for _ in range(random):
        chosen = tuple((k.path, _drawn(rng, k.low, k.high) if k.low is not None
                        else k.values[int(rng.integers(len(k.values)))]) for k in keys)
        if describe(chosen) not in names:  # a variant drawn again would make the same frames
            names.add(describe(chosen))
            variants.append(chosen)
    return variants


def _drawn(rng: np.random.Generator, low: float, high: float) -> float:
    """A number drawn uniformly in [low, high], rounded to ``SIGNIFICANT_DIGITS`` (and kept in the range)."""
    value = float(f"{rng.uniform(low, high):.{SIGNIFICANT_DIGITS}g}")
    return min(max(value, low), high)


_STEP = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def with_setting(data: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    """``data`` (a scene file's) with ``path`` set to ``value``: an array of tables without an index is
    set in each of its tables; a table on the way that is not there is made (the scene's checks then
    refuse a key that does not exist)."""
    data = copy.deepcopy(data)
    steps = path.split(".")
    targets = [data]
    for depth, step in enumerate(steps):
        match = _STEP.match(step)
        if match is None:
            raise SceneError(f"--set {path}", "a key path of names, each maybe with an [index]", step,
                             source="command line")
        name, index = match.group(1), match.group(2)
        last = depth == len(steps) - 1
        following = []
        for target in targets:
            if not isinstance(target, dict):
                raise SceneError(f"--set {path}", f"a path through tables ({'.'.join(steps[:depth])} is not one)",
                                 has_got=False, source="command line")
            if last and index is None:
                target[name] = value
                continue
            item = target.setdefault(name, {} if index is None else [])
            if isinstance(item, list):
                chosen = item if index is None else item[int(index):int(index) + 1]
                if index is not None and not chosen:
                    raise SceneError(f"--set {path}", f"an index below {len(item)} for {name}", int(index),
                                     source="command line")
                if last:
                    item[int(index)] = value
                following += chosen
            else:
                following.append(item)
        targets = following
    return data


def describe(settings: tuple[tuple[str, Any], ...]) -> str:
    return " ".join(f"{k}={json.dumps(v) if not isinstance(v, str) else v}" for k, v in settings)


def file_stem(settings: tuple[tuple[str, Any], ...]) -> str:
    """A file name for a variant, from its settings: readable where short, with a hash that keeps it unique."""
    text = describe(settings)
    readable = re.sub(r"[^A-Za-z0-9._=-]+", "_", text.replace(" ", "__"))[:80]
    return f"{readable}-{hashlib.sha1(text.encode()).hexdigest()[:8]}"


@dataclass(frozen=True)
class Variant:
    settings: tuple[tuple[str, Any], ...]
    data: dict[str, Any]

    @property
    def name(self) -> str:
        return describe(self.settings)


def build_variants(base: dict[str, Any], settings: list[tuple[tuple[str, Any], ...]], frames: int | None):
    """Each variant's scene as a simulator runs it (its step chosen where it sets none), checked: a bad value,
    or a step that cannot be chosen, is refused before anything runs, naming the variant."""
    from .scene_file import scene_from_dict
    from .stability import scene_with_step

    variants, scenes = [], []
    for chosen in settings:
        data = base
        for path, value in chosen:
            data = with_setting(data, path, value)
        if frames is not None:
            data = with_setting(data, "simulation.frames", frames)
        try:
            scene = scene_with_step(scene_from_dict(data))
        except SceneError as exc:
            raise SceneError(exc.key, exc.expected, exc.got, source=f"variant {describe(chosen)}",
                             has_got=exc.has_got) from None
        variants.append(Variant(chosen, data))
        scenes.append(scene)
    return variants, scenes


def batches(scenes: list, most: int) -> list[list[int]]:
    """The variants' indices in batches: those that can share a step (``batch.step_key``: each the step it
    takes alone) and run as many frames together, ``most`` at a time."""
    from .batch import step_key

    groups: dict[tuple[str, int], list[int]] = {}
    for k, scene in enumerate(scenes):
        groups.setdefault((step_key(scene), scene.simulation.frames), []).append(k)
    return [members[i:i + most] for members in groups.values() for i in range(0, len(members), most)]


class SweepInterrupted(Exception):
    """A batch stopped by a signal after a frame (Ctrl-C, SIGTERM, SIGHUP): its variants have no rows."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def run_batch(variants: list[Variant], out: Path, device: str | None, usd: bool) -> list[dict[str, Any]]:
    """Run one batch of variants and give their rows (what a cluster's task runs, too). Only while the
    sweep holds its folder's lock: a variant's frames left under the staging name are then those of an
    attempt of this sweep that was killed, and are removed (under the variant's own lock, so that a run
    writing that file by hand is refused rather than overwritten)."""
    import warnings

    from .batch import Batch
    from .scene_file import scene_from_dict
    from .stability import UnstableStepWarning
    from .strain import WorldStrain
    from .writers import UsdWriter

    scenes = [scene_from_dict(v.data) for v in variants]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableStepWarning)  # a step past its bound: the table says if it blew up
        batch = Batch(scenes, device=device)
    paths = {w: out / f"{file_stem(v.settings)}.usdc" for w, v in enumerate(variants)} if usd else {}
    writers = {w: UsdWriter(p) for w, p in paths.items()}
    strain = WorldStrain()
    frames = scenes[0].simulation.frames
    started = time.perf_counter()
    try:
        for w, writer in writers.items():
            writer.lock.acquire(writer.key, f"variant {variants[w].name}")
            writer.staging.unlink(missing_ok=True)
        summary = batch.run(frames, writers={w: [writer] for w, writer in writers.items()}, monitors=[strain])
    except Exception as exc:  # every world stopped: the table says where each blew up
        from .errors import UnstableSimulation

        if not isinstance(exc, UnstableSimulation):
            raise
    else:
        if summary.interrupted:  # its worlds are not done: no rows, so that the sweep started again runs them
            raise SweepInterrupted(summary.stop_signal)
    finally:
        for writer in writers.values():  # those the batch did not end (a writer ending releases its own)
            writer.lock.release()
    seconds = time.perf_counter() - started
    worst = strain.worst()
    contacts = batch.closest_contacts()
    rows = []
    for w, variant in enumerate(variants):
        v, masses = batch.velocities(w).astype(np.float64), batch.masses(w).astype(np.float64)
        stopped = batch.stopped_worlds.get(w)
        usd_path = paths.get(w)
        if usd_path is not None and stopped is not None:
            usd_path = usd_path.with_name(f"{usd_path.stem}.failed.usdc")
        rows.append({"variant": variant.name, "settings": dict(variant.settings),
                     "stretch": float(worst[w, 0]), "compression": float(worst[w, 1]),
                     "kinetic_energy": float(0.5 * np.sum(masses * np.sum(v * v, axis=1))),
                     "closest_contact": float(contacts[w]) if contacts is not None and np.isfinite(contacts[w])
                     else None,
                     "unstable_frame": None if stopped is None else stopped.frame,
                     "batch_worlds": len(variants), "batch_seconds": seconds,
                     "usd": None if usd_path is None else str(usd_path)})
    return rows


def _is_row(line: str | bytes) -> bool:
    try:
        row = json.loads(line)
    except ValueError:
        return False
    return (isinstance(row, dict) and all(c in row for c in COLUMNS) and isinstance(row["variant"], str)
            and isinstance(row["settings"], dict))


def mend_last_row(out: Path) -> None:
    """A sweep killed as it wrote a row leaves the row's start without an end of line: that is cut off
    (its variant runs again), saying so. A whole last row without one (a file saved by an editor) gets
    its end of line, so that the next row starts a line of its own. Call it holding the sweep's lock."""
    path = out / RESULTS
    if not path.exists():
        return
    text = path.read_bytes()
    if not text or text.endswith(b"\n"):
        return
    start = text.rfind(b"\n") + 1
    if _is_row(text[start:]):
        with open(path, "ab") as handle:
            handle.write(b"\n")
    elif text[start:].startswith(b'{"variant": '):  # how append_rows begins a row; anything else is refused
        os.truncate(path, start)
        line = text.count(b"\n") + 1
        print(f"warp-cloth sweep: note: {path}: line {line} was cut short (a sweep stopped as it wrote it); its "
              "variant runs again", file=sys.stderr)


def done_variants(out: Path) -> dict[str, dict[str, Any]]:
    """The rows an earlier run of this sweep wrote, by variant; a line that is not one is refused, naming it."""
    path = out / RESULTS
    if not path.exists():
        return {}
    rows = {}
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        if not line.strip():
            continue
        if not _is_row(line):
            raise SceneError(f"line {number}", f"a row of a sweep's table (an object with {', '.join(COLUMNS)}); "
                                               "mend the line or move the file away", line, source=str(path))
        row = json.loads(line)
        rows[row["variant"]] = row
    return rows


def append_rows(out: Path, rows: list[dict[str, Any]]) -> None:
    with open(out / RESULTS, "a") as handle:
        for row in rows:
            handle.write(json.dumps(row) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


def write_table(out: Path, rows: list[dict[str, Any]]) -> None:
    staging = out / f"{TABLE}.incomplete"
    with open(staging, "w", newline="") as handle:
        writer = csv.writer(handle)
        keys = sorted({k for row in rows for k in row["settings"]})
        writer.writerow([*keys, *[c for c in COLUMNS if c != "settings"]])
        for row in rows:
            writer.writerow([row["settings"].get(k, "") for k in keys] +
                            ["" if row[c] is None else row[c] for c in COLUMNS if c != "settings"])
    os.replace(staging, out / TABLE)


def run_local(todo: list[list[Variant]], out: Path, device: str | None, usd: bool) -> Iterator[list]:
    for chunk in todo:
        rows = run_batch(chunk, out, device, usd)
        append_rows(out, rows)
        yield rows


def require_ray() -> None:
    try:
        import ray  # noqa: F401
    except ImportError:
        raise SceneError("--cluster", "Ray installed (it is not: pip install 'warp-cloth[cluster]')", has_got=False,
                         source="command line") from None


_SETTINGS = 0x4  # the type of an HTTP/2 SETTINGS frame


def check_cluster_address(address: str) -> None:
    """Refuse, within seconds, an address where no Ray cluster answers (Ray itself tries for minutes).
    Ray's GCS (``HOST:6379``) and its client server (``ray://HOST:10001``) speak gRPC, HTTP/2 whose server
    opens every connection with a SETTINGS frame; whatever else answers (a web server, Redis) is named."""
    if address == "local":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        answer, what = _first_answer(host.strip("[]") or "127.0.0.1", int(port))
    except (OSError, ValueError) as exc:
        what = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    else:
        if _is_settings_frame(answer):
            return
    raise SceneError("--cluster", f"the address of a running Ray cluster, HOST:PORT, or local ({what})", address,
                     source="command line")


def _first_answer(host: str, port: int) -> tuple[bytes, str]:
    """What the server at ``host:port`` says first, and that in words."""
    deadline = time.monotonic() + PROBE_SECONDS
    with socket.create_connection((host, port), timeout=PROBE_SECONDS) as connection:
        # A gRPC server sends its SETTINGS frame on connecting, whatever it is sent; a web server answers
        # this with a status line.
        connection.sendall(f"GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
        answer = b""
        while len(answer) < 9 or (answer.startswith(b"HTTP/") and b"\n" not in answer and len(answer) < 512):
            connection.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                chunk = connection.recv(512)
            except TimeoutError:
                return answer, f"nothing answered there as Ray does within {PROBE_SECONDS:g} s"
            if not chunk:
                return answer, "it closed the connection without answering as Ray does"
            answer += chunk
    first = answer.split(b"\n")[0].strip().decode("ascii", "replace")
    if answer.startswith(b"HTTP/"):
        return answer, f"an HTTP server answered: {first}"
    return answer, f"something other than Ray answered: {first[:40]!r}"


def _is_settings_frame(answer: bytes) -> bool:
    """An HTTP/2 frame header (length, type, flags, stream) of a SETTINGS frame, not an acknowledgement,
    on stream 0."""
    return (len(answer) >= 9 and answer[3] == _SETTINGS and not answer[4] & 0x1
            and int.from_bytes(answer[5:9], "big") & 0x7FFFFFFF == 0)


def run_cluster(todo: list[list[Variant]], out: Path, device: str | None, usd: bool, address: str, workers: int,
                retries: int, verbose: bool) -> Iterator[list]:
    """Each batch a Ray task; rows come back as tasks end, in whatever order. Ray's own log lines (and
    its workers' output) reach the terminal only where ``verbose``."""
    import ray

    with contextlib.nullcontext() if verbose else _quiet_logger("ray"):
        try:
            with contextlib.nullcontext() if verbose else _stderr_dropped():
                _start_ray(ray, address, workers, verbose)
            resources = ray.cluster_resources()
            gpus = int(resources.get("GPU", 0)) if device in (None, "cuda") else 0
            # max_calls=0: a worker runs batch after batch (Ray's default for a GPU task is a process a task,
            # which paid Python's start and Warp's module loads again for each batch: 0.57x of a sweep without Ray)
            task = ray.remote(num_gpus=1 / TASKS_PER_GPU if gpus else 0, num_cpus=0 if gpus else 1,
                              max_retries=retries, retry_exceptions=False, max_calls=0)(run_batch)
            slots = gpus * TASKS_PER_GPU or int(resources.get("CPU", 1))
            pending = [task.remote(chunk, out.absolute(), "cuda" if gpus else "cpu", usd)
                       for chunk in spread(todo, slots)]
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                rows = ray.get(done[0])
                append_rows(out, rows)
                yield rows
        finally:
            ray.shutdown()


def spread(todo: list[list[Variant]], slots: int) -> list[list[Variant]]:
    """The batches split until each of ``slots`` workers (a cluster's GPUs, or its CPUs) has one, where
    there are variants enough: the largest halved each time, so that a sweep of one batch of 8 worlds runs
    as two of 4 on a host of two GPUs rather than on one of them."""
    todo = list(todo)
    while len(todo) < slots and max(map(len, todo), default=1) > 1:
        largest = max(range(len(todo)), key=lambda k: len(todo[k]))
        chunk = todo.pop(largest)
        half = (len(chunk) + 1) // 2
        todo[largest:largest] = [chunk[:half], chunk[half:]]
    return todo


class ClusterUnavailable(Exception):
    """Ray could not start a cluster here or join the one at the address: nothing ran."""


def _start_ray(ray, address: str, workers: int, verbose: bool) -> None:
    try:
        if address == "local":  # a cluster of its own, not one RAY_ADDRESS or the last "ray start" here names
            ray.init(address="local", num_cpus=workers, include_dashboard=False, log_to_driver=verbose,
                     configure_logging=verbose)
        else:
            ray.init(address=address, log_to_driver=verbose, configure_logging=verbose)
    except Exception as exc:
        action = "start a Ray cluster here" if address == "local" else f"join the Ray cluster at {address}"
        raise ClusterUnavailable(f"could not {action} ({type(exc).__name__}: {_last_line(exc)})") from exc


def _last_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [""])[-1]


@contextlib.contextmanager
def _stderr_dropped() -> Iterator[None]:
    """This process's file descriptor 2, where Ray's C++ core writes its log lines, sent nowhere (and so
    for the processes started meanwhile: a local cluster's)."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    os.close(devnull)
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


@contextlib.contextmanager
def _quiet_logger(name: str) -> Iterator[None]:
    """The ``name`` logger and those under it silent (Ray gives its own a handler that writes to stderr)."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)


def _parser() -> argparse.ArgumentParser:
    text = __doc__.replace("``", "")  # the docstring's literals, as the help shows them: plain
    parser = argparse.ArgumentParser(prog="warp-cloth sweep", description=text.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(text.split("\n\n")[1:]))
    parser.add_argument("scene", help="built-in scene name or path to a .toml file")
    parser.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=V1,V2,...",
                        help="a key and its values (repeat for more keys)")
    parser.add_argument("--random", type=int, metavar="N", help="N variants drawn at random instead of the product")
    parser.add_argument("--seed", type=int, default=0, help="the random draws' seed (default 0)")
    parser.add_argument("--frames", type=int, help="frames of each variant (default: the scene's)")
    parser.add_argument("--device", help="cpu, cuda or cuda:N (default: cuda if available, else cpu)")
    parser.add_argument("--worlds", type=int, default=DEFAULT_WORLDS,
                        help=f"most variants in one batch (default {DEFAULT_WORLDS})")
    parser.add_argument("--out", type=Path, help="output folder (default: out/sweep-SCENE)")
    parser.add_argument("--no-usd", action="store_true", help="write the table only, no USD per variant")
    parser.add_argument("--cluster", metavar="ADDRESS",
                        help="run the batches on a Ray cluster: its address (HOST:PORT), or local to start one here")
    parser.add_argument("--cluster-workers", type=int, default=2,
                        help="with --cluster local on a machine without GPUs, how many workers (default 2); "
                             "with GPUs, one a GPU")
    parser.add_argument("--retries", type=int, default=3,
                        help="with --cluster, how often a batch whose worker was lost runs again (default 3)")
    parser.add_argument("--verbose", action="store_true",
                        help="with --cluster, show Ray's own log lines and its workers' output")
    return parser


def check_output_folder(out: Path, variants: list[Variant], usd: bool) -> None:
    """Every check a run's ``--out`` has, for the sweep's folder and the files it writes there."""
    from .writers import UsdWriter

    check_folder_output(out, "--out", "command line")
    table = out / RESULTS
    check_names_fit(table, [TABLE, f"{TABLE}.incomplete", lock_path(table).name], "--out", "command line")
    try:
        for variant in variants if usd else []:
            UsdWriter(out / f"{file_stem(variant.settings)}.usdc")
    except SceneError as exc:
        raise SceneError("--out", exc.expected, str(out), "command line") from None


def main(argv: list[str] | None = None) -> int:
    import warp as wp

    args = _parser().parse_args(argv)
    wp.config.log_level = wp.LOG_ERROR  # Warp's messages of modules loaded are not for the command's user
    try:
        return _sweep(args)
    except SceneError as exc:  # before anything runs, or a batch's (an output another run is writing)
        print(f"warp-cloth sweep: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


def _sweep(args: argparse.Namespace) -> int:
    from .scene_file import load_scene_data

    if not args.sets:
        raise SceneError("--set", "at least one KEY=V1,V2,...", has_got=False, source="command line")
    if args.random is not None and args.random < 1:
        raise SceneError("--random", "a number of variants >= 1", args.random, source="command line")
    if args.worlds < 1:
        raise SceneError("--worlds", "a number of worlds >= 1", args.worlds, source="command line")
    keys = [parse_set(text, args.random is not None) for text in args.sets]
    check_keys_once(keys)
    settings = settings_of(keys, args.random, args.seed)
    if not settings:
        raise SceneError("--set", "values that make at least one variant", "none", source="command line")
    if args.cluster is not None:
        require_ray()
        check_cluster_address(args.cluster)
    base, _ = load_scene_data(args.scene)
    variants, scenes = build_variants(base, settings, args.frames)
    out = args.out or Path("out") / f"sweep-{scenes[0].name}"
    check_output_folder(out, variants, not args.no_usd)
    lock = OutputLock(out / RESULTS)  # the folder's, held while the sweep runs: a second sweep is refused
    with file_system_refusals("--out", out, "command line"):
        lock.acquire("--out", "command line")
    try:
        with file_system_refusals("--out", out, "command line"):
            mend_last_row(out)
        done = done_variants(out)
        return _run(args, out, variants, scenes, done)
    finally:
        lock.release()  # and the folder, where the sweep made it and left nothing in it


def _run(args: argparse.Namespace, out: Path, variants: list[Variant], scenes: list, done: dict) -> int:
    from .simulator import StopOnSignal

    todo = [[variants[k] for k in chunk if variants[k].name not in done]
            for chunk in batches(scenes, args.worlds)]
    todo = [chunk for chunk in todo if chunk]
    skipped = len(variants) - sum(len(c) for c in todo)
    bar = Progress(len(variants), f"sweep {scenes[0].name}")
    bar.update(skipped)
    finished, unstable, batches_run, started = skipped, 0, 0, time.perf_counter()
    usd = not args.no_usd
    runs = run_local(todo, out, args.device, usd) if args.cluster is None else \
        run_cluster(todo, out, args.device, usd, args.cluster, args.cluster_workers, args.retries, args.verbose)
    stopped_by = None  # the first Ctrl-C stops the batch in progress after its frame, a second at once
    try:
        with StopOnSignal() as stop:  # a signal between batches
            for rows in runs:
                batches_run += 1
                finished += len(rows)
                unstable += sum(row["unstable_frame"] is not None for row in rows)
                bar.update(finished)
                if stop.requested:
                    stopped_by = stop.signal
                    break
    except SweepInterrupted as exc:
        stopped_by = exc.signum
    except (KeyboardInterrupt, SceneError):
        raise
    except ClusterUnavailable as exc:
        bar.close()
        hint = "" if args.verbose else "; --verbose shows Ray's log lines"
        print(f"warp-cloth sweep: error: --cluster: {exc}; nothing ran{hint}", file=sys.stderr)
        return EXIT_FAILED
    except Exception as exc:  # a batch that failed (a full disk; on a cluster, a worker lost past its retries)
        bar.close()
        kept = (f"the {counted(finished, 'variant')} done are in {out / RESULTS}" if finished else
                "no variant was done")
        print(f"warp-cloth sweep: error: a batch failed ({type(exc).__name__}: {_last_line(exc)}); {kept}; start "
              "the sweep again to go on", file=sys.stderr)
        return EXIT_FAILED
    finally:
        runs.close()  # on a cluster, shuts Ray down
        bar.close()
        rows = list(done_variants(out).values())
        if rows:
            write_table(out, rows)
    status = (f"{counted(len(variants), 'variant')} ({skipped} done before) in "
              f"{counted(batches_run, 'batch', 'batches')}")
    if stopped_by is not None:
        status = (f"interrupted by {signal.Signals(stopped_by).name} after {finished} of {len(variants)} variants "
                  f"({skipped} done before); start the sweep again to go on")
    print(f"sweep {scenes[0].name}: {status}, {time.perf_counter() - started:.1f} s; {unstable} blew up; "
          f"wrote {out / TABLE} and {out / RESULTS}")
    return 0 if stopped_by is None else EXIT_SIGNAL_BASE + stopped_by


if __name__ == "__main__":
    sys.exit(main())
