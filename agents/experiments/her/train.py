"""Train SAC with hindsight experience replay (or plain SAC, the control) on a one-target rung.

:func:`train_sac` is the library function behind ``python -m agents.experiments.her``. It
writes, in ``out``:

==================  ===========================================================================
``model.zip``       the final SAC model (written atomically); fly it with
                    :mod:`agents.experiments.her.policy`
``curve.csv``       held-out evaluation every ``eval_freq`` env steps and at the end: steps,
                    wall seconds, success rate, captures, collisions, mean return (env reward),
                    Δv budget spent
``train_log.json``  options, wall time, env-steps/s (end to end, and without the evaluations)
==================  ===========================================================================

The held-out evaluation flies the *registered* env (its own observation, reward and rules),
deterministically, on the same missions every time: episode ``i`` is reset with seed
``EVAL_SEED + i`` (1 000 000 + i, as ``train.py``), never a training field first. Training
resets with seeds from ``seed`` on (SB3 seeds the env once; later fields follow from it).
"""

from __future__ import annotations

import csv
import io
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import SAC, HerReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.monitor import Monitor

import debris_gym  # noqa: F401  (registers the envs)
from agents.experiments.her.goal_env import (
    DEFAULT_CRASH_PENALTY,
    FAILURE_KEYS,
    GoalConditionedEnv,
)
from agents.experiments.her.policy import GoalPolicy
from agents.experiments.training.config import EVAL_SEED
from debris_gym.files import save_atomic, write_atomic

__all__ = [
    "CURVE_COLUMNS",
    "CrashFlagHerReplayBuffer",
    "SacOptions",
    "evaluate_policy_on_env",
    "train_sac",
]

CURVE_COLUMNS = (
    "steps",
    "seconds",
    "episodes",
    "success_rate",
    "captures_mean",
    "collisions",
    "return_mean",
    "budget_spent",
)
"""Columns of ``curve.csv``: env steps so far, wall seconds since the start, held-out episodes,
their success rate (0-1), mean targets captured, collisions + out of bounds (count), mean env
return, episodes that ran out of Δv (count; a failure too)."""


@dataclass(frozen=True)
class SacOptions:
    """SAC's hyper-parameters, the same for the HER run and the control.

    Attributes:
        learning_rate: Adam step size.
        buffer_size: replay capacity, transitions (None: the run's timesteps).
        learning_starts: env steps of random actions before the first update.
        batch_size: transitions per gradient step.
        tau: target-network soft-update rate.
        gamma: discount per step (10 s).
        train_freq: env steps between updates (4 with one gradient step each: one gradient step
            per 4 env steps, the ratio of ``agents/configs/rendezvous2d_sac.yaml``).
        gradient_steps: gradient steps per update.
        ent_coef: SAC's entropy coefficient (``"auto_0.1"``: learned, starting at 0.1).
        net_arch: hidden layers of actor and critics.
        n_sampled_goal: HER's relabelled goals per real transition.
        crash_penalty: goal reward of a crash is ``-crash_penalty`` (HER only).
    """

    learning_rate: float = 1e-3
    buffer_size: int | None = None
    learning_starts: int = 1_000
    batch_size: int = 256
    tau: float = 0.005
    gamma: float = 0.98
    train_freq: int = 4
    gradient_steps: int = 1
    ent_coef: str = "auto_0.1"
    net_arch: tuple[int, ...] = (256, 256)
    n_sampled_goal: int = 4
    crash_penalty: float = DEFAULT_CRASH_PENALTY


