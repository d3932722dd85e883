"""Hyper-parameter sweeps with Ray Tune over ``train.py``'s recipes: :func:`run_sweep`, the
library call of ``sweep.py``.

The search space is the recipe's ``sweep:`` section
(:mod:`agents.experiments.training.sweep_config`). Each trial is a normal ``train.py`` run —
the recipe with the trial's values set as ``--set`` overrides, trained by
:func:`agents.experiments.training.run.train` into its own run directory
``OUT/trials/<trial id>/`` (model.zip, vecnormalize.pkl, config.yaml, checkpoints/, tb/, …) —
and reports the success rate and mean return of its final periodic evaluation (held-out seeds,
``eval.n_episodes`` episodes) to Tune. Every trial trains with the same seed, so trials differ
only by their hyper-parameters. The best trial (by ``sweep.metric``; ties go to the higher mean
return) has its model files (``model.zip``, ``vecnormalize.pkl``, ``config.yaml``) copied to
``OUT/best/``, so ``evaluate.py --agents ppo=OUT/best/model.zip`` loads it like any trained run;
``OUT/sweep.json`` lists every trial. Tune's own records go to ``OUT/tune/``.

On a cluster (``address``), ``OUT`` must be a directory every node sees (a shared file system):
trials write their run directories there.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.experiments.distributed import require_ray
from agents.experiments.distributed.evaluation import check_workers
from agents.experiments.run_directory import OutputDirError, RunDirectoryLock, check_output_dir
from agents.experiments.training.run import TrainOptions, resolve_config, train
from agents.experiments.training.sweep_config import SweepConfig
from agents.policies.model_files import FINAL_MODEL, sidecar_path
from debris_gym.files import write_atomic

__all__ = ["BEST_DIR", "SweepOptions", "SweepResult", "TrialResult", "run_sweep", "trial_metrics"]

BEST_DIR = "best"
"""Folder of ``OUT`` that receives the best trial's model files."""

TRIALS_DIR = "trials"
"""Folder of ``OUT`` holding one run directory per trial."""


@dataclass
class SweepOptions:
    """What ``sweep.py`` was asked for (see its ``--help``).

    Attributes:
        out: the sweep's directory (created; must not hold a finished sweep).
        config, env_id, algo, overrides, timesteps, n_envs, seed: the recipe, as for
            ``train.py`` (:class:`~agents.experiments.training.run.TrainOptions`); ``timesteps``
            and ``n_envs`` apply to every trial.
        samples: trials; None: the recipe's ``sweep.num_samples``.
        address: the Ray cluster to join; None: a local Ray, stopped after the sweep.
        workers: trials run at once (one CPU each); None: as many as the cluster has CPUs.
        threads: torch CPU threads per trial.
    """

    out: str | Path
    config: Path | None = None
    env_id: str | None = None
    algo: str | None = None
    overrides: list[str] = field(default_factory=list)
    timesteps: int | None = None
    n_envs: int | None = None
    seed: int = 0
    samples: int | None = None
    address: str | None = None
    workers: int | None = None
    threads: int = 1


