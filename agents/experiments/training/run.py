"""One training run, fresh or resumed: ``train(TrainOptions(...))`` — the library call of
``train.py``.

Everything is checked, and the envs and model built, before the run directory is written; the
run holds the directory's lock throughout (docs/validation.md lists the rules). A
``KeyboardInterrupt`` during learning saves ``DIR/checkpoints/interrupted.zip`` and returns;
``train(TrainOptions(resume=DIR))`` continues from the latest complete checkpoint.
"""

from __future__ import annotations

import dataclasses
import os
import shlex
import signal
import sys
import threading
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.experiments.config_files import load_config_file
from agents.experiments.provenance import library_versions, utc_now
from agents.experiments.run_directory import LOCK_FILE, RunDirectoryLock, check_output_dir
from agents.experiments.training import finetune
from agents.experiments.training.callbacks import (
    RunProgressBar,
    close_progress_bar,
    make_callbacks,
)
from agents.experiments.training.checkpoints import (
    INTERRUPTED,
    describe_damaged,
    find_latest_checkpoint,
    model_timesteps,
    save_model_files,
    scan_checkpoints,
    write_failure,
)
from agents.experiments.training.config import (
    MAX_TIMESTEPS,
    OFF_POLICY,
    TrainConfig,
)
from agents.experiments.training.curve import plot_learning_curve
from agents.experiments.training.models import (
    build_model,
    make_eval_env,
    make_train_env,
    resolve_device,
    tensorboard_dir,
)
from agents.experiments.training.resolve import (
    MAX_THREADS,
    TrainOptions,
    check_seed,
    refuse_suite_seeds_of,
    resolve_config,
)
from agents.experiments.training.run_files import (
    RUNNING,
    STOPPED,
    TrainWriteError,
    clear_unstarted_run,
    read_train_log,
    truncate_episode_log,
    write_run_config,
    write_train_log,
)
from agents.policies.model_files import FINAL_MODEL, algo_class, sidecar_path

__all__ = ["TrainOptions", "TrainResult", "TrainWriteError", "resolve_config", "train"]


@dataclass
class TrainResult:
    """How a run (or one resumed segment) ended.

    Attributes:
        out: the run directory.
        env_id, algo: what the run trained (its config's).
        status: ``"completed"`` or ``"interrupted"``.
        num_timesteps: the model's ``num_timesteps`` at the end.
        model_path: ``DIR/model.zip`` (completed) or the interrupt checkpoint.
        wall_time_s: wall time of this segment (s).
        env_steps_per_s: env steps of this segment / its wall time.
    """

    out: Path
    env_id: str
    algo: str
    status: str
    num_timesteps: int
    model_path: Path
    wall_time_s: float
    env_steps_per_s: float


@dataclass
class _Segment:
    """One segment of a run, validated and built, before anything is written.

    Attributes:
        out: the run directory.
        config: the run's config (``timesteps``: the budget after this segment).
        source: where the config came from.
        seed: the run's base seed.
        run: the ``run:`` section of ``config.yaml`` so far.
        checkpoint: the model resumed from (None: a fresh run).
        start_steps: the model's timesteps at the start.
        add: env steps this segment trains.
        segment_seed: seed of this segment's training envs and model.
        log: ``train_log.json`` so far.
        train_env, eval_env, model: the SB3 objects (closed by :func:`train`).
    """

    out: Path
    config: TrainConfig
    source: str
    seed: int
    run: dict[str, Any]
    checkpoint: Path | None
    start_steps: int
    add: int
    segment_seed: int
    log: dict[str, Any]
    train_env: Any = None
    eval_env: Any = None
    model: Any = None


