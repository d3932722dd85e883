"""Output directories as transactions: checked before a run starts, owned by one run at a time,
and filled with a whole set of files or none.

* :func:`check_output_dir` is the one check of an ``--out`` argument: it must name a directory
  that exists or can be created and written, before any episode runs or any step trains.
* :class:`RunDirectoryLock` gives a run exclusive use of its directory for as long as it runs (an
  advisory ``flock`` on ``DIR/.lock``, released by the operating system when the process ends, so
  a killed run never leaves a stale lock; a run that ends removes the file). A second run on the
  same directory is refused with :class:`RunDirectoryBusy`, naming the process that holds it.
* :class:`OutputSet` stages a set of files in a scratch directory inside ``DIR`` and moves them
  into place together, with Ctrl-C deferred for those few renames; files an earlier set wrote and
  this one does not (a trajectory plot of an episode no longer plotted, say) are removed, so the
  directory never holds one run's tables beside another run's plots. ``DIR/manifest.json``,
  written last, names the set.

POSIX only (``fcntl``), like the rest of the scripts' signal handling.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import signal
import tempfile
from collections.abc import Iterator, Sequence
from fnmatch import fnmatch
from pathlib import Path
from typing import Any

from debris_gym.files import write_atomic

__all__ = [
    "MANIFEST",
    "OutputDirError",
    "OutputSet",
    "RunDirectoryBusy",
    "RunDirectoryLock",
    "check_output_dir",
    "deferred_interrupts",
    "make_dirs",
]

MANIFEST = "manifest.json"
"""The file naming the set of outputs a directory holds (written last by ``commit``)."""

LOCK_FILE = ".lock"
STAGING_PREFIX = ".staging-"


class OutputDirError(ValueError):
    """An output directory argument cannot be used; ``flag`` names the argument (``"--out"``)."""

    def __init__(self, flag: str, message: str) -> None:
        super().__init__(message)
        self.flag = flag


class RunDirectoryBusy(OutputDirError):
    """Another running process holds the directory's lock."""


MAX_NAME_BYTES = 255
"""Longest file or directory name (bytes) on the usual file systems (ext4, XFS, APFS, NTFS)."""

MAX_PATH_BYTES = 4096 - 256
"""Longest output directory path (bytes, made absolute): Linux's PATH_MAX less room for the
files a run writes inside it (``checkpoints/…``, ``videos/<agent>/…``)."""


def check_output_dir(path: str | os.PathLike[str], flag: str = "--out") -> Path:
    """The directory ``path`` names, checked to be usable for a run's outputs.

    Nothing is created: the directory may be made later, when the run has something to write.

    Raises:
        OutputDirError: ``path`` is empty, has a name longer than :data:`MAX_NAME_BYTES` or is
            longer than :data:`MAX_PATH_BYTES` in all, is (or lies under) a file, or can be
            neither created nor written by this user.
    """
    text = os.fspath(path)
    if not str(text).strip():
        raise OutputDirError(flag, "must name a directory, got an empty string")
    _check_length(str(text), flag)
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise OutputDirError(flag, f"{out} is a file, not a directory")
    existing = out
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing != out and not existing.is_dir():
        raise OutputDirError(flag, f"{out} lies under {existing}, which is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        what = "write into" if existing == out else f"create directories in {existing} for"
        raise OutputDirError(flag, f"cannot {what} {out} (permission denied)")
    return out


def _check_length(text: str, flag: str) -> None:
    """Refuse a path the file system cannot hold, before any system call sees it."""
    for name in Path(text).parts:
        size = len(os.fsencode(name))
        if size > MAX_NAME_BYTES:
            raise OutputDirError(
                flag,
                f"the name {name[:40]}… is {size} bytes long; file and directory names hold at "
                f"most {MAX_NAME_BYTES}",
            )
    size = len(os.fsencode(os.path.abspath(text)))
    if size > MAX_PATH_BYTES:
        raise OutputDirError(
            flag,
            f"the path is {size} bytes long ({len(Path(text).parts)} levels) made absolute; an "
            f"output directory's path holds at most {MAX_PATH_BYTES} (room is left for the "
            "files inside it)",
        )


def make_dirs(path: Path) -> None:
    """Create ``path`` and its missing parents, one level at a time (``Path.mkdir(parents=True)``
    recurses once per level, past Python's recursion limit for a deep path)."""
    missing = []
    level = path
    while not level.is_dir() and level.parent != level:
        missing.append(level)
        level = level.parent
    for directory in reversed(missing):
        directory.mkdir(exist_ok=True)


class RunDirectoryLock:
    """Exclusive use of a run directory for the life of a run (``with RunDirectoryLock(out):``).

    The directory is created if needed. Locks are per open file description, so a second lock of
    the same directory in the same process is refused too. :meth:`release` deletes the lock file
    (while still holding it), so a finished run leaves no ``.lock`` behind; :meth:`acquire`
    checks that the file it locked is still the one in the directory (not one a releasing run
    just deleted) and tries again otherwise.
    """

    def __init__(self, out: str | os.PathLike[str], flag: str = "--out") -> None:
        self.out = Path(out)
        self.flag = flag
        self._fd: int | None = None

    def acquire(self) -> None:
        """Take the lock, or raise :class:`RunDirectoryBusy` at once (never waits).

        Raises:
            RunDirectoryBusy: another process holds the lock.
            OutputDirError: the directory or its lock file cannot be created (a place
                :func:`check_output_dir` cannot foresee, e.g. a read-only or virtual file system).
        """
        path = self.out / LOCK_FILE
        while True:
            try:
                make_dirs(self.out)
                fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise OutputDirError(self.flag, f"cannot create {path} ({exc.strerror})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise RunDirectoryBusy(
                    self.flag,
                    f"{self.out} is in use by another run (process {holder}); wait for it to "
                    "end or choose another directory",
                ) from None
            try:
                current = os.stat(path).st_ino
            except FileNotFoundError:
                current = None
            if current == os.fstat(fd).st_ino:
                break
            os.close(fd)  # a run that ended deleted the file we locked: lock the new one
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        """Give the lock back and delete the lock file."""
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.out / LOCK_FILE)
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> RunDirectoryLock:
        self.acquire()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.release()


