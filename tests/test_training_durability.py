"""A training run's records survive what ends a process from outside: a SIGKILL (the OOM killer,
a pre-emption) keeps every training-episode row and held-out evaluation up to the checkpoint a
resume starts from, and a disk that fills up (or a directory made read-only) mid-run gives one
message naming the file, what is whole on disk and the resume command — with the files whole.

Runs are tiny (Easy rung, 2 envs, a 16-unit network, constant learning rate so that a run cut
short learns exactly what the same run with a shorter budget learns)."""

from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.experiments.training import callbacks, checkpoints
from agents.experiments.training.checkpoints import find_latest_checkpoint, model_timesteps
from agents.experiments.training.run import TrainOptions, TrainWriteError, train
from tests.helpers import ROOT, load_script

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
SETS = [
    "algo_kwargs.n_steps=32", "algo_kwargs.batch_size=64", "algo_kwargs.n_epochs=1",
    "algo_kwargs.learning_rate=3.0e-4", "policy_kwargs.net_arch=[16]",
    "checkpoint.freq=256", "checkpoint.keep=0",
    "eval.freq=256", "eval.n_episodes=2", "eval.n_envs=2", "env_kwargs.max_episode_steps=40",
]  # fmt: skip
"""Every 256 steps (128 of each of the 2 envs) a checkpoint and an evaluation; episodes of at
most 40 steps, so that every stretch between checkpoints ends some."""


def _options(out: Path, timesteps: int, **kwargs) -> TrainOptions:
    return TrainOptions(
        out=out, env_id=EASY, overrides=SETS, timesteps=timesteps, n_envs=2, seed=0,
        progress=False, argv=["test"], **kwargs,
    )  # fmt: skip


def _rows(out: Path, until: int) -> list[list[str]]:
    """The episode rows of ``out`` up to ``until`` steps, without their wall-clock column."""
    with open(out / "train_episodes.csv", newline="") as fh:
        rows = list(csv.reader(fh))[1:]
    return [r[:-1] for r in rows if int(r[0]) <= until]


def _evaluations(out: Path, until: int) -> tuple[list[int], list[list[float]]]:
    with np.load(out / "evaluations.npz") as data:
        keep = [i for i, t in enumerate(data["timesteps"]) if t <= until]
        return [int(data["timesteps"][i]) for i in keep], [list(data["results"][i]) for i in keep]


def _segments(out: Path) -> list[tuple[str, int, int]]:
    log = json.loads((out / "train_log.json").read_text())
    return [(s["status"], s["start_timesteps"], s["end_timesteps"]) for s in log["segments"]]


def test_sigkill_after_a_checkpoint_keeps_every_record_up_to_it(tmp_path):
    """Regression: episode rows were appended every 256 episodes and the evaluation at a
    checkpoint's step came after it, so a SIGKILL lost the rows and, at times, an evaluation
    point that the checkpoint a resume starts from had seen."""
    killed = tmp_path / "killed"
    argv = [sys.executable, str(ROOT / "train.py"), "--env", EASY, "--n-envs", "2", "--seed", "0"]
    argv += ["--timesteps", "1e6", "--no-progress", "--out", str(killed)]
    argv += [w for item in SETS for w in ("--set", item)]
    with open(tmp_path / "stderr", "w") as err:
        proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err)
        try:
            third = killed / "checkpoints" / "rl_model_vecnormalize_768_steps.pkl"
            deadline = time.monotonic() + 120
            while not third.is_file():
                assert proc.poll() is None, (tmp_path / "stderr").read_text()
                assert time.monotonic() < deadline, "no third checkpoint"
                time.sleep(0.05)
            proc.send_signal(signal.SIGKILL)
            assert proc.wait(timeout=30) == -signal.SIGKILL
        finally:
            if proc.poll() is None:
                proc.kill()
    start = model_timesteps(find_latest_checkpoint(killed, needs_stats=True))
    assert start >= 768
    # the log is written just after its checkpoint: a kill in between leaves the one before
    assert _segments(killed) in ([("running", 0, start)], [("running", 0, start - 256)])

    reference = tmp_path / "reference"  # the same run, budget ending at that checkpoint
    assert train(_options(reference, start)).num_timesteps == start
    rows = _rows(reference, start)
    assert len(rows) > 10
    assert _rows(killed, start) == rows
    assert _evaluations(killed, start) == _evaluations(reference, start)
    assert _evaluations(killed, start)[0][-1] == start  # the checkpoint's own evaluation

    result = train(TrainOptions(resume=killed, timesteps=128, progress=False, argv=["test"]))
    assert result.status == "completed" and result.num_timesteps == start + 128
    assert _rows(killed, start) == rows  # kept by the resume, nothing after them
    steps, _ = _evaluations(killed, result.num_timesteps)
    assert steps == sorted(set(steps)) and steps[-1] == start + 128
    assert [s[0] for s in _segments(killed)] == ["stopped", "completed"]
    assert _segments(killed)[-1] == ("completed", start, start + 128)


