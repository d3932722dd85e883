"""The SB3 callbacks of a training run: curriculum stages, the episode log, held-out evaluation,
the best model and pruned checkpoints — each saving its files atomically.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import sys
import time
import zipfile
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CheckpointCallback,
    EvalCallback,
    ProgressBarCallback,
)

from agents.experiments.training.checkpoints import (
    CHECKPOINT_PREFIX,
    SIDECARS,
    checkpoint_steps,
    interrupts_deferred,
    save_model_files,
    save_whole,
)
from agents.experiments.training.config import EVAL_SEED, TrainConfig
from agents.policies.model_files import sidecar_path
from debris_gym.files import write_atomic

__all__ = [
    "CurriculumCallback",
    "EpisodeLogCallback",
    "HeldOutEvalCallback",
    "PruningCheckpointCallback",
    "RunProgressBar",
    "SaveBestCallback",
    "StartLegsCallback",
    "close_progress_bar",
    "make_callbacks",
]


class CurriculumCallback(BaseCallback):
    """Before a rollout that starts a new stage, move the training env to that stage's mission.

    The env does it itself (:meth:`~debris_gym.integrations.sb3.NativeVecEnv.set_mission`: at
    the next step every running episode is truncated and restarted on the new rung), so the
    normalisation statistics, the model and the rollout stay as SB3 keeps them.

    Args:
        config: the run's config (its ``curriculum`` stages).
    """

    def __init__(self, config: TrainConfig) -> None:
        super().__init__()
        self.config = config
        self.current: int | None = None

    def _on_rollout_start(self) -> None:
        config = self.config
        stage = config.stage(self.num_timesteps)
        if stage == self.current:
            return
        mission = config.stage_mission(stage)
        # NativeVecEnv's; VecNormalize/VecMonitor hand it down (attribute forwarding)
        self.training_env.set_mission(mission)  # type: ignore[attr-defined]
        self.current = stage
        final = stage == len(config.curriculum)
        what = "the final task" if final else f"until {config.curriculum[stage]['until']:,}"
        print(
            f"curriculum: stage {stage} ({what}) from step {self.num_timesteps:,}: "
            f"mission {mission or 'of ' + config.env_id}",
            flush=True,
        )

    def _on_step(self) -> bool:
        return True


class StartLegsCallback(BaseCallback):
    """Log the start sampler's legs after every rollout: ``starts/leg{k}_failure`` (moving-
    average failure rate) and ``starts/leg{k}_p`` (chance of a bank start on leg k) in SB3's
    log, and the whole state in ``DIR/start_legs.json`` (written atomically).

    Args:
        path: the JSON file.
    """

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path

    def _sampler(self) -> Any:
        native: Any = self.training_env.unwrapped
        return native.venv.shell.start_sampler

    def _on_rollout_end(self) -> None:
        sampler = self._sampler()
        if sampler is None:
            return
        stats = sampler.stats()
        for k, (fail, p) in enumerate(zip(stats["failure"], stats["probability"])):
            self.logger.record(f"starts/leg{k}_failure", fail)
            self.logger.record(f"starts/leg{k}_p", p)
        stats["timesteps"] = int(self.num_timesteps)
        write_atomic(self.path, json.dumps(stats, indent=1) + "\n")

    def _on_step(self) -> bool:
        return True


class EpisodeLogCallback(BaseCallback):
    """Append every finished training episode (VecMonitor's ``info["episode"]``) to a CSV.

    Rows are held in memory and appended in batches; :meth:`flush` with ``sync`` puts every row
    so far on disk, which each checkpoint does before it saves the model (so a killed run keeps
    the rows of every step its resume starts after).

    Args:
        path: the CSV (``DIR/train_episodes.csv``); its header is written if it is new.
    """

    columns = ("timesteps", "return", "length", "is_success", "targets_captured", "wall_s")

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path
        self.rows: list[tuple] = []
        self.start = time.perf_counter()
        self.recent_captures: deque[int] = deque(maxlen=100)
        """Targets captured in the last 100 training episodes (SB3's window for its
        ``rollout/ep_rew_mean`` and ``rollout/success_rate``)."""

    def _on_training_start(self) -> None:
        if not self.path.exists():
            with open(self.path, "w", newline="") as fh:
                csv.writer(fh).writerow(self.columns)

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            ep = info.get("episode")
            if ep is not None:
                self.rows.append(
                    (
                        self.num_timesteps,
                        round(float(ep["r"]), 6),
                        int(ep["l"]),
                        int(bool(ep.get("is_success", False))),
                        int(ep.get("targets_captured", 0)),
                        round(time.perf_counter() - self.start, 3),
                    )
                )
                self.recent_captures.append(int(ep.get("targets_captured", 0)))
        if len(self.rows) >= 256:
            self.flush()
        return True

    def flush(self, sync: bool = False) -> None:
        """Append the rows held so far to the CSV; with ``sync``, flushed to disk too."""
        if not self.rows and not sync:
            return
        text = io.StringIO()
        csv.writer(text).writerows(self.rows)
        append_whole(self.path, text.getvalue().encode(), sync)
        self.rows = []

    def _on_rollout_end(self) -> None:
        # beside SB3's rollout/success_rate in TensorBoard and the console table
        if self.recent_captures:
            self.logger.record("rollout/targets_captured", float(np.mean(self.recent_captures)))

    def _on_training_end(self) -> None:
        self.flush()


def append_whole(path: Path, data: bytes, sync: bool) -> None:
    """Append ``data`` to ``path`` (flushed to disk with ``sync``), or, if the write fails (a
    full disk), leave the file as it was: no row is ever left half-written."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        end = os.lseek(fd, 0, os.SEEK_END)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
            if sync:
                os.fsync(fd)
        except BaseException:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, end)
            raise
    finally:
        os.close(fd)


