"""Model files of a run: saving a model with its sidecars atomically, finding the latest one.

A model ``PATH.zip`` travels with its VecNormalize statistics and (off-policy, per config) its
replay buffer under the :func:`~agents.policies.model_files.sidecar_path` names; every file is
written atomically (:func:`debris_gym.files.save_atomic`) and a Ctrl-C during a save is held
until the save is whole.
"""

from __future__ import annotations

import contextlib
import errno
import json
import pickle
import signal
import threading
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.training.config import OFF_POLICY, TrainConfig
from agents.policies.model_files import CHECKPOINT_RE, FINAL_MODEL, sidecar_path
from debris_gym.files import save_atomic

CHECKPOINT_PREFIX = "rl_model"
"""Name prefix of periodic checkpoints, ``rl_model_<N>_steps.zip``."""

INTERRUPTED = "interrupted"
"""Stem of the checkpoint a Ctrl-C writes, ``checkpoints/interrupted.zip``."""

SIDECARS = ("vecnormalize", "replay_buffer")
"""The kinds of file that travel with a model (see :func:`sidecar_path`)."""


WRITE_ERRNOS = {
    errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS, errno.EIO, errno.EFBIG,
    errno.ENOENT, errno.ENOTDIR, errno.ESTALE,
}  # fmt: skip
"""Errors of a run directory that stopped taking files (full disk or quota, permissions or a
read-only remount, a failing or vanished device or directory)."""


def write_failure(exc: BaseException) -> OSError | None:
    """The file-system error behind ``exc`` (itself, or one it was raised from or during, as
    torch's zip writer wraps it in a RuntimeError), or None if it is not a write failure."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in WRITE_ERRNOS:
            return seen
        seen = seen.__cause__ or seen.__context__
    return None


def save_whole(path: Path, save: Callable[[str], None]) -> Path:
    """:func:`~debris_gym.files.save_atomic`, with a write failure naming ``path`` (torch's zip
    writer and numpy report a full disk without a file name)."""
    try:
        return save_atomic(path, save)
    except (OSError, RuntimeError) as exc:
        failure = write_failure(exc)
        if failure is None or failure.filename:
            raise
        raise OSError(failure.errno, failure.strerror, str(path)) from exc


def checkpoint_steps(path: Path) -> int:
    """The step count in a checkpoint's name (``rl_model_4000_steps.zip`` → 4000), else -1."""
    match = CHECKPOINT_RE.match(path.stem)
    return int(match["steps"]) if match else -1


def model_timesteps(model_path: str | Path) -> int:
    """``num_timesteps`` stored in an SB3 model zip (read without building the model)."""
    with zipfile.ZipFile(model_path) as archive:
        data = json.loads(archive.read("data"))
    return int(data["num_timesteps"])


@dataclass(frozen=True)
class CheckpointScan:
    """The models of a run directory that a resume could start from.

    Attributes:
        latest: the complete model with the most timesteps (None: there is none).
        damaged: models (or their statistics) that cannot be read, each with the reason — a file
            cut short by a hard kill or a full disk.
    """

    latest: Path | None
    damaged: list[tuple[Path, str]]


def _stats_problem(model: Path) -> str | None:
    """Why ``model``'s VecNormalize statistics cannot be used, or None if they can."""
    stats = sidecar_path(model, "vecnormalize")
    if not stats.is_file():
        return f"has no VecNormalize statistics ({stats.name})"
    try:
        with open(stats, "rb") as fh:
            pickle.load(fh)
    except Exception as exc:  # any unpickling failure means a damaged file
        return f"has damaged VecNormalize statistics {stats.name} ({type(exc).__name__})"
    return None


