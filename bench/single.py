"""Section ``single``: the single env's step cost, its scaling with the debris count, reset cost.

What is timed:

* Step rows (section "step"): ``env.step(a)`` over pre-generated valid actions (see
  :func:`bench.harness.draw_actions`), both through ``gym.make`` (default wrappers) and on
  ``env.unwrapped``. On termination / truncation the env is reset; the step that ended the
  episode counts as a step, but the time spent *inside* ``reset()`` is excluded from the step
  time (the clock is stopped around it). "steps/s incl. resets" is the plain wall-clock rate
  with the resets included.
* Scaling rows (section "scaling"): the unwrapped 2D env with ``n_obstacles`` debris in a field
  whose edge grows as ``1000 m * sqrt(max(1, n / 20))`` (constant debris density), relative to
  the 20-debris default.
* Reset rows (section "reset"): ``env.reset()`` through ``gym.make``; a random-field env draws a
  new field (and checks it is solvable) on every reset.

The steps (resets) per repeat are calibrated during a warm-up so that every repeat lasts about
the same wall time, unless fixed by the caller.
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from bench.config import (
    CARTPOLE,
    DEBRIS_IDS,
    ID_2D,
    ID_V1,
    MAX_RESETS,
    MAX_STEPS,
    SCALING_COUNTS,
    field_size_for,
)
from bench.harness import NAN_RANGE, RANDOM, calibrated, draw_actions, interleave

WARMUP_STEPS = 200
"""Untimed steps that calibrate the count per repeat (at most 20 when the count is fixed)."""
MIN_RESETS = 3
"""Fewest resets per repeat."""


@dataclass
class Measurement:
    """One single env to time: ``count`` steps (or resets) per repeat, times in seconds."""

    section: str  # "step", "scaling" or "reset"
    label: str
    env_id: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    level: str = "make"  # "make" (default wrappers) or "unwrapped"
    n_obstacles: int | None = None
    action_kind: str = "gentle"  # bench.harness.ACTION_KINDS
    fixed: int | None = None  # steps (resets) per repeat; None: calibrated to ``seconds``
    seconds: float = 0.0  # wall time a calibrated repeat aims at
    min_steps: int = 1  # fewest steps per calibrated repeat
    count: int = 0  # steps (or resets) per repeat
    times: list[float] = field(default_factory=list)  # seconds per repeat, excluding resets
    walls: list[float] = field(default_factory=list)  # seconds per repeat, including resets
    resets: int = 0  # resets during step repeats
    reset_time: float = 0.0  # seconds spent in those resets
    error: str | None = None
    env: Any = None
    actions: list[Any] = field(default_factory=list)

    def describe(self) -> str:
        extra = self.label or (f"n={self.n_obstacles}" if self.n_obstacles is not None else "")
        return " ".join(x for x in (self.env_id, extra, self.level) if x)

    def set_up(self) -> None:
        """Build the env, warm it up, fix the count per repeat and pre-generate the actions."""
        env = gym.make(self.env_id, **self.kwargs)
        self.env = env = env.unwrapped if self.level == "unwrapped" else env
        env.reset(seed=0)
        rng = np.random.default_rng(12345)
        if self.section == "reset":
            per = reset_loop(env, MIN_RESETS) / MIN_RESETS
            if self.fixed is not None:
                self.count = self.fixed
            else:
                self.count = calibrated(per, self.seconds, MIN_RESETS, MAX_RESETS)
            return
        warm = WARMUP_STEPS if self.fixed is None else min(self.fixed, 20)
        t, _, _ = step_loop(env, self._actions(warm, rng))
        if self.fixed is not None:
            self.count = self.fixed
        else:
            self.count = calibrated(t / warm, self.seconds, self.min_steps, MAX_STEPS)
        self.actions = self._actions(self.count, rng)
        env.reset(seed=1)

    def measure(self, round_index: int = 0) -> None:
        if self.section == "reset":
            t = reset_loop(self.env, self.count)
            self.times.append(t)
            self.walls.append(t)
            return
        t, wall, r = step_loop(self.env, self.actions)
        self.times.append(t)
        self.walls.append(wall)
        self.resets += r
        self.reset_time += wall - t

    def tear_down(self) -> None:
        env, self.env, self.actions = self.env, None, []
        if env is not None:
            env.close()

    def _actions(self, n: int, rng: np.random.Generator) -> list[Any]:
        values = draw_actions(self.env.action_space, self.env_id, (n,), rng, self.action_kind)
        if isinstance(self.env.action_space, gym.spaces.Discrete):
            return [int(v) for v in values]
        return list(values)


def step_loop(env: Any, actions: list[Any]) -> tuple[float, float, int]:
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


def reset_loop(env: Any, n: int) -> float:
    """Seconds for ``n`` calls of ``env.reset()``."""
    reset, clock = env.reset, time.perf_counter
    start = clock()
    for _ in range(n):
        reset()
    return clock() - start


def step_measurement(
    env_id: str,
    cfg: dict[str, Any],
    steps: int | None,
    *,
    section: str = "step",
    label: str = "",
    kwargs: dict[str, Any] | None = None,
    level: str = "make",
    n_obstacles: int | None = None,
    action_kind: str = "gentle",
) -> Measurement:
    """A step measurement of ``env_id`` sized by ``cfg`` (``step_seconds``, ``min_steps``).

    Args:
        env_id: the registered env ID.
        cfg: sizes (:data:`bench.config.QUICK` or alike).
        steps: fixed steps per repeat (default: calibrated to ``cfg["step_seconds"]``).
        section: "step" or "scaling".
        label: the variant's name in the report ("observation=lidar"; "" for the default).
        kwargs: keyword arguments of ``gym.make``.
        level: "make" (default wrappers) or "unwrapped".
        n_obstacles: debris count of a scaling row.
        action_kind: "gentle" or "random" (:data:`bench.harness.ACTION_KINDS`).
    """
    return Measurement(
        section,
        label,
        env_id,
        kwargs or {},
        level,
        n_obstacles,
        action_kind,
        fixed=steps,
        seconds=cfg["step_seconds"],
        min_steps=cfg["min_steps"],
    )


def measurements(
    cfg: dict[str, Any], steps: int | None = None, resets: int | None = None
) -> list[Measurement]:
    """The measurement list, in the order they are interleaved.

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike).
        steps: fixed steps per repeat (default: calibrated).
        resets: fixed resets per repeat (default: calibrated).
    """
    out: list[Measurement] = []
    variants: list[tuple[str, str, dict[str, Any]]] = [(CARTPOLE, "", {})]
    variants += [(env_id, "", {}) for env_id in DEBRIS_IDS]
    variants += [(ID_2D, "observation=lidar", {"observation": "lidar"})]
    variants += [(ID_2D, "action=discrete", {"action": "discrete"})]
    for level in ("make", "unwrapped"):
        for env_id, label, kwargs in variants:
            out.append(
                step_measurement(env_id, cfg, steps, label=label, kwargs=kwargs, level=level)
            )
    # uniformly random actions, as an exploring policy acts: episodes end often, and the
    # resets count (CartPole's actions are uniform already: its default row is the reference)
    # (and on the v1 world, whose goal the mission-shell work was set on)
    for env_id in (ID_2D, ID_V1):
        out.append(step_measurement(env_id, cfg, steps, label=RANDOM, action_kind="random"))
    for n in SCALING_COUNTS:
        kwargs = {"n_obstacles": n, "field_size": field_size_for(n)}
        out.append(
            step_measurement(
                ID_2D,
                cfg,
                steps,
                section="scaling",
                kwargs=kwargs,
                level="unwrapped",
                n_obstacles=n,
            )
        )
    for env_id in (*DEBRIS_IDS, CARTPOLE):
        out.append(Measurement("reset", "", env_id, fixed=resets, seconds=cfg["reset_seconds"]))
    return out


def run_single(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, resets: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`single_rows`)."""
    todo = measurements(cfg, steps, resets)
    interleave(todo, n_repeats, "single", progress)
    return single_rows(todo)


