"""Section ``swarm``: chaser-steps/s of the native swarm core next to VMAS at equal envs × agents.

The swarm core (:class:`debris_gym.swarm.core.SwarmCore`, the world of ``DebrisGym/Swarm2D-v0``:
six targets and twenty debris per field) with K = 1, 8, 48, 256 chasers per field and E fields,
E · K about ``swarm_chasers_total`` (E = total // K: 1024 chasers as 1024 × 1, 128 × 8, 21 × 48,
4 × 256), next to VMAS's ``navigation`` scenario on the CPU with num_envs = E and n_agents = K,
all on one thread.

What is timed, for the swarm core: one step as a learner's loop makes it, all rows together:
check the (E·K, 2) actions (:func:`debris_gym.envs.common.checked_continuous_actions`), step,
restart the fields whose chasers have all ended, write every chaser's observation. Actions are
gentle thrusts or uniformly random (rows ``actions=random``), as in the ``vector`` section
(:func:`bench.harness.draw_actions`); a chaser that has ended keeps its row, idle, until its
field restarts (the rows report the share of rows that flew). For VMAS: ``env.step`` of K
tensors of (E, 2) uniformly random actions in [-1, 1], then the done envs reset as TorchRL's
``VmasWrapper`` resets them (``env.reset()`` when every env is done, else ``env.reset_at(i)``
for each, then the observations read again). The navigation task is BenchMARL's
(:data:`VMAS_TASK`, time limit 100 steps), its goals and agents spawned in a square grown with
K at the default density (:func:`vmas_half_width`); ``torch.set_num_threads(1)``.

Every measurement first runs warm-up steps from its reset (``swarm_warmup_steps`` for the swarm
core, as the ``vector`` section does, so that fields end and restart all the time;
``vmas_warmup_steps`` for VMAS, whose step at K = 256 takes seconds), then the measurements are
timed in interleaved rounds; ``ratio_vmas`` pairs each swarm row with the VMAS row of the same
E and K, round by round. Rows have section "swarm".
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from bench.config import MAX_VECTOR_STEPS, MIN_VECTOR_STEPS
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
from debris_gym.envs.common import checked_continuous_actions
from debris_gym.swarm import SWARM_SPECS
from debris_gym.swarm.core import SwarmCore

SWARM_ID = "DebrisGym/Swarm2D-v0"
"""The swarm ID whose world the section flies (``n_chasers`` set per row)."""

VMAS_SCENARIO = "navigation"
"""The VMAS scenario compared with: agents fly to their own goals, avoiding each other."""

VMAS_TASK: dict[str, Any] = {
    "max_steps": 100,
    "collisions": True,
    "agents_with_same_goal": 1,
    "split_goals": False,
    "observe_all_goals": False,
    "shared_rew": False,
    "lidar_range": 0.35,
    "agent_radius": 0.1,
}
"""BenchMARL's configuration of VMAS navigation (``conf/task/vmas/navigation.yaml``) but for
``n_agents``, which is each row's K."""

VMAS_DEFAULT_AGENTS = 3
"""Agents of BenchMARL's navigation task, which spawn in VMAS's default 2 × 2 square."""

VMAS_LABEL = f"VMAS {VMAS_SCENARIO}"
"""The ``env_id`` of the VMAS rows."""

CALIBRATION_STEPS = 20
"""The last warm-up steps, at most this many, are timed to calibrate the steps per repeat."""


def vmas_half_width(chasers: int) -> float:
    """Half the edge (VMAS units) of the square VMAS navigation spawns K agents and goals in:
    the default square (half-width 1) for BenchMARL's 3 agents, grown at constant density.
    Without the growth, 256 agents and goals do not fit at VMAS's spacing and the spawn never
    ends."""
    return max(1.0, math.sqrt(chasers / VMAS_DEFAULT_AGENTS))


