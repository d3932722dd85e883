"""Section ``decisions``: decision times of every baseline and of the pretrained policy, and of
APF-MPC and the pretrained policy behind the safety shield (``evaluate.py --shield``). The
pretrained rows appear when a policy ships for the bench's env (``agents.load_agent``'s
``pretrained`` for :data:`~bench.config.ID_2D`), as in the default evaluation.

Every agent flies the same seeded missions of the default evaluation (``python evaluate.py``,
reset seeds :data:`DECISION_SEED`, +1, …) through the evaluation's own loop
(``run_episode``), one mission of each agent in turn, and every
``agent.predict(obs, state, episode_start, deterministic=True)`` call is timed (ms). Before each
round of missions a block of plain ``env.step`` calls of the same env through ``gym.make`` is
timed (as in the single-env step rows): the reference that expresses the p50 in env steps.
Untimed warm-up calls on another mission come first (compilation, model loading, first
planning). Rows have section "decisions".

This is the only module of the bench that uses the ``agents`` package; :func:`agents_api` is
the one place that imports it.
"""

from __future__ import annotations

import functools
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from bench.config import DEFAULT_OBSTACLES, ID_2D
from bench.harness import interleave
from bench.single import Measurement, step_measurement

DECISION_SEED = 0
"""Seed of the first timed mission: the default evaluation's (``python evaluate.py``) missions."""
DECISION_WARMUP_SEED = 999_999
"""Seed of the untimed warm-up calls (compilation, model loading, first planning)."""
DECISION_WARMUP_CALLS = 3
"""Untimed ``predict`` calls per agent before its first timed mission."""


class AgentsAPI(NamedTuple):
    """What this section takes from ``agents`` (see :mod:`agents.experiments.evaluation`)."""

    baselines: tuple[str, ...]  # names of the classical baselines
    pretrained: str  # the agent spec of the shipped pretrained policy
    pretrained_ships: Callable[[str], bool]  # env ID -> a pretrained policy ships for it
    agent_env_options: Callable[..., dict[str, Any]]
    build_agent: Callable[..., Any]
    make_env: Callable[..., Any]
    parse_agent_spec: Callable[[str], Any]
    run_episode: Callable[..., Any]
    shielded: Callable[[Any, Any], Any]  # (agent, env) -> the agent behind the default shield


@functools.cache
def agents_api() -> AgentsAPI:
    """Import the agents package's evaluation API on first use.

    Imported here and nowhere else, so that the other sections run without the agents package
    and a move of these names touches one place.

    Raises:
        ImportError: the agents package (or something it needs) is missing.
    """
    from agents import BASELINES
    from agents.experiments import evaluation
    from agents.policies.learned import pretrained_path
    from agents.policies.shielded import ShieldedAgent

    def pretrained_ships(env_id: str) -> bool:
        try:
            pretrained_path(env_id)
        except (FileNotFoundError, ValueError):
            return False
        return True

    return AgentsAPI(
        baselines=tuple(BASELINES),
        pretrained=evaluation.PRETRAINED,
        pretrained_ships=pretrained_ships,
        agent_env_options=evaluation.agent_env_options,
        build_agent=evaluation.build_agent,
        make_env=evaluation.make_env,
        parse_agent_spec=evaluation.parse_agent_spec,
        run_episode=evaluation.run_episode,
        shielded=ShieldedAgent,
    )


SHIELD_SUFFIX = "+shield"
"""Label suffix of an agent flown behind the safety shield."""


def decision_agents() -> list[str]:
    """Every baseline of ``agents.BASELINES``, the shipped pretrained policy, then APF-MPC and the
    pretrained policy behind the shield (``NAME+shield``); the pretrained ones only when a
    policy ships for :data:`~bench.config.ID_2D`."""
    api = agents_api()
    learned = [api.pretrained] if api.pretrained_ships(ID_2D) else []
    return [
        *api.baselines,
        *learned,
        *(f"{name}{SHIELD_SUFFIX}" for name in ("apf-mpc", *learned)),
    ]


@dataclass
class DecisionMeasurement:
    """One agent flying whole missions, every ``predict`` call timed."""

    spec: str  # an evaluate.py agent spec (a baseline name, "pretrained"), optionally +shield
    label: str = ""
    env_id: str = ID_2D  # the env it flies
    max_steps: int | None = None  # time limit of a mission (None: the env's)
    env: Any = None
    agent: Any = None
    decision_ms: list[np.ndarray] = field(default_factory=list)  # per mission, ms per call
    successes: int = 0
    setup_s: float = math.nan  # building the agent and the warm-up calls
    error: str | None = None

    def describe(self) -> str:
        return self.label or self.spec

    def set_up(self) -> None:
        """Build the agent's env and the agent (as evaluate.py does), then make untimed warm-up
        calls so compilation and loading stay out of the timed calls."""
        api = agents_api()
        start = time.perf_counter()
        name = self.spec.removesuffix(SHIELD_SUFFIX)
        spec = api.parse_agent_spec(name)
        self.env_id = ID_2D
        self.label = self.spec if name != self.spec else spec.label
        self.env = api.make_env(
            self.env_id, api.agent_env_options(spec, self.env_id), self.max_steps
        )
        self.agent = api.build_agent(spec, self.env)
        if name != self.spec:
            self.agent = api.shielded(self.agent, self.env)
        obs, _ = self.env.reset(seed=DECISION_WARMUP_SEED)
        state = None
        for k in range(DECISION_WARMUP_CALLS):
            action, state = self.agent.predict(
                obs, state=state, episode_start=np.array([k == 0]), deterministic=True
            )
            obs, _, terminated, truncated, _ = self.env.step(action)
            if terminated or truncated:
                break
        self.setup_s = time.perf_counter() - start

    def measure(self, round_index: int) -> None:
        """Fly mission ``round_index`` (reset seed ``DECISION_SEED + round_index``)."""
        seed = DECISION_SEED + round_index
        record = agents_api().run_episode(self.env, self.agent, self.label, round_index, seed)
        self.decision_ms.append(record.trajectory.decision_ms)
        self.successes += int(record.success)

    def tear_down(self) -> None:
        env, self.env, self.agent = self.env, None, None
        if env is not None:
            env.close()


def run_decisions(cfg: dict[str, Any], steps: int | None, progress: bool) -> list[dict[str, Any]]:
    """Run the section: every agent on the same seeded missions, interleaved mission by mission
    with a timed block of plain env steps (the reference for the ratio).

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike): ``decision_episodes`` (missions per
            agent), ``decision_max_steps``, and the single-env ``step_seconds`` / ``min_steps``
            of the reference block.
        steps: fixed env steps per reference block (default: calibrated).
        progress: show a progress bar.
    """
    try:
        names = decision_agents()
    except ImportError as exc:  # the agents package (or an extra it needs) is missing
        names, missing = ["agents"], f"{type(exc).__name__}: {exc}"
    else:
        missing = None
    max_steps = cfg["decision_max_steps"]
    todo = [DecisionMeasurement(n, label=n, max_steps=max_steps, error=missing) for n in names]
    ref = step_measurement(ID_2D, cfg, steps, label="env steps")
    interleave([ref, *todo], int(cfg["decision_episodes"]), "decisions", progress, "mission")
    return decision_rows(todo, ref)


def decision_rows(todo: list[DecisionMeasurement], ref: Measurement) -> list[dict[str, Any]]:
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
                "env_id": m.env_id,
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
