"""Where a run's files go and how they get there, without losing anything the user had.

A run writes each output (the USD file, the .poly folder) under a staging name beside it and moves it into
place only when the run completes; it holds a lock beside the output while it runs. For an output
``out/hanging.usdc`` (a folder ``out/hanging/poly`` alike, without a suffix):

- ``out/hanging.incomplete.usdc``: the frames of the run in progress, or of one that was killed
- ``out/hanging.failed.usdc``: the frames of a run that failed (unstable, a full disk, a writer's error)
- ``out/hanging.interrupted.usdc``: the frames of a stopped run (Ctrl-C, SIGTERM, SIGHUP) where an output
  was already in place (a stopped run with nothing to replace puts its frames in place)
- ``out/hanging.lock``: held while a run writes the output; it names the run's process. It is named after
  the output's stem, like the checkpoint, so that it covers every output sharing those names:
  ``hanging.usd``, ``.usda`` and ``.usdc`` (one staging file), and a folder ``out/hanging`` (one
  checkpoint). Outputs of one run share it (see ``OutputLock``).
- ``out/hanging.checkpoint.npz``: the state at the last saved frame, for ``--resume`` (see
  ``warp_cloth.checkpoint``); removed when the run completes or goes unstable, kept when it was stopped,
  killed or failed otherwise. ``out/hanging.exporting.usdc``: the compact copy being written at the end

Where a labelled name is taken, ``.failed.2``, ``.failed.3``, ... are used: a run never replaces a file it
did not make. A new run (not ``--resume``) is refused before simulating while a staging name or the
checkpoint of a run that did not complete is there, and where one of these names would be longer than the
file system allows.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
from pathlib import Path

from .errors import SceneError

INCOMPLETE = "incomplete"
FAILED = "failed"
INTERRUPTED = "interrupted"


class OutputError(RuntimeError):
    """An output could not be written (a full disk, a folder that went away); the run ends as failed."""


def labelled(path: Path, label: str, suffix: str | None = None) -> Path:
    """A file: ``labelled(out/hanging.usdc, label, ".usdc")`` -> ``out/hanging.<label>.usdc`` (``suffix``
    replaces the file's own); a folder (no ``suffix``): ``poly`` -> ``poly.<label>``."""
    if suffix is None:
        return path.with_name(f"{path.name}.{label}")
    return path.with_name(f"{path.name[:len(path.name) - len(path.suffix)]}.{label}{suffix}")


def first_free(path: Path, label: str, suffix: str | None = None) -> Path:
    """The first of ``labelled(path, label)``, then ``label.2``, ``label.3``, ... that does not exist."""
    candidate = labelled(path, label, suffix)
    n = 2
    while os.path.lexists(candidate):
        candidate = labelled(path, f"{label}.{n}", suffix)
        n += 1
    return candidate


def stem_path(output: Path) -> Path:
    """What an output's lock and checkpoint are named after: ``out/hanging.usdc`` -> ``out/hanging`` (so
    ``hanging.usd``, ``.usda`` and ``.usdc``, whose staging file is one, share them); a folder
    ``out/hanging/poly`` -> itself, ``renders/shot.v2`` -> ``renders/shot`` (as a file would)."""
    return output.with_name(output.name[:len(output.name) - len(output.suffix)])


def lock_path(output: Path) -> Path:
    return output.with_name(f"{stem_path(output).name}.lock")


def checkpoint_path(output: Path) -> Path:
    """The checkpoint beside a run's first output: ``out/hanging.usdc`` -> ``out/hanging.checkpoint.npz``,
    a folder ``poly`` -> ``poly.checkpoint.npz`` (see ``stem_path``)."""
    return output.with_name(f"{stem_path(output).name}.checkpoint.npz")


def temporary_path(path: Path) -> Path:
    """Where a checkpoint is written before it is renamed to ``path``."""
    return path.with_name(path.name + ".tmp")


def _nearest_existing(path: Path) -> Path:
    path = path.absolute()
    while not os.path.exists(path) and path != path.parent:  # os.path: False for a name too long, not OSError
        path = path.parent
    return path


def _limit(existing: Path, name: str, default: int) -> int:
    try:
        return os.pathconf(existing, name)
    except (OSError, ValueError):
        return default


@contextlib.contextmanager
def file_system_refusals(key: str, path: Path, source: str | None = None):
    """Turn the file system's refusal of an output path (a name too long, a folder it cannot make) into
    bad input, before the simulation starts."""
    try:
        yield
    except OSError as exc:
        what = "a path the file system can hold" if exc.errno == errno.ENAMETOOLONG else "a path this run can write"
        raise SceneError(key, f"{what} ({exc.strerror or exc})", str(path), source) from None


def check_names_fit(target: Path, made: list[str], key: str, source: str | None = None) -> None:
    """Refuse ``target`` where one of the folders to make for it, or one of the names ``made`` beside it,
    is longer than its file system allows (``NAME_MAX``), or the whole path of one is (``PATH_MAX``; USD
    opens its files by their absolute paths)."""
    target = target.absolute()
    existing = _nearest_existing(target)
    name_max, path_max = _limit(existing, "PC_NAME_MAX", 255), _limit(existing, "PC_PATH_MAX", 4096)
    checks = [(name, name_max) for name in (*target.relative_to(existing).parts, *made)]
    checks += [(str(target.with_name(name)), path_max - 1) for name in made]  # PATH_MAX counts the final NUL
    for name, limit in checks:
        size = len(os.fsencode(name))
        if size > limit:
            shown = name if len(name) <= 40 else f"{name[:20]}...{name[-16:]}"
            raise SceneError(key, f"a path the file system can hold (File name too long: {shown} is {size} bytes, "
                                  f"at most {limit})", str(target), source)


def check_writable_place(path: Path, key: str, source: str | None = None) -> None:
    """Refuse an output whose folder cannot be made or written (before the simulation starts)."""
    existing = _nearest_existing(path.parent)
    if not existing.is_dir():
        raise SceneError(key, f"a path whose folders can be made ({existing} is a file)", str(path), source)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise SceneError(key, f"an output in a folder this user can write ({existing} is read-only)", str(path),
                         source)


def check_file_output(path: Path, suffixes: tuple[str, ...], key: str, source: str | None = None) -> None:
    if path.suffix.lower() not in suffixes:
        raise SceneError(key, f"a file name ending in {', '.join(suffixes)}", str(path), source)
    with file_system_refusals(key, path, source):
        if path.is_dir():
            raise SceneError(key, "a file name (this is a folder)", str(path), source)
        check_writable_place(path, key, source)


def check_folder_output(path: Path, key: str, source: str | None = None) -> None:
    with file_system_refusals(key, path, source):
        if path.exists() and not path.is_dir():
            raise SceneError(key, "a folder (this is a file)", str(path), source)
        check_writable_place(path / "x", key, source)


class _HeldLock:
    """A lock file this process holds, with the outputs it holds it for."""

    def __init__(self, fd: int, made: list[Path]) -> None:
        self.fd = fd
        self.made = made  # folders made for the lock, removed with it if still empty
        self.claims: set[Path] = set()  # the targets and staging names of the outputs holding it


class OutputLock:
    """``<stem>.lock`` beside an ``output`` (see ``stem_path``), held with ``flock`` for as long as the run
    writes the output. One lock covers every output that shares the stem's staging and checkpoint names, so
    runs on ``x.usd`` and ``x.usdc`` (or ``--usd out/p.usdc`` and ``--no-usd --poly out/p``) exclude each
    other. Within one process the outputs of one run share the lock, as long as none of them writes a file
    (``claims``: its target and staging name) another one holding it writes. The kernel drops the lock when
    its process dies, however it dies, so a lock file left by a dead run is simply taken over."""

    _held: dict[Path, _HeldLock] = {}  # by the lock file's absolute path

    def __init__(self, output: Path, claims: tuple[Path, ...] = ()) -> None:
        self.output = output
        self.path = lock_path(output)
        self.claims = {p.absolute() for p in (output, *claims)}
        self._holding = False

    def acquire(self, key: str, source: str | None = None) -> None:
        if self._holding:
            return
        held = self._held.get(self.path.absolute())
        if held is None:
            held = self._held[self.path.absolute()] = self._lock(key, source)
        elif held.claims & self.claims:
            raise SceneError(key, f"an output no other output of this run writes (another output of this run "
                                  f"writes {min(held.claims & self.claims)})", str(self.output), source)
        held.claims |= self.claims
        self._holding = True

    def _lock(self, key: str, source: str | None) -> _HeldLock:
        missing = [p for p in (self.path.parent, *self.path.parent.parents) if not p.exists()]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise
                _remove_empty(missing)
                raise SceneError(key, f"an output no other run is writing (the run with process id "
                                      f"{self._holder()} holds {self.path})", str(self.output), source) from None
            # The holder before us may have removed the file after we opened it: lock the file that is there.
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        return _HeldLock(fd, missing)

    def _holder(self) -> str:
        try:
            return self.path.read_text().strip() or "?"
        except OSError:
            return "?"

    def release(self) -> None:
        if not self._holding:
            return
        self._holding = False
        held = self._held[self.path.absolute()]
        held.claims -= self.claims
        if held.claims:
            return  # another output of this run still holds it
        del self._held[self.path.absolute()]
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        os.close(held.fd)
        _remove_empty(held.made)


def _remove_empty(folders: list[Path]) -> None:
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            break


def fsync_path(path: Path) -> None:
    """Ask the disk to keep ``path`` (a file or a folder) over a power cut."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def free_bytes(folder: Path) -> int:
    stats = os.statvfs(folder)
    return stats.f_bavail * stats.f_frsize


def describe_size(size: float) -> str:
    """``size`` bytes for a message: in MiB, or KiB or bytes where that would read 0.0 MiB."""
    if size >= 0.1 * 2**20:
        return f"{size / 2**20:.1f} MiB"
    if size >= 1024:
        return f"{size / 1024:.0f} KiB"
    return f"{size:.0f} bytes"


def move_files_into(staging: Path, folder: Path, names: list[str]) -> None:
    """Move the named files from ``staging`` into ``folder`` (replacing files of those names only), then
    remove ``staging`` if that left it empty."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        os.replace(staging / name, folder / name)
    try:
        staging.rmdir()
    except OSError:
        pass


def copy_tree_files(source: Path, target: Path, names: list[str]) -> None:
    target.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy2(source / name, target / name)


class StagedOutput:
    """What the USD and .poly writers share: an output at ``target`` written under ``staging`` beside it,
    the lock held while the run writes it, and where its frames are once the run has ended. ``key`` names
    the output in messages (``usd``, ``poly``); ``kind`` says what moving it away means (``file``, ``folder``);
    ``suffix`` is that of the staging and labelled names (none for a folder)."""

    key = ""
    kind = ""
    suffix: str | None = None

    def __init__(self, target: Path, staging: Path, resume: bool) -> None:
        self.target = target
        self.staging = staging
        self.lock = OutputLock(target, claims=(staging,))
        self.resume = resume
        self.location: Path | None = None  # where the frames are once the run has ended
        check_names_fit(target, self._names_made(), self.key)

    def _names_made(self) -> list[str]:
        """The names a run makes beside the output (``interrupted.99`` the longest label, ``.tmp`` the
        checkpoint's temporary name)."""
        return [self.staging.name, labelled(self.target, f"{INTERRUPTED}.99", self.suffix).name,
                self.lock.path.name, temporary_path(checkpoint_path(self.target)).name]

    def prepare(self) -> None:
        """Take the output's lock and check that no unfinished run's frames or checkpoint would be
        overwritten (done by ``begin`` too; call it first to be refused before simulating)."""
        with file_system_refusals(self.key, self.target):
            self.lock.acquire(self.key)
            try:
                if not self.resume:
                    self._refuse_an_unfinished_run()
            except BaseException:
                self.lock.release()
                raise

    def _refuse_an_unfinished_run(self) -> None:
        if self.staging.exists():
            raise SceneError(self.key, f"an output without a killed run's frames beside it: {self.staging} holds "
                                       f"them; continue that run with --resume or move the {self.kind} away",
                             has_got=False)
        checkpoint = checkpoint_path(self.target)
        if checkpoint.exists():
            raise SceneError(self.key, f"an output without an unfinished run's checkpoint beside it: {checkpoint} "
                                       "holds the state of a run that did not complete; continue it with --resume "
                                       "or move it away", has_got=False)

    def take_back(self, location: Path, frame: int, cloths: list[str], start: int = 0) -> None:
        """Before resuming, for a file output: the frames an earlier run left at ``location`` go back under
        the staging name (copied where they are in place: that file stays until the resumed run completes).
        ``frame``, ``cloths`` and ``start`` (the first frame written) are for outputs of a file a frame."""
        if location.absolute() == self.staging.absolute():
            return
        if location.absolute() == self.target.absolute():
            self._copy_to_staging(location)
        else:
            os.replace(location, self.staging)

    def _copy_to_staging(self, location: Path) -> None:
        raise NotImplementedError

    def _end(self, location: Path) -> None:
        self.location = location
        self.lock.release()

    @property
    def outputs(self) -> list[Path]:
        return [self.location or self.target]


PNG_MARK_KEY = "Software"  # a PNG text entry saying which of our commands made the picture


def png_mark(what: str) -> dict[str, str]:
    """The text entry a PNG that warp-cloth makes carries: ``what`` names the kind of picture."""
    return {PNG_MARK_KEY: f"warp-cloth {what}"}


def refuse_replacing_unmarked_png(path: Path, what: str, key: str, named_after: Path) -> None:
    """A picture a run makes under a name the user did not give (``what`` named after ``named_after``)
    replaces only a picture of the same kind made by warp-cloth (see ``png_mark``), never a file of the
    user's."""
    if os.path.lexists(path) and not _marked(path, what):
        raise SceneError(key, f"a name whose {what} ({path}) would replace no file of yours ({path.name} is there "
                              "and is not one warp-cloth made; name another output or move it away)",
                         str(named_after))


def _marked(path: Path, what: str) -> bool:
    from PIL import Image

    try:
        with Image.open(path) as image:
            return image.format == "PNG" and image.text.get(PNG_MARK_KEY) == png_mark(what)[PNG_MARK_KEY]
    except (OSError, ValueError):
        return False


class RunOutcome:
    """How a run that did not complete ended: stopped by a signal after a whole frame (``interrupted``), or
    failed with ``error``. Writers' ``abandon`` gets it."""

    def __init__(self, interrupted: bool, error: BaseException | None = None) -> None:
        self.interrupted = interrupted
        self.error = error

    @property
    def label(self) -> str:
        return INTERRUPTED if self.interrupted else FAILED
