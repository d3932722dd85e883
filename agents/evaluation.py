"""Evaluate agents on the same seeded scenarios: episode records, summaries, tables and plots.

The library behind ``evaluate.py``. Every agent flies the same episodes: episode ``i`` starts with
``env.reset(seed=seed + i)``, and the field comes from the reset seed, so all agents meet the same
debris fields (checked after every run through a fingerprint of each scenario).

Agents are named by *specs*:

* a baseline name from :data:`agents.BASELINES` (``apf``, ``astar``, …), built with
  :func:`agents.make_agent`;
* ``ALGO=PATH`` (or ``ALGO:PATH``) for a learned policy, ALGO one of :data:`LEARNED_ALGOS`,
  e.g. ``ppo=runs/ppo/model.zip``;
* ``pretrained``, the policy shipped with the package.

Learned and pretrained specs are resolved by ``agents.load_agent("algo:path", env)``, which arrives
with the training issue; until then they raise :class:`NotImplementedError` saying so.

Decision time is measured with :func:`time.perf_counter` around each ``predict`` call (ms). A
classical agent plans inside its first ``predict`` of an episode, so that call includes planning.

Outputs (written atomically: a temporary file in the same directory, then :func:`os.replace`):
``episodes.csv``, ``summary.json``, ``summary.md`` and ``trajectories_epNNN.png``.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import importlib
import io
import json
import math
import os
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the DebrisGym IDs)
from agents.metrics import TrajectoryMetrics, trajectory_metrics
from debris_gym.files import write_atomic
from debris_gym.scenario import Scenario
from debris_gym.thrust import commanded_accel, delta_v_rate

__all__ = [
    "CONFIDENCE",
    "LEARNED_ALGOS",
    "PRETRAINED",
    "AgentSpec",
    "EpisodeRecord",
    "EvaluationResults",
    "Trajectory",
    "build_agent",
    "check_agent_available",
    "evaluate_agents",
    "paired_delta_v",
    "parse_agent_spec",
    "parse_agent_specs",
    "plot_episode",
    "scenario_fingerprint",
    "summarize",
    "summary_markdown",
    "t_interval",
    "wilson_interval",
    "write_atomic",
    "write_outputs",
]

LEARNED_ALGOS = ("ppo", "sac", "td3", "dqn")
"""Algorithms a learned-agent spec ``ALGO=PATH`` may name (those ``train.py`` trains)."""

PRETRAINED = "pretrained"
"""Spec of the policy shipped with the package."""

CONFIDENCE = 0.95
"""Level of every confidence interval reported."""

CI_METHODS = {
    "wilson": "Wilson score interval, 95 %",
    "t": "Student t interval of the mean (scipy.stats.t), 95 %",
}

RATE_KEYS = ("success_rate", "collision_rate", "out_of_bounds_rate")
MEAN_KEYS = ("targets_captured_mean", "delta_v_mean", "time_mean", "path_length_mean")

_LEARNED_NOTE = "learned agents arrive with the training issue"


# --------------------------------------------------------------------------------------------------
# agent specs
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AgentSpec:
    """One agent to evaluate, parsed from a spec string.

    Attributes:
        text: the spec as given (``"apf"``, ``"ppo=model.zip"``, ``"pretrained"``).
        kind: ``"baseline"``, ``"learned"`` or ``"pretrained"``.
        name: the baseline name, the algorithm (``"ppo"``) or ``"pretrained"``.
        path: model file of a learned agent, else None.
        label: the agent's name in tables, CSV and plots (unique within one evaluation).
    """

    text: str
    kind: str
    name: str
    path: str | None = None
    label: str = ""

    @property
    def load_string(self) -> str:
        """What ``agents.load_agent`` takes: ``"ppo:path/model.zip"`` or ``"pretrained"``."""
        return f"{self.name}:{self.path}" if self.kind == "learned" else self.name


def _known_specs_text() -> str:
    from agents import BASELINES

    return (
        f"known baselines: {', '.join(BASELINES)}; learned agents: "
        f"{'|'.join(LEARNED_ALGOS)}=PATH (e.g. ppo=runs/ppo/model.zip); {PRETRAINED!r}"
    )


def parse_agent_spec(text: str) -> AgentSpec:
    """Parse one agent spec (see the module docstring).

    Raises:
        ValueError: unknown name or algorithm, or a learned spec without a path; the message
            lists what is known.
    """
    from agents import BASELINES

    spec = str(text).strip()
    if not spec:
        raise ValueError(f"empty agent name; {_known_specs_text()}")
    sep = min((i for i in (spec.find("="), spec.find(":")) if i >= 0), default=-1)
    if sep >= 0:
        algo, path = spec[:sep].strip().lower(), spec[sep + 1 :].strip()
        if algo not in LEARNED_ALGOS:
            raise ValueError(
                f"unknown learning algorithm {algo!r} in agent {spec!r}; "
                f"use one of {', '.join(LEARNED_ALGOS)} as ALGO=PATH"
            )
        if not path:
            raise ValueError(f"agent {spec!r} needs a model path: {algo}=path/to/model.zip")
        return AgentSpec(text=spec, kind="learned", name=algo, path=path, label=algo)
    if spec in BASELINES:
        return AgentSpec(text=spec, kind="baseline", name=spec, label=spec)
    if spec == PRETRAINED:
        return AgentSpec(text=spec, kind="pretrained", name=PRETRAINED, label=PRETRAINED)
    if spec.lower() in LEARNED_ALGOS:
        raise ValueError(f"agent {spec!r} needs a model path: {spec.lower()}=path/to/model.zip")
    raise ValueError(f"unknown agent {spec!r}; {_known_specs_text()}")


def parse_agent_specs(specs: str | Iterable[str | AgentSpec]) -> list[AgentSpec]:
    """Parse a comma-separated string or a list of specs; give each a unique label.

    Two learned agents of the same algorithm are labelled ``ppo:model_a``, ``ppo:model_b`` (the
    file stems), further clashes get ``#2``, ``#3``. The same spec twice is an error.

    Raises:
        ValueError: an unparsable spec, a repeated spec, or an empty list.
    """
    items = specs.split(",") if isinstance(specs, str) else list(specs)
    parsed = [s if isinstance(s, AgentSpec) else parse_agent_spec(s) for s in items]
    if not parsed:
        raise ValueError(f"no agents given; {_known_specs_text()}")
    texts = [p.text for p in parsed]
    repeated = sorted({t for t in texts if texts.count(t) > 1})
    if repeated:
        raise ValueError(f"agent(s) listed more than once: {', '.join(repeated)}")
    base = [p.label or p.name for p in parsed]
    labels = [
        f"{p.name}:{Path(p.path or '').stem}" if p.kind == "learned" and base.count(b) > 1 else b
        for p, b in zip(parsed, base, strict=True)
    ]
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):
        seen[label] = seen.get(label, 0) + 1
        if seen[label] > 1:
            labels[i] = f"{label}#{seen[label]}"
    return [dataclasses.replace(p, label=label) for p, label in zip(parsed, labels, strict=True)]


def check_agent_available(spec: AgentSpec) -> None:
    """Fail early, with a clear message, if ``spec`` cannot be built; do nothing otherwise.

    Baselines: their module must import. Learned agents: the model file must exist and
    ``agents.load_agent`` must exist. Pretrained: ``agents.load_agent`` must exist (whether a
    pretrained policy ships is for ``load_agent`` to say when it is called).

    Raises:
        ImportError: a baseline's module does not import (e.g. not written yet, or a missing
            optional dependency).
        FileNotFoundError: a learned agent's model file is missing.
        NotImplementedError: learned / pretrained agents while ``agents.load_agent`` is missing.
    """
    import agents

    if spec.kind == "baseline":
        module_name, class_name = agents.BASELINES[spec.name].split(":")
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise ImportError(
                f"agent {spec.label!r}: its module {module_name} cannot be imported ({exc})"
            ) from exc
        if not hasattr(module, class_name):
            raise ImportError(f"agent {spec.label!r}: {module_name} has no class {class_name}")
        return
    if spec.kind == "learned" and not Path(spec.path or "").is_file():
        raise FileNotFoundError(f"agent {spec.label!r}: model file {spec.path!r} not found")
    if getattr(agents, "load_agent", None) is None:
        raise NotImplementedError(
            f"agent {spec.text!r}: {_LEARNED_NOTE} (agents.load_agent does not exist yet); "
            "evaluate the classical baselines for now"
        )


def agent_env_options(spec: AgentSpec | str, env_id: str) -> dict[str, Any]:
    """Env options an agent needs beyond the evaluation's: for a learned policy, the
    observation options it was trained with (fields, dynamics and rules stay the same)."""
    if isinstance(spec, str):
        spec = parse_agent_spec(spec)
    if spec.kind == "baseline":
        return {}
    from agents.learned import observation_options

    try:
        return observation_options(spec.load_string, env_id)
    except (FileNotFoundError, ValueError):
        return {}  # load_agent reports the problem when the agent is built


def build_agent(spec: AgentSpec | str, env: gym.Env) -> Any:
    """The policy for ``spec`` acting in ``env`` (anything with SB3's ``predict``).

    Raises:
        NotImplementedError: learned or pretrained agents while ``agents.load_agent`` is missing.
    """
    import agents

    if isinstance(spec, str):
        spec = parse_agent_spec(spec)
    if spec.kind == "baseline":
        return agents.make_agent(spec.name, env)
    load_agent = getattr(agents, "load_agent", None)
    if load_agent is None:
        raise NotImplementedError(
            f"agent {spec.text!r}: {_LEARNED_NOTE} (agents.load_agent does not exist yet)"
        )
    return load_agent(spec.load_string, env)


# --------------------------------------------------------------------------------------------------
# records
# --------------------------------------------------------------------------------------------------


@dataclass
class Trajectory:
    """What one episode flew, sampled at step ends (kept in memory, not written to CSV).

    Attributes:
        positions: (K + 1, d) chaser positions (m), the start first.
        velocities: (K + 1, d) chaser velocities (m/s).
        accelerations: (K, d) commanded accelerations (m/s²), after the env's thrust limit and
            Δv-budget cut.
        decision_ms: (K,) wall-clock time of each ``predict`` call (ms).
        dt: step length (s).
        collision_point: position (m) at the end of the step that collided, else None.
        thrust_model: the env's thrust model ("ball" or "box"), which decides how Δv is counted.
    """

    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    decision_ms: np.ndarray
    dt: float
    collision_point: np.ndarray | None = None
    thrust_model: str = "ball"


def _csv(**kwargs: Any) -> Any:
    return field(metadata={"csv": True}, **kwargs)


@dataclass
class EpisodeRecord:
    """Result of one agent on one episode. Fields marked for CSV become ``episodes.csv`` columns.

    Units: delta_v m/s, time s, path_length m, min_clearance m (smallest surface gap to any
    body, chaser radius subtracted), decision times ms.
    """

    agent: str = _csv()
    episode: int = _csv()
    seed: int = _csv()
    success: bool = _csv()
    outcome: str = _csv()
    targets_captured: int = _csv()
    n_targets: int = _csv()
    collision: bool = _csv()
    out_of_bounds: bool = _csv()
    delta_v: float = _csv()
    time: float = _csv()
    steps: int = _csv()
    path_length: float = _csv()
    min_clearance: float = _csv()
    decision_ms_p50: float = _csv()
    decision_ms_p95: float = _csv()
    decision_ms_max: float = _csv()
    episode_return: float = _csv()
    smoothness: float = _csv()
    max_acceleration: float = _csv()
    max_deceleration: float = _csv()
    total_curvature: float = _csv()
    scenario_id: str = _csv()
    trajectory: Trajectory | None = field(default=None, repr=False)
    scenario: Scenario | None = field(default=None, repr=False)

    @property
    def metrics(self) -> TrajectoryMetrics:
        """Seed 000 Table I metrics of this episode's trajectory."""
        traj = self.trajectory
        if traj is None:
            raise ValueError("this record keeps no trajectory")
        return trajectory_metrics(
            traj.positions, traj.velocities, traj.accelerations, traj.dt, traj.thrust_model
        )


CSV_COLUMNS: tuple[str, ...] = tuple(
    "return" if f.name == "episode_return" else f.name
    for f in dataclasses.fields(EpisodeRecord)
    if f.metadata.get("csv")
)
"""Columns of ``episodes.csv`` (``episode_return`` is written as ``return``)."""


@dataclass
class EvaluationResults:
    """Everything one evaluation produced.

    Attributes:
        env_id, env_kwargs, episodes, seed: how it was run.
        max_episode_steps: the time limit in force (steps; the registered one unless overridden).
        agents: the agent specs, in evaluation order.
        records: one per agent × episode, agent-major.
        scenarios: the field of each episode (index = episode).
        elapsed: wall-clock duration of the run (s).
    """

    env_id: str
    env_kwargs: dict[str, Any]
    episodes: int
    seed: int
    max_episode_steps: int | None
    agents: list[AgentSpec]
    records: list[EpisodeRecord]
    scenarios: list[Scenario]
    elapsed: float = 0.0

    def for_agent(self, label: str) -> list[EpisodeRecord]:
        """The records of one agent, in episode order."""
        return [r for r in self.records if r.agent == label]

    def for_episode(self, episode: int) -> list[EpisodeRecord]:
        """The records of one episode, in agent order."""
        return [r for r in self.records if r.episode == episode]


def scenario_fingerprint(scenario: Scenario) -> str:
    """A short stable hash (16 hex digits) of a scenario's full content."""
    text = json.dumps(scenario.to_dict(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# --------------------------------------------------------------------------------------------------
# running episodes
# --------------------------------------------------------------------------------------------------


def _applied_accel(base: Any, action: Any, dv_spent: float) -> np.ndarray:
    """The acceleration (m/s²) the env applied for ``action``, from its public configuration."""
    cfg, scen, d = base.config, base.scenario, base.dim
    if cfg.action == "discrete":
        index = int(np.asarray(action).reshape(()))
        a = np.zeros(d)
        if index > 0:
            a[(index - 1) // 2] = 1.0 if index % 2 == 1 else -1.0
    else:
        a = np.asarray(action, dtype=float).reshape(d)
    accel = commanded_accel(a, scen.max_accel, cfg.thrust_model)
    nominal = float(delta_v_rate(accel, cfg.thrust_model)) * scen.dt
    if nominal > 0.0 and dv_spent < nominal:  # the Δv budget cut the last burn
        accel = accel * (dv_spent / nominal)
    return accel


def _outcome(info: dict[str, Any], truncated: bool) -> str:
    if info["is_success"]:
        return "success"
    if info["collision"]:
        return "collision"
    if info["out_of_bounds"]:
        return "out_of_bounds"
    if truncated:
        return "time_limit"
    return "delta_v_budget"


def run_episode(env: gym.Env, agent: Any, label: str, episode: int, seed: int) -> EpisodeRecord:
    """Fly one episode of ``agent`` from ``env.reset(seed=seed)``; return its record."""
    base = env.unwrapped
    obs, info = env.reset(seed=seed)
    scenario = base.scenario
    d = base.dim
    states = [np.asarray(info["chaser_state"], dtype=float)]
    accels: list[np.ndarray] = []
    decision_ms: list[float] = []
    total_reward = 0.0
    state = None
    done = truncated = False
    first = True
    prev_dv = float(info["delta_v"])
    clock = time.perf_counter
    while not done:
        start = clock()
        action, state = agent.predict(
            obs, state=state, episode_start=np.array([first]), deterministic=True
        )
        decision_ms.append((clock() - start) * 1e3)
        first = False
        obs, reward, terminated, truncated, info = env.step(action)
        total_reward += float(reward)
        dv = float(info["delta_v"])
        accels.append(_applied_accel(base, action, dv - prev_dv))
        prev_dv = dv
        states.append(np.asarray(info["chaser_state"], dtype=float))
        done = terminated or truncated
    state_arr = np.array(states)
    trajectory = Trajectory(
        positions=state_arr[:, :d],
        velocities=state_arr[:, d:],
        accelerations=np.array(accels).reshape(-1, d),
        decision_ms=np.array(decision_ms),
        dt=float(scenario.dt),
        collision_point=state_arr[-1, :d].copy() if info["collision"] else None,
        thrust_model=base.config.thrust_model,
    )
    metrics = trajectory_metrics(
        trajectory.positions,
        trajectory.velocities,
        trajectory.accelerations,
        trajectory.dt,
        trajectory.thrust_model,
    )
    ms = trajectory.decision_ms
    return EpisodeRecord(
        agent=label,
        episode=episode,
        seed=seed,
        success=bool(info["is_success"]),
        outcome=_outcome(info, bool(truncated)),
        targets_captured=int(info["targets_captured"]),
        n_targets=int(info["n_targets"]),
        collision=bool(info["collision"]),
        out_of_bounds=bool(info["out_of_bounds"]),
        delta_v=float(info["delta_v"]),
        time=float(info["time"]),
        steps=len(ms),
        path_length=metrics.path_length,
        min_clearance=float(info["min_clearance"]),
        decision_ms_p50=float(np.percentile(ms, 50)),
        decision_ms_p95=float(np.percentile(ms, 95)),
        decision_ms_max=float(ms.max()),
        episode_return=total_reward,
        smoothness=metrics.smoothness,
        max_acceleration=metrics.max_acceleration,
        max_deceleration=metrics.max_deceleration,
        total_curvature=metrics.total_curvature,
        scenario_id=scenario_fingerprint(scenario),
        trajectory=trajectory,
        scenario=scenario,
    )


def make_env(
    env_id: str, env_kwargs: dict[str, Any] | None = None, max_episode_steps: int | None = None
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, with the time limit overridden if given."""
    kwargs = dict(env_kwargs or {})
    if max_episode_steps is not None:
        if int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        kwargs["max_episode_steps"] = int(max_episode_steps)
    return gym.make(env_id, **kwargs)


def evaluate_agents(
    env_id: str,
    agent_specs: str | Sequence[str | AgentSpec],
    episodes: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
    max_episode_steps: int | None = None,
) -> EvaluationResults:
    """Fly every agent on the same ``episodes`` seeded scenarios.

    Episode ``i`` of every agent starts with ``env.reset(seed=seed + i)``. Each agent gets its own
    env (``gym.make(env_id, **env_kwargs)``), built once and reset per episode; a learned agent's
    env also gets the observation options it was trained with (:func:`agent_env_options`).

    Args:
        env_id: a registered ID, e.g. ``"DebrisGym/Rendezvous2D-v0"``.
        agent_specs: specs (see :func:`parse_agent_spec`), a list or a comma-separated string.
        episodes: episodes per agent, >= 1.
        seed: seed of episode 0.
        env_kwargs: keyword arguments for ``gym.make``.
        progress: show a tqdm bar over agent × episode on stderr.
        max_episode_steps: override the registration's time limit (steps).

    Raises:
        ValueError: bad arguments.
        RuntimeError: two agents met different scenarios in the same episode (a bug).
    """
    from tqdm import tqdm

    if isinstance(episodes, bool) or int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    specs = parse_agent_specs(agent_specs)
    env_kwargs = dict(env_kwargs or {})
    records: list[EpisodeRecord] = []
    time_limit = max_episode_steps
    start = time.perf_counter()
    bar = tqdm(
        total=len(specs) * episodes,
        desc="evaluate",
        unit="ep",
        file=sys.stderr,
        disable=not progress,
        dynamic_ncols=True,
    )
    try:
        for spec in specs:
            kwargs = {**env_kwargs, **agent_env_options(spec, env_id)}
            env = make_env(env_id, kwargs, max_episode_steps)
            if env.spec is not None:
                time_limit = env.spec.max_episode_steps
            try:
                agent = build_agent(spec, env)
                for i in range(episodes):
                    bar.set_postfix_str(f"{spec.label} ep {i}", refresh=False)
                    records.append(run_episode(env, agent, spec.label, i, seed + i))
                    bar.update()
            finally:
                env.close()
    finally:
        bar.close()
    scenarios = _check_same_scenarios(records, episodes)
    return EvaluationResults(
        env_id=env_id,
        env_kwargs=env_kwargs,
        episodes=int(episodes),
        seed=int(seed),
        max_episode_steps=time_limit,
        agents=specs,
        records=records,
        scenarios=scenarios,
        elapsed=time.perf_counter() - start,
    )


def _check_same_scenarios(records: list[EpisodeRecord], episodes: int) -> list[Scenario]:
    scenarios: list[Scenario] = []
    for i in range(episodes):
        group = [r for r in records if r.episode == i]
        ids = {r.scenario_id for r in group}
        if len(ids) != 1:
            raise RuntimeError(f"agents met different scenarios in episode {i}: {sorted(ids)}")
        scenarios.append(group[0].scenario)
    return scenarios


# --------------------------------------------------------------------------------------------------
# statistics
# --------------------------------------------------------------------------------------------------


def _z(confidence: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(0.5 + confidence / 2.0))


def wilson_interval(successes: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``successes / n``.

    Unlike the normal ("Wald") interval it stays inside [0, 1] and is not empty at 0/n or n/n.

    Raises:
        ValueError: n < 1 or successes outside [0, n].
    """
    if n < 1 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n and n >= 1, got {successes}/{n}")
    z = _z(confidence)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def t_interval(
    values: Sequence[float], confidence: float = CONFIDENCE
) -> tuple[float | None, float | None]:
    """Student t confidence interval of the mean of ``values``; (None, None) for fewer than 2."""
    from scipy.stats import t

    x = np.asarray(values, dtype=float)
    if x.size < 2 or not np.all(np.isfinite(x)):
        return None, None
    mean = float(x.mean())
    sem = float(x.std(ddof=1)) / math.sqrt(x.size)
    half = float(t.ppf(0.5 + confidence / 2.0, x.size - 1)) * sem
    return mean - half, mean + half


def _mean(values: Sequence[float]) -> float | None:
    return float(np.mean(values)) if len(values) else None


PAIRED_REFERENCE = "apf-mpc"
"""The agent the others' Δv is paired against when it is evaluated (else the first agent)."""


def paired_delta_v(results: EvaluationResults, reference: str | None = None) -> dict[str, Any]:
    """Each agent's Δv against ``reference`` on the episodes that both complete, paired by seed.

    Means over all episodes mix fuel with failure (a crash can be cheap: it ends early), and
    means over each agent's own successes compare different fields. Here an agent is compared
    with the reference only where both succeed on the same field: per episode the difference
    agent − reference (m/s; negative = the agent spends less), its mean and a Student t interval.

    Args:
        reference: an agent label; default :data:`PAIRED_REFERENCE` if evaluated, else the
            first agent.

    Returns:
        ``{"reference": label, "agents": {label: {"both_succeeded", "delta_v_mean",
        "reference_delta_v_mean", "difference_mean", "difference_mean_ci95"}}}`` (means None
        where no episode qualifies); ``agents`` is empty with fewer than two agents.

    Raises:
        ValueError: ``reference`` is not one of the evaluated agents.
    """
    labels = [spec.label for spec in results.agents]
    if reference is None:
        reference = PAIRED_REFERENCE if PAIRED_REFERENCE in labels else labels[0]
    if reference not in labels:
        raise ValueError(f"reference={reference!r} is not an evaluated agent; agents: {labels}")
    ref = {r.episode: r for r in results.for_agent(reference)}
    paired: dict[str, Any] = {}
    for label in labels:
        if label == reference:
            continue
        both = [
            (r.delta_v, ref[r.episode].delta_v)
            for r in results.for_agent(label)
            if r.success and r.episode in ref and ref[r.episode].success
        ]
        diff = [a - b for a, b in both]
        paired[label] = {
            "both_succeeded": len(both),
            "delta_v_mean": _mean([a for a, _ in both]),
            "reference_delta_v_mean": _mean([b for _, b in both]),
            "difference_mean": _mean(diff),
            "difference_mean_ci95": list(t_interval(diff)),
        }
    return {"reference": reference, "agents": paired}


def summarize(results: EvaluationResults, reference: str | None = None) -> dict[str, Any]:
    """Per-agent summary (DESIGN §6 keys, confidence intervals) plus how the run was made, and
    the :func:`paired_delta_v` comparison against ``reference``.

    Rates get a Wilson score interval, means a Student t interval (``ci_method`` names them).
    ``decision_ms_p50/p95`` are over all decisions of the agent, across episodes.
    ``delta_v_mean_success`` and ``time_mean_success`` average over successful episodes only
    (None without any): a failed episode can be cheap because it ended early.
    """
    agents: dict[str, Any] = {}
    for spec in results.agents:
        recs = results.for_agent(spec.label)
        n = len(recs)
        ms = np.concatenate([r.trajectory.decision_ms for r in recs if r.trajectory is not None])
        ok = [r for r in recs if r.success]
        entry: dict[str, Any] = {"spec": spec.text, "kind": spec.kind, "episodes": n}
        counts = {
            "success_rate": sum(r.success for r in recs),
            "collision_rate": sum(r.collision for r in recs),
            "out_of_bounds_rate": sum(r.out_of_bounds for r in recs),
        }
        for key, k in counts.items():
            entry[key] = k / n
            entry[f"{key}_ci95"] = list(wilson_interval(k, n))
        columns = {
            "targets_captured_mean": [r.targets_captured for r in recs],
            "delta_v_mean": [r.delta_v for r in recs],
            "time_mean": [r.time for r in recs],
            "path_length_mean": [r.path_length for r in recs],
        }
        for key, values in columns.items():
            entry[key] = _mean(values)
            entry[f"{key}_ci95"] = list(t_interval(values))
        entry["n_targets"] = recs[0].n_targets if recs else None
        entry["delta_v_mean_success"] = _mean([r.delta_v for r in ok])
        entry["time_mean_success"] = _mean([r.time for r in ok])
        entry["min_clearance_min"] = min(r.min_clearance for r in recs)
        entry["decision_ms_p50"] = float(np.percentile(ms, 50))
        entry["decision_ms_p95"] = float(np.percentile(ms, 95))
        entry["decision_ms_max"] = float(ms.max())
        entry["decisions"] = int(ms.size)
        agents[spec.label] = entry
    ci_method = {f"{k}_ci95": CI_METHODS["wilson"] for k in RATE_KEYS}
    ci_method |= {f"{k}_ci95": CI_METHODS["t"] for k in MEAN_KEYS}
    return {
        "env_id": results.env_id,
        "env_kwargs": results.env_kwargs,
        "max_episode_steps": results.max_episode_steps,
        "episodes": results.episodes,
        "seed": results.seed,
        "reset_seeds": [results.seed + i for i in range(results.episodes)],
        "scenario_ids": [scenario_fingerprint(s) for s in results.scenarios],
        "confidence": CONFIDENCE,
        "ci_method": ci_method,
        "units": {
            "delta_v": "m/s",
            "time": "s",
            "path_length": "m",
            "min_clearance": "m",
            "decision_ms": "ms",
        },
        "elapsed_s": results.elapsed,
        "agents": agents,
        "paired_delta_v": paired_delta_v(results, reference),
    }


# --------------------------------------------------------------------------------------------------
# tables and files
# --------------------------------------------------------------------------------------------------


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 10**digits else f"{value:.0f}"
    return str(value)


def _with_ci(entry: dict[str, Any], key: str, digits: int = 3) -> str:
    lo, hi = entry.get(f"{key}_ci95", (None, None))
    text = _fmt(entry[key], digits)
    if lo is None or hi is None:
        return text
    return f"{text} [{_fmt(lo, digits)}, {_fmt(hi, digits)}]"


def summary_markdown(summary: dict[str, Any]) -> str:
    """The summary as a Markdown table, one row per agent, 95 % intervals in brackets."""
    n = summary["episodes"]
    lines = [
        f"Env `{summary['env_id']}`"
        + (f" with `{json.dumps(summary['env_kwargs'])}`" if summary["env_kwargs"] else "")
        + (
            f", time limit {summary['max_episode_steps']} steps"
            if summary.get("max_episode_steps")
            else ""
        )
        + f"; {n} episode{'s' if n != 1 else ''} per agent, "
        + (
            f"reset seeds {summary['seed']}…{summary['seed'] + n - 1}."
            if n > 1
            else f"reset seed {summary['seed']}."
        ),
        "",
        "| agent | success | targets captured | Δv [m/s] | time [s] | path [m] | collision "
        "| min clearance [m] | decision p50 / p95 [ms] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, e in summary["agents"].items():
        captured = _with_ci(e, "targets_captured_mean")
        if e.get("n_targets") is not None:
            captured += f" / {e['n_targets']}"
        lines.append(
            f"| {label} | {_with_ci(e, 'success_rate', 2)} | {captured} "
            f"| {_with_ci(e, 'delta_v_mean')} | {_with_ci(e, 'time_mean')} "
            f"| {_with_ci(e, 'path_length_mean')} | {_with_ci(e, 'collision_rate', 2)} "
            f"| {_fmt(e['min_clearance_min'])} "
            f"| {_fmt(e['decision_ms_p50'])} / {_fmt(e['decision_ms_p95'])} |"
        )
    lines += [
        "",
        "Brackets: 95 % confidence intervals — Wilson score for rates, Student t for means "
        "(means are over all episodes, failed ones included).",
    ]
    paired = summary.get("paired_delta_v") or {}
    if paired.get("agents"):
        ref = paired["reference"]
        lines += [
            "",
            f"Δv on the missions both complete, paired with {ref} by seed:",
            "",
            f"| agent | both complete | agent Δv [m/s] | {ref} Δv [m/s] | agent − {ref} [m/s] |",
            "|---|---|---|---|---|",
        ]
        for label, e in paired["agents"].items():
            lines.append(
                f"| {label} | {e['both_succeeded']} / {n} | {_fmt(e['delta_v_mean'])} "
                f"| {_fmt(e['reference_delta_v_mean'])} | {_with_ci(e, 'difference_mean')} |"
            )
    return "\n".join(lines) + "\n"


def _json_safe(value: Any) -> Any:
    """Replace non-finite floats by None (JSON has no NaN/inf) and numpy scalars by Python ones."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def to_json(data: Any) -> str:
    """Strict JSON text (non-finite numbers become null), indented, with a final newline."""
    return json.dumps(_json_safe(data), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def episodes_csv(records: Iterable[EpisodeRecord]) -> str:
    """``episodes.csv`` text: a header and one row per record (trajectories left out)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    names = [f.name for f in dataclasses.fields(EpisodeRecord) if f.metadata.get("csv")]
    for r in records:
        row = []
        for name in names:
            value = getattr(r, name)
            row.append(repr(value) if isinstance(value, float) else value)
        writer.writerow(row)
    return buf.getvalue()


# --------------------------------------------------------------------------------------------------
# plots
# --------------------------------------------------------------------------------------------------

AGENT_COLOURS = (
    "#1f5fd0",
    "#d62728",
    "#9467bd",
    "#17becf",
    "#8c564b",
    "#e377c2",
    "#bcbd22",
    "#000000",
    "#7f7f7f",
)
"""One colour per agent (targets keep the renderer's orange, debris its grey)."""


def plot_episode(results: EvaluationResults, episode: int) -> bytes:
    """PNG bytes: every agent's trajectory of ``episode`` over its field.

    Drawn like the env's renderer (:mod:`debris_gym.envs.rendering`): top view, along-track (y)
    right, radial (x) up; a 3D field gets a second panel (y right, z up). Debris grey, targets
    orange, dock a square, the start a triangle, each agent its own colour, a collision an ×
    (at the end of the step that collided). Uses matplotlib's Agg canvas (no pyplot state).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PatchCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Patch, Polygon

    from debris_gym.envs.rendering import (
        DEBRIS_EDGE,
        DEBRIS_FACE,
        DOCK,
        TARGET_EDGE,
        TARGET_OPEN,
        VIEWS,
        style_field_axes,
    )

    scenario = results.scenarios[episode]
    recs = results.for_episode(episode)
    views = VIEWS[scenario.dim]
    n = len(views)
    fig = Figure(figsize=(6.4 * n + 0.4, 7.4), dpi=100, facecolor="white")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    handles: list[Any] = []
    for k, ((h, v), ax) in enumerate(zip(views, axes, strict=True)):
        style_field_axes(ax, scenario, h, v, title=n > 1)
        patches = []
        for body in scenario.obstacles:
            if body.vertices is not None:
                pts = np.asarray(body.position) + np.asarray(body.vertices)
                patches.append(Polygon(pts[:, [h, v]], closed=True))
            else:
                patches.append(Circle((body.position[h], body.position[v]), body.radius))
        ax.add_collection(
            PatchCollection(
                patches, facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, linewidth=0.7, zorder=1
            ),
            autolim=False,
        )
        for i, t in enumerate(scenario.targets):
            ax.add_patch(
                Circle(
                    (t.position[h], t.position[v]),
                    t.radius,
                    facecolor=TARGET_OPEN,
                    edgecolor=TARGET_EDGE,
                    linewidth=0.6,
                    zorder=3,
                )
            )
            ax.scatter(
                [t.position[h]], [t.position[v]], s=110, facecolors="none",
                edgecolors=TARGET_OPEN, linewidths=1.8, zorder=3,
            )  # fmt: skip
            ax.annotate(
                str(i), (t.position[h], t.position[v]), xytext=(7, 6),
                textcoords="offset points", fontsize=8, color=TARGET_EDGE, fontweight="bold",
                zorder=4,
            )  # fmt: skip
        ax.plot(
            [scenario.dock[h]], [scenario.dock[v]], marker="s", markersize=11,
            markerfacecolor="white", markeredgecolor=DOCK, markeredgewidth=1.8,
            linestyle="none", zorder=2,
        )  # fmt: skip
        for j, rec in enumerate(recs):
            traj = rec.trajectory
            if traj is None:
                continue
            colour = AGENT_COLOURS[j % len(AGENT_COLOURS)]
            p = traj.positions
            ax.plot(p[:, h], p[:, v], color=colour, linewidth=1.4, alpha=0.9, zorder=5)
            ax.plot(
                [p[-1, h]], [p[-1, v]], marker="o", markersize=5, color=colour,
                markeredgecolor="white", markeredgewidth=0.6, linestyle="none", zorder=6,
            )  # fmt: skip
            if traj.collision_point is not None:
                c = traj.collision_point
                ax.plot(
                    [c[h]], [c[v]], marker="x", markersize=11, markeredgewidth=2.5,
                    color=colour, linestyle="none", zorder=7,
                )  # fmt: skip
            if k == 0:
                handles.append(
                    Line2D(
                        [], [], color=colour, linewidth=2.0,
                        label=f"{rec.agent}: {rec.outcome.replace('_', ' ')}, "
                        f"{rec.targets_captured}/{rec.n_targets} captured, "
                        f"Δv {rec.delta_v:.3g} m/s",
                    )
                )  # fmt: skip
        start = recs[0].trajectory.positions[0] if recs and recs[0].trajectory else scenario.dock
        ax.plot(
            [start[h]], [start[v]], marker="^", markersize=8, markerfacecolor=DOCK,
            markeredgecolor="white", linestyle="none", zorder=5.5,
        )  # fmt: skip

    def marker(label: str, **kw: Any) -> Any:
        return Line2D([], [], linestyle="none", label=label, **kw)

    handles += [
        marker("dock", marker="s", markersize=8, markerfacecolor="white", markeredgecolor=DOCK,
               markeredgewidth=1.5),
        marker("start", marker="^", markersize=8, markerfacecolor=DOCK, markeredgecolor="white"),
        marker("end", marker="o", markersize=6, markerfacecolor="#333333",
               markeredgecolor="white"),
        marker("target", marker="o", markersize=8, markerfacecolor=TARGET_OPEN,
               markeredgecolor=TARGET_OPEN),
        Patch(facecolor=DEBRIS_FACE, edgecolor=DEBRIS_EDGE, label="debris"),
        marker("collision", marker="x", markersize=8, markeredgewidth=2.0, color="#333333"),
    ]  # fmt: skip
    name = scenario.name or "debris field"
    fig.suptitle(
        f"{results.env_id} — episode {episode} (reset seed {results.seed + episode}, {name})",
        fontsize=10,
        fontweight="bold",
    )
    fig.legend(
        handles=handles, loc="lower center", ncol=2 if n == 1 else 3, fontsize=8, frameon=False
    )
    rows = math.ceil(len(handles) / (2 if n == 1 else 3))
    fig.subplots_adjust(left=0.1 / n, right=1 - 0.03 / n, top=0.92, bottom=0.1 + 0.032 * rows)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def write_outputs(
    results: EvaluationResults,
    out_dir: str | os.PathLike[str],
    plots: int = 3,
    summary: dict[str, Any] | None = None,
) -> list[Path]:
    """Write episodes.csv, summary.json, summary.md and ``plots`` trajectory PNGs into out_dir.

    Returns the paths written, in that order. ``out_dir`` is created if needed.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarize(results) if summary is None else summary
    written = []
    for name, text in (
        ("episodes.csv", episodes_csv(results.records)),
        ("summary.json", to_json(summary)),
        ("summary.md", summary_markdown(summary)),
    ):
        write_atomic(out / name, text)
        written.append(out / name)
    for i in range(min(max(plots, 0), results.episodes)):
        path = out / f"trajectories_ep{i:03d}.png"
        write_atomic(path, plot_episode(results, i))
        written.append(path)
    return written


# --------------------------------------------------------------------------------------------------
# seed 000 Table I (the --paper run)
# --------------------------------------------------------------------------------------------------

PAPER_ENV_ID = "DebrisGym/PaperField2D-v0"
"""The world of seed 000 (fixed: one episode is enough)."""

PAPER_AGENTS = ("apf", "apf-mpc", "astar")
"""Our agents compared with seed 000's Table I: its potential planner, APF-MPC, and A*."""

PAPER_TABLE_I: dict[str, dict[str, float]] = {
    "apf": {
        "path_length": 841.7818,
        "fuel": 2367.9007,
        "smoothness": 3.6116,
        "time": 0.2000,
        "max_acceleration": 361.1585,
        "max_deceleration": 361.1585,
        "waypoints": 2,
        "total_curvature": 0.0,
    },
    "apf-mpc": {
        "path_length": 105.1884,
        "fuel": 69.5320,
        "smoothness": 3.8684e-4,
        "time": 8379.0,
        "max_acceleration": 21.8227,
        "max_deceleration": 2.2462e-7,
        "waypoints": 83790,
        "total_curvature": 2.3422e4,
    },
}
"""Seed 000 Table I as printed ("Potential Planner" → apf, "Integrated APF-MPC" → apf-mpc; the
paper prints no A* row). Its units: path m, fuel "units of fuel" (undefined), smoothness
undefined, time s (for APF-MPC apparently the computing time), accelerations m/s², curvature rad."""

TABLE_I_ROWS: tuple[tuple[str, str], ...] = (
    ("path_length", "Path length [m]"),
    ("fuel", "Fuel [paper: units of fuel; ours: Δv m/s]"),
    ("smoothness", "Smoothness [ours: mean ‖Δu‖², m²/s⁴]"),
    ("time", "Total time [s]"),
    ("max_acceleration", "Max acceleration [m/s²]"),
    ("max_deceleration", "Max deceleration [m/s²]"),
    ("waypoints", "Number of waypoints"),
    ("total_curvature", "Total curvature [rad]"),
)


def paper_table(results: EvaluationResults, skipped: dict[str, str] | None = None) -> dict:
    """Seed 000 Table I beside our measurement of the same metrics on its world (episode 0).

    Returns ``{"paper": PAPER_TABLE_I, "ours": {agent: {metric: value, plus "success",
    "targets_captured", "n_targets", "compute_s"}}, "skipped": {agent: reason}}``; agents not in
    ``results`` appear in neither ``ours`` nor the table's numbers.
    """
    ours: dict[str, dict[str, Any]] = {}
    for rec in results.for_episode(0):
        row: dict[str, Any] = dict(rec.metrics.to_dict())
        row["success"] = rec.success
        row["outcome"] = rec.outcome
        row["targets_captured"] = rec.targets_captured
        row["n_targets"] = rec.n_targets
        traj = rec.trajectory
        row["compute_s"] = float(traj.decision_ms.sum() / 1e3) if traj is not None else None
        ours[rec.agent] = row
    return {
        "env_id": results.env_id,
        "metric_units": {
            "path_length": "m",
            "fuel": "m/s (Δv); paper: undefined 'units of fuel'",
            "smoothness": "m²/s⁴ (mean squared change of the acceleration command); paper: "
            "undefined",
            "time": "s (simulated mission time)",
            "max_acceleration": "m/s² (commanded, along the motion)",
            "max_deceleration": "m/s² (commanded, against the motion)",
            "waypoints": "steps",
            "total_curvature": "rad",
        },
        "paper": PAPER_TABLE_I,
        "ours": ours,
        "skipped": dict(skipped or {}),
    }


def paper_table_markdown(table: dict[str, Any]) -> str:
    """Markdown: metric | paper APF | ours APF | paper APF-MPC | ours APF-MPC | ours A*."""
    paper, ours = table["paper"], table["ours"]

    def cell(agent: str, key: str) -> str:
        if agent not in ours:
            return "n/a"
        value = ours[agent].get(key)
        if isinstance(value, bool):
            return "yes" if value else "no"
        return _fmt(value, 5) if isinstance(value, float) else _fmt(value)

    lines = [
        "| metric | paper APF | ours APF | paper APF-MPC | ours APF-MPC | ours A* |",
        "|---|---|---|---|---|---|",
    ]
    for key, title in TABLE_I_ROWS:
        lines.append(
            f"| {title} | {paper['apf'][key]:.10g} | {cell('apf', key)} "
            f"| {paper['apf-mpc'][key]:.10g} | {cell('apf-mpc', key)} "
            f"| {cell('astar', key)} |"
        )
    lines.append(
        f"| *mission success (not in Table I)* | — | {cell('apf', 'success')} | — "
        f"| {cell('apf-mpc', 'success')} | {cell('astar', 'success')} |"
    )
    lines.append(
        f"| *compute time, Σ predict [s] (not in Table I)* | — | {cell('apf', 'compute_s')} | — "
        f"| {cell('apf-mpc', 'compute_s')} | {cell('astar', 'compute_s')} |"
    )
    notes = [
        "",
        f"Ours: one episode of `{table['env_id']}` (seed 000's world, double integrator). "
        "Fuel is Δv; smoothness is our definition (the paper gives none); time is simulated "
        "mission time (the paper's 8379 s for APF-MPC matches its reported computing time).",
    ]
    for agent, reason in table.get("skipped", {}).items():
        notes.append(f"Not run: {agent} — {reason}")
    return "\n".join(lines + notes) + "\n"