def swarm_fields(chasers: int, total: int) -> int:
    """Fields E of K = ``chasers`` chasers so that E · K is about ``total`` (at least one)."""
    return max(1, total // chasers)


def import_vmas() -> Any:
    """The ``vmas`` module, with torch on one thread.

    Raises:
        ImportError: VMAS is not installed (it comes with the ``bench`` extra).
    """
    pin_torch()
    try:
        import vmas
    except ImportError as exc:
        raise ImportError(f"{exc}; install it with pip install 'debris-gym[bench]'") from exc
    return vmas


@dataclass
class SwarmMeasurement:
    """One simulator at one (E, K) to time: built and warmed up once, then timed per repeat."""

    backend: str  # "native" (the swarm core) or "vmas"
    chasers: int  # K per field (VMAS: n_agents)
    num_envs: int  # fields E (VMAS: num_envs)
    action_kind: str = "random"  # bench.harness.ACTION_KINDS
    warmup: int = 1  # untimed steps after the reset
    fixed: int | None = None  # steps per repeat; None: calibrated to ``seconds``
    seconds: float = 0.0
    low: int = MIN_VECTOR_STEPS  # fewest steps per calibrated repeat
    max_count: int = MAX_VECTOR_STEPS
    count: int = 0  # steps per repeat
    times: list[float] = field(default_factory=list)  # seconds per repeat
    ends: list[int] = field(default_factory=list)  # chasers (agents) ended per repeat
    resets: list[int] = field(default_factory=list)  # fields (envs) restarted per repeat
    reset_times: list[float] = field(default_factory=list)  # seconds of them per repeat
    flew: list[int] = field(default_factory=list)  # rows that flew, summed over steps
    warmup_steps: int = 0
    build_s: float = math.nan
    reset_s: float = math.nan  # the first reset of every field
    obs_size: int = 0
    error: str | None = None
    env: Any = None
    actions: Any = None

    @property
    def rows(self) -> int:
        """Chasers (agents) in all fields: E · K."""
        return self.chasers * self.num_envs

    @property
    def env_id(self) -> str:
        return SWARM_ID if self.backend == "native" else VMAS_LABEL

    def describe(self) -> str:
        kind = " random" if self.action_kind == "random" else ""
        return f"{self.backend} K={self.chasers} E={self.num_envs}{kind}"

    def set_up(self) -> None:
        """Build and reset, run the warm-up, fix the steps per repeat, draw the actions."""
        clock = time.perf_counter
        start = clock()
        self.env = self._make()
        self.build_s = clock() - start
        start = clock()
        self._reset()
        self.reset_s = clock() - start
        rng = np.random.default_rng(12345)
        warm = self.warmup
        tail = min(warm, CALIBRATION_STEPS)
        if warm > tail:
            self._loop(self._actions(warm - tail, rng))
        t = self._loop(self._actions(tail, rng))[0]
        self.warmup_steps = warm
        if self.fixed is not None:
            self.count = self.fixed
        else:
            low = min(self.low, self.max_count)
            self.count = calibrated(t / tail, self.seconds, low, self.max_count)
        self.actions = self._actions(self.count, rng)

    def measure(self, round_index: int = 0) -> None:
        t, ends, resets, flew, in_resets = self._loop(self.actions)
        self.times.append(t)
        self.ends.append(ends)
        self.resets.append(resets)
        self.flew.append(flew)
        self.reset_times.append(in_resets)

    def tear_down(self) -> None:
        env, self.env, self.actions = self.env, None, None
        if env is not None and self.backend == "native":
            env.close()

    def _make(self) -> Any:
        if self.backend == "native":
            spec = SWARM_SPECS[SWARM_ID]
            options = {**spec["kwargs"], "n_chasers": self.chasers}
            core = SwarmCore(self.num_envs, spec["max_episode_steps"], **options)
            self.obs_size = int(core.observation_space.shape[0])
            return core
        vmas = import_vmas()
        half = vmas_half_width(self.chasers)
        return vmas.make_env(
            VMAS_SCENARIO,
            num_envs=self.num_envs,
            device="cpu",
            continuous_actions=True,
            seed=0,
            n_agents=self.chasers,
            world_spawning_x=half,
            world_spawning_y=half,
            **VMAS_TASK,
        )

    def _reset(self) -> None:
        if self.backend == "native":
            self.env.reset([np.random.default_rng(e) for e in range(self.num_envs)])
        else:
            obs = self.env.reset()
            self.obs_size = int(obs[0].shape[-1])

    def _actions(self, steps: int, rng: np.random.Generator) -> Any:
        """Actions for ``steps`` steps: (steps, E·K, 2) for the swarm core, a list of K
        (E, 2) tensors per step for VMAS."""
        if self.backend == "native":
            space = self.env.action_space
            return draw_actions(space, SWARM_ID, (steps, self.rows), rng, self.action_kind)
        import torch

        box = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)  # VMAS navigation: u_range 1
        drawn = draw_actions(box, VMAS_LABEL, (steps, self.chasers, self.num_envs), rng, "random")
        return [list(torch.from_numpy(a).unbind(0)) for a in drawn]

    def _loop(self, actions: Any) -> tuple[float, int, int, int, float]:
        """Step through ``actions``; returns (seconds, chasers ended, fields restarted, rows
        that flew, seconds of the restarts). Counting is not timed."""
        if self.backend == "native":
            return self._swarm_loop(actions)
        return self._vmas_loop(actions)

    def _swarm_loop(self, actions: np.ndarray) -> tuple[float, int, int, int, float]:
        core, clock = self.env, time.perf_counter
        step, restart, observe = core.step, core.restart, core.observe
        shape = (self.rows, core.config.dim)
        outs: list[Any] = []
        add = outs.append
        in_resets = 0.0
        start = clock()
        for action in actions:
            out = step(checked_continuous_actions(action, shape))
            over = out.field_over
            if over.any():
                begin = clock()
                restart(over)
                in_resets += clock() - begin
            observe()
            add((out.terminated, out.truncated, over, out.flew))
        elapsed = clock() - start
        ends = sum(int(np.count_nonzero(a | b)) for a, b, _, _ in outs)
        resets = sum(int(np.count_nonzero(over)) for _, _, over, _ in outs)
        flew = sum(int(np.count_nonzero(f)) for _, _, _, f in outs)
        return elapsed, ends, resets, flew, in_resets

    def _vmas_loop(self, actions: list[list[Any]]) -> tuple[float, int, int, int, float]:
        env, clock = self.env, time.perf_counter
        step, reset, reset_at = env.step, env.reset, env.reset_at
        flags: list[Any] = []
        add = flags.append
        in_resets = 0.0
        start = clock()
        for action in actions:
            obs, rewards, dones, infos = step(action)
            if dones.any():
                begin = clock()
                if dones.all():
                    reset(return_observations=False)
                else:
                    for i in dones.nonzero().flatten().tolist():
                        reset_at(i, return_observations=False)
                (obs,) = env.get_from_scenario(
                    get_observations=True, get_rewards=False, get_infos=False, get_dones=False
                )
                in_resets += clock() - begin
            add(dones)
        elapsed = clock() - start
        resets = sum(int(d.sum()) for d in flags)
        return elapsed, resets * self.chasers, resets, len(flags) * self.rows, in_resets


