"""Statistics of an evaluation: confidence intervals, per-agent summaries, paired Δv.

Rates get a Wilson score interval, means a Student t interval; Δv is compared
paired by seed on the episodes both agents complete.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.experiments.evaluation.records import EvaluationResults, scenario_fingerprint

__all__ = [
    "CONFIDENCE",
    "PAIRED_REFERENCE",
    "paired_delta_v",
    "summarize",
    "t_interval",
    "wilson_interval",
]

CONFIDENCE = 0.95
"""Level of every confidence interval reported."""

CI_METHODS = {
    "wilson": "Wilson score interval, 95 %",
    "t": "Student t interval of the mean (scipy.stats.t), 95 %",
}

RATE_KEYS = ("success_rate", "collision_rate", "out_of_bounds_rate")
MEAN_KEYS = (
    "targets_captured_mean", "delta_v_mean", "time_mean", "path_length_mean", "task_score_mean"
)  # fmt: skip


def _z(confidence: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(0.5 + confidence / 2.0))


def wilson_interval(successes: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval [Wilson27] of a binomial proportion ``successes / n``.

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
    """Student t confidence interval [Student08] of the mean of ``values``; (None, None) for
    fewer than 2 values."""
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
            "task_score_mean": [r.task_score for r in recs],
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