def train(options: TrainOptions) -> TrainResult:
    """Train (or resume) one run; see the module docstring for what lands in the directory.

    Every option is checked, and the envs and the model are built, before the run directory is
    touched; the directory's lock (:class:`~agents.experiments.run_directory.RunDirectoryLock`)
    is held for the whole run, so a second run on it is refused at its start.

    A ``KeyboardInterrupt`` during learning saves ``DIR/checkpoints/interrupted.zip`` (with its
    VecNormalize stats and, per config, replay buffer), updates the logs and the learning curve,
    and returns with ``status="interrupted"``; ``train(TrainOptions(resume=DIR))`` continues it.

    Raises:
        FileNotFoundError, FileExistsError, ValueError: bad options, config or run directory
            (messages name the option or key, the value and what is allowed).
        TrainWriteError: a file of the run could not be written mid-run (a full disk, a
            directory made read-only); the message says what is on disk and how to resume.
    """
    import torch

    device = resolve_device(options.device)
    threads = options.threads
    if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= MAX_THREADS:
        raise ValueError(f"--threads must be an integer in [1, {MAX_THREADS}], got {threads!r}")
    torch.set_num_threads(threads)
    argv = options.argv if options.argv is not None else sys.argv
    command = shlex.join(["python", *argv]) if argv else ""
    segment: _Segment | None = None
    try:
        if options.resume is not None:
            out = _check_resume_options(options)
            with RunDirectoryLock(out, "--resume"):
                segment = _prepare_resume(options, out, device, command)
                return _run_segment(segment, options)
        out = check_output_dir(options.out if options.out is not None else "")
        lock = RunDirectoryLock(out, "--out")
        # a directory with a lock file may be busy: lock it at once, so that a busy one is
        # refused before anything else; otherwise lock (and create) it once all is checked
        held = (out / LOCK_FILE).is_file()
        if held:
            lock.acquire()
        try:
            _refuse_used_directory(out)
            segment = _prepare_fresh(options, out, device, command)
            if not held:
                lock.acquire()
                held = True
                _refuse_used_directory(out)  # another run may have made it meanwhile
            removed = clear_unstarted_run(out)
            if removed:
                print(
                    f"note: {out} held a run that never saved a model ({', '.join(removed)}); "
                    "starting afresh in its place",
                    file=sys.stderr,
                )
            return _run_segment(segment, options)
        finally:
            lock.release()
    finally:
        if segment is not None:
            _close_envs(segment)


def _check_resume_options(options: TrainOptions) -> Path:
    """The run directory of ``--resume``, checked to hold a run, and no options that would
    change its config."""
    text = os.fspath(options.resume) if options.resume is not None else ""
    if not str(text).strip():
        raise ValueError("--resume must name a run directory, got an empty string")
    out = Path(text)
    for name, value in (
        ("--config", options.config),
        ("--env", options.env_id),
        ("--algo", options.algo),
        ("--n-envs", options.n_envs),
        ("--seed", options.seed),
        ("--set", options.overrides or None),
        ("--init", options.init),
    ):
        if value is not None:
            raise ValueError(
                f"{name} cannot be combined with --resume (a resumed run keeps its own config "
                f"in {out / 'config.yaml'})"
            )
    if options.out is not None and Path(options.out).resolve() != out.resolve():
        raise ValueError("--out and --resume name different directories; give only --resume")
    if not out.is_dir():
        raise ValueError(f"--resume {out}: no such run directory")
    if not (out / "config.yaml").is_file():
        raise ValueError(
            f"--resume {out}: not a run of train.py (no config.yaml); start one with --out {out}"
        )
    return out


def _refuse_used_directory(out: Path) -> None:
    """A fresh run may not take a directory that holds a model (complete or damaged)."""
    scan = scan_checkpoints(out)
    if scan.latest is not None:
        raise FileExistsError(
            f"{out} already holds a run; continue it with --resume {out} or pick another --out"
        )
    if scan.damaged:
        raise FileExistsError(
            f"{out} holds damaged models ({describe_damaged(scan.damaged)}); delete them to "
            "start afresh there, or pick another --out"
        )


def _build(segment: _Segment, stats: Path | None, device: str) -> None:
    """The training and evaluation envs and a fresh model (``segment.checkpoint`` None) —
    in the order that fixes the seeded results."""
    from stable_baselines3.common.utils import set_random_seed

    config = segment.config
    set_random_seed(segment.segment_seed)
    segment.train_env = make_train_env(config, segment.segment_seed, stats)
    try:
        segment.eval_env = make_eval_env(config) if config.eval.freq > 0 else None
        if segment.checkpoint is None:
            segment.model = build_model(
                config,
                segment.train_env,
                seed=segment.segment_seed,
                device=device,
                tensorboard_log=tensorboard_dir(segment.out),
                source=segment.source,
            )
    except BaseException:
        _close_envs(segment)
        raise


def _close_envs(segment: _Segment) -> None:
    for env in (segment.train_env, segment.eval_env):
        if env is not None:
            env.close()
    segment.train_env = segment.eval_env = None


def _prepare_fresh(options: TrainOptions, out: Path, device: str, command: str) -> _Segment:
    config, source = resolve_config(options)
    seed = 0 if options.seed is None else int(options.seed)
    check_seed(seed, config.n_envs)
    refuse_suite_seeds_of(seed, config)
    run = {"command": command}
    segment = _Segment(out, config, source, seed, run, None, 0, config.timesteps, seed, {})
    _build(segment, None, device)
    segment.run = _run_section(segment, device)
    segment.run["overrides"] = list(options.overrides)
    return segment


