"""Section ``train``: end-to-end SB3 PPO env-steps/s on the native and on a Dummy VecEnv.

``PPO("MlpPolicy", venv, n_steps, batch_size, n_epochs, device="cpu")`` with torch on one thread
on ``NativeVecEnv`` (the native vector env behind SB3's VecEnv API) at several N and on a
``DummyVecEnv`` of single envs made by ``gym.make``.

What is timed: ``model.learn(k rollouts)`` after one warm-up rollout + update (which also does
the env reset SB3 starts with). A ``VecEnvWrapper`` clocks the env's ``step`` and a callback
clocks the rollouts, which splits ``learn`` into env time, the rest of the rollout (policy
forward, buffer, SB3 bookkeeping) and the update. SB3 and torch are imported on first use: the
other sections run without them, and their absence becomes an error in every row here.
"""

from __future__ import annotations

import functools
import math
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from bench.config import DEFAULT_OBSTACLES, ID_2D
from bench.harness import NAN_RANGE, drop_rates, interleave, paired_ratio, pin_torch

FORWARD_CALLS = 20
"""Policy forward passes averaged for ``forward_ms``."""


@dataclass
class TrainMeasurement:
    """SB3 PPO on one VecEnv: built and warmed up once, then ``model.learn`` once per repeat."""

    backend: str  # "NativeVecEnv" or "DummyVecEnv"
    num_envs: int
    timers: tuple[type, type] | None = None  # (VecEnv wrapper, callback) of :func:`sb3_timers`
    n_steps: int = 0
    batch_size: int = 0
    n_epochs: int = 0
    rollouts: int = 0  # rollouts (+ updates) per repeat
    walls: list[float] = field(default_factory=list)  # learn() seconds per repeat
    rollout_s: list[float] = field(default_factory=list)  # inside collect_rollouts
    env_s: list[float] = field(default_factory=list)  # inside the VecEnv's step
    ends: list[int] = field(default_factory=list)  # episodes ended per repeat
    build_s: float = math.nan
    warmup_s: float = math.nan
    forward_ms: float = math.nan  # policy forward pass on N observations
    error: str | None = None
    model: Any = None
    timed: Any = None
    clock: Any = None

    def describe(self) -> str:
        return f"{self.backend} N={self.num_envs}"

    def set_up(self) -> None:
        """Build the VecEnv and PPO, run one warm-up ``learn``, time the policy forward pass."""
        torch = pin_torch()
        from stable_baselines3 import PPO
        from stable_baselines3.common.utils import obs_as_tensor
        from stable_baselines3.common.vec_env import DummyVecEnv

        from debris_gym.integrations.sb3 import NativeVecEnv

        if self.timers is None:
            raise ValueError("timers must be the classes of sb3_timers(), got None")
        timed_cls, clock_cls = self.timers
        start = time.perf_counter()
        if self.backend == "NativeVecEnv":
            venv = NativeVecEnv(ID_2D, num_envs=self.num_envs)
        else:
            venv = DummyVecEnv([functools.partial(gym.make, ID_2D)] * self.num_envs)
        self.timed = timed_cls(venv)
        self.clock = clock_cls()
        self.model = PPO(
            "MlpPolicy",
            self.timed,
            n_steps=self.n_steps,
            batch_size=self.batch_size,
            n_epochs=self.n_epochs,
            device="cpu",
            seed=0,
            verbose=0,
        )
        self.build_s = time.perf_counter() - start
        start = time.perf_counter()
        self.model.learn(self.n_steps * self.num_envs)  # the env reset, first torch calls
        self.warmup_s = time.perf_counter() - start
        obs = obs_as_tensor(self.model._last_obs, self.model.device)
        with torch.no_grad():
            self.model.policy(obs)
            start = time.perf_counter()
            for _ in range(FORWARD_CALLS):
                self.model.policy(obs)
        self.forward_ms = 1e3 * (time.perf_counter() - start) / FORWARD_CALLS

    def measure(self, round_index: int = 0) -> None:
        self.timed.seconds, self.timed.ends = 0.0, 0
        self.clock.seconds = 0.0
        total = self.rollouts * self.n_steps * self.num_envs
        start = time.perf_counter()
        self.model.learn(total, reset_num_timesteps=False, callback=self.clock)
        self.walls.append(time.perf_counter() - start)
        self.rollout_s.append(self.clock.seconds)
        self.env_s.append(self.timed.seconds)
        self.ends.append(self.timed.ends)

    def tear_down(self) -> None:
        model, self.model, self.timed, self.clock = self.model, None, None, None
        if model is not None:
            model.get_env().close()


