"""What an evaluation produces: per-episode records, their trajectories, and the whole run.

Units: positions m, velocities m/s, accelerations m/s², times s, Δv m/s, decision times ms.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.experiments.evaluation.metrics import TrajectoryMetrics, trajectory_metrics
from agents.experiments.evaluation.specs import AgentSpec
from debris_gym.scenario import Scenario

__all__ = [
    "CSV_COLUMNS",
    "RECORD_FIELDS",
    "SHIELD_COLUMNS",
    "TIMING_COLUMNS",
    "EpisodeRecord",
    "EvaluationResults",
    "Trajectory",
    "scenario_fingerprint",
]


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
    body, chaser radius subtracted), decision times ms. ``outcome`` is how the episode ended:
    ``success``, ``collision``, ``out_of_bounds``, ``delta_v_budget`` (the Δv budget ran out:
    a failure, flagged by ``budget_spent``) or ``time_limit``. ``task_score`` is the env's unshaped
    score of the episode (every reward term but the progress shaping, undiscounted);
    ``episode_return`` the shaped return. ``shield_*``: with the safety shield on
    (``evaluate.py --shield``), the commands it replaced and the mean and largest change
    (‖u_safe − u_cmd‖ / max_accel, a fraction of the thrust limit); 0 without it.
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
    budget_spent: bool = _csv()
    delta_v: float = _csv()
    time: float = _csv()
    steps: int = _csv()
    path_length: float = _csv()
    min_clearance: float = _csv()
    decision_ms_p50: float = _csv()
    decision_ms_p95: float = _csv()
    decision_ms_max: float = _csv()
    episode_return: float = _csv()
    task_score: float = _csv()
    smoothness: float = _csv()
    max_acceleration: float = _csv()
    max_deceleration: float = _csv()
    total_curvature: float = _csv()
    scenario_id: str = _csv()
    shield_interventions: int = _csv(default=0)
    shield_size_mean: float = _csv(default=0.0)
    shield_size_max: float = _csv(default=0.0)
    trajectory: Trajectory | None = field(default=None, repr=False)
    scenario: Scenario | None = field(default=None, repr=False)

    @property
    def metrics(self) -> TrajectoryMetrics:
        """[APF-MPC] Table I metrics of this episode's trajectory."""
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

RECORD_FIELDS: tuple[str, ...] = tuple(
    f.name for f in dataclasses.fields(EpisodeRecord) if f.metadata.get("csv")
)
"""The :class:`EpisodeRecord` fields behind :data:`CSV_COLUMNS`, in the same order."""

SHIELD_COLUMNS: tuple[str, ...] = ("shield_interventions", "shield_size_mean", "shield_size_max")
"""The columns the safety shield fills (0 for an unshielded run)."""

TIMING_COLUMNS: tuple[str, ...] = ("decision_ms_p50", "decision_ms_p95", "decision_ms_max")
"""The columns that measure wall-clock time (ms) and so differ between two runs of the same
evaluation; every other column is a function of the seeds, the agents and the env."""


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
        suite: name of the frozen suite flown (``evaluate.py --suite``), else None.
        suite_hash: the suite's content hash (:attr:`debris_gym.suites.Suite.content_hash`).
        suite_size: missions in the whole suite (``episodes`` flies its first ones).
        seeds: reset seed of each episode when they are not ``seed + i`` (a suite's), else None.
        shield: the safety shield's parameters when every agent flew shielded, else None.
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
    suite: str | None = None
    suite_hash: str | None = None
    suite_size: int | None = None
    seeds: list[int] | None = None
    shield: dict[str, Any] | None = None

    @property
    def reset_seeds(self) -> list[int]:
        """The reset seed of each episode, episode order."""
        if self.seeds is not None:
            return list(self.seeds)
        return [self.seed + i for i in range(self.episodes)]

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