class SaveBestCallback(BaseCallback):
    """Called by EvalCallback on a new best model: save ``DIR/best_model.zip`` and its
    VecNormalize stats, atomically and with a Ctrl-C held until both are written
    (EvalCallback's own save writes in place).

    Args:
        out: the run directory.
    """

    def __init__(self, out: Path) -> None:
        super().__init__()
        self.out = out

    def _on_step(self) -> bool:
        path = self.out / "best_model.zip"
        with interrupts_deferred():
            save_whole(path, self.model.save)
            venv = self.model.get_vec_normalize_env()
            if venv is not None:
                save_whole(sidecar_path(path, "vecnormalize"), venv.save)
        return True


class HeldOutEvalCallback(EvalCallback):
    """EvalCallback on the same held-out fields every time (seeds EVAL_SEED + i), timed, with
    the targets captured of every episode logged beside SB3's arrays."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.seconds = 0.0
        self._targets_buffer: list[int] = []
        self.evaluations_targets: list[list[int]] = []

    def _log_success_callback(self, locals_: dict, globals_: dict) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_["done"]:
            self._targets_buffer.append(int(locals_["info"].get("targets_captured", 0)))

    def _on_step(self) -> bool:
        if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
            return True
        self.eval_env.seed(EVAL_SEED)
        self._targets_buffer = []
        start = time.perf_counter()
        # EvalCallback writes its log in place (a Ctrl-C mid-write would leave it cut): let
        # it write to a scratch name, and write the real file below, atomically
        log_path = self.log_path
        scratch = (
            None if log_path is None else str(Path(log_path).with_name(".evaluations_scratch"))
        )
        if scratch is not None:
            self.log_path = scratch
        try:
            result = super()._on_step()
        finally:
            if scratch is not None:
                with contextlib.suppress(FileNotFoundError):
                    Path(scratch + ".npz").unlink()
            self.log_path = log_path
        self.evaluations_targets.append(self._targets_buffer)
        if len(self.evaluations_successes) < len(self.evaluations_timesteps):
            # no episode reported is_success (SB3 types the list as bools only)
            self.evaluations_successes.append([np.nan])  # type: ignore[list-item]
        if self.log_path is not None:  # EvalCallback's file, plus targets captured
            arrays: dict[str, Any] = {
                "timesteps": self.evaluations_timesteps,
                "results": self.evaluations_results,
                "ep_lengths": self.evaluations_length,
                "successes": self.evaluations_successes,
                "targets_captured": self.evaluations_targets,
            }
            save_whole(Path(self.log_path + ".npz"), lambda tmp: np.savez(tmp, **arrays))
        self.seconds += time.perf_counter() - start
        returns = self.evaluations_results[-1] if self.evaluations_results else [np.nan]
        success = self.evaluations_successes[-1] if self.evaluations_successes else [np.nan]
        captures = float(np.mean(self._targets_buffer)) if self._targets_buffer else np.nan
        # SB3 recorded and wrote eval/mean_reward and eval/success_rate at this step; the
        # captures go beside them (SB3's logger writes only TensorBoard here: verbose=0)
        self.logger.record("eval/targets_captured", captures)
        self.logger.dump(self.num_timesteps)
        print(
            f"eval @ {self.num_timesteps:,} steps: return {np.mean(returns):.2f} "
            f"± {np.std(returns):.2f}, success {100 * np.mean(success):.0f}%, "
            f"targets captured {captures:.2f} per episode "
            f"({len(returns)} held-out episodes, {time.perf_counter() - start:.1f} s)",
            flush=True,
        )
        return result

    def evaluate_now(self) -> None:
        """One evaluation now (at the end of training, if the last one is older)."""
        freq, calls = self.eval_freq, self.n_calls
        self.eval_freq, self.n_calls = 1, 0
        try:
            self._on_step()
        finally:
            self.eval_freq, self.n_calls = freq, calls

    def preload(self, path: Path, until: int) -> None:
        """Continue an earlier run's ``evaluations.npz`` (entries after ``until`` dropped)."""
        if not path.is_file():
            return
        try:
            self._preload(path, until)
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:  # cut by a kill
            print(f"note: ignoring unreadable {path.name} ({exc})", file=sys.stderr)

    def _preload(self, path: Path, until: int) -> None:
        with np.load(path, allow_pickle=True) as data:
            # every evaluation has an entry in each array; a run cut mid-write can leave
            # some arrays shorter, so keep only the evaluations that every array holds
            names = ("timesteps", "results", "ep_lengths", "successes", "targets_captured")
            present = [data[k] for k in names if k in data]
            n = min(len(a) for a in present)
            keep = [i for i in range(n) if data["timesteps"][i] <= until]
            self.evaluations_timesteps = [int(data["timesteps"][i]) for i in keep]
            self.evaluations_results = [list(data["results"][i]) for i in keep]
            self.evaluations_length = [list(data["ep_lengths"][i]) for i in keep]
            if "successes" in data:
                self.evaluations_successes = [list(data["successes"][i]) for i in keep]
            if "targets_captured" in data:
                self.evaluations_targets = [list(data["targets_captured"][i]) for i in keep]
        if self.evaluations_results:
            self.best_mean_reward = max(float(np.mean(r)) for r in self.evaluations_results)