@dataclass(frozen=True)
class TrialResult:
    """One trial: its drawn ``params``, ``metrics`` (success_rate, mean_reward, timesteps),
    run directory, and the error if it failed (then ``metrics`` is empty)."""

    trial_id: str
    params: dict[str, Any]
    metrics: dict[str, float]
    run_dir: str
    error: str | None = None


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep: every trial, the best one, where its model was exported, the metric
    and mode it was chosen by, and the wall time (s)."""

    out: Path
    trials: list[TrialResult]
    best: TrialResult
    best_dir: Path
    metric: str
    mode: str
    wall_time_s: float


def trial_metrics(run_dir: str | Path) -> dict[str, float]:
    """The final periodic evaluation of a ``train.py`` run: ``success_rate`` (NaN when the env
    reports no success), ``mean_reward`` (the env's own return) and ``timesteps``.

    Raises:
        FileNotFoundError: the run made no evaluation (``evaluations.npz`` missing).
    """
    import numpy as np

    with np.load(Path(run_dir) / "evaluations.npz") as log:
        successes = np.asarray(log["successes"][-1], dtype=float)
        return {
            "success_rate": float(np.nanmean(successes)) if successes.size else math.nan,
            "mean_reward": float(np.mean(log["results"][-1])),
            "timesteps": int(log["timesteps"][-1]),
        }


def _resolve(options: SweepOptions) -> tuple[Any, Path, SweepConfig]:
    """The recipe, its file (absolute) and its sweep section, checked.

    Raises:
        ValueError: no ``sweep:`` section, no evaluation to rank by, bad samples or workers.
    """
    train_options = TrainOptions(
        config=options.config, env_id=options.env_id, algo=options.algo,
        overrides=list(options.overrides), timesteps=options.timesteps, n_envs=options.n_envs,
    )  # fmt: skip
    config, source = resolve_config(train_options)
    if config.sweep is None:
        raise ValueError(
            f"{source} has no 'sweep:' section (the search space); add one, see docs/distributed.md"
        )
    if config.eval.freq < 1:
        raise ValueError(
            f"{source}: a sweep ranks trials by their final evaluation; eval.freq must be > 0"
        )
    samples = config.sweep.num_samples if options.samples is None else options.samples
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    check_workers(options.workers)
    return config, Path(source).resolve(), config.sweep


def _search_space(tune: Any, sweep: SweepConfig) -> dict[str, Any]:
    """Tune's distributions for the swept keys."""
    space = {}
    for key, param in sweep.params.items():
        if param.kind == "choice":
            space[key] = tune.choice(param.values)
        else:
            space[key] = getattr(tune, param.kind)(*param.values)
    return space


def _trainable(options: SweepOptions, source: Path, trials: Path) -> Any:
    """The Tune function trainable: one ``train.py`` run per trial, its final evaluation
    reported."""

    def trial(params: dict[str, Any]) -> None:
        from ray import tune

        run_dir = trials / tune.get_context().get_trial_id()
        overrides = [*options.overrides, "sweep=null"]
        overrides += [f"{key}={json.dumps(_plain(value))}" for key, value in params.items()]
        train(
            TrainOptions(
                out=run_dir, config=source, env_id=options.env_id, algo=options.algo,
                overrides=overrides, timesteps=options.timesteps, n_envs=options.n_envs,
                seed=options.seed, progress=False, threads=options.threads,
                argv=["train.py", "--config", str(source), "--out", str(run_dir),
                      *[w for o in overrides for w in ("--set", o)]],
            )
        )  # fmt: skip
        tune.report({**trial_metrics(run_dir), "run_dir": str(run_dir)})

    return trial


def run_sweep(options: SweepOptions) -> SweepResult:
    """Run the sweep (see the module docstring) and export its best trial.

    Raises:
        FileNotFoundError, ValueError: a bad recipe, option or output directory (the message
            names it); :class:`~agents.experiments.run_directory.OutputDirError` names ``--out``.
        ImportError: Ray Tune is not installed.
        RuntimeError: every trial failed (the first error is in the message).
    """
    _, source, sweep = _resolve(options)
    out = check_output_dir(str(options.out)).resolve()
    for name in (BEST_DIR, "sweep.json"):
        if (out / name).exists():
            raise OutputDirError(
                "--out", f"{out} holds a finished sweep ({out / name}); choose another directory"
            )
    ray = require_ray("a sweep", "ray")
    tune = require_ray("a sweep", "ray.tune")
    from ray.tune.search.basic_variant import BasicVariantGenerator

    samples = sweep.num_samples if options.samples is None else options.samples
    start = time.perf_counter()
    with RunDirectoryLock(out, "--out"):
        trials_dir = out / TRIALS_DIR
        trials_dir.mkdir(parents=True, exist_ok=True)
        started = not ray.is_initialized()
        if started:
            kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": "WARNING"}
            if options.address is not None:
                kwargs["address"] = options.address
            elif options.workers is not None:
                kwargs["num_cpus"] = options.workers
            ray.init(**kwargs)
        try:
            tuner = tune.Tuner(
                tune.with_resources(_trainable(options, source, trials_dir), {"cpu": 1}),
                param_space=_search_space(tune, sweep),
                tune_config=tune.TuneConfig(
                    metric=sweep.metric, mode=sweep.mode, num_samples=samples,
                    max_concurrent_trials=options.workers,
                    search_alg=BasicVariantGenerator(random_state=sweep.seed),
                ),
                run_config=tune.RunConfig(
                    name="sweep", storage_path=str(out / "tune"), verbose=0,
                ),
            )  # fmt: skip
            grid = tuner.fit()
        finally:
            if started:
                ray.shutdown()
        trials = [_trial_result(result, trials_dir) for result in grid]
        ranked = [t for t in trials if t.error is None and not math.isnan(t.metrics[sweep.metric])]
        if not ranked:
            errors = [t.error for t in trials if t.error]
            raise RuntimeError(
                f"no trial finished with a {sweep.metric}"
                + (f"; first error: {errors[0]}" if errors else "")
            )
        sign = 1.0 if sweep.mode == "max" else -1.0
        best = max(  # ties (the same success rate) go to the higher return
            ranked, key=lambda t: (sign * t.metrics[sweep.metric], t.metrics["mean_reward"])
        )
        best_dir = _export(Path(best.run_dir), out / BEST_DIR)
        result = SweepResult(
            out, trials, best, best_dir, sweep.metric, sweep.mode, time.perf_counter() - start
        )
        write_atomic(out / "sweep.json", json.dumps(_summary(result, source), indent=1) + "\n")
    return result


def _trial_result(result: Any, trials_dir: Path) -> TrialResult:
    """A Tune result as a :class:`TrialResult`."""
    trial_id = Path(result.path).name if result.path else "?"
    metrics = dict(result.metrics or {})
    run_dir = str(metrics.get("run_dir") or trials_dir / metrics.get("trial_id", trial_id))
    keep = {k: metrics[k] for k in ("success_rate", "mean_reward", "timesteps") if k in metrics}
    return TrialResult(
        trial_id=str(metrics.get("trial_id", trial_id)),
        params={key: _plain(value) for key, value in (result.config or {}).items()},
        metrics=keep if result.error is None else {},
        run_dir=run_dir,
        error=None if result.error is None else f"{type(result.error).__name__}: {result.error}",
    )


def _plain(value: Any) -> Any:
    """A numpy scalar drawn by Tune as a plain Python number (for JSON and YAML)."""
    return value.item() if hasattr(value, "item") else value


def _export(run_dir: Path, dest: Path) -> Path:
    """Copy the run's model, VecNormalize statistics and config to ``dest`` as one set (built
    aside, then renamed into place)."""
    partial = dest.with_name(dest.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    model = run_dir / FINAL_MODEL
    files = [model, sidecar_path(model, "vecnormalize"), run_dir / "config.yaml"]
    for path in files:
        if path.is_file():
            shutil.copy2(path, partial / path.name)
    os.replace(partial, dest)
    return dest


def _summary(result: SweepResult, source: Path) -> dict[str, Any]:
    """``sweep.json``: the recipe, the ranking rule, every trial and the best."""

    def trial(t: TrialResult) -> dict[str, Any]:
        return {"trial_id": t.trial_id, "params": t.params, "metrics": t.metrics,
                "run_dir": t.run_dir, "error": t.error}  # fmt: skip

    return {
        "config": str(source),
        "metric": result.metric,
        "mode": result.mode,
        "wall_time_s": round(result.wall_time_s, 3),
        "best": trial(result.best),
        "best_dir": str(result.best_dir),
        "trials": [trial(t) for t in result.trials],
    }
