"""Section ``vector``: env-steps/s of the native vector env next to other ways to batch envs.

The native vector env (``gym.make_vec(..., vectorization_mode="vector_entry_point")``) at several
N, next to gymnasium's ``SyncVectorEnv``, SB3's ``SubprocVecEnv`` (one process per env) and
CartPole-v1's native vector env; the 3D env and lidar observations at one N; and, where numba may
use two threads, the default env stepped by two threads.

What is timed: ``venv.step(actions)`` with actions pre-generated as for the single env, one
(N, …) batch per step: gentle thrusts, and for the default 2D env and its v1 world (native at
CartPole's N, and ``SyncVectorEnv``) also uniformly random actions (rows ``actions=random``),
which end episodes several times as often. Autoresets happen inside ``step`` and are part of
the time (they cannot be clocked apart); the rows count the episodes that ended in the timed
windows. Every vector env first runs ``warmup_steps`` steps from ``reset(seed=0)``, so the
timed windows are in the steady state where episodes end and restart all the time: all
sub-envs start at the dock together, and no episode ends before the first missions have run
their course.

The :class:`VecMeasurement` and the row builder here also serve the ``scaling`` section
(:mod:`bench.scaling`).
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

from bench.config import CARTPOLE, ID_2D, ID_3D, ID_V1, MAX_VECTOR_STEPS, MIN_VECTOR_STEPS
from bench.harness import (
    NAN_RANGE,
    RANDOM,
    calibrated,
    draw_actions,
    drop_rates,
    interleave,
    paired_ratio,
    pin_torch,
)

CALIBRATION_STEPS = 20
"""The last warm-up steps, at most this many, are timed to calibrate the steps per repeat."""


@dataclass
class VecMeasurement:
    """One vector env to time: built and warmed up once, then timed once per repeat."""

    section: str  # "vector" or "vector_scaling"
    backend: str  # "native" (vector_entry_point), "sync" (SyncVectorEnv), "subproc" (SB3)
    env_id: str
    num_envs: int
    kwargs: dict[str, Any] = field(default_factory=dict)
    label: str = ""
    n_obstacles: int | None = None
    action_kind: str = "gentle"  # bench.harness.ACTION_KINDS
    warmup: int = 1  # untimed steps after reset(seed=0)
    fixed: int | None = None  # vector steps per repeat; None: calibrated to ``seconds``
    seconds: float = 0.0  # wall time a calibrated repeat aims at
    max_count: int = MAX_VECTOR_STEPS  # most vector steps per calibrated repeat
    count: int = 0  # vector steps per repeat
    times: list[float] = field(default_factory=list)  # seconds per repeat
    ends: list[int] = field(default_factory=list)  # episodes ended per repeat
    warmup_steps: int = 0
    warmup_ends: int = 0
    build_s: float = math.nan
    reset_s: float = math.nan  # the first reset(seed=0) of all sub-envs
    error: str | None = None
    env: Any = None
    actions: Any = None

    def describe(self) -> str:
        extra = self.label or (f"n={self.n_obstacles}" if self.n_obstacles is not None else "")
        parts = (self.backend, self.env_id, extra, f"N={self.num_envs}")
        return " ".join(x for x in parts if x)

    def set_up(self) -> None:
        """Build and reset the env, run the warm-up, fix the steps per repeat, draw the actions."""
        clock = time.perf_counter
        start = clock()
        self.env = self._make()
        self.build_s = clock() - start
        start = clock()
        if self.backend == "subproc":
            self.env.seed(0)
            self.env.reset()
        else:
            self.env.reset(seed=0)
        self.reset_s = clock() - start
        rng = np.random.default_rng(12345)
        warm = self.warmup
        actions = self._actions(warm, rng)
        tail = min(warm, CALIBRATION_STEPS)
        ends = self._loop(actions[:-tail])[1] if warm > tail else 0
        t, tail_ends = self._loop(actions[-tail:])
        self.warmup_steps, self.warmup_ends = warm, ends + tail_ends
        if self.fixed is not None:
            self.count = self.fixed
        else:
            low = min(MIN_VECTOR_STEPS, self.max_count)
            self.count = calibrated(t / tail, self.seconds, low, self.max_count)
        self.actions = self._actions(self.count, rng)

    def measure(self, round_index: int = 0) -> None:
        t, ends = self._loop(self.actions)
        self.times.append(t)
        self.ends.append(ends)

    def tear_down(self) -> None:
        env, self.env, self.actions = self.env, None, None
        if env is not None:
            env.close()

    def _make(self) -> Any:
        if self.backend == "subproc":
            from stable_baselines3.common.vec_env import SubprocVecEnv

            pin_torch()
            # "module:ID" so every worker registers the IDs; a partial pickles by reference
            make = functools.partial(gym.make, f"debris_gym:{self.env_id}", **self.kwargs)
            return SubprocVecEnv([make] * self.num_envs)
        mode = "vector_entry_point" if self.backend == "native" else "sync"
        return gym.make_vec(
            self.env_id, num_envs=self.num_envs, vectorization_mode=mode, **self.kwargs
        )

    def _actions(self, steps: int, rng: np.random.Generator) -> np.ndarray:
        """(steps, N, …) actions, drawn as for the single env."""
        env = self.env
        space = env.action_space if self.backend == "subproc" else env.single_action_space
        return draw_actions(space, self.env_id, (steps, self.num_envs), rng, self.action_kind)

    def _loop(self, actions: np.ndarray) -> tuple[float, int]:
        """Step through ``actions``; returns (seconds, episodes ended). Counting is not timed."""
        step, clock = self.env.step, time.perf_counter
        flags: list[Any] = []
        add = flags.append
        if self.backend == "subproc":  # SB3 API: (obs, rewards, dones, infos)
            start = clock()
            for action in actions:
                add(step(action)[2])
            elapsed = clock() - start
            return elapsed, int(sum(np.count_nonzero(f) for f in flags))
        start = clock()
        for action in actions:
            _, _, terminated, truncated, _ = step(action)
            add((terminated, truncated))
        elapsed = clock() - start
        return elapsed, int(sum(np.count_nonzero(np.logical_or(a, b)) for a, b in flags))


def numba_threads() -> int:
    """Threads numba may use (the ``num_threads`` limit of the native vector env)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def vector_measurements(cfg: dict[str, Any], steps: int | None = None) -> list[VecMeasurement]:
    """The vector-throughput measurement list, in the order they are interleaved.

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike).
        steps: fixed vector steps per repeat (default: calibrated to ``cfg["vector_seconds"]``).
    """

    def vec(
        backend: str,
        env_id: str,
        num_envs: int,
        kwargs: dict[str, Any] | None = None,
        label: str = "",
        action_kind: str = "gentle",
    ) -> VecMeasurement:
        high = cfg["sync_max_steps"] if backend == "sync" else MAX_VECTOR_STEPS
        return VecMeasurement(
            "vector",
            backend,
            env_id,
            num_envs,
            kwargs or {},
            label,
            action_kind=action_kind,
            warmup=max(1, cfg["warmup_steps"]),
            fixed=steps,
            seconds=cfg["vector_seconds"],
            max_count=high,
        )

    out = [vec("native", CARTPOLE, cfg["cartpole_envs"])]
    out += [vec("native", ID_2D, n) for n in cfg["vector_envs"]]
    # uniformly random actions, as an exploring policy gives them: episodes end often
    for env_id in (ID_2D, ID_V1):
        out.append(vec("native", env_id, cfg["cartpole_envs"], label=RANDOM, action_kind="random"))
    n = cfg["vector_variant_envs"]
    out.append(vec("native", ID_3D, n))
    out.append(vec("native", ID_2D, n, {"observation": "lidar"}, "observation=lidar"))
    threads = min(2, numba_threads())
    if threads > 1:  # the same env stepped by 2 threads (CartPole and Sync use one)
        kw = {"num_threads": threads}
        for num in dict.fromkeys((cfg["cartpole_envs"], cfg["vector_envs"][-1])):
            out.append(vec("native", ID_2D, num, kw, f"num_threads={threads}"))
    out.append(vec("sync", ID_2D, cfg["sync_envs"]))
    for env_id in (ID_2D, ID_V1):
        out.append(vec("sync", env_id, cfg["sync_envs"], label=RANDOM, action_kind="random"))
    out += [vec("subproc", ID_2D, n) for n in cfg["subproc_envs"]]
    return out