def single_rows(todo: list[Measurement]) -> list[dict[str, Any]]:
    """One row per measurement.

    Fields: ``section`` ("step", "scaling", "reset"), ``env_id``, ``variant``, ``level``,
    ``n_obstacles``, ``field_size`` (m), ``count`` (steps or resets per repeat), ``repeats``,
    ``median_us`` / ``min_us`` (µs per step or per reset, resets excluded from step time),
    ``steps_per_s`` (median), ``steps_per_s_wall`` (median, resets included),
    ``resets_per_1000``, ``loop_reset_ms`` (mean ms per reset done inside the step loop, at that
    wrapper level), ``ratio`` (cost relative to CartPole at the same wrapper level for "step"
    rows; relative to the 20-debris default for "scaling" rows; to CartPole's reset for "reset"
    rows) with ``ratio_range`` (the smallest and largest ratio of two measurements of the same
    round), ``ratio_wall`` / ``ratio_wall_range`` (step rows: the cost relative to CartPole
    with the resets included on both sides), and ``error`` (None, or the message if the env
    could not be built or stepped).
    """
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
            "ratio_range": NAN_RANGE,
            "ratio_wall": math.nan,
            "ratio_wall_range": NAN_RANGE,
            "error": m.error,
            "_per_item": [],
            "_per_wall": [],
        }
        if m.times and m.count:
            per = [t / m.count for t in m.times]
            row["_per_item"] = per
            row["median_us"] = statistics.median(per) * 1e6
            row["min_us"] = min(per) * 1e6
            if m.section != "reset":
                row["_per_wall"] = [w / m.count for w in m.walls]
                row["steps_per_s"] = 1.0 / statistics.median(per)
                row["steps_per_s_wall"] = m.count / statistics.median(m.walls)
                row["resets_per_1000"] = 1000.0 * m.resets / (m.count * len(m.times))
                if m.resets:
                    row["loop_reset_ms"] = 1e3 * m.reset_time / m.resets
        rows.append(row)
    _add_ratios(rows)
    for row in rows:
        del row["_per_item"], row["_per_wall"]
    return rows