def scan_checkpoints(run_dir: str | Path, needs_stats: bool = False) -> CheckpointScan:
    """Every model in ``DIR/checkpoints/*.zip`` and ``DIR/model.zip``, sorted into the latest
    complete one and the damaged ones.

    Args:
        run_dir: the run directory.
        needs_stats: a model counts as complete only with readable VecNormalize statistics (runs
            with normalisation on).
    """
    run_dir = Path(run_dir)
    candidates = sorted((run_dir / "checkpoints").glob("*.zip"))
    if (run_dir / FINAL_MODEL).is_file():
        candidates.append(run_dir / FINAL_MODEL)
    best: tuple[int, float, Path] | None = None
    damaged: list[tuple[Path, str]] = []
    for path in candidates:
        try:
            key = (model_timesteps(path), path.stat().st_mtime, path)
        except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
            damaged.append((path, f"is not a complete SB3 model ({type(exc).__name__}: {exc})"))
            continue
        problem = _stats_problem(path) if needs_stats else None
        if problem is not None:
            damaged.append((path, problem))
            continue
        if best is None or key[:2] > best[:2]:
            best = key
    return CheckpointScan(latest=best[2] if best else None, damaged=damaged)


def describe_damaged(damaged: list[tuple[Path, str]]) -> str:
    """``"checkpoints/a.zip is …; model.zip is …"`` (paths relative to their run directory)."""
    return "; ".join(f"{path.parent.name}/{path.name} {why}" for path, why in damaged)


def find_latest_checkpoint(run_dir: str | Path, needs_stats: bool = False) -> Path:
    """The complete model with the most timesteps among ``DIR/checkpoints/*.zip`` and
    ``DIR/model.zip`` (damaged files are skipped; :func:`scan_checkpoints` lists them).

    Raises:
        FileNotFoundError: no complete model in the run directory; the message names every
            damaged file and what to do.
    """
    run_dir = Path(run_dir)
    scan = scan_checkpoints(run_dir, needs_stats)
    if scan.latest is not None:
        return scan.latest
    if scan.damaged:
        raise FileNotFoundError(
            f"no complete checkpoint in {run_dir} to resume from: "
            f"{describe_damaged(scan.damaged)}. The run cannot be resumed; start it again with "
            f"--out {run_dir} after deleting the damaged files, or with another --out"
        )
    raise FileNotFoundError(
        f"no checkpoint in {run_dir} (looked for checkpoints/*.zip and {FINAL_MODEL}): the run "
        f"never saved a model; start it again with --out {run_dir}"
    )


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) that arrives inside the block, and raise it as a
    ``KeyboardInterrupt`` when the block ends.

    For saves during learning: a ``KeyboardInterrupt`` inside torch's zip writer comes out as a
    ``RuntimeError`` ("unexpected pos …"), which is not an interrupt and ended the run with an
    error instead of the interrupt checkpoint (seen in the Ctrl-C test). Only Python's default
    handler is replaced; off the main thread, or under any other handler (e.g. SIG_IGN while the
    final files are written), the block runs as it is.
    """
    main = threading.current_thread() is threading.main_thread()
    if not main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def _replay_buffer_bytes(model: Any) -> int:
    buffer = getattr(model, "replay_buffer", None)
    if buffer is None:
        return 0
    return sum(v.nbytes for v in vars(buffer).values() if isinstance(v, np.ndarray))


def _save_replay_buffer(config: TrainConfig, model: Any) -> bool:
    if config.algo not in OFF_POLICY or config.checkpoint.replay_buffer == "never":
        return False
    if config.checkpoint.replay_buffer == "always":
        return True
    return _replay_buffer_bytes(model) <= config.checkpoint.replay_buffer_max_mb * 1e6


def save_model_files(model: Any, config: TrainConfig, path: Path) -> list[Path]:
    """Save ``model`` at ``path`` with its VecNormalize stats and (per config) replay buffer,
    each atomically, under the :func:`sidecar_path` names. Returns the files written."""
    written = [save_whole(path, model.save)]
    venv = model.get_vec_normalize_env()
    if venv is not None:
        written.append(save_whole(sidecar_path(path, "vecnormalize"), venv.save))
    if _save_replay_buffer(config, model):
        written.append(save_whole(sidecar_path(path, "replay_buffer"), model.save_replay_buffer))
    return written
