"""The bookkeeping files of a run directory: ``config.yaml`` (the resolved config and how the run
was made), ``train_log.json`` (wall time and env-steps/s per segment) and ``train_episodes.csv``
(every finished training episode), each written atomically — and what a run says when one of its
files cannot be written (:class:`TrainWriteError`).
"""

from __future__ import annotations

import csv
import errno
import json
import os
import shutil
from pathlib import Path
from typing import Any

import yaml

from agents.experiments.training.checkpoints import model_timesteps
from agents.experiments.training.config import TrainConfig
from debris_gym.files import write_atomic

__all__ = [
    "RUNNING",
    "STOPPED",
    "UNSTARTED_RUN_FILES",
    "TrainWriteError",
    "clear_unstarted_run",
    "is_complete_row",
    "read_train_log",
    "truncate_episode_log",
    "write_run_config",
    "write_train_log",
]

RUNNING = "running"
"""``train_log.json`` status of a segment still learning: written with each checkpoint, so the
log of a killed run stands as of its last checkpoint."""

STOPPED = "stopped"
"""Status a resume gives a segment left ``running``: its process ended without saving (killed,
or its files could not be written)."""


class TrainWriteError(OSError):
    """A file of a training run could not be written; the message says which and why, what is
    on disk (every file is whole: atomic writes) and the command that goes on.

    Attributes:
        out: the run directory.
        failure: the file-system error.
        latest: the latest complete model in ``out`` (None: none).
    """

    def __init__(self, out: Path, failure: OSError, steps: int, latest: Path | None) -> None:
        self.out, self.failure, self.latest = out, failure, latest
        where = f" {failure.filename}" if failure.filename else f" a file in {out}"
        problem = failure.strerror or os.strerror(failure.errno or 0)
        if failure.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
            fix = f"free space on the disk of {out}"
        elif failure.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            fix = f"make {out} writable again"
        else:
            fix = f"check the disk and directory {out}"
        text = f"cannot write{where}: {problem}. Training stopped at {steps:,} steps; "
        if latest is None:
            text += (
                f"no checkpoint was saved yet. Once you {fix}, start the run again with the same "
                "command"
            )
        else:
            steps_on_disk = model_timesteps(latest)
            text += (
                f"the run's files are whole, up to {latest.relative_to(out)} ({steps_on_disk:,} "
                f"steps). Once you {fix}, resume with: python train.py --resume {out}"
            )
        super().__init__(text)
        self.errno = failure.errno


UNSTARTED_RUN_FILES = (
    "config.yaml",
    "train_log.json",
    "train_episodes.csv",
    "evaluations.npz",
    "learning_curve.png",
    "best_model.zip",
    "best_model_vecnormalize.pkl",
    "best_model_replay_buffer.pkl",
    "checkpoints",
    "tb",
    "init_model.zip",  # a fine-tune's copy of its initial policy (training/finetune.py)
    "init_model_vecnormalize.pkl",
    "init_model.yaml",
)
"""What a run leaves before its first complete model: removed when a fresh run takes over a
directory whose run never saved one (it cannot be resumed, and its episode log would otherwise
be appended to)."""


def clear_unstarted_run(out: Path) -> list[str]:
    """Remove the :data:`UNSTARTED_RUN_FILES` in ``out`` and return the names removed.

    Only for a directory without a complete model, under the directory's lock.
    """
    removed = []
    for name in UNSTARTED_RUN_FILES:
        path = out / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()
        else:
            continue
        removed.append(name)
    return removed


def write_run_config(out: Path, config: TrainConfig, run: dict[str, Any]) -> None:
    header = (
        "# Resolved training config of this run (train.py writes it; --resume reads it).\n"
        "# The 'run' section records how the run was made.\n"
    )
    body = yaml.safe_dump(
        {**config.to_dict(), "run": run}, sort_keys=False, width=100, default_flow_style=None
    )
    write_atomic(out / "config.yaml", header + body)


def read_train_log(out: Path) -> dict[str, Any]:
    path = out / "train_log.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def write_train_log(out: Path, log: dict[str, Any]) -> None:
    segments = log.get("segments", [])
    wall = sum(s["wall_time_s"] for s in segments)
    steps = sum(s["end_timesteps"] - s["start_timesteps"] for s in segments)
    log["wall_time_s"] = round(wall, 3)
    log["env_steps"] = steps
    log["env_steps_per_s"] = round(steps / wall, 1) if wall > 0 else None
    ordered = {k: v for k, v in log.items() if k != "segments"} | {"segments": segments}
    write_atomic(out / "train_log.json", json.dumps(ordered, indent=2) + "\n")


def is_complete_row(row: list[str], width: int) -> bool:
    """A complete numeric CSV row (a hard kill can leave a half-written last line)."""
    if len(row) != width:
        return False
    try:
        [float(v) for v in row]
    except ValueError:
        return False
    return True


def truncate_episode_log(path: Path, until: int) -> None:
    if not path.is_file():
        return
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    width = len(rows[0]) if rows else 0
    kept = [rows[0], *(r for r in rows[1:] if is_complete_row(r, width) and int(r[0]) <= until)]
    if len(kept) != len(rows):
        buffer = "".join(",".join(r) + "\n" for r in kept)
        write_atomic(path, buffer)