def evaluate_policy_on_env(
    policy: Any, env: gym.Env[Any, Any], episodes: int, seed: int = EVAL_SEED
) -> dict[str, float]:
    """Fly ``policy`` (SB3 ``predict`` over flat observations) deterministically on ``env``.

    Episode ``i`` is reset with seed ``seed + i``. Returns success_rate (0-1), captures_mean,
    collisions (count, collisions + out of bounds), budget_spent (count, episodes that ran out
    of Δv) and return_mean (the env's reward).
    """
    successes, captures, crashes, spent, returns = 0, 0, 0, 0, []
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        total, done = 0.0, False
        while not done:
            action, _ = policy.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            done = terminated or truncated
        successes += bool(info.get("is_success", False))
        captures += int(info.get("targets_captured", 0))
        crashes += bool(info.get("collision", False) or info.get("out_of_bounds", False))
        spent += bool(info.get("budget_spent", False))
        returns.append(total)
    return {
        "episodes": float(episodes),
        "success_rate": successes / episodes,
        "captures_mean": captures / episodes,
        "collisions": float(crashes),
        "budget_spent": float(spent),
        "return_mean": float(np.mean(returns)),
    }


class CrashFlagHerReplayBuffer(HerReplayBuffer):
    """SB3's HER buffer that keeps, of each step's info, only what
    :meth:`GoalConditionedEnv.compute_reward` reads (the failure flags, ``FAILURE_KEYS``) and what
    the buffer itself reads (``TimeLimit.truncated``): ``copy_info_dict=True`` deep-copies the
    stored infos of every relabelled sample, and the env's full infos made that markedly slower
    (docs/benchmarks.md, "Measured design choices")."""

    # (the signature of SB3's HerReplayBuffer.add, which overrides ReplayBuffer.add's arrays
    # with dicts and carries the same ignore)
    def add(  # type: ignore[override]
        self,
        obs: dict[str, np.ndarray],
        next_obs: dict[str, np.ndarray],
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        slim = [{k: info[k] for k in _KEPT_INFO if k in info} for info in infos]
        super().add(obs, next_obs, action, reward, done, slim)


_KEPT_INFO = (*FAILURE_KEYS, "TimeLimit.truncated")


class _CurveCallback(BaseCallback):
    """Held-out evaluation every ``freq`` env steps, appended to ``curve.csv`` (rewritten
    atomically), timed apart from training."""

    def __init__(
        self, env_id: str, env_kwargs: dict[str, Any], path: Path, freq: int, episodes: int
    ) -> None:
        super().__init__()
        self.eval_env = gym.make(env_id, **env_kwargs)
        self.path, self.freq, self.episodes = path, freq, episodes
        self.rows: list[dict[str, float]] = []
        self.start = time.perf_counter()
        self.eval_seconds = 0.0
        self.last_steps = -1

    def evaluate(self) -> None:
        begin = time.perf_counter()
        policy = GoalPolicy(self.model, self.eval_env)
        row = evaluate_policy_on_env(policy, self.eval_env, self.episodes)
        self.eval_seconds += time.perf_counter() - begin
        row = {"steps": float(self.num_timesteps), "seconds": begin - self.start, **row}
        self.rows.append(row)
        self.last_steps = self.num_timesteps
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=CURVE_COLUMNS, lineterminator="\n")
        writer.writeheader()
        for r in self.rows:
            writer.writerow(
                {
                    k: (int(r[k]) if k in ("steps", "episodes") else round(r[k], 4))
                    for k in CURVE_COLUMNS
                }
            )
        write_atomic(self.path, buffer.getvalue())
        # the latest model beside its curve, so a run stopped early still leaves one
        save_atomic(self.path.with_name("model.zip"), self.model.save)
        print(
            f"eval @ {self.num_timesteps:,} steps ({row['seconds']:.0f} s): success "
            f"{100 * row['success_rate']:.0f} %, captures {row['captures_mean']:.2f}, "
            f"collisions {int(row['collisions'])} of {self.episodes}, Δv budget spent "
            f"{int(row['budget_spent'])}",
            flush=True,
        )

    def _on_step(self) -> bool:
        if self.num_timesteps % self.freq == 0:
            self.evaluate()
        return True


def _check_positive(name: str, value: int, low: int = 1) -> None:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
        raise ValueError(f"{name}: an integer >= {low} needed, got {value!r}")


