"""One episode flown and recorded (:func:`run_episode`): what every backend runs, in this process
or a worker.

Decision time is measured with :func:`time.perf_counter` around each ``predict`` call (ms). A
classical agent plans inside its first ``predict`` of an episode, so that call includes planning.
The accelerations recorded are the env's own ``info["applied_accel"]`` (after its thrust limit and
Δv-budget cut), so the metrics see exactly what was flown. An agent that fails (its ``predict``
raises, answers with no ``(action, state)``, or gives an action the env refuses) raises
:class:`~agents.experiments.evaluation.failures.AgentFailure` naming the agent, episode and step.
"""

from __future__ import annotations

import math
import time
from typing import Any

import gymnasium as gym
import numpy as np

from agents.experiments.evaluation.failures import AgentFailure, describe
from agents.experiments.evaluation.metrics import trajectory_metrics
from agents.experiments.evaluation.records import EpisodeRecord, Trajectory, scenario_fingerprint
from agents.policies.base import unwrap
from agents.policies.shielded import ShieldedAgent
from debris_gym.scenario import Scenario

__all__ = ["run_episode"]


def _outcome(info: dict[str, Any], truncated: bool) -> str:
    """How the episode ended, from its last step's info: the env's own verdict first (its
    Δv budget running out is a failure of its own, even on the time limit's last step)."""
    if info["is_success"]:
        return "success"
    if info["collision"]:
        return "collision"
    if info["out_of_bounds"]:
        return "out_of_bounds"
    if info["budget_spent"]:
        return "delta_v_budget"
    if truncated:
        return "time_limit"
    raise RuntimeError(f"the episode ended with no outcome in its info: {sorted(info)}")


def run_episode(
    env: gym.Env,
    agent: Any,
    label: str,
    episode: int,
    seed: int,
    scenario: Scenario | None = None,
) -> EpisodeRecord:
    """Fly one episode of ``agent`` from ``env.reset(seed=seed)``, with ``scenario`` pinned if
    given (a suite's mission); return its record.

    Raises:
        AgentFailure: the agent's ``predict`` raised (``SystemExit`` included), returned
            something other than ``(action, state)``, or gave an action the env refused (NaN, a
            wrong shape, None, a string, ...); the error names the agent, episode and step.
    """
    base = unwrap(env)
    options = None if scenario is None else {"scenario": scenario}
    obs, info = env.reset(seed=seed, options=options)
    scenario = base.scenario
    if scenario is None:
        raise RuntimeError(f"the env has no field after reset(seed={seed})")
    d = base.dim
    states = [np.asarray(info["chaser_state"], dtype=float)]
    accels: list[np.ndarray] = []
    decision_ms: list[float] = []
    total_reward = 0.0
    state = None
    done = truncated = False
    first = True
    clock = time.perf_counter
    while not done:
        step = len(decision_ms)
        start = clock()
        try:
            answer = agent.predict(
                obs, state=state, episode_start=np.array([first]), deterministic=True
            )
        except (Exception, SystemExit) as exc:  # the agent's code, not the evaluation, failed
            reason = f"predict raised {describe(exc)}"
            raise AgentFailure(label, episode, seed, step, reason) from exc
        decision_ms.append((clock() - start) * 1e3)
        first = False
        if not (isinstance(answer, tuple) and len(answer) == 2):
            raise AgentFailure(
                label, episode, seed, step,
                f"predict must return (action, state), got {_shown(answer)}",
            )  # fmt: skip
        action, state = answer
        try:
            obs, reward, terminated, truncated, info = env.step(action)
        except (ValueError, TypeError) as exc:  # the env checks the action before it steps
            raise AgentFailure(
                label, episode, seed, step, f"the env refused its action {_shown(action)}: {exc}"
            ) from exc
        total_reward += float(reward)
        accels.append(np.asarray(info["applied_accel"], dtype=float))
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
    stats = agent.stats if isinstance(agent, ShieldedAgent) else None
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
        budget_spent=bool(info["budget_spent"]),
        delta_v=float(info["delta_v"]),
        time=float(info["time"]),
        steps=len(ms),
        path_length=metrics.path_length,
        min_clearance=float(info["min_clearance"]),
        decision_ms_p50=float(np.percentile(ms, 50)),
        decision_ms_p95=float(np.percentile(ms, 95)),
        decision_ms_max=float(ms.max()),
        episode_return=total_reward,
        task_score=float(info.get("task_score", math.nan)),
        smoothness=metrics.smoothness,
        max_acceleration=metrics.max_acceleration,
        max_deceleration=metrics.max_deceleration,
        total_curvature=metrics.total_curvature,
        scenario_id=scenario_fingerprint(scenario),
        shield_interventions=0 if stats is None else stats.interventions,
        shield_size_mean=0.0 if stats is None else stats.size_mean,
        shield_size_max=0.0 if stats is None else stats.size_max,
        trajectory=trajectory,
        scenario=scenario,
    )


def _shown(value: Any, width: int = 80) -> str:
    """``repr(value)`` cut to ``width`` characters (for error messages)."""
    text = repr(value)
    return text if len(text) <= width else text[: width - 1] + "…"
