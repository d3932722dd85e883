"""Step and reset throughput of the DebrisGym environments, relative to CartPole-v1.

Run as a script::

    python bench/run.py                       # every section (~5 min on a 2-core machine)
    python bench/run.py --quick               # ~1-3 min, fewer / shorter repeats, smaller N
    python bench/run.py --only vector,train   # some sections only
    python bench/run.py --out docs/bench_table.md

Sections (``--only`` takes a comma-separated list; default: all of them):

* ``single``: the single env. Step cost against CartPole-v1 (``gym.make`` and unwrapped), step
  cost against the debris count, reset cost. Row sections "step", "scaling", "reset".
* ``vector``: env-steps/s of the native vector env (``gym.make_vec(...,
  vectorization_mode="vector_entry_point")``) at several N, next to gymnasium's SyncVectorEnv,
  SB3's SubprocVecEnv and CartPole-v1's native vector env. Row section "vector".
* ``scaling``: the native vector env against the debris count. Row section "vector_scaling".
* ``memory``: bytes of state per sub-env: numpy arrays held by the env, Python objects, and
  process RSS growth (measured in fresh subprocesses). Row section "memory".
* ``train``: end-to-end SB3 PPO env-steps/s on ``NativeVecEnv`` and on a ``DummyVecEnv`` of
  single envs, split into env time, the rest of the rollout, and the update. Row section "train".
* ``decisions``: decision times (p50 / p95 / max ms per ``predict`` call) of every baseline and
  the pretrained policy flying the default evaluation's first missions, and the p50 in single
  env steps. Row section "decisions".

Everything is measured in one process, in one run (the memory section in child processes, and
SubprocVecEnv steps its envs in its workers), and reported as *ratios* measured within that run:
absolute speeds on shared machines are noisy and only comparable inside a run. Within a section,
measurements are interleaved across repeats (A, B, C, A, B, C, …) so that machine noise hits them
alike; each cell reports the median and the best (minimum time) of the repeats.

What is timed:

* Step rows: ``env.step(a)`` over pre-generated valid actions (small random thrusts, uniform in
  [-0.05, 0.05] of ``max_accel``, for continuous DebrisGym envs; mostly coasting for discrete
  ones; uniform {0, 1} for CartPole), both through ``gym.make`` (default wrappers) and on
  ``env.unwrapped``. On termination / truncation the env is reset; the step that ended the
  episode counts as a step, but the time spent *inside* ``reset()`` is excluded from the step
  time (the clock is stopped around it). "steps/s incl. resets" is the plain wall-clock rate with
  the resets included. Resets are costed separately in the reset table.
* Scaling rows: the unwrapped 2D env with ``n_obstacles`` debris in a field whose edge grows as
  ``1000 m * sqrt(max(1, n / 20))`` (constant debris density), relative to the 20-debris default.
* Reset rows: ``env.reset()`` through ``gym.make``; a random-field env draws a new field (and
  checks it is solvable) on every reset.
* Vector rows: ``venv.step(actions)`` with actions pre-generated as for the single env, one
  (N, …) batch per step. Autoresets happen inside ``step`` and are part of the time (they cannot
  be clocked apart); the table gives how many episodes ended per 1000 env-steps in the timed
  windows. Every vector env first runs the same number of warm-up steps from ``reset(seed=0)``
  (250; 150 with ``--quick``) so the timed windows are in the steady state where episodes end
  and restart all the time (all sub-envs start at the dock together, and the first episodes
  end only after about 100 steps).
* Vector scaling rows: the native vector env right after ``reset(seed=0)`` (a few warm-up steps,
  then at most ``early_steps`` steps in all), i.e. the *step* cost with (almost) no autoresets,
  next to the reset cost per sub-env timed on that ``reset``; relative to 20 debris at the same N.
* Memory rows: a fresh ``python bench/run.py --memory-child N`` builds and resets an N-env
  native vector env and reports its arrays and its RSS growth (``/proc/self/statm``).
* Train rows: ``model.learn(k rollouts)`` of SB3 PPO (default ``MlpPolicy``, CPU, one torch
  thread) after one warm-up rollout+update (which also does the env reset SB3 starts with).
* Decision rows: ``agent.predict`` calls inside :func:`agents.evaluation.run_episode` (the
  loop of ``evaluate.py``), every agent on the same seeded missions, one mission of each agent
  in turn, with a block of plain ``env.step`` calls (as in the step rows) timed before each
  round as the reference; untimed warm-up calls on another mission first.

The number of steps (resets) per repeat is calibrated per measurement during a warm-up so every
repeat lasts about the same wall time, unless fixed with ``run(steps=…, resets=…)``.
"""

from __future__ import annotations

import argparse
import functools
import gc
import hashlib
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import debris_gym
from debris_gym.files import write_atomic

if "torch" in sys.modules:  # only pin threads if something imported it
    sys.modules["torch"].set_num_threads(1)

DEBRIS_IDS = tuple(debris_gym.ENV_SPECS)
CARTPOLE = "CartPole-v1"
ID_2D = "DebrisGym/Rendezvous2D-v0"
ID_3D = "DebrisGym/Rendezvous3D-v0"
SCALING_COUNTS = (10, 50, 200, 1000)
DEFAULT_OBSTACLES = 20
THRUST = 0.05  # continuous actions are uniform in [-THRUST, THRUST] (fraction of max_accel)
DISCRETE_COAST = 0.9  # share of coast (0) actions for discrete DebrisGym envs

SECTIONS = ("single", "vector", "scaling", "memory", "train", "decisions")
"""Section names for ``--only`` / ``run(sections=…)``, in the order they run."""

QUICK: dict[str, Any] = {
    # single env
    "repeats": 3,
    "step_seconds": 0.12,
    "reset_seconds": 0.1,
    "min_steps": 50,
    # vector env: N values, warm-up steps from reset, seconds per repeat
    "vector_envs": (64, 1024),
    "vector_variant_envs": 256,  # Rendezvous3D and observation=lidar rows
    "sync_envs": 64,
    "subproc_envs": (2, 8),
    "cartpole_envs": 1024,
    "warmup_steps": 150,
    "vector_seconds": 0.25,
    "sync_max_steps": 20,
    # vector scaling: (n_obstacles, N); a 20-debris row is added for every N
    "scaling_rows": ((10, 256), (50, 256), (200, 64), (1000, 16)),
    "scaling_seconds": 0.15,
    "early_steps": 45,
    # memory: (small N, large N)
    "memory_envs": (64, 1024),
    # training
    "train_envs": (64, 256),
    "dummy_envs": 8,
    "train_rollout": 8192,  # env-steps per rollout (n_steps = rollout / N)
    "train_rollouts": 1,  # timed rollouts+updates per repeat
    "train_repeats": 1,
    "train_batch": 4096,
    "train_epochs": 2,
    # decision times: missions per agent (seeds DECISION_SEED …), time limit (None: the env's)
    "decision_episodes": 1,
    "decision_max_steps": None,
}
FULL: dict[str, Any] = {
    **QUICK,
    "repeats": 5,
    "step_seconds": 0.9,
    "reset_seconds": 0.6,
    "min_steps": 200,
    "vector_envs": (64, 256, 1024, 4096),
    "vector_variant_envs": 1024,
    "warmup_steps": 250,
    "vector_seconds": 0.8,
    "sync_max_steps": 60,
    "scaling_rows": ((10, 1024), (50, 1024), (200, 1024), (1000, 256)),
    "scaling_seconds": 0.5,
    "early_steps": 60,
    "memory_envs": (64, 4096),
    "train_rollout": 16384,
    "train_rollouts": 3,
    "train_repeats": 2,
    "decision_episodes": 3,
}
TINY: dict[str, Any] = {
    "vector_envs": (4,),
    "vector_variant_envs": 4,
    "sync_envs": 4,
    "subproc_envs": (2,),
    "cartpole_envs": 4,
    "warmup_steps": 3,
    "scaling_rows": ((10, 4), (50, 4), (200, 2), (1000, 2)),
    "early_steps": 30,
    "memory_envs": (2, 6),
    "train_envs": (4,),
    "dummy_envs": 2,
    "train_rollout": 256,
    "train_rollouts": 1,
    "train_repeats": 1,
    "train_batch": 64,
    "train_epochs": 1,
    "decision_episodes": 1,
    "decision_max_steps": 5,
}
"""Sizes for smoke tests (``run(sizes=TINY)``): every code path, seconds not minutes."""

MAX_STEPS = 300_000
MAX_RESETS = 20_000
MAX_VECTOR_STEPS = 4000
MIN_VECTOR_STEPS = 3


def field_size_for(n_obstacles: int) -> float:
    """Field edge (m) for ``n_obstacles`` debris at the default density (20 per 1000 m square)."""
    return 1000.0 * math.sqrt(max(1.0, n_obstacles / DEFAULT_OBSTACLES))


# --- measurements ---------------------------------------------------------------------------------


@dataclass
class Measurement:
    """One thing to time: set up once, then timed once per repeat (interleaved with the others)."""

    section: str  # "step", "scaling" or "reset"
    label: str
    env_id: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    level: str = "make"  # "make" (default wrappers) or "unwrapped"
    n_obstacles: int | None = None
    count: int = 0  # steps (or resets) per repeat
    times: list[float] = field(default_factory=list)  # seconds per repeat, excluding resets
    walls: list[float] = field(default_factory=list)  # seconds per repeat, including resets
    resets: int = 0  # resets during step repeats
    reset_time: float = 0.0  # seconds spent in those resets
    error: str | None = None
    env: Any = None
    actions: list[Any] = field(default_factory=list)