def _add_ratios(rows: list[dict[str, Any]]) -> None:
    """Cost ratios from medians; ``ratio_range`` = min/max over paired (same-round) ratios."""

    def find(section: str, env_id: str, level: str) -> dict[str, Any] | None:
        key = (section, env_id, level, "")
        return next((r for r in rows if _key(r) == key), None)

    def fill(row: dict[str, Any], ref: dict[str, Any] | None) -> None:
        if ref is None or not row["_per_item"] or not ref["_per_item"]:
            return
        row["ratio"] = row["median_us"] / ref["median_us"]
        paired = [a / b for a, b in zip(row["_per_item"], ref["_per_item"], strict=False)]
        row["ratio_range"] = (min(paired), max(paired))

    def fill_wall(row: dict[str, Any], ref: dict[str, Any] | None) -> None:
        if ref is None or not row["_per_wall"] or not ref["_per_wall"]:
            return
        row["ratio_wall"] = statistics.median(row["_per_wall"]) / statistics.median(
            ref["_per_wall"]
        )
        paired = [a / b for a, b in zip(row["_per_wall"], ref["_per_wall"], strict=False)]
        row["ratio_wall_range"] = (min(paired), max(paired))

    for row in rows:
        if row["section"] == "step":
            fill(row, find("step", CARTPOLE, row["level"]))
            fill_wall(row, find("step", CARTPOLE, row["level"]))
        elif row["section"] == "scaling":
            fill(row, find("step", ID_2D, "unwrapped"))
        elif row["section"] == "reset":
            fill(row, find("reset", CARTPOLE, "make"))


def _key(row: dict[str, Any]) -> tuple[str, str, str, str]:
    return row["section"], row["env_id"], row["level"], row["variant"]