def train_sac(
    out: str | Path,
    timesteps: int,
    seed: int = 0,
    her: bool = True,
    env_id: str = "DebrisGym/Rendezvous2D-Easy-v2",
    env_kwargs: dict[str, Any] | None = None,
    options: SacOptions | None = None,
    eval_freq: int = 25_000,
    eval_episodes: int = 20,
    progress: bool = True,
) -> dict[str, Any]:
    """Train SAC+HER (``her=True``) or plain SAC on the env's own reward (``her=False``).

    Args:
        out: run directory; created, and refused if it already holds a ``model.zip``.
        timesteps: env steps, >= 1.
        seed: SAC's and the training env's seed, 0 <= seed < EVAL_SEED.
        her: goal-conditioned (:class:`GoalConditionedEnv`, ``MultiInputPolicy``, HER buffer)
            or the control (the env as registered, ``MlpPolicy``, its own reward).
        env_id: a one-target, no-return debris-gym env (HER needs it; the control too, so the
            two compare).
        env_kwargs: extra ``gym.make`` options (both runs, and the evaluation).
        options: SAC hyper-parameters (:class:`SacOptions`).
        eval_freq: env steps between held-out evaluations, >= 1.
        eval_episodes: held-out missions per evaluation, >= 1.
        progress: SB3's progress bar on stderr.

    Returns:
        The content of ``train_log.json``.
    """
    _check_positive("timesteps", timesteps)
    _check_positive("eval_freq", eval_freq)
    _check_positive("eval_episodes", eval_episodes)
    _check_positive("seed", seed, low=0)
    if seed >= EVAL_SEED:
        raise ValueError(f"seed: 0 <= seed < {EVAL_SEED} needed (evaluation seeds), got {seed}")
    options = options or SacOptions()
    env_kwargs = dict(env_kwargs or {})
    out = Path(out)
    if (out / "model.zip").exists():
        raise ValueError(f"out: {str(out)!r} already holds a model.zip; choose another directory")
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)

    env: gym.Env[Any, Any] = gym.make(env_id, **env_kwargs)
    if her:
        env = GoalConditionedEnv(env, crash_penalty=options.crash_penalty)
    env = Monitor(env)
    extra: dict[str, Any] = {}
    if her:
        extra = dict(
            replay_buffer_class=CrashFlagHerReplayBuffer,
            replay_buffer_kwargs=dict(
                n_sampled_goal=options.n_sampled_goal,
                goal_selection_strategy="future",
                copy_info_dict=True,  # the crash penalty is read from the infos
            ),
        )
    model = SAC(
        "MultiInputPolicy" if her else "MlpPolicy",
        env,
        learning_rate=options.learning_rate,
        buffer_size=options.buffer_size or timesteps,
        learning_starts=options.learning_starts,
        batch_size=options.batch_size,
        tau=options.tau,
        gamma=options.gamma,
        train_freq=options.train_freq,
        gradient_steps=options.gradient_steps,
        ent_coef=options.ent_coef,
        policy_kwargs=dict(net_arch=list(options.net_arch)),
        seed=seed,
        device="cpu",
        verbose=0,
        **extra,
    )
    curve = _CurveCallback(env_id, env_kwargs, out / "curve.csv", eval_freq, eval_episodes)
    start = time.perf_counter()
    model.learn(total_timesteps=timesteps, callback=curve, progress_bar=progress)
    train_seconds = time.perf_counter() - start
    if curve.last_steps != model.num_timesteps:
        curve.evaluate()
    save_atomic(out / "model.zip", model.save)
    wall = time.perf_counter() - start
    log = {
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "her": her,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "options": asdict(options),
        "eval_freq": eval_freq,
        "eval_episodes": eval_episodes,
        "wall_seconds": round(wall, 1),
        "eval_seconds": round(curve.eval_seconds, 1),
        "steps_per_second": round(model.num_timesteps / wall, 1),
        "steps_per_second_without_eval": round(
            model.num_timesteps / max(train_seconds - curve.eval_seconds, 1e-9), 1
        ),
        "final_eval": curve.rows[-1] if curve.rows else None,
    }
    write_atomic(out / "train_log.json", json.dumps(log, indent=2) + "\n")
    env.close()
    curve.eval_env.close()
    return log