def _make(m: Measurement) -> Any:
    env = gym.make(m.env_id, **m.kwargs)
    return env.unwrapped if m.level == "unwrapped" else env


def _actions(m: Measurement, n: int, rng: np.random.Generator) -> list[Any]:
    """``n`` valid actions, generated up front so sampling is not timed."""
    space = m.env.action_space
    if isinstance(space, gym.spaces.Discrete):
        if m.env_id != CARTPOLE:
            thrust = rng.integers(1, int(space.n), size=n)
            values = np.where(rng.random(n) < DISCRETE_COAST, 0, thrust)
        else:
            values = rng.integers(0, int(space.n), size=n)
        return [int(v) for v in values]
    assert isinstance(space, gym.spaces.Box)
    values = rng.uniform(-THRUST, THRUST, size=(n, *space.shape)).astype(space.dtype)
    return list(values)


def _step_loop(env: Any, actions: list[Any]) -> tuple[float, float, int]:
    """Step through ``actions``; returns (step seconds excluding resets, wall seconds, resets).

    The clock is read only around resets, not around every step, so the per-step overhead of
    the harness is one loop iteration and one tuple unpack (the same for every env).
    """
    step, reset, clock = env.step, env.reset, time.perf_counter
    stepping = 0.0
    resets = 0
    start = segment = clock()
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            now = clock()
            stepping += now - segment
            reset()
            resets += 1
            segment = clock()
    end = clock()
    return stepping + (end - segment), end - start, resets


def _reset_loop(env: Any, n: int) -> float:
    reset, clock = env.reset, time.perf_counter
    start = clock()
    for _ in range(n):
        reset()
    return clock() - start


def _calibrated(per_item: float, seconds: float, low: int, high: int) -> int:
    return int(min(high, max(low, round(seconds / max(per_item, 1e-9)))))


def _setup(m: Measurement, cfg: dict[str, Any], steps: int | None, resets: int | None) -> None:
    """Build the env, warm it up, fix the count per repeat and pre-generate the actions."""
    m.env = env = _make(m)
    env.reset(seed=0)
    rng = np.random.default_rng(12345)
    if m.section == "reset":
        per = _reset_loop(env, 3) / 3
        m.count = (
            resets if resets is not None else _calibrated(per, cfg["reset_seconds"], 3, MAX_RESETS)
        )
        return
    warm = 200 if steps is None else min(steps, 20)
    t, _, _ = _step_loop(env, _actions(m, warm, rng))
    if steps is not None:
        m.count = steps
    else:
        m.count = _calibrated(t / warm, cfg["step_seconds"], cfg["min_steps"], MAX_STEPS)
    m.actions = _actions(m, m.count, rng)
    env.reset(seed=1)


def _measure(m: Measurement) -> None:
    if m.section == "reset":
        t = _reset_loop(m.env, m.count)
        m.times.append(t)
        m.walls.append(t)
        return
    t, wall, r = _step_loop(m.env, m.actions)
    m.times.append(t)
    m.walls.append(wall)
    m.resets += r
    m.reset_time += wall - t


def measurements() -> list[Measurement]:
    """The measurement list, in the order they are interleaved."""
    out: list[Measurement] = []
    variants: list[tuple[str, str, dict[str, Any]]] = [(CARTPOLE, "", {})]
    variants += [(env_id, "", {}) for env_id in DEBRIS_IDS]
    variants += [(ID_2D, "observation=lidar", {"observation": "lidar"})]
    variants += [(ID_2D, "action=discrete", {"action": "discrete"})]
    for level in ("make", "unwrapped"):
        for env_id, label, kwargs in variants:
            out.append(Measurement("step", label, env_id, kwargs, level))
    for n in SCALING_COUNTS:
        kwargs = {"n_obstacles": n, "field_size": field_size_for(n)}
        out.append(Measurement("scaling", "", ID_2D, kwargs, "unwrapped", n_obstacles=n))
    for env_id in (*DEBRIS_IDS, CARTPOLE):
        out.append(Measurement("reset", "", env_id, {}, "make"))
    return out


# --- run ------------------------------------------------------------------------------------------


def run(
    quick: bool = False,
    steps: int | None = None,
    *,
    resets: int | None = None,
    repeats: int | None = None,
    progress: bool = True,
    sections: Iterable[str] | None = None,
    sizes: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Run every measurement of the chosen sections and return one row (dict) per measurement.

    Args:
        quick: fewer and shorter repeats, smaller N.
        steps: fixed steps per repeat for every step measurement, single-env and vector (default:
            calibrated so a repeat lasts about the same time for every env).
        resets: fixed resets per repeat for the reset measurements (default: calibrated).
        repeats: number of interleaved repeats (default 3 quick, 5 full; the training section
            uses ``train_repeats`` unless this is given).
        progress: show a tqdm bar on stderr.
        sections: names from :data:`SECTIONS` (default: all).
        sizes: overrides of the :data:`QUICK` / :data:`FULL` settings, e.g. :data:`TINY`.

    Single-env rows carry ``section`` ("step", "scaling", "reset"), ``env_id``, ``variant``,
    ``level``, ``count`` (steps or resets per repeat), ``repeats``, ``median_us`` / ``min_us``
    (µs per step or per reset, resets excluded from step time), ``steps_per_s`` (median),
    ``steps_per_s_wall`` (median, resets included), ``resets_per_1000``, ``loop_reset_ms`` (mean
    ms per reset done inside the step loop, at that wrapper level), ``ratio`` (cost relative to
    CartPole at the same wrapper level for "step" rows; relative to the 20-debris default for
    "scaling" rows) and ``error`` (None, or the message if the env could not be built or
    stepped). The other sections' rows ("vector", "vector_scaling", "memory", "train",
    "decisions") carry ``section``, ``env_id``, ``variant``, ``level``, ``n_obstacles``,
    ``error`` and their own fields (see :func:`_vector_rows`, :func:`_memory_row`,
    :func:`_train_rows` and :func:`_decision_rows`).
    """
    chosen = _sections(sections)
    cfg = dict(QUICK if quick else FULL)
    cfg.update(sizes or {})
    n_repeats = repeats if repeats is not None else cfg["repeats"]
    rows: list[dict[str, Any]] = []
    if "single" in chosen:
        rows += _run_single(cfg, n_repeats, steps, resets, progress)
    if "vector" in chosen:
        rows += _run_vector(vector_measurements(cfg), cfg, n_repeats, steps, progress)
    if "scaling" in chosen:
        rows += _run_vector(scaling_measurements(cfg), cfg, n_repeats, steps, progress)
    if "memory" in chosen:
        rows.append(_memory_row(cfg))
    if "train" in chosen:
        train_repeats = repeats if repeats is not None else cfg["train_repeats"]
        rows += _run_train(cfg, train_repeats, progress)
    if "decisions" in chosen:
        rows += _run_decisions(cfg, steps, progress)
    return rows


def _sections(sections: Iterable[str] | None) -> tuple[str, ...]:
    if sections is None:
        return SECTIONS
    chosen = tuple(s.strip() for s in sections if s.strip())
    unknown = sorted(set(chosen) - set(SECTIONS))
    if unknown or not chosen:
        raise ValueError(f"unknown section(s) {unknown}; choose from {', '.join(SECTIONS)}")
    return tuple(s for s in SECTIONS if s in chosen)


def _bar(total: int, desc: str, progress: bool) -> tqdm:
    return tqdm(
        total=total, desc=desc, unit="meas", file=sys.stderr, disable=not progress, leave=False
    )


def _run_single(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, resets: int | None, progress: bool
) -> list[dict[str, Any]]:
    """The single-env section: step, scaling and reset rows."""
    todo = measurements()
    with _bar(len(todo) * (n_repeats + 1), "single", progress) as bar:
        for m in todo:
            bar.set_postfix_str(f"setup {_name(m)}", refresh=False)
            _guard(m, lambda m=m: _setup(m, cfg, steps, resets))
            bar.update()
        for rep in range(n_repeats):
            for m in todo:
                bar.set_postfix_str(f"rep {rep + 1}/{n_repeats} {_name(m)}", refresh=False)
                if m.error is None:
                    _guard(m, lambda m=m: _measure(m))
                bar.update()
    for m in todo:
        if m.env is not None:
            m.env.close()
            m.env = None
        m.actions = []
    return _rows(todo)


def _guard(m: Any, fn: Callable[[], Any]) -> None:
    try:
        fn()
    except Exception as exc:  # report, don't hide: e.g. the field generator giving up
        m.error = f"{type(exc).__name__}: {exc}"


def _name(m: Measurement) -> str:
    extra = m.label or (f"n={m.n_obstacles}" if m.n_obstacles is not None else "")
    return " ".join(x for x in (m.env_id, extra, m.level) if x)


def _rows(todo: list[Measurement]) -> list[dict[str, Any]]:
    rows = []
    for m in todo:
        row: dict[str, Any] = {
            "section": m.section,
            "env_id": m.env_id,
            "variant": m.label,
            "level": m.level,
            "n_obstacles": m.n_obstacles,
            "field_size": m.kwargs.get("field_size"),
            "count": m.count,
            "repeats": len(m.times),
            "median_us": math.nan,
            "min_us": math.nan,
            "steps_per_s": math.nan,
            "steps_per_s_wall": math.nan,
            "resets_per_1000": math.nan,
            "loop_reset_ms": math.nan,
            "ratio": math.nan,
            "ratio_range": (math.nan, math.nan),
            "error": m.error,
            "_per_item": [],
        }
        if m.times and m.count:
            per = [t / m.count for t in m.times]
            row["_per_item"] = per
            row["median_us"] = statistics.median(per) * 1e6
            row["min_us"] = min(per) * 1e6
            if m.section != "reset":
                row["steps_per_s"] = 1.0 / statistics.median(per)
                row["steps_per_s_wall"] = m.count / statistics.median(m.walls)
                row["resets_per_1000"] = 1000.0 * m.resets / (m.count * len(m.times))
                if m.resets:
                    row["loop_reset_ms"] = 1e3 * m.reset_time / m.resets
        rows.append(row)
    _add_ratios(rows)
    for row in rows:
        del row["_per_item"]
    return rows


def _add_ratios(rows: list[dict[str, Any]]) -> None:
    """Cost ratios from medians; ``ratio_range`` = min/max over paired (same-repeat) ratios."""

    def find(section: str, env_id: str, level: str, variant: str = "") -> dict[str, Any] | None:
        for r in rows:
            if (r["section"], r["env_id"], r["level"], r["variant"]) == (
                section,
                env_id,
                level,
                variant,
            ):
                return r
        return None

    def fill(row: dict[str, Any], ref: dict[str, Any] | None) -> None:
        if ref is None or not row["_per_item"] or not ref["_per_item"]:
            return
        row["ratio"] = row["median_us"] / ref["median_us"]
        paired = [a / b for a, b in zip(row["_per_item"], ref["_per_item"], strict=False)]
        row["ratio_range"] = (min(paired), max(paired))

    for row in rows:
        if row["section"] == "step":
            fill(row, find("step", CARTPOLE, row["level"]))
        elif row["section"] == "scaling":
            fill(row, find("step", ID_2D, "unwrapped"))
        elif row["section"] == "reset":
            fill(row, find("reset", CARTPOLE, "make"))


# --- report ---------------------------------------------------------------------------------------


# --- vector envs ----------------------------------------------------------------------------------


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


def vector_measurements(cfg: dict[str, Any]) -> list[VecMeasurement]:
    """The vector-throughput measurement list, in the order they are interleaved."""
    out = [VecMeasurement("vector", "native", CARTPOLE, cfg["cartpole_envs"])]
    out += [VecMeasurement("vector", "native", ID_2D, n) for n in cfg["vector_envs"]]
    n = cfg["vector_variant_envs"]
    out.append(VecMeasurement("vector", "native", ID_3D, n))
    lidar = {"observation": "lidar"}
    out.append(VecMeasurement("vector", "native", ID_2D, n, lidar, "observation=lidar"))
    threads = min(2, numba_threads())
    if threads > 1:  # the same env stepped by 2 threads (CartPole and Sync use one)
        kw = {"num_threads": threads}
        for num in dict.fromkeys((cfg["cartpole_envs"], cfg["vector_envs"][-1])):
            out.append(VecMeasurement("vector", "native", ID_2D, num, kw, f"num_threads={threads}"))
    out.append(VecMeasurement("vector", "sync", ID_2D, cfg["sync_envs"]))
    out += [VecMeasurement("vector", "subproc", ID_2D, n) for n in cfg["subproc_envs"]]
    return out


def numba_threads() -> int:
    """Threads numba may use (the ``num_threads`` limit of the native vector env)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def scaling_measurements(cfg: dict[str, Any]) -> list[VecMeasurement]:
    """Native vector env against the debris count; a 20-debris reference for every N."""
    pairs = [(int(n), int(num)) for n, num in cfg["scaling_rows"]]
    for num in dict.fromkeys(num for _, num in pairs):
        if (DEFAULT_OBSTACLES, num) not in pairs:
            pairs.append((DEFAULT_OBSTACLES, num))
    out = []
    for n, num in sorted(pairs, key=lambda p: (-p[1], p[0])):
        kwargs = {"n_obstacles": n, "field_size": field_size_for(n)}
        out.append(VecMeasurement("vector_scaling", "native", ID_2D, num, kwargs, n_obstacles=n))
    return out