def _fail_saves_after(monkeypatch, good: int, error: BaseException) -> list[Path]:
    """Make every atomic save of the training code after the first ``good`` ones fail with
    ``error``; returns the targets of the failed saves."""
    real = checkpoints.save_atomic
    calls: list[Path] = []
    failed: list[Path] = []

    def save_atomic(path, save):
        calls.append(Path(path))
        if len(calls) > good:
            failed.append(Path(path))

            def fail(tmp: str) -> None:
                Path(tmp).write_bytes(b"half a model")
                raise error

            return real(path, fail)
        return real(path, save)

    monkeypatch.setattr(checkpoints, "save_atomic", save_atomic)
    return failed


@pytest.mark.parametrize(
    ("error", "fix"),
    [
        (OSError(errno.ENOSPC, "No space left on device"), "free space on the disk of"),
        (PermissionError(errno.EACCES, "Permission denied"), "writable again"),
        # torch's zip writer reports a full disk as a RuntimeError raised while handling it
        ("torch", "free space on the disk of"),
    ],
)
def test_a_full_disk_mid_run_is_one_message_with_the_resume_command(
    error, fix, monkeypatch, tmp_path, capsys
):
    """Regression: a full disk mid-run ended train.py with three chained tracebacks."""
    if error == "torch":
        try:
            try:
                raise OSError(errno.ENOSPC, "No space left on device")
            except OSError:
                raise RuntimeError("[enforce fail at inline_container.cc:672] unexpected pos")  # noqa: B904
        except RuntimeError as exc:
            error = exc
    out = tmp_path / "run"
    # at 256 steps: evaluations.npz, best model and its statistics, checkpoint and its
    # statistics; the next save (evaluations.npz at 512) fails
    failed = _fail_saves_after(monkeypatch, 5, error)
    cli = load_script("train.py")
    argv = ["--env", EASY, "--n-envs", "2", "--timesteps", "2048", "--no-progress"]
    argv += ["--out", str(out), *(w for item in SETS for w in ("--set", item))]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 1
    lines = [line for line in err.splitlines() if line.startswith("train.py:")]
    assert "Traceback" not in err and len(lines) == 1, err
    assert failed[0].name == "evaluations.npz"
    reason = "Permission denied" if "writable" in fix else "No space left on device"
    assert lines[0].startswith(f"train.py: cannot write {failed[0]}: {reason}. Training stopped")
    assert "files are whole, up to checkpoints/rl_model_256_steps.zip (256 steps)" in err
    assert f"{fix}" in err and f"resume with: python train.py --resume {out}" in err
    assert not [p for p in out.rglob("*") if ".tmp" in p.name]  # no half-written file left
    assert find_latest_checkpoint(out, needs_stats=True).name == "rl_model_256_steps.zip"

    monkeypatch.undo()  # room again: the run resumes from its checkpoint
    assert cli.main(["--resume", str(out), "--no-progress"]) == 0
    assert model_timesteps(out / "model.zip") == 2048
    assert [s[0] for s in _segments(out)] == ["stopped", "completed"]


def test_a_run_that_cannot_write_before_its_first_checkpoint_says_to_start_again(
    monkeypatch, tmp_path
):
    out = tmp_path / "run"
    _fail_saves_after(monkeypatch, 0, OSError(errno.ENOSPC, "No space left on device"))
    with pytest.raises(TrainWriteError, match=r"no checkpoint was saved yet.* same command"):
        train(_options(out, 1024))


def test_a_failed_append_leaves_the_episode_log_as_it_was(monkeypatch, tmp_path):
    path = tmp_path / "train_episodes.csv"
    path.write_text("timesteps,return\n1,2.5\n")
    real_write = os.write

    def half_then_full(fd, data):  # a disk that fills up in the middle of the rows
        if len(data) > 4:
            real_write(fd, bytes(data[: len(data) // 2]))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(callbacks.os, "write", half_then_full)
    with pytest.raises(OSError, match="No space left"):
        callbacks.append_whole(path, b"2,3.5\n3,4.5\n", sync=True)
    monkeypatch.undo()
    assert path.read_text() == "timesteps,return\n1,2.5\n"
    callbacks.append_whole(path, b"2,3.5\n", sync=True)
    assert path.read_text() == "timesteps,return\n1,2.5\n2,3.5\n"