def run_vector(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`vector_rows`)."""
    todo = vector_measurements(cfg, steps)
    interleave(todo, n_repeats, "vector", progress)
    rows = vector_rows(todo)
    cartpole = next((r for r in rows if r["env_id"] == CARTPOLE), None)
    syncs = {
        (r["env_id"], r["actions"]): r
        for r in rows
        if r["level"] == "sync" and r["variant"] in ("", RANDOM)
    }
    for row in rows:
        if row["env_id"] == CARTPOLE:
            continue
        if row["level"] == "native":
            paired_ratio(row, cartpole, "ratio_cartpole")
        default_env = row["variant"] in ("", RANDOM) or row["variant"].startswith("num_threads=")
        if row["env_id"] in (ID_2D, ID_V1) and default_env and row["level"] != "sync":
            paired_ratio(row, syncs.get((row["env_id"], row["actions"])), "ratio_sync")
    return drop_rates(rows)


def vector_rows(todo: list[VecMeasurement]) -> list[dict[str, Any]]:
    """One row per vector measurement, ratios not yet filled in.

    Fields: ``section``, ``env_id``, ``variant``, ``level`` (the backend), ``actions``
    (:data:`bench.harness.ACTION_KINDS`; a random row is compared with the random
    SyncVectorEnv row), ``n_obstacles``,
    ``field_size`` (m), ``num_envs``, ``count`` (vector steps per repeat), ``repeats``,
    ``warmup_steps``, ``env_steps_per_s`` (median over repeats) and ``env_steps_per_s_best``,
    ``us_per_env_step`` (median), ``ends_per_1000`` (episodes ended per 1000 env-steps in the
    timed windows), ``warmup_ends_per_1000``, ``build_s``, ``reset_ms_per_env`` (first
    ``reset(seed=0)`` / N), ``error``, and the ratios of env-steps/s with their paired
    (same-round) ranges, NaN here: ``ratio_cartpole`` (DebrisGym native rows / CartPole native),
    ``ratio_sync`` (2D default rows / SyncVectorEnv) and, for the scaling section, ``ratio``
    (the *cost* per env-step relative to 20 debris at the same N). ``_rates`` holds the
    env-steps/s per repeat for the ratios; :func:`bench.harness.drop_rates` removes it.
    """
    rows = []
    for m in todo:
        env_steps = m.count * m.num_envs
        rates = [env_steps / t for t in m.times if t > 0]
        median = statistics.median(rates) if rates else math.nan
        row: dict[str, Any] = {
            "section": m.section,
            "env_id": m.env_id,
            "variant": m.label,
            "level": m.backend,
            "actions": m.action_kind,
            "n_obstacles": m.n_obstacles,
            "field_size": m.kwargs.get("field_size"),
            "num_envs": m.num_envs,
            "count": m.count,
            "repeats": len(rates),
            "warmup_steps": m.warmup_steps,
            "env_steps_per_s": median,
            "env_steps_per_s_best": max(rates) if rates else math.nan,
            "us_per_env_step": 1e6 / median if rates else math.nan,
            "ends_per_1000": 1000.0 * sum(m.ends) / (env_steps * len(rates)) if rates else math.nan,
            "warmup_ends_per_1000": 1000.0 * m.warmup_ends / (m.warmup_steps * m.num_envs)
            if m.warmup_steps
            else math.nan,
            "build_s": m.build_s,
            "reset_ms_per_env": 1e3 * m.reset_s / m.num_envs,
            "ratio": math.nan,
            "ratio_range": NAN_RANGE,
            "ratio_cartpole": math.nan,
            "ratio_cartpole_range": NAN_RANGE,
            "ratio_sync": math.nan,
            "ratio_sync_range": NAN_RANGE,
            "error": m.error,
            "_rates": rates,
        }
        rows.append(row)
    return rows