def _pin_torch() -> Any:
    """Import torch with one thread (the measurements compare single-threaded work)."""
    import torch

    torch.set_num_threads(1)
    return torch


def _vec_make(m: VecMeasurement) -> Any:
    if m.backend == "subproc":
        from stable_baselines3.common.vec_env import SubprocVecEnv

        _pin_torch()
        # "module:ID" so every worker registers the IDs; a partial pickles by reference
        make = functools.partial(gym.make, f"debris_gym:{m.env_id}", **m.kwargs)
        return SubprocVecEnv([make] * m.num_envs)
    mode = "vector_entry_point" if m.backend == "native" else "sync"
    return gym.make_vec(m.env_id, num_envs=m.num_envs, vectorization_mode=mode, **m.kwargs)


def _vec_reset(m: VecMeasurement) -> None:
    if m.backend == "subproc":
        m.env.seed(0)
        m.env.reset()
    else:
        m.env.reset(seed=0)


def _vec_actions(m: VecMeasurement, steps: int, rng: np.random.Generator) -> np.ndarray:
    """(steps, N, …) actions, drawn as for the single env."""
    env = m.env
    space = env.action_space if m.backend == "subproc" else env.single_action_space
    n = m.num_envs
    if isinstance(space, gym.spaces.Discrete):
        if m.env_id == CARTPOLE:
            return rng.integers(0, int(space.n), size=(steps, n))
        thrust = rng.integers(1, int(space.n), size=(steps, n))
        return np.where(rng.random((steps, n)) < DISCRETE_COAST, 0, thrust)
    assert isinstance(space, gym.spaces.Box)
    return rng.uniform(-THRUST, THRUST, size=(steps, n, *space.shape)).astype(space.dtype)


def _vec_loop(m: VecMeasurement, actions: np.ndarray) -> tuple[float, int]:
    """Step through ``actions``; returns (seconds, episodes ended). Counting is not timed."""
    step, clock = m.env.step, time.perf_counter
    flags: list[Any] = []
    add = flags.append
    if m.backend == "subproc":  # SB3 API: (obs, rewards, dones, infos)
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


