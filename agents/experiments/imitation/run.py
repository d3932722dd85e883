"""An imitation run: behaviour cloning, then DAgger rounds, into a run directory that
:func:`agents.load_agent` and ``evaluate.py`` read like any trained policy's.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.imitation.collection import collect
from agents.experiments.imitation.config import ImitationConfig
from agents.experiments.imitation.fitting import (
    CLIP_OBS,
    OBS_EPSILON,
    MLPActor,
    export_actor,
    fit,
    make_model,
    set_observation_stats,
)
from agents.experiments.provenance import iso_time, library_versions
from agents.experiments.run_directory import OutputSet, RunDirectoryLock, check_output_dir
from debris_gym.files import save_atomic, write_atomic

__all__ = ["RUN_FILES", "imitate", "plot_rounds", "run_config_yaml"]

RUN_FILES = (
    "model.zip",
    "vecnormalize.pkl",
    "imitation_log.json",
    "config.yaml",
    "imitation_curve.png",
)
"""The files of an imitation run, committed together at its end."""


def imitate(
    config: ImitationConfig,
    out: str | Path,
    log: Callable[[str], None] = print,
    progress: bool = True,
    command: str | None = None,
) -> dict[str, Any]:
    """Behaviour cloning then DAgger; writes a run directory ``out`` (see the module doc).

    Args:
        config: the run's settings.
        out: run directory (checked by
            :func:`~agents.experiments.run_directory.check_output_dir`, created, locked for the
            whole run; refused if it already holds a model).
        log: where the per-round lines go.
        progress: tqdm bars over the rollouts.
        command: the command line, recorded in ``config.yaml``.

    Returns:
        the run log (also written to ``out/imitation_log.json``): per round the rollout outcomes
        of the policy that flew it, the data set size, the fit losses and wall times.
    """
    import torch

    out = check_output_dir(out)
    with RunDirectoryLock(out):
        if (out / "model.zip").exists():
            raise FileExistsError(f"{out} already holds a run (model.zip); choose another --out")
        torch.set_num_threads(1)
        return _imitate(config, out, log, progress, command)


def _imitate(
    config: ImitationConfig,
    out: Path,
    log: Callable[[str], None],
    progress: bool,
    command: str | None,
) -> dict[str, Any]:
    """The rounds of :func:`imitate`, then the run's files committed as one set."""
    import torch

    rng = np.random.default_rng(config.seed)
    torch.manual_seed(config.seed)
    next_seed = config.field_seeds.start  # the seeds the config checked against the suites
    started = time.time()
    history: list[dict[str, Any]] = []

    def seeds(n: int) -> list[int]:
        nonlocal next_seed
        out_seeds = list(range(next_seed, next_seed + n))
        next_seed += n
        return out_seeds

    def rollouts(n: int, actor: MLPActor | None, what: str) -> tuple:
        bar = _progress_bar(n, what) if progress else None
        try:
            return collect(
                config,
                seeds(n),
                actor,
                config.dagger_beta if actor is not None else 0.0,
                progress=bar.update if bar is not None else None,
            )
        finally:
            if bar is not None:
                bar.close()

    model, venv = make_model(config)
    for r in range(config.dagger_rounds + 1):
        cloning = r == 0  # round 0: behaviour cloning on the expert's own flights
        actor = None if cloning else export_actor(model, venv, config.activation_fn)
        t0 = time.time()
        if cloning:
            observations, actions, stats = rollouts(config.bc_episodes, None, "expert rollouts")
            set_observation_stats(venv, observations)
        else:
            obs_r, act_r, stats = rollouts(config.dagger_episodes, actor, f"DAgger round {r}")
            observations = np.concatenate([observations, obs_r])
            actions = np.concatenate([actions, act_r])
        collect_time = time.time() - t0
        t0 = time.time()
        epochs = config.epochs if cloning else config.refit_epochs
        losses = fit(model, venv, observations, actions, epochs, config, rng)
        history.append(
            {
                "round": r,
                "flown_by": config.expert if cloning else "policy",
                **stats.summary(),
                "dataset": len(observations),
                "loss_first": losses[0],
                "loss_last": losses[-1],
                "collect_s": collect_time,
                "fit_s": time.time() - t0,
            }
        )
        log(_round_line(history[-1]))

    model_path = out / "model.zip"
    run_log: dict[str, Any] = {
        "config": config.to_dict(),
        "rounds": history,
        "wall_s": time.time() - started,
        "model": str(model_path),
    }
    run = {
        "command": command,
        "started_at": iso_time(started),
        "finished_at": iso_time(time.time()),
        "wall_s": round(run_log["wall_s"], 1),
        "versions": library_versions(),
    }
    with OutputSet(out, owned=RUN_FILES) as files:  # all of the run's files, or none
        save_atomic(files.path("model.zip"), model.save)
        save_atomic(files.path("vecnormalize.pkl"), venv.save)
        write_atomic(files.path("imitation_log.json"), json.dumps(run_log, indent=2) + "\n")
        write_atomic(files.path("config.yaml"), run_config_yaml(config, run))
        plot_rounds(run_log, files.path("imitation_curve.png"))
        files.commit(run={"command": command, "finished_at": run["finished_at"]})
    return run_log


