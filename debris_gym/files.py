"""Atomic file writes: a reader (or a crash) never sees a half-written file.

Every file the suite writes for a user (scenarios, evaluation tables, models, logs, benchmark
reports) goes through :func:`save_atomic`: the content is written to a temporary file in the
target's directory, flushed to disk, and moved over the target with :func:`os.replace`, which
is atomic on POSIX and Windows within one file system. On any error, ``KeyboardInterrupt``
included, the temporary file is removed and the target is left as it was.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

__all__ = ["save_atomic", "write_atomic"]


def save_atomic(path: str | os.PathLike[str], save: Callable[[str], None]) -> Path:
    """Run ``save(tmp)`` for a temporary name beside ``path``, then move it onto ``path``.

    For writers that take a file name (``model.save``, ``np.savez``, ``fig.savefig``). The
    temporary name ends in ``path``'s suffix (some writers append one otherwise) and starts
    with a dot. Parent directories are created; the file gets the usual permissions
    (0666 minus the umask), not :func:`tempfile.mkstemp`'s 0600.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}"
    )
    os.close(fd)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        save(tmp)
        with open(tmp, "rb+") as f:  # on disk before it replaces the old file
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8, or bytes) to ``path`` atomically (:func:`save_atomic`)."""
    payload = data.encode("utf-8") if isinstance(data, str) else data

    def save(tmp: str) -> None:
        with open(tmp, "wb") as f:
            f.write(payload)

    return save_atomic(path, save)