def _vec_setup(m: VecMeasurement, cfg: dict[str, Any], n_repeats: int, steps: int | None) -> None:
    """Build and reset the env, run the warm-up, fix the steps per repeat, draw the actions."""
    clock = time.perf_counter
    start = clock()
    m.env = _vec_make(m)
    m.build_s = clock() - start
    start = clock()
    _vec_reset(m)
    m.reset_s = clock() - start
    rng = np.random.default_rng(12345)
    early = m.section == "vector_scaling"
    warm = max(1, min(3, cfg["early_steps"]) if early else cfg["warmup_steps"])
    actions = _vec_actions(m, warm, rng)
    tail = min(warm, 20)  # the calibration times the end of the warm-up
    ends = _vec_loop(m, actions[:-tail])[1] if warm > tail else 0
    t, tail_ends = _vec_loop(m, actions[-tail:])
    m.warmup_steps, m.warmup_ends = warm, ends + tail_ends
    if steps is not None:
        m.count = steps
    else:
        seconds = cfg["scaling_seconds"] if early else cfg["vector_seconds"]
        high = MAX_VECTOR_STEPS
        if m.backend == "sync":
            high = cfg["sync_max_steps"]
        if early:  # stay in the first steps after reset, before episodes start to end
            high = max(1, (cfg["early_steps"] - warm) // max(n_repeats, 1))
        m.count = _calibrated(t / tail, seconds, min(MIN_VECTOR_STEPS, high), high)
    m.actions = _vec_actions(m, m.count, rng)


def _vec_measure(m: VecMeasurement) -> None:
    t, ends = _vec_loop(m, m.actions)
    m.times.append(t)
    m.ends.append(ends)


def _vec_name(m: VecMeasurement) -> str:
    extra = m.label or (f"n={m.n_obstacles}" if m.n_obstacles is not None else "")
    return " ".join(x for x in (m.backend, m.env_id, extra, f"N={m.num_envs}") if x)


def _run_vector(
    todo: list[VecMeasurement],
    cfg: dict[str, Any],
    n_repeats: int,
    steps: int | None,
    progress: bool,
) -> list[dict[str, Any]]:
    desc = todo[0].section if todo else "vector"
    try:
        with _bar(len(todo) * (n_repeats + 1), desc, progress) as bar:
            for m in todo:
                bar.set_postfix_str(f"setup {_vec_name(m)}", refresh=False)
                _guard(m, lambda m=m: _vec_setup(m, cfg, n_repeats, steps))
                bar.update()
            for rep in range(n_repeats):
                for m in todo:
                    bar.set_postfix_str(f"rep {rep + 1}/{n_repeats} {_vec_name(m)}", refresh=False)
                    if m.error is None:
                        _guard(m, lambda m=m: _vec_measure(m))
                    bar.update()
    finally:
        for m in todo:
            if m.env is not None:
                _guard(m, m.env.close)
                m.env = None
            m.actions = None
    return _vector_rows(todo)


def _vector_rows(todo: list[VecMeasurement]) -> list[dict[str, Any]]:
    """One row per vector measurement.

    Fields: ``num_envs``, ``count`` (vector steps per repeat), ``repeats``, ``warmup_steps``,
    ``env_steps_per_s`` (median over repeats) and ``env_steps_per_s_best``, ``us_per_env_step``
    (median), ``ends_per_1000`` (episodes ended per 1000 env-steps in the timed windows),
    ``build_s``, ``reset_ms_per_env`` (first ``reset(seed=0)`` / N), and ratios of env-steps/s
    with the paired (same-repeat) range: ``ratio_cartpole`` (DebrisGym native rows / CartPole
    native), ``ratio_sync`` (2D default rows / SyncVectorEnv); for "vector_scaling" rows
    ``ratio`` is the *cost* per env-step relative to 20 debris at the same N.
    """
    rows = []
    for m in todo:
        env_steps = m.count * m.num_envs
        rates = [env_steps / t for t in m.times if t > 0]
        row: dict[str, Any] = {
            "section": m.section,
            "env_id": m.env_id,
            "variant": m.label,
            "level": m.backend,
            "n_obstacles": m.n_obstacles,
            "field_size": m.kwargs.get("field_size"),
            "num_envs": m.num_envs,
            "count": m.count,
            "repeats": len(rates),
            "warmup_steps": m.warmup_steps,
            "env_steps_per_s": statistics.median(rates) if rates else math.nan,
            "env_steps_per_s_best": max(rates) if rates else math.nan,
            "us_per_env_step": 1e6 / statistics.median(rates) if rates else math.nan,
            "ends_per_1000": 1000.0 * sum(m.ends) / (env_steps * len(rates)) if rates else math.nan,
            "warmup_ends_per_1000": 1000.0 * m.warmup_ends / (m.warmup_steps * m.num_envs)
            if m.warmup_steps
            else math.nan,
            "build_s": m.build_s,
            "reset_ms_per_env": 1e3 * m.reset_s / m.num_envs,
            "ratio": math.nan,
            "ratio_range": (math.nan, math.nan),
            "ratio_cartpole": math.nan,
            "ratio_cartpole_range": (math.nan, math.nan),
            "ratio_sync": math.nan,
            "ratio_sync_range": (math.nan, math.nan),
            "error": m.error,
            "_rates": rates,
        }
        rows.append(row)
    cartpole = next((r for r in rows if r["env_id"] == CARTPOLE), None)
    sync = next((r for r in rows if r["level"] == "sync" and not r["variant"]), None)
    for row in rows:
        if row["section"] == "vector_scaling":
            ref = next(
                (r for r in rows if r["section"] == "vector_scaling"
                 and r["n_obstacles"] == DEFAULT_OBSTACLES and r["num_envs"] == row["num_envs"]),
                None,
            )  # fmt: skip
            _paired(row, ref, "ratio", cost=True)
            continue
        if row["env_id"] == CARTPOLE:
            continue
        if row["level"] == "native":
            _paired(row, cartpole, "ratio_cartpole")
        default_env = not row["variant"] or row["variant"].startswith("num_threads=")
        if row["env_id"] == ID_2D and default_env and row["level"] != "sync":
            _paired(row, sync, "ratio_sync")
    for row in rows:
        del row["_rates"]
    return rows


def _paired(row: dict[str, Any], ref: dict[str, Any] | None, key: str, cost: bool = False) -> None:
    """``row[key]`` = ratio of median rates (inverted if ``cost``), with the same-repeat range."""
    if ref is None or not row["_rates"] or not ref["_rates"]:
        return
    a, b = (ref, row) if cost else (row, ref)
    row[key] = a["env_steps_per_s"] / b["env_steps_per_s"]
    paired = [x / y for x, y in zip(a["_rates"], b["_rates"], strict=False)]
    row[key + "_range"] = (min(paired), max(paired))


# --- memory ---------------------------------------------------------------------------------------

OBSERVATION_BUFFERS = ("_obs",)
"""Array attributes of the native vector env that only hold the observation being built."""


def _rss_bytes() -> int:
    """Resident set size of this process (``/proc/self/statm``, second field × page size)."""
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _deep_size(root: Any) -> int:
    """Bytes of ``root`` and everything it references (containers, instance dicts, arrays).

    Objects shared between references are counted once; classes, modules and functions are not
    followed. Numpy arrays count their data (``sys.getsizeof`` includes it for owners).
    """
    skip = (type, type(sys), type(_deep_size), type(len))
    seen: set[int] = set()
    stack = [root]
    total = 0
    while stack:
        obj = stack.pop()
        if id(obj) in seen or isinstance(obj, skip):
            continue
        seen.add(id(obj))
        total += sys.getsizeof(obj)
        if isinstance(obj, np.ndarray):
            if obj.base is not None:
                stack.append(obj.base)
        elif isinstance(obj, dict):
            stack.extend(obj.keys())
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple, set, frozenset)):
            stack.extend(obj)
        elif isinstance(obj, np.random.Generator):
            stack.append(obj.bit_generator)
        else:
            if hasattr(obj, "__dict__"):
                stack.append(vars(obj))
            for slot in getattr(type(obj), "__slots__", ()):
                if hasattr(obj, slot):
                    stack.append(getattr(obj, slot))
    return total


def memory_child(num_envs: int, env_id: str = ID_2D) -> dict[str, Any]:
    """Build and reset an ``num_envs`` native vector env here; report its memory.

    Meant to run in a fresh process (``python bench/run.py --memory-child N``): a 1-env instance
    is built, reset, stepped and dropped first, so that imports and one-off caches are not
    counted; then RSS is read before building, after ``reset(seed=0)`` and after 10 steps.
    """
    warm = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    warm.reset(seed=0)
    warm.step(np.zeros((1, *warm.single_action_space.shape), dtype=np.float32))
    warm.close()
    del warm
    gc.collect()
    rss_before = _rss_bytes()
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    gc.collect()
    rss_reset = _rss_bytes()
    rng = np.random.default_rng(0)
    shape = (num_envs, *env.single_action_space.shape)
    for _ in range(10):
        env.step(rng.uniform(-THRUST, THRUST, size=shape).astype(np.float32))
    gc.collect()
    rss_steps = _rss_bytes()
    un = env.unwrapped
    arrays = []
    seen: set[int] = set()  # an array held by two attributes counts once
    for owner, obj in (("env", un), ("missions", un._missions), ("field", un._field)):
        for name, value in vars(obj).items():
            if isinstance(value, np.ndarray) and id(value) not in seen:
                seen.add(id(value))
                arrays.append(
                    {
                        "owner": owner,
                        "name": name,
                        "shape": list(value.shape),
                        "dtype": str(value.dtype),
                        "nbytes": int(value.nbytes),
                        "observation_buffer": owner == "env" and name in OBSERVATION_BUFFERS,
                    }
                )
    return {
        "num_envs": num_envs,
        "env_id": env_id,
        "n_bodies": int(un._field.n_bodies),
        "rss_before": rss_before,
        "rss_after_reset": rss_reset,
        "rss_after_steps": rss_steps,
        "arrays": arrays,
        "python_bytes": {
            "scenarios": _deep_size(list(un.scenarios)),
            "rngs": _deep_size(list(un._rngs)),
        },
    }