def _prepare_resume(options: TrainOptions, out: Path, device: str, command: str) -> _Segment:
    data, run = load_config_file(out / "config.yaml")
    config = TrainConfig.from_dict(data, source=str(out / "config.yaml"))
    seed = int(run.get("seed", 0))
    if config.init.path is not None:  # the anchor's reference must be there before anything
        finetune.reference_path(config, out)
    needs_stats = config.normalize.enabled
    checkpoint = find_latest_checkpoint(out, needs_stats)
    start_steps = model_timesteps(checkpoint)
    damaged = scan_checkpoints(out, needs_stats).damaged
    if damaged:
        print(
            f"note: skipping damaged model files ({describe_damaged(damaged)}); resuming from "
            f"the latest complete checkpoint {checkpoint.name} ({start_steps:,} steps). Delete "
            "the damaged files to silence this note",
            file=sys.stderr,
        )
    if options.timesteps is not None:
        add = int(options.timesteps)
    else:
        add = int(config.timesteps) - start_steps
        if add <= 0:
            raise ValueError(
                f"the run in {out} already reached its budget ({start_steps:,} >= "
                f"{config.timesteps:,} steps); pass --timesteps N to train N more"
            )
    if add < 1:
        raise ValueError(f"--timesteps must be >= 1, got {add}")
    if start_steps + add > MAX_TIMESTEPS:
        raise ValueError(
            f"--timesteps {add:,} would take the run past {MAX_TIMESTEPS:,} steps (it is at "
            f"{start_steps:,})"
        )
    config = dataclasses.replace(config, timesteps=max(config.timesteps, start_steps + add))
    source = run.get("config_source", str(out / "config.yaml"))
    log = read_train_log(out)
    segments = log.get("segments", [])
    if segments and segments[-1].get("status") == RUNNING:
        segments[-1]["status"] = STOPPED  # its process ended without saving
    segment_seed = seed + len(log.get("segments", [])) * config.n_envs
    check_seed(segment_seed, config.n_envs)
    refuse_suite_seeds_of(segment_seed, config)
    segment = _Segment(
        out, config, source, seed, run, checkpoint, start_steps, add, segment_seed, log
    )
    stats = sidecar_path(checkpoint, "vecnormalize") if needs_stats else None
    _build(segment, stats, device)
    try:
        cls = finetune.AnchoredPPO if config.init.path is not None else algo_class(config.algo)
        model = cls.load(str(checkpoint), env=segment.train_env, device=device)
    except (RuntimeError, EOFError, OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        _close_envs(segment)
        raise ValueError(
            f"--resume {out}: checkpoint {checkpoint} is damaged ({type(exc).__name__}: {exc}); "
            "delete it to resume from the previous checkpoint"
        ) from None
    model.tensorboard_log = tensorboard_dir(out)
    model.set_random_seed(segment_seed)
    if isinstance(model, finetune.AnchoredPPO):  # a fine-tuning run (config.init.path)
        finetune.configure_resumed(model, config, out)
    if config.algo in OFF_POLICY:
        _restore_replay_buffer(model, config, checkpoint)
    segment.model = model
    segment.run = _run_section(segment, device)
    segment.run.setdefault("resumes", []).append(
        {"command": command, "from": str(checkpoint), "at": utc_now(), "add_timesteps": add}
    )
    return segment


def _restore_replay_buffer(model: Any, config: TrainConfig, checkpoint: Path) -> None:
    """Load the replay buffer saved with ``checkpoint``; without one (or with one cut short) the
    run resumes with an empty buffer and random actions for ``learning_starts`` steps."""
    buffer = sidecar_path(checkpoint, "replay_buffer")
    problem = f"no replay buffer saved with {checkpoint.name}"
    if buffer.is_file():
        try:
            model.load_replay_buffer(str(buffer))
            return
        except Exception as exc:  # any unpickling failure means a damaged file
            problem = f"replay buffer {buffer.name} is damaged ({type(exc).__name__})"
    print(
        f"note: {problem}; resuming with an empty buffer (random actions until it refills)",
        file=sys.stderr,
    )
    model.learning_starts = model.num_timesteps + int(
        config.algo_kwargs.get("learning_starts", model.learning_starts)
    )


def _run_section(segment: _Segment, device: str) -> dict[str, Any]:
    """The ``run:`` section of ``config.yaml`` for this segment."""
    import torch

    run = segment.run
    return {
        **run,
        "command": run.get("command", ""),
        "seed": segment.seed,
        "config_source": segment.source,
        "config_version": segment.config.version,
        "started_at": run.get("started_at", utc_now()),
        "versions": library_versions(),
        "device": device,
        "torch_threads": torch.get_num_threads(),
    }


def _run_segment(segment: _Segment, options: TrainOptions) -> TrainResult:
    """Learn one segment into its (locked) directory and write its files.

    Raises:
        TrainWriteError: a file of the run could not be written (a full disk, a directory made
            read-only); the run's files are as the last complete write left them.
    """
    try:
        return _learn_segment(segment, options)
    except (OSError, RuntimeError) as exc:
        failure = write_failure(exc)
        if failure is None:
            raise
        steps = int(segment.model.num_timesteps)
        latest = scan_checkpoints(segment.out, segment.config.normalize.enabled).latest
        raise TrainWriteError(segment.out, failure, steps, latest) from None


def _learn_segment(segment: _Segment, options: TrainOptions) -> TrainResult:
    import torch

    out, config, run, model = segment.out, segment.config, segment.run, segment.model
    checkpoint, start_steps, add = segment.checkpoint, segment.start_steps, segment.add
    log = segment.log
    earlier = list(log.get("segments", []))
    out.mkdir(parents=True, exist_ok=True)
    if checkpoint is not None:
        truncate_episode_log(out / "train_episodes.csv", start_steps)
    write_run_config(out, config, run)  # before learning, so an interrupted run can be resumed
    if checkpoint is None and config.init.path is not None:
        # a resume restores the anchor's reference from the run
        finetune.save_reference(out, config)

    def record(status: str, model_path: Path, steps: int, wall: float | None = None) -> None:
        """``train_log.json`` with this segment as it stands at ``steps`` (``wall``: its
        learning time, s; default: so far)."""
        wall = time.perf_counter() - start if wall is None else wall
        eval_s = evaluation.seconds if evaluation is not None else 0.0
        ckpt_s = checkpointer.seconds if checkpointer is not None else 0.0
        done = steps - start_steps
        entry = {
            "status": status,
            "started_at": run["resumes"][-1]["at"] if checkpoint else run["started_at"],
            "resumed_from": str(checkpoint) if checkpoint else None,
            "n_envs": config.n_envs,
            "env_seed": segment.segment_seed,
            "torch_threads": torch.get_num_threads(),
            "start_timesteps": start_steps,
            "end_timesteps": steps,
            "wall_time_s": round(wall, 3),
            "eval_time_s": round(eval_s, 3),
            "checkpoint_time_s": round(ckpt_s, 3),
            "env_steps_per_s": round(done / wall, 1) if wall > 0 else None,
            "env_steps_per_s_excluding_eval": (
                round(done / (wall - eval_s - ckpt_s), 1) if wall - eval_s - ckpt_s > 0 else None
            ),
        }
        log.update(
            {
                "env_id": config.env_id,
                "algo": config.algo,
                "status": status,
                "num_timesteps": steps,
                "target_timesteps": int(config.timesteps),
                "model": str(model_path),
                "segments": [*earlier, entry],
            }
        )
        write_train_log(out, log)

    def checkpointed(path: Path, steps: int) -> None:
        record(RUNNING, path, steps)  # a killed run's log stands as of its last checkpoint

    callbacks, evaluation, checkpointer, episodes = make_callbacks(
        config,
        out,
        segment.eval_env,
        start_steps if checkpoint is not None else None,
        after_checkpoint=checkpointed,
    )
    if options.progress:
        callbacks.append(RunProgressBar())

    what = f"resuming {out} at {start_steps:,} steps" if checkpoint else f"training into {out}"
    print(
        f"{what}: {config.algo} on {config.env_id}, {add:,} steps, {config.n_envs} envs, "
        f"seed {segment.seed}, config {Path(segment.source).name} v{config.version}",
        flush=True,
    )
    status = "completed"
    start = time.perf_counter()
    try:
        model.learn(
            total_timesteps=add,
            callback=callbacks,
            reset_num_timesteps=checkpoint is None,
            tb_log_name=config.algo.upper(),
            progress_bar=False,
        )
    except KeyboardInterrupt:
        status = "interrupted"
        close_progress_bar(callbacks)
    wall = time.perf_counter() - start
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:  # a second Ctrl-C must not cut the saving short
        if status == "completed":
            if evaluation is not None and (
                not evaluation.evaluations_timesteps
                or evaluation.evaluations_timesteps[-1] < model.num_timesteps
            ):
                evaluation.evaluate_now()
            model_path = out / FINAL_MODEL
        else:
            model_path = out / "checkpoints" / f"{INTERRUPTED}.zip"
        episodes.flush(sync=True)  # the rows of every step the model has seen, first
        save_model_files(model, config, model_path)
        record(status, model_path, int(model.num_timesteps), wall)
        run["finished_at" if status == "completed" else "interrupted_at"] = utc_now()
        write_run_config(out, config, run)
        plot_learning_curve(out)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous)
    return TrainResult(
        out=out,
        env_id=config.env_id,
        algo=config.algo,
        status=status,
        num_timesteps=int(model.num_timesteps),
        model_path=model_path,
        wall_time_s=wall,
        env_steps_per_s=(model.num_timesteps - start_steps) / wall if wall > 0 else 0.0,
    )