class PruningCheckpointCallback(CheckpointCallback):
    """CheckpointCallback that saves through :func:`save_model_files` (atomic and whole) and
    keeps the last ``keep`` checkpoints (0 = all) and the latest replay buffer.

    Before the model, every record of the run up to this step goes to disk (``before_save``: the
    episode log, flushed and synced); after it, ``after_save(path, steps)`` runs (the run's log).
    A checkpoint on disk therefore means its run's records up to it are on disk too.

    Args:
        config: the run's config (what to save with each model).
        keep: periodic checkpoints kept.
        before_save: called before each checkpoint is written.
        after_save: called with the checkpoint's path and timesteps once it is written.
    """

    def __init__(
        self,
        *args: Any,
        config: TrainConfig,
        keep: int = 0,
        before_save: Callable[[], None] | None = None,
        after_save: Callable[[Path, int], None] | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        self.config = config
        self.keep = keep
        self.before_save = before_save
        self.after_save = after_save
        self.seconds = 0.0

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq != 0:
            return True
        start = time.perf_counter()
        with interrupts_deferred():  # atomic and whole, unlike CheckpointCallback's
            if self.before_save is not None:
                self.before_save()
            path = Path(self._checkpoint_path(extension="zip"))
            save_model_files(self.model, self.config, path)
            self._prune()
        self.seconds += time.perf_counter() - start
        if self.after_save is not None:
            self.after_save(path, self.num_timesteps)
        return True

    def _prune(self) -> None:
        folder = Path(self.save_path)
        models = sorted(folder.glob(f"{self.name_prefix}_*_steps.zip"), key=checkpoint_steps)
        if self.keep > 0:
            for old in models[: -self.keep]:
                for path in (old, *(sidecar_path(old, k) for k in SIDECARS)):
                    path.unlink(missing_ok=True)
        buffers = sorted(
            folder.glob(f"{self.name_prefix}_replay_buffer_*_steps.pkl"),
            key=lambda p: int(p.stem.split("_")[-2]),
        )
        for old in buffers[:-1]:
            old.unlink(missing_ok=True)


def make_callbacks(
    config: TrainConfig,
    out: Path,
    eval_env: Any,
    resume_at: int | None,
    after_checkpoint: Callable[[Path, int], None] | None = None,
) -> tuple[list[Any], HeldOutEvalCallback | None, PruningCheckpointCallback | None, Any]:
    """The callbacks of a run: (all of them, the evaluation or None, the checkpointer or None,
    the episode logger).

    At a step that both evaluates and checkpoints, the evaluation runs first, so that a
    checkpoint's step has its evaluation on disk as well as its episode rows.

    Args:
        config: the run's config.
        out: the run directory.
        eval_env: the evaluation VecEnv (None when ``config.eval.freq`` is 0).
        resume_at: timesteps of the checkpoint a resumed run starts from (None: a fresh run);
            the evaluation log continues up to it.
        after_checkpoint: called with the path and timesteps of each periodic checkpoint once
            it is written.
    """
    episodes = EpisodeLogCallback(out / "train_episodes.csv")
    callbacks: list[Any] = [episodes]
    if config.curriculum:
        callbacks.insert(0, CurriculumCallback(config))
    if config.starts.bank is not None:
        callbacks.append(StartLegsCallback(out / "start_legs.json"))
    n = config.n_envs
    evaluation = None
    if config.eval.freq > 0:
        evaluation = HeldOutEvalCallback(
            eval_env,
            callback_on_new_best=SaveBestCallback(out),
            n_eval_episodes=config.eval.n_episodes,
            eval_freq=max(config.eval.freq // n, 1),
            log_path=str(out),
            best_model_save_path=None,  # SaveBestCallback writes best_model.zip
            deterministic=config.eval.deterministic,
            verbose=0,
        )
        if resume_at is not None:
            evaluation.preload(out / "evaluations.npz", resume_at)
        callbacks.append(evaluation)
    checkpoint = None
    if config.checkpoint.freq > 0:
        checkpoint = PruningCheckpointCallback(
            save_freq=max(config.checkpoint.freq // n, 1),
            save_path=str(out / "checkpoints"),
            name_prefix=CHECKPOINT_PREFIX,
            save_replay_buffer=False,  # unused: _on_step saves through save_model_files
            save_vecnormalize=False,
            config=config,
            keep=config.checkpoint.keep,
            before_save=lambda: episodes.flush(sync=True),
            after_save=after_checkpoint,
        )
        callbacks.append(checkpoint)
    return callbacks, evaluation, checkpoint, episodes


class RunProgressBar(ProgressBarCallback):
    """SB3's progress bar, counting the run's steps as its log does: a resumed run's bar starts
    at its checkpoint's step count and ends at the run's target, not at 0 and the segment's
    length."""

    def _on_training_start(self) -> None:
        from tqdm.rich import tqdm  # as SB3's bar (sb3 imports it the same way)

        done = int(self.model.num_timesteps)
        self.pbar = tqdm(total=int(self.locals["total_timesteps"]), initial=done)


def close_progress_bar(callbacks: Sequence[Any]) -> None:
    """Close a progress bar left open by an interrupted ``learn``."""
    for c in callbacks:
        if isinstance(c, ProgressBarCallback) and getattr(c, "pbar", None) is not None:
            with contextlib.suppress(Exception):
                c.pbar.close()