def _memory_child_run(num_envs: int) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--memory-child", str(num_envs)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, check=False)
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        raise RuntimeError(f"memory child N={num_envs} exited {done.returncode}: {tail[0]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _memory_row(cfg: dict[str, Any]) -> dict[str, Any]:
    """Bytes of state per sub-env of the native 2D vector env (20 debris).

    Fields: ``small_envs`` / ``large_envs`` (the two instance sizes, each built in a fresh
    process), ``rss_growth`` (N → bytes of RSS growth on build + reset), ``rss_per_env``
    ((growth at large N − growth at small N) / (large − small)), ``rss_steps_per_env`` (the same
    after 10 more steps), ``array_bytes_per_env`` (numpy arrays of the env, its MissionBatch and
    FieldBatch at
    the large N, observation buffers excluded, / N), ``obs_buffer_bytes_per_env``, ``arrays``
    (the large instance's arrays, biggest first), ``python_bytes_per_env`` (deep size of the
    ``scenarios`` and per-sub-env generators, / N) and ``error``.
    """
    small, large = (int(n) for n in cfg["memory_envs"])
    row: dict[str, Any] = {
        "section": "memory",
        "env_id": ID_2D,
        "variant": "",
        "level": "native",
        "n_obstacles": DEFAULT_OBSTACLES,
        "small_envs": small,
        "large_envs": large,
        "rss_growth": {},
        "rss_per_env": math.nan,
        "rss_steps_per_env": math.nan,
        "array_bytes_per_env": math.nan,
        "obs_buffer_bytes_per_env": math.nan,
        "arrays": [],
        "python_bytes_per_env": {},
        "n_bodies": None,
        "error": None,
    }
    try:
        children = {n: _memory_child_run(n) for n in (small, large)}
    except (OSError, RuntimeError, ValueError, subprocess.TimeoutExpired) as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    grow = {n: c["rss_after_reset"] - c["rss_before"] for n, c in children.items()}
    grow_steps = {n: c["rss_after_steps"] - c["rss_before"] for n, c in children.items()}
    big = children[large]
    arrays = sorted(big["arrays"], key=lambda a: -a["nbytes"])
    state = sum(a["nbytes"] for a in arrays if not a["observation_buffer"])
    obs = sum(a["nbytes"] for a in arrays if a["observation_buffer"])
    row.update(
        rss_growth=grow,
        rss_steps_growth=grow_steps,
        rss_per_env=(grow[large] - grow[small]) / (large - small),
        rss_steps_per_env=(grow_steps[large] - grow_steps[small]) / (large - small),
        array_bytes_per_env=state / large,
        obs_buffer_bytes_per_env=obs / large,
        arrays=arrays,
        python_bytes_per_env={k: v / large for k, v in big["python_bytes"].items()},
        n_bodies=big["n_bodies"],
    )
    return row


# --- training -------------------------------------------------------------------------------------


@dataclass
class TrainMeasurement:
    """SB3 PPO on one VecEnv: built and warmed up once, then ``model.learn`` once per repeat."""

    backend: str  # "NativeVecEnv" or "DummyVecEnv"
    num_envs: int
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


def _sb3_timers() -> tuple[type, type]:
    """A VecEnv wrapper timing ``step`` and a callback timing rollouts (SB3 imported lazily)."""
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


def train_measurements(cfg: dict[str, Any]) -> list[TrainMeasurement]:
    out = [TrainMeasurement("NativeVecEnv", int(n)) for n in cfg["train_envs"]]
    out.append(TrainMeasurement("DummyVecEnv", int(cfg["dummy_envs"])))
    return out


def _train_setup(m: TrainMeasurement, cfg: dict[str, Any], timers: tuple[type, type]) -> None:
    torch = _pin_torch()
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import obs_as_tensor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from debris_gym.integrations.sb3 import NativeVecEnv

    timed_cls, clock_cls = timers
    m.n_steps = max(2, int(cfg["train_rollout"]) // m.num_envs)
    rollout = m.n_steps * m.num_envs
    m.batch_size = min(int(cfg["train_batch"]), rollout)
    m.n_epochs = int(cfg["train_epochs"])
    m.rollouts = int(cfg["train_rollouts"])
    start = time.perf_counter()
    if m.backend == "NativeVecEnv":
        venv = NativeVecEnv(ID_2D, num_envs=m.num_envs)
    else:
        venv = DummyVecEnv([functools.partial(gym.make, ID_2D)] * m.num_envs)
    m.timed = timed_cls(venv)
    m.clock = clock_cls()
    m.model = PPO(
        "MlpPolicy",
        m.timed,
        n_steps=m.n_steps,
        batch_size=m.batch_size,
        n_epochs=m.n_epochs,
        device="cpu",
        seed=0,
        verbose=0,
    )
    m.build_s = time.perf_counter() - start
    start = time.perf_counter()
    m.model.learn(rollout)  # warm-up: the env reset SB3 starts with, first torch calls
    m.warmup_s = time.perf_counter() - start
    obs = obs_as_tensor(m.model._last_obs, m.model.device)
    calls = 20
    with torch.no_grad():
        m.model.policy(obs)
        start = time.perf_counter()
        for _ in range(calls):
            m.model.policy(obs)
    m.forward_ms = 1e3 * (time.perf_counter() - start) / calls


def _train_measure(m: TrainMeasurement) -> None:
    m.timed.seconds, m.timed.ends = 0.0, 0
    m.clock.seconds = 0.0
    total = m.rollouts * m.n_steps * m.num_envs
    start = time.perf_counter()
    m.model.learn(total, reset_num_timesteps=False, callback=m.clock)
    m.walls.append(time.perf_counter() - start)
    m.rollout_s.append(m.clock.seconds)
    m.env_s.append(m.timed.seconds)
    m.ends.append(m.timed.ends)


def _run_train(cfg: dict[str, Any], n_repeats: int, progress: bool) -> list[dict[str, Any]]:
    todo = train_measurements(cfg)
    try:
        timers = _sb3_timers()
    except ImportError as exc:  # SB3 / torch missing: every row says so
        for m in todo:
            m.error = f"{type(exc).__name__}: {exc}"
        return _train_rows(todo)
    try:
        with _bar(len(todo) * (n_repeats + 1), "train", progress) as bar:
            for m in todo:
                bar.set_postfix_str(f"setup {m.backend} N={m.num_envs}", refresh=False)
                _guard(m, lambda m=m: _train_setup(m, cfg, timers))
                bar.update()
            for rep in range(n_repeats):
                for m in todo:
                    name = f"{m.backend} N={m.num_envs}"
                    bar.set_postfix_str(f"rep {rep + 1}/{n_repeats} {name}", refresh=False)
                    if m.error is None:
                        _guard(m, lambda m=m: _train_measure(m))
                    bar.update()
    finally:
        for m in todo:
            if m.model is not None:
                _guard(m, m.model.get_env().close)
            m.model = m.timed = m.clock = None
    return _train_rows(todo)


def _train_rows(todo: list[TrainMeasurement]) -> list[dict[str, Any]]:
    """One row per training measurement.

    Fields: ``num_envs``, ``n_steps``, ``batch_size``, ``n_epochs``, ``rollouts`` (timed rollouts
    + updates per repeat), ``timesteps`` (env-steps per repeat), ``repeats``, ``env_steps_per_s``
    (end to end, median over repeats) and ``env_steps_per_s_best``, ``env_share`` /
    ``policy_share`` / ``update_share`` (median fractions of ``learn`` time spent in the VecEnv's
    step, in the rest of the rollout — policy forward, buffer, SB3 bookkeeping — and in the
    update), ``rollout_env_steps_per_s`` (timesteps / rollout time), ``env_only_steps_per_s``
    (timesteps / VecEnv step time), ``forward_ms`` (one policy forward on N observations),
    ``ends_per_1000``, ``build_s``, ``warmup_s``, ``ratio_dummy`` (end-to-end env-steps/s over
    the DummyVecEnv row's, with the paired range) and ``error``.
    """
    rows = []
    for m in todo:
        steps = m.rollouts * m.n_steps * m.num_envs
        rates = [steps / w for w in m.walls if w > 0]
        med = statistics.median

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
            "ratio_dummy_range": (math.nan, math.nan),
            "error": m.error,
            "_rates": rates,
        }
        rows.append(row)
    dummy = next((r for r in rows if r["level"] == "DummyVecEnv"), None)
    for row in rows:
        if row is not dummy:
            _paired(row, dummy, "ratio_dummy")
    for row in rows:
        del row["_rates"]
    return rows


# --- decision times -----------------------------------------------------------------------------

DECISION_SEED = 0
"""Seed of the first timed mission: the default evaluation's (``python evaluate.py``) missions."""
DECISION_WARMUP_SEED = 999_999
"""Seed of the untimed warm-up calls (compilation, model loading, first planning)."""
DECISION_WARMUP_CALLS = 3


@dataclass
class DecisionMeasurement:
    """One agent flying whole missions, every ``predict`` call timed."""

    spec: str  # an evaluate.py agent spec: a baseline name or "pretrained"
    label: str = ""
    env: Any = None
    agent: Any = None
    decision_ms: list[np.ndarray] = field(default_factory=list)  # per mission, ms per call
    successes: int = 0
    setup_s: float = math.nan  # building the agent and the warm-up calls
    error: str | None = None


def decision_agents() -> list[str]:
    """Every baseline of ``agents.BASELINES`` and the shipped pretrained policy."""
    import agents
    from agents.evaluation import PRETRAINED

    return [*agents.BASELINES, PRETRAINED]


def _decision_setup(m: DecisionMeasurement, cfg: dict[str, Any]) -> None:
    """Build the agent's env and the agent (as evaluate.py does), then make untimed warm-up
    calls so compilation and loading stay out of the timed calls."""
    from agents.evaluation import agent_env_options, build_agent, make_env, parse_agent_spec

    start = time.perf_counter()
    spec = parse_agent_spec(m.spec)
    m.label = spec.label
    m.env = make_env(ID_2D, agent_env_options(spec, ID_2D), cfg["decision_max_steps"])
    m.agent = build_agent(spec, m.env)
    obs, _ = m.env.reset(seed=DECISION_WARMUP_SEED)
    state = None
    for k in range(DECISION_WARMUP_CALLS):
        action, state = m.agent.predict(
            obs, state=state, episode_start=np.array([k == 0]), deterministic=True
        )
        obs, _, terminated, truncated, _ = m.env.step(action)
        if terminated or truncated:
            break
    m.setup_s = time.perf_counter() - start


def _decision_measure(m: DecisionMeasurement, episode: int) -> None:
    from agents.evaluation import run_episode

    record = run_episode(m.env, m.agent, m.label, episode, DECISION_SEED + episode)
    m.decision_ms.append(record.trajectory.decision_ms)
    m.successes += int(record.success)


def _run_decisions(cfg: dict[str, Any], steps: int | None, progress: bool) -> list[dict[str, Any]]:
    """The decision-time section: every agent on the same seeded missions, interleaved mission by
    mission with a timed block of plain env steps (the reference for the ratio)."""
    try:
        names = decision_agents()
    except ImportError as exc:  # the agents package (or an extra it needs) is missing
        names, missing = ["agents"], f"{type(exc).__name__}: {exc}"
    else:
        missing = None
    todo = [DecisionMeasurement(name, label=name, error=missing) for name in names]
    ref = Measurement("step", "", ID_2D, {}, "make")
    episodes = int(cfg["decision_episodes"])
    try:
        with _bar((len(todo) + 1) * (episodes + 1), "decisions", progress) as bar:
            bar.set_postfix_str(f"setup {ID_2D} env steps", refresh=False)
            _guard(ref, lambda: _setup(ref, cfg, steps, None))
            bar.update()
            for m in todo:
                bar.set_postfix_str(f"setup {m.spec}", refresh=False)
                if m.error is None:
                    _guard(m, lambda m=m: _decision_setup(m, cfg))
                bar.update()
            for ep in range(episodes):
                bar.set_postfix_str(f"mission {ep + 1}/{episodes} env steps", refresh=False)
                if ref.error is None:
                    _guard(ref, lambda: _measure(ref))
                bar.update()
                for m in todo:
                    bar.set_postfix_str(f"mission {ep + 1}/{episodes} {m.label}", refresh=False)
                    if m.error is None:
                        _guard(m, lambda m=m, ep=ep: _decision_measure(m, ep))
                    bar.update()
    finally:
        for m in [*todo, ref]:
            if m.env is not None:
                _guard(m, m.env.close)
            m.env = None
        for m in todo:
            m.agent = None
    return _decision_rows(todo, ref)


def _decision_rows(todo: list[DecisionMeasurement], ref: Measurement) -> list[dict[str, Any]]:
    """One row per agent.

    Fields: ``agent`` (its label), ``episodes`` (missions flown), ``decisions`` (timed calls),
    ``successes``, ``p50_ms`` / ``p95_ms`` / ``max_ms`` over every call, ``first_ms`` (median of
    the missions' first calls, where a classical agent plans), ``later_p50_ms`` (median of the
    other calls), ``env_step_us`` (median µs of one ``env.step`` through ``gym.make``, timed
    between the missions), ``p50_steps`` (``p50_ms`` in env steps), ``setup_s`` and ``error``.
    """
    env_step_us = math.nan
    if ref.times and ref.count:
        env_step_us = statistics.median(t / ref.count for t in ref.times) * 1e6
    rows = []
    for m in todo:
        calls = [a for a in m.decision_ms if a.size]
        every = np.concatenate(calls) if calls else np.zeros(0)
        later = np.concatenate([a[1:] for a in calls]) if calls else np.zeros(0)

        def pct(values: np.ndarray, q: float) -> float:
            return float(np.percentile(values, q)) if values.size else math.nan

        p50 = pct(every, 50)
        rows.append(
            {
                "section": "decisions",
                "env_id": ID_2D,
                "variant": m.label,
                "level": "predict",
                "n_obstacles": DEFAULT_OBSTACLES,
                "agent": m.label,
                "episodes": len(calls),
                "decisions": int(every.size),
                "successes": m.successes,
                "p50_ms": p50,
                "p95_ms": pct(every, 95),
                "max_ms": float(every.max()) if every.size else math.nan,
                "first_ms": statistics.median(float(a[0]) for a in calls) if calls else math.nan,
                "later_p50_ms": pct(later, 50),
                "env_step_us": env_step_us,
                "p50_steps": p50 * 1e3 / env_step_us,
                "setup_s": m.setup_s,
                "error": m.error or ref.error,
            }
        )
    return rows


def machine_description() -> list[str]:
    """Lines describing the machine and library versions."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    try:
        load = "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = "n/a"
    import pymunk

    source = _source_fingerprint()

    return [
        f"- CPU: {cpu}",
        f"- Cores: {os.cpu_count()} logical ({usable} usable by this process)",
        f"- Load average at start (1/5/15 min): {load}",
        f"- OS: {platform.platform()}",
        f"- Python {platform.python_version()} ({platform.python_implementation()})",
        f"- numpy {np.__version__}, gymnasium {gym.__version__}, pymunk {pymunk.version}, "
        f"debris_gym {debris_gym.__version__}, torch {_version('torch')}, "
        f"stable-baselines3 {_version('stable-baselines3')}",
        f"- debris_gym source measured: {source}",
    ]


def _version(dist: str) -> str:
    """Installed version of ``dist`` without importing it, or "not installed"."""
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def _source_fingerprint() -> str:
    """Git commit, whether ``debris_gym/`` has uncommitted changes, and a hash of its sources.

    The hash identifies the exact code measured when the working tree is being edited.
    """
    package = Path(debris_gym.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    text = f"sources sha256 {digest.hexdigest()[:12]}"
    try:
        git = ["git", "-C", str(package.parent)]
        head = subprocess.run(
            [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "--", str(package)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        text = f"git {head}" + (" + uncommitted changes" if dirty else "") + f", {text}"
    except (OSError, subprocess.CalledProcessError):
        pass
    return text


def _f(x: float, digits: int = 1) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:,.{digits}f}"


def _ratio(row: dict[str, Any]) -> str:
    lo, hi = row["ratio_range"]
    if not math.isfinite(row["ratio"]):
        return "–"
    return f"{row['ratio']:.2f} ({lo:.2f}–{hi:.2f})"


def _env_name(row: dict[str, Any]) -> str:
    name = f"`{row['env_id']}`"
    return f"{name} {row['variant']}" if row["variant"] else name


GOAL_CARTPOLE = 0.075  # native(1024) env-steps/s ≥ this × CartPole native(1024)
GOAL_SYNC = 25.0  # native env-steps/s ≥ this × SyncVectorEnv
GOAL_MEMORY = 10 * 1024  # bytes of state per sub-env
GOAL_TRAIN = 20_000  # end-to-end PPO env-steps/s

BACKENDS = {
    "native": "native",
    "sync": "gymnasium `SyncVectorEnv`",
    "subproc": "SB3 `SubprocVecEnv`",
}


def _range(row: dict[str, Any], key: str, digits: int = 2) -> str:
    value = row.get(key, math.nan)
    if value is None or not math.isfinite(value):
        return "–"
    lo, hi = row[key + "_range"]
    return f"{value:.{digits}f} ({lo:.{digits}f}–{hi:.{digits}f})"


def _verdict(value: float, goal: float, higher: bool = True) -> str:
    """ "met" / "missed", with the value as a multiple of the goal (a floor, or a limit)."""
    if not math.isfinite(value):
        return "not measured"
    met = value >= goal if higher else value <= goal
    what = "the goal" if higher else "the limit"
    return f"{'met' if met else 'missed'} ({value / goal:.2f}× {what})"


def _vector_lines(rows: list[dict[str, Any]]) -> list[str]:
    vec = [r for r in rows if r["section"] == "vector"]
    if not vec:
        return []
    warm = max(r["warmup_steps"] for r in vec)
    repeats = max(r["repeats"] for r in vec)
    sync = next((r for r in vec if r["level"] == "sync"), None)
    cart = next((r for r in vec if r["env_id"] == CARTPOLE), None)
    sync_n = sync["num_envs"] if sync else "–"
    cart_n = cart["num_envs"] if cart else "–"
    lines = [
        "## Vector env throughput",
        "",
        f"env-steps/s = vector steps × N / seconds; {repeats} interleaved repeats after {warm} "
        "warm-up steps from `reset(seed=0)` (steady state: episodes end and autoreset all the "
        "time). Autoresets run inside `step` and are included. Actions: uniform in [-0.05, 0.05] "
        "of `max_accel` (DebrisGym), uniform {0, 1} (CartPole). `SubprocVecEnv` runs one process "
        "per env (on 2 cores). *× Sync* is env-steps/s over `SyncVectorEnv`'s at "
        f"N={sync_n}: at equal N where N={sync_n}, otherwise against Sync's per-env rate (Sync "
        "steps its envs one after the other, so its env-steps/s does not depend on N). *× "
        f"CartPole* is env-steps/s over CartPole-v1's native vector env at N={cart_n}. In "
        "brackets: the smallest and largest ratio of two measurements taken in the same repeat.",
        "",
        "| backend | env | N | steps/repeat | env-steps/s (median) | env-steps/s (best) "
        "| µs per env-step | episodes ended / 1000 env-steps | `reset(seed)` ms per sub-env "
        f"| × Sync (N={sync_n}) | × CartPole native (N={cart_n}) |",
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in vec:
        first = [BACKENDS.get(row["level"], row["level"]), _env_name(row), str(row["num_envs"])]
        if row["error"] and not math.isfinite(row["env_steps_per_s"]):
            lines.append("| " + " | ".join([*first, f"error: {row['error']}"] + [""] * 7) + " |")
            continue
        reset = "–" if row["level"] == "subproc" else _f(row["reset_ms_per_env"], 2)
        cells = [
            *first,
            str(row["count"]),
            _f(row["env_steps_per_s"], 0),
            _f(row["env_steps_per_s_best"], 0),
            _f(row["us_per_env_step"], 2),
            _f(row["ends_per_1000"], 2),
            reset,
            _range(row, "ratio_sync"),
            _range(row, "ratio_cartpole", 4),
        ]
        lines.append("| " + " | ".join(cells) + " |")

    def native(n: int | None = None) -> list[dict[str, Any]]:
        return [
            r for r in vec
            if r["level"] == "native" and r["env_id"] == ID_2D and not r["variant"]
            and (n is None or r["num_envs"] == n) and math.isfinite(r["env_steps_per_s"])
        ]  # fmt: skip

    lines += ["", "Goals (2D, 20 debris, kinematics observations):", ""]
    at_cart = native(cart["num_envs"]) if cart else []
    if at_cart:
        r = at_cart[0]
        lines.append(
            f"- native N={r['num_envs']} / CartPole native N={cart_n}: "
            f"{r['ratio_cartpole']:.4f}× (goal ≥ {GOAL_CARTPOLE}×): "
            f"{_verdict(r['ratio_cartpole'], GOAL_CARTPOLE)}"
        )
    if sync:
        equal = native(sync["num_envs"])
        if equal:
            r = equal[0]
            lines.append(
                f"- native / SyncVectorEnv at equal N={sync_n}: {r['ratio_sync']:.1f}× "
                f"(goal ≥ {GOAL_SYNC:.0f}×): {_verdict(r['ratio_sync'], GOAL_SYNC)}"
            )
        best = max(native(), key=lambda r: r["ratio_sync"], default=None)
        if best is not None and math.isfinite(best["ratio_sync"]):
            lines.append(
                f"- best native (N={best['num_envs']}) / SyncVectorEnv's per-env rate: "
                f"{best['ratio_sync']:.1f}× (goal ≥ {GOAL_SYNC:.0f}×): "
                f"{_verdict(best['ratio_sync'], GOAL_SYNC)}"
            )
    threaded = [
        r for r in vec
        if r["level"] == "native" and r["variant"].startswith("num_threads=")
        and math.isfinite(r["env_steps_per_s"])
    ]  # fmt: skip
    if threaded:
        lines += [
            "",
            "The same env with `num_threads=2` (two threads step the sub-envs; CartPole's "
            "native env and SyncVectorEnv use one):",
            "",
        ]
    for r in threaded:
        if r["num_envs"] == cart_n and cart:
            lines.append(
                f"- native N={r['num_envs']}, {r['variant']} / CartPole native N={cart_n}: "
                f"{r['ratio_cartpole']:.4f}× (goal ≥ {GOAL_CARTPOLE}×): "
                f"{_verdict(r['ratio_cartpole'], GOAL_CARTPOLE)}; "
                f"{r['env_steps_per_s']:,.0f} env-steps/s"
            )
        if sync and math.isfinite(r["ratio_sync"]):
            lines.append(
                f"- native N={r['num_envs']}, {r['variant']} / SyncVectorEnv's per-env rate: "
                f"{r['ratio_sync']:.1f}× (goal ≥ {GOAL_SYNC:.0f}×): "
                f"{_verdict(r['ratio_sync'], GOAL_SYNC)}"
            )
    return [*lines, ""]


def _vector_scaling_lines(rows: list[dict[str, Any]]) -> list[str]:
    scal = [r for r in rows if r["section"] == "vector_scaling"]
    if not scal:
        return []
    lines = [
        f"## Vector env: scaling with debris count (`{ID_2D}`, native)",
        "",
        "field_size = 1000 m · sqrt(max(1, n/20)). Timed right after `reset(seed=0)` (a few "
        "warm-up steps, then at most "
        f"{max(r['warmup_steps'] + r['count'] * r['repeats'] for r in scal)} steps in all), so "
        "this is the *step* cost with (almost) no autoresets; the reset cost per sub-env is the "
        "first `reset(seed=0)` of all N sub-envs divided by N. Cost is relative to 20 debris at "
        "the same N.",
        "",
        "| n_obstacles | field_size (m) | N | steps/repeat | env-steps/s (median) "
        "| env-steps/s (best) | µs per env-step | episodes ended / 1000 env-steps "
        "| `reset(seed)` ms per sub-env | cost × 20 debris (same N) |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in scal:
        n = row["n_obstacles"]
        label = f"{n} (reference)" if n == DEFAULT_OBSTACLES else str(n)
        first = [label, _f(row["field_size"], 0), str(row["num_envs"])]
        if row["error"] and not math.isfinite(row["env_steps_per_s"]):
            lines.append("| " + " | ".join([*first, f"error: {row['error']}"] + [""] * 6) + " |")
            continue
        cells = [
            *first,
            str(row["count"]),
            _f(row["env_steps_per_s"], 0),
            _f(row["env_steps_per_s_best"], 0),
            _f(row["us_per_env_step"], 2),
            _f(row["ends_per_1000"], 2),
            _f(row["reset_ms_per_env"], 2),
            _range(row, "ratio"),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, ""]


def _memory_lines(rows: list[dict[str, Any]]) -> list[str]:
    row = next((r for r in rows if r["section"] == "memory"), None)
    if row is None:
        return []
    lines = [f"## Memory per sub-env (`{ID_2D}`, native, {DEFAULT_OBSTACLES} debris)", ""]
    if row["error"]:
        return [*lines, f"error: {row['error']}", ""]
    small, large = row["small_envs"], row["large_envs"]
    py = row["python_bytes_per_env"]
    a = row["array_bytes_per_env"]
    b = row["rss_per_env"]
    lines += [
        "Each instance is built in a fresh process (`python bench/run.py --memory-child N`), "
        "after a 1-env instance was built, reset and dropped (imports and one-off caches are not "
        f"counted). Bodies per field: {row['n_bodies']} (targets + debris).",
        "",
        "- (a) numpy arrays held by the env, its `MissionBatch` and its `FieldBatch` at "
        f"N={large}, observation "
        f"buffer excluded: **{a:,.0f} B per sub-env ({a / 1024:.2f} KiB)**; the observation "
        f"buffer adds {row['obs_buffer_bytes_per_env']:,.0f} B",
        f"- Python objects per sub-env (deep `sys.getsizeof`): `scenarios` "
        f"{py.get('scenarios', math.nan):,.0f} B, per-sub-env generators "
        f"{py.get('rngs', math.nan):,.0f} B",
        f"- (b) RSS growth on build + `reset(seed=0)`: {row['rss_growth'][small] / 2**20:,.2f} MiB "
        f"at N={small}, {row['rss_growth'][large] / 2**20:,.2f} MiB at N={large}; (difference) "
        f"/ {large - small} envs = **{b:,.0f} B per sub-env ({b / 1024:.2f} KiB)**; after 10 "
        f"more steps {row['rss_steps_per_env']:,.0f} B",
        f"- Goal ≤ {GOAL_MEMORY // 1024} KiB per sub-env: arrays only (a) "
        f"{_verdict(a, GOAL_MEMORY, higher=False)}; RSS (b) {_verdict(b, GOAL_MEMORY, False)}",
        "",
        f"Biggest arrays (N={large}):",
        "",
        "| array | shape | dtype | bytes | bytes per sub-env |",
        "|---|---|---|--:|--:|",
    ]
    for arr in row["arrays"][:10]:
        name = f"`{arr['owner']}.{arr['name']}`"
        if arr["observation_buffer"]:
            name += " (observation buffer, excluded)"
        shape = "×".join(str(s) for s in arr["shape"])
        cells = [name, shape, arr["dtype"], f"{arr['nbytes']:,}", f"{arr['nbytes'] / large:,.0f}"]
        lines.append("| " + " | ".join(cells) + " |")
    rest = row["arrays"][10:]
    if rest:
        total = sum(x["nbytes"] for x in rest)
        lines.append(f"| {len(rest)} more | | | {total:,} | {total / large:,.0f} |")
    return [*lines, ""]


def _train_lines(rows: list[dict[str, Any]]) -> list[str]:
    train = [r for r in rows if r["section"] == "train"]
    if not train:
        return []
    lines = [
        f"## Training throughput (SB3 PPO on `{ID_2D}`)",
        "",
        '`PPO("MlpPolicy", venv, n_steps, batch_size, n_epochs, device="cpu")`, torch with 1 '
        "thread. Timed: `model.learn(rollouts × n_steps × N, reset_num_timesteps=False)` after "
        "one warm-up rollout + update (which also did the env reset). The split: *env* = time "
        "in the VecEnv's `step` (adapter included), *policy & rest* = the rest of "
        "`collect_rollouts` (policy forward, buffer, SB3 bookkeeping), *update* = the rest of "
        "`learn` (`train()`). *× Dummy* = end-to-end env-steps/s over the DummyVecEnv row's "
        "(paired range in brackets). The DummyVecEnv holds single envs made by `gym.make`.",
        "",
        "| VecEnv | N | n_steps | batch | epochs | timed env-steps | env-steps/s end to end "
        "(median) | best | × Dummy | env % | policy & rest % | update % | rollout env-steps/s "
        "| env-only env-steps/s | policy forward ms (N obs) | episodes ended / 1000 |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in train:
        first = [f"`{row['level']}`", str(row["num_envs"])]
        if row["error"] and not math.isfinite(row["env_steps_per_s"]):
            lines.append("| " + " | ".join([*first, f"error: {row['error']}"] + [""] * 13) + " |")
            continue
        cells = [
            *first,
            str(row["n_steps"]),
            str(row["batch_size"]),
            str(row["n_epochs"]),
            f"{row['timesteps']:,}",
            _f(row["env_steps_per_s"], 0),
            _f(row["env_steps_per_s_best"], 0),
            _range(row, "ratio_dummy"),
            _f(100 * row["env_share"], 0),
            _f(100 * row["policy_share"], 0),
            _f(100 * row["update_share"], 0),
            _f(row["rollout_env_steps_per_s"], 0),
            _f(row["env_only_steps_per_s"], 0),
            _f(row["forward_ms"], 2),
            _f(row["ends_per_1000"], 2),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", f"Goal ≥ {GOAL_TRAIN:,} env-steps/s end to end:", ""]
    for row in train:
        if row["level"] == "NativeVecEnv":
            lines.append(
                f"- `NativeVecEnv` N={row['num_envs']}: {_f(row['env_steps_per_s'], 0)} "
                f"env-steps/s: {_verdict(row['env_steps_per_s'], GOAL_TRAIN)}"
            )
    return [*lines, ""]


def _decision_lines(rows: list[dict[str, Any]]) -> list[str]:
    decisions = [r for r in rows if r["section"] == "decisions"]
    if not decisions:
        return []
    episodes = max((r["episodes"] for r in decisions), default=0)
    step_us = next((r["env_step_us"] for r in decisions if math.isfinite(r["env_step_us"])), None)
    lines = [
        f"## Decision times (`{ID_2D}`)",
        "",
        f"Every agent flies the same {episodes} mission(s) of the default evaluation (`python "
        f"evaluate.py`, reset seeds {DECISION_SEED}, {DECISION_SEED + 1}, …), mission by mission "
        "in turn, and every `agent.predict(obs, state, episode_start, deterministic=True)` call "
        "is timed (`time.perf_counter`); a few untimed calls on another mission come first "
        "(compilation, model loading). A classical agent plans inside the first call of a "
        "mission (APF-MPC and A* plan again after each capture, or when the chaser strays from "
        "the path), so *p95* and *max* include planning; *first call* is the median over the "
        "missions' first calls, *later calls* the median of all the others. *p50 in env "
        "steps* = p50 over the median "
        "`env.step` of the same env through `gym.make`"
        + (f" ({step_us:.1f} µs)" if step_us is not None else "")
        + ", timed between the missions in the same run.",
        "",
        "| agent | missions | decisions | successes | p50 ms | p95 ms | max ms "
        "| first call ms | later calls p50 ms | p50 in env steps |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in decisions:
        first = [f"`{row['agent']}`"]
        if row["error"] and not math.isfinite(row["p50_ms"]):
            lines.append("| " + " | ".join([*first, f"error: {row['error']}"] + [""] * 8) + " |")
            continue
        cells = [
            *first,
            str(row["episodes"]),
            f"{row['decisions']:,}",
            str(row["successes"]),
            _f(row["p50_ms"], 3),
            _f(row["p95_ms"], 3),
            _f(row["max_ms"], 2),
            _f(row["first_ms"], 2),
            _f(row["later_p50_ms"], 3),
            _f(row["p50_steps"], 1),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, ""]


def format_report(
    rows: list[dict[str, Any]],
    *,
    command: str,
    elapsed: float,
    machine: list[str] | None = None,
) -> str:
    """Markdown report: machine description, then one block of tables per section present."""
    machine = machine_description() if machine is None else machine
    lines = ["# DebrisGym benchmark", "", *machine]
    lines += [f"- Command: `{command}`", f"- Wall time of the run: {elapsed:.0f} s", ""]
    lines += _single_lines(rows)
    lines += _vector_lines(rows)
    lines += _vector_scaling_lines(rows)
    lines += _memory_lines(rows)
    lines += _train_lines(rows)
    lines += _decision_lines(rows)
    errors = [r for r in rows if r["error"]]
    if errors:
        lines += ["## Errors", ""]
        lines += [f"- {_name_row(r)}: `{r['error']}`" for r in errors]
        lines.append("")
    while lines and not lines[-1]:
        lines.pop()
    return "\n".join(lines) + "\n"


def _single_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The single-env step, scaling and reset tables."""
    single = [r for r in rows if r["section"] in ("step", "scaling", "reset")]
    if not single:
        return []
    repeats = max((r["repeats"] for r in single), default=0)
    lines = [
        f"Each cell: {repeats} interleaved repeats; *median* and *min* are µs per step over the "
        "repeats. Ratios come from the medians; in brackets the smallest and largest ratio of "
        "two measurements taken in the same repeat.",
        "",
        "## Single-env step cost",
        "",
        "Time inside `reset()` is excluded from step time; *steps/s incl. resets* includes it.",
        "",
        "| env | wrappers | steps/repeat | median µs/step | min µs/step | steps/s (median) "
        "| steps/s incl. resets | resets / 1000 steps | cost × CartPole (same wrappers) |",
        "|---|---|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for row in rows:
        if row["section"] != "step":
            continue
        wrappers = "gym.make" if row["level"] == "make" else "unwrapped"
        lines.append(_step_line(row, [_env_name(row), wrappers], _ratio(row)))
    lines += [
        "",
        f"## Scaling with debris count (`{ID_2D}`, unwrapped)",
        "",
        "field_size = 1000 m · sqrt(max(1, n/20)), i.e. constant debris density above 20.",
        "",
        "| n_obstacles | field_size (m) | steps/repeat | median µs/step | min µs/step "
        "| steps/s (median) | steps/s incl. resets | resets / 1000 steps | cost × 20-debris "
        "| ms per in-loop reset |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    ref = next(
        (r for r in rows if (r["section"], r["env_id"], r["level"], r["variant"])
         == ("step", ID_2D, "unwrapped", "")),
        None,
    )  # fmt: skip
    scaling = [r for r in rows if r["section"] == "scaling"]
    if ref is not None:
        ref = {**ref, "n_obstacles": DEFAULT_OBSTACLES, "field_size": field_size_for(20)}
        ref["ratio"], ref["ratio_range"] = 1.0, (1.0, 1.0)
        scaling.append(ref)
    for row in sorted(scaling, key=lambda r: r["n_obstacles"]):
        n = row["n_obstacles"]
        label = f"{n} (default, reference)" if row is ref else str(n)
        extra = [_f(row["loop_reset_ms"], 1)]
        lines.append(_step_line(row, [label, _f(row["field_size"], 0)], _ratio(row), extra))
    lines += [
        "",
        "## Reset cost (through `gym.make`)",
        "",
        "| env | resets/repeat | median ms/reset | min ms/reset | cost × CartPole reset |",
        "|---|--:|--:|--:|--:|",
    ]
    for row in rows:
        if row["section"] != "reset":
            continue
        cells = [_env_name(row), str(row["count"])]
        if row["error"]:
            cells += [f"error: {row['error']}", "", ""]
        else:
            cells += [_f(row["median_us"] / 1e3, 3), _f(row["min_us"] / 1e3, 3), _ratio(row)]
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, ""]


def _name_row(row: dict[str, Any]) -> str:
    extra = f" n_obstacles={row['n_obstacles']}" if row["n_obstacles"] is not None else ""
    if row.get("num_envs") is not None:
        extra += f" N={row['num_envs']}"
    return f"{row['section']} {_env_name(row)}{extra} ({row['level']})"


def _step_line(
    row: dict[str, Any], first: list[str], ratio: str, extra: list[str] | None = None
) -> str:
    extra = extra or []
    if row["error"] and not math.isfinite(row["median_us"]):
        cells = [*first, f"error: {row['error']}"] + [""] * (6 + len(extra))
        return "| " + " | ".join(cells) + " |"
    cells = [
        *first,
        str(row["count"]),
        _f(row["median_us"], 2),
        _f(row["min_us"], 2),
        _f(row["steps_per_s"], 0),
        _f(row["steps_per_s_wall"], 0),
        _f(row["resets_per_1000"], 2),
        ratio,
        *extra,
    ]
    return "| " + " | ".join(cells) + " |"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer, shorter repeats, smaller N")
    parser.add_argument(
        "--only",
        metavar="SECTIONS",
        help=f"comma-separated sections to run, from: {','.join(SECTIONS)} (default: all). "
        "single = single-env step, scaling and reset tables; scaling = the vector env "
        "against the debris count",
    )
    parser.add_argument("--out", metavar="FILE", help="also write the Markdown report to FILE")
    parser.add_argument("--memory-child", type=int, metavar="N", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.memory_child is not None:  # internal: one fresh-process memory measurement
        print(json.dumps(memory_child(args.memory_child)))
        return 0
    try:
        sections = _sections(args.only.split(",")) if args.only else SECTIONS
    except ValueError as exc:
        parser.error(str(exc))
    command = "python bench/run.py" + (" --quick" if args.quick else "")
    if args.only:
        command += f" --only {','.join(sections)}"
    if args.out:
        command += f" --out {args.out}"
    machine = machine_description()  # taken before the run (load average at start)
    start = time.perf_counter()
    rows = run(quick=args.quick, sections=sections)
    elapsed = time.perf_counter() - start
    report = format_report(rows, command=command, elapsed=elapsed, machine=machine)
    print(report, end="")
    if args.out:
        write_atomic(args.out, report)
    return 1 if any(r["error"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