def swarm_measurements(cfg: dict[str, Any], steps: int | None = None) -> list[SwarmMeasurement]:
    """The measurement list, in the order they are interleaved: for each K the swarm core with
    gentle and with random actions, then VMAS.

    Args:
        cfg: sizes (:data:`bench.config.FULL` or alike): ``swarm_chasers``,
            ``swarm_chasers_total``, ``swarm_warmup_steps``, ``vmas_warmup_steps``,
            ``swarm_seconds``.
        steps: fixed steps per repeat (default: calibrated to ``cfg["swarm_seconds"]``).
    """
    out = []
    for k in cfg["swarm_chasers"]:
        e = swarm_fields(int(k), int(cfg["swarm_chasers_total"]))
        common = {"fixed": steps, "seconds": cfg["swarm_seconds"]}
        warm = max(1, cfg["swarm_warmup_steps"])
        for kind in ("gentle", "random"):
            out.append(SwarmMeasurement("native", int(k), e, kind, warm, **common))
        # a VMAS step at K = 256 takes seconds: one step is a repeat
        warm = max(1, cfg["vmas_warmup_steps"])
        out.append(SwarmMeasurement("vmas", int(k), e, "random", warm, low=1, **common))
    return out


def run_swarm(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`swarm_rows`)."""
    todo = swarm_measurements(cfg, steps)
    interleave(todo, n_repeats, "swarm", progress)
    rows = swarm_rows(todo)
    vmas = {(r["chasers"], r["num_envs"]): r for r in rows if r["level"] == "vmas"}
    for row in rows:
        if row["level"] == "native":
            ref = vmas.get((row["chasers"], row["num_envs"]))
            paired_ratio(row, ref, "ratio_vmas", rate="chaser_steps_per_s")
            row["ratio_vmas_flying"] = row["ratio_vmas"] * row["flying_share"]
    return drop_rates(rows)


def swarm_rows(todo: list[SwarmMeasurement]) -> list[dict[str, Any]]:
    """One row per measurement, ``ratio_vmas`` not yet filled in.

    Fields: ``section`` ("swarm"), ``env_id`` (:data:`SWARM_ID` or :data:`VMAS_LABEL`),
    ``variant`` (:data:`bench.harness.RANDOM` or ""), ``level`` ("native" or "vmas"),
    ``actions``, ``n_obstacles`` (debris per field; None for VMAS), ``chasers`` (K),
    ``num_envs`` (fields E), ``count`` (steps per repeat), ``repeats``, ``warmup_steps``,
    ``chaser_steps_per_s`` (E·K × steps / seconds, median over repeats) and
    ``chaser_steps_per_s_best``, ``us_per_chaser_step`` (median), ``flying_share`` (share of
    the rows stepped that flew; VMAS 1), ``ends_per_1000`` (chasers ended per 1000
    chaser-steps; VMAS: K per env done), ``resets_per_1000`` (fields restarted per 1000
    chaser-steps), ``reset_share`` (share of the timed time spent restarting fields: the swarm
    core's ``restart``, VMAS's resets and the observations read after them), ``obs_size``
    (observation numbers per chaser), ``build_s``,
    ``reset_ms_per_field`` (first reset / E), ``ratio_vmas`` (chaser-steps/s over the VMAS
    row's of the same E and K; NaN for VMAS rows) with ``ratio_vmas_range`` (the smallest and
    largest ratio of two measurements taken in the same round), ``ratio_vmas_flying`` (the same
    counting only the rows that flew: ``ratio_vmas × flying_share``; every VMAS agent flies
    every step), ``error``, and ``_rates`` (per repeat, removed by
    :func:`bench.harness.drop_rates`).
    """
    rows = []
    for m in todo:
        chaser_steps = m.count * m.rows
        rates = [chaser_steps / t for t in m.times if t > 0]
        median = statistics.median(rates) if rates else math.nan
        timed = chaser_steps * len(rates)
        rows.append(
            {
                "section": "swarm",
                "env_id": m.env_id,
                "variant": RANDOM if m.action_kind == "random" else "",
                "level": m.backend,
                "actions": m.action_kind,
                "n_obstacles": SWARM_SPECS[SWARM_ID]["kwargs"]["n_obstacles"]
                if m.backend == "native"
                else None,
                "chasers": m.chasers,
                "num_envs": m.num_envs,
                "count": m.count,
                "repeats": len(rates),
                "warmup_steps": m.warmup_steps,
                "chaser_steps_per_s": median,
                "chaser_steps_per_s_best": max(rates) if rates else math.nan,
                "us_per_chaser_step": 1e6 / median if rates else math.nan,
                "flying_share": _share(sum(m.flew), timed),
                "ends_per_1000": 1000.0 * _share(sum(m.ends), timed),
                "resets_per_1000": 1000.0 * _share(sum(m.resets), timed),
                "reset_share": sum(m.reset_times) / sum(m.times) if rates else math.nan,
                "obs_size": m.obs_size,
                "build_s": m.build_s,
                "reset_ms_per_field": 1e3 * m.reset_s / m.num_envs,
                "ratio_vmas": math.nan,
                "ratio_vmas_range": NAN_RANGE,
                "ratio_vmas_flying": math.nan,
                "error": m.error,
                "_rates": rates,
            }
        )
    return rows


def _share(part: int, whole: int) -> float:
    """``part / whole``, NaN when nothing was timed."""
    return part / whole if whole else math.nan