@contextlib.contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Hold back SIGINT and SIGTERM until the block ends, then deliver them as
    ``KeyboardInterrupt``: a few renames that must happen together are never cut in half.

    Outside the main thread (where handlers cannot be set) the block just runs.
    """
    pending: list[int] = []

    def remember(signum: int, frame: Any) -> None:
        pending.append(signum)

    try:
        previous = {s: signal.signal(s, remember) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if pending:
        raise KeyboardInterrupt


class OutputSet:
    """A set of output files written into a scratch directory and committed together.

    Use::

        with OutputSet(out, owned=("episodes.csv", "trajectories_ep*.png")) as files:
            write_atomic(files.path("episodes.csv"), text)
            ...
            files.commit(run={"command": ...})

    Leaving the block without :meth:`commit` (an error, Ctrl-C) discards the staged files and
    leaves ``out`` as it was. ``owned`` are the name patterns this kind of run writes: files in
    ``out`` matching them that the new set does not contain are removed at commit, as are the
    files the previous manifest named. Other files in ``out`` are never touched.
    """

    def __init__(self, out: str | os.PathLike[str], owned: Sequence[str] = ()) -> None:
        self.out = Path(out)
        self.owned = tuple(owned)
        self._staging: Path | None = None
        self.committed: list[Path] = []

    def __enter__(self) -> OutputSet:
        make_dirs(self.out)
        for leftover in self.out.glob(STAGING_PREFIX + "*"):  # of a killed run (callers hold
            shutil.rmtree(leftover, ignore_errors=True)  # the directory's lock)
        self._staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=self.out))
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.discard()

    def path(self, name: str) -> Path:
        """Where to write the output ``name`` (a plain file name) before the commit."""
        if self._staging is None:
            raise RuntimeError("OutputSet.path() outside its 'with' block")
        if Path(name).name != name or name in (MANIFEST, LOCK_FILE):
            raise ValueError(f"output names are plain file names other than {MANIFEST}: {name!r}")
        return self._staging / name

    def commit(self, **manifest: Any) -> list[Path]:
        """Move every staged file into ``out``, remove the previous set's leftovers, and write
        the manifest (``files`` plus the ``manifest`` keyword items). Returns the final paths."""
        if self._staging is None:
            raise RuntimeError("OutputSet.commit() outside its 'with' block")
        names = sorted(p.name for p in self._staging.iterdir())
        with deferred_interrupts():
            for stale in self._stale(set(names)):
                stale.unlink(missing_ok=True)
            for name in names:
                os.replace(self._staging / name, self.out / name)
            write_atomic(
                self.out / MANIFEST, json.dumps({"files": names, **manifest}, indent=1) + "\n"
            )
        self.committed = [self.out / name for name in names]
        return self.committed

    def discard(self) -> None:
        """Remove the scratch directory and whatever is still staged in it."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None

    def _stale(self, keep: set[str]) -> list[Path]:
        previous: set[str] = set()
        manifest = self.out / MANIFEST
        if manifest.is_file():
            with contextlib.suppress(ValueError, OSError):
                previous = set(json.loads(manifest.read_text()).get("files", []))
        stale = []
        for entry in self.out.iterdir():
            name = entry.name
            if name in keep or not entry.is_file():
                continue
            if name in previous or any(fnmatch(name, pattern) for pattern in self.owned):
                stale.append(entry)
        return stale