def _round_line(h: dict[str, Any]) -> str:
    return (
        f"round {h['round']} ({h['flown_by']} flew {h['episodes']} episodes): success "
        f"{h['success']:.0%}, collisions {h['collision']:.0%}, captured {h['captured']:.2f}, "
        f"dv on successes {h['delta_v_success']:.1f} m/s; data {h['dataset']} pairs, loss "
        f"{h['loss_first']:.4f} -> {h['loss_last']:.4f}; "
        f"{h['collect_s']:.0f} s + {h['fit_s']:.0f} s"
    )


def run_config_yaml(config: ImitationConfig, run: dict[str, Any] | None = None) -> str:
    """``config.yaml`` of an imitation run: what :mod:`agents.policies.learned` reads
    (``env_kwargs`` for the observation options, ``normalize`` for the statistics) plus the
    imitation settings."""
    import yaml

    data = {
        "env_id": config.env_id,
        "algo": "ppo",
        "env_kwargs": dict(config.env_kwargs),
        "normalize": {
            "enabled": True,
            "norm_obs": True,
            "norm_reward": False,
            "clip_obs": CLIP_OBS,
            "epsilon": OBS_EPSILON,
        },
        "imitation": config.to_dict(),
    }
    if run is not None:
        data["run"] = run
    header = (
        "# Imitation run (imitate.py): an SB3 PPO model whose actor was fit to the expert's\n"
        "# actions (behaviour cloning + DAgger); see agents/experiments/imitation/.\n"
    )
    return header + yaml.safe_dump(data, sort_keys=False)


def _progress_bar(total: int, what: str) -> Any:
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=what, unit="ep", leave=False)


def plot_rounds(run_log: dict[str, Any], path: str | Path) -> Path:
    """Success and collision rate of each round's rollouts, and the data set size (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rounds = run_log["rounds"]
    r = [h["round"] for h in rounds]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    ax1.plot(r, [h["success"] for h in rounds], "o-", label="success")
    ax1.plot(r, [h["collision"] for h in rounds], "s--", label="collision")
    ax1.set_xlabel("round (0: the expert flies; k: the policy of fit k flies)")
    ax1.set_ylabel("rate on the round's training fields")
    ax1.set_ylim(-0.02, 1.02)
    ax1.grid(alpha=0.3)
    ax1.legend()
    ax2.plot(r, [h["dataset"] / 1000 for h in rounds], "o-")
    ax2.set_xlabel("round")
    ax2.set_ylabel("data set [thousand pairs]")
    ax2.grid(alpha=0.3)
    fig.suptitle(f"imitation of {run_log['config']['expert']} on {run_log['config']['env_id']}")
    fig.tight_layout()
    out = Path(path)
    save_atomic(out, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return out