def sb3_timers() -> tuple[type, type]:
    """A VecEnv wrapper timing ``step`` and a callback timing rollouts.

    Built here rather than at module level so that SB3 is imported only when this section runs.

    Raises:
        ImportError: stable-baselines3 (or torch) is not installed.
    """
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class TimedVecEnv(VecEnvWrapper):
        """Adds up the time spent in step_async + step_wait and the episodes that ended."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.seconds, self.ends, self._start = 0.0, 0, 0.0

        def reset(self) -> Any:
            return self.venv.reset()

        def step_async(self, actions: np.ndarray) -> None:
            self._start = time.perf_counter()
            self.venv.step_async(actions)

        def step_wait(self) -> Any:
            obs, rewards, dones, infos = self.venv.step_wait()
            self.seconds += time.perf_counter() - self._start
            self.ends += int(np.count_nonzero(dones))
            return obs, rewards, dones, infos

    class RolloutClock(BaseCallback):
        """Adds up the time between on_rollout_start and on_rollout_end."""

        def __init__(self) -> None:
            super().__init__()
            self.seconds, self._start = 0.0, 0.0

        def _on_rollout_start(self) -> None:
            self._start = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.seconds += time.perf_counter() - self._start

        def _on_step(self) -> bool:
            return True

    return TimedVecEnv, RolloutClock


def train_measurements(
    cfg: dict[str, Any], timers: tuple[type, type] | None = None
) -> list[TrainMeasurement]:
    """One measurement per ``train_envs`` N on ``NativeVecEnv``, then the ``DummyVecEnv`` one.

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike): ``train_envs``, ``dummy_envs``,
            ``train_rollout`` (env-steps per rollout; ``n_steps`` = rollout / N),
            ``train_batch``, ``train_epochs`` and ``train_rollouts`` (per repeat).
        timers: the classes of :func:`sb3_timers` (None: the measurements cannot be set up).
    """
    backends = [("NativeVecEnv", int(n)) for n in cfg["train_envs"]]
    backends.append(("DummyVecEnv", int(cfg["dummy_envs"])))
    out = []
    for backend, num_envs in backends:
        n_steps = max(2, int(cfg["train_rollout"]) // num_envs)
        m = TrainMeasurement(
            backend,
            num_envs,
            timers,
            n_steps=n_steps,
            batch_size=min(int(cfg["train_batch"]), n_steps * num_envs),
            n_epochs=int(cfg["train_epochs"]),
            rollouts=int(cfg["train_rollouts"]),
        )
        out.append(m)
    return out


def run_train(cfg: dict[str, Any], n_repeats: int, progress: bool) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`train_rows`)."""
    try:
        timers = sb3_timers()
    except ImportError as exc:  # SB3 / torch missing: every row says so
        todo = train_measurements(cfg)
        for m in todo:
            m.error = f"{type(exc).__name__}: {exc}"
        return train_rows(todo)
    todo = train_measurements(cfg, timers)
    interleave(todo, n_repeats, "train", progress)
    return train_rows(todo)


def train_rows(todo: list[TrainMeasurement]) -> list[dict[str, Any]]:
    """One row per training measurement.

    Fields: ``num_envs``, ``n_steps``, ``batch_size``, ``n_epochs``, ``rollouts`` (timed rollouts
    + updates per repeat), ``timesteps`` (env-steps per repeat), ``repeats``, ``env_steps_per_s``
    (end to end, median over repeats) and ``env_steps_per_s_best``, ``env_share`` /
    ``policy_share`` / ``update_share`` (median fractions of ``learn`` time spent in the VecEnv's
    step, in the rest of the rollout — policy forward, buffer, SB3 bookkeeping — and in the
    update), ``rollout_env_steps_per_s`` (timesteps / rollout time), ``env_only_steps_per_s``
    (timesteps / VecEnv step time), ``forward_ms`` (one policy forward on N observations),
    ``ends_per_1000``, ``build_s`` and ``warmup_s`` (s), ``ratio_dummy`` (end-to-end
    env-steps/s over the DummyVecEnv row's, with the paired range) and ``error``.
    """
    rows = []
    med = statistics.median
    for m in todo:
        steps = m.rollouts * m.n_steps * m.num_envs
        rates = [steps / w for w in m.walls if w > 0]

        def share(part: list[float], walls: list[float] = m.walls) -> float:
            fractions = [p / w for p, w in zip(part, walls, strict=False) if w > 0]
            return statistics.median(fractions) if fractions else math.nan

        policy = [r - e for r, e in zip(m.rollout_s, m.env_s, strict=False)]
        update = [w - r for w, r in zip(m.walls, m.rollout_s, strict=False)]
        row: dict[str, Any] = {
            "section": "train",
            "env_id": ID_2D,
            "variant": m.backend,
            "level": m.backend,
            "n_obstacles": DEFAULT_OBSTACLES,
            "num_envs": m.num_envs,
            "n_steps": m.n_steps,
            "batch_size": m.batch_size,
            "n_epochs": m.n_epochs,
            "rollouts": m.rollouts,
            "timesteps": steps,
            "repeats": len(rates),
            "env_steps_per_s": med(rates) if rates else math.nan,
            "env_steps_per_s_best": max(rates) if rates else math.nan,
            "env_share": share(m.env_s),
            "policy_share": share(policy),
            "update_share": share(update),
            "rollout_env_steps_per_s": med([steps / r for r in m.rollout_s if r > 0])
            if m.rollout_s
            else math.nan,
            "env_only_steps_per_s": med([steps / e for e in m.env_s if e > 0])
            if m.env_s
            else math.nan,
            "forward_ms": m.forward_ms,
            "ends_per_1000": 1000.0 * sum(m.ends) / (steps * len(m.ends)) if m.ends else math.nan,
            "build_s": m.build_s,
            "warmup_s": m.warmup_s,
            "ratio_dummy": math.nan,
            "ratio_dummy_range": NAN_RANGE,
            "error": m.error,
            "_rates": rates,
        }
        rows.append(row)
    dummy = next((r for r in rows if r["level"] == "DummyVecEnv"), None)
    for row in rows:
        if row is not dummy:
            paired_ratio(row, dummy, "ratio_dummy")
    return drop_rates(rows)
