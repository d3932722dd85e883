"""Statistics of an evaluation: confidence intervals, per-agent summaries, paired comparisons.

Every interval stays inside its metric's range:

* rates (success, collision, out of bounds, Δv budget spent) get a Wilson score interval
  [Wilson27], exactly 0 or 1 at the ends of [0, 1];
* means of per-episode metrics (targets captured in [0, n_targets]; Δv, time and path length,
  non-negative; the task score) get a seeded percentile bootstrap [Efron93]: its ends are means
  of resampled episodes, so they lie between the smallest and largest value observed, never
  outside the metric's range, and the same data always give the same interval. A column equal
  in every episode has no spread to speak of: its interval is the value itself and the summary
  says the column is constant;
* paired differences (agent − reference on the same seed) may be negative: a Student t interval
  [Student08].

Success is compared paired by seed with the exact McNemar test [McNemar47]; Δv and the time of
flight paired on the episodes both agents complete.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.experiments.evaluation.records import EvaluationResults, scenario_fingerprint

__all__ = [
    "BOOTSTRAP_RESAMPLES",
    "BOOTSTRAP_SEED",
    "CONFIDENCE",
    "PAIRED_REFERENCE",
    "bootstrap_interval",
    "is_constant",
    "mcnemar_exact",
    "paired_delta_v",
    "paired_success",
    "summarize",
    "t_interval",
    "wilson_interval",
]

CONFIDENCE = 0.95
"""Level of every confidence interval reported."""

BOOTSTRAP_RESAMPLES = 10_000
"""Resamples of a bootstrap interval."""

BOOTSTRAP_SEED = 0
"""Seed of the bootstrap's generator: the same episodes always give the same interval."""

CI_METHODS = {
    "wilson": "Wilson score interval, 95 %, ends exactly 0 / 1 at 0/n and n/n",
    "bootstrap": f"percentile bootstrap of the mean over episodes, {BOOTSTRAP_RESAMPLES} "
    f"resamples, generator seed {BOOTSTRAP_SEED}, 95 %; ends within the observed values",
    "t": "Student t interval of the mean (scipy.stats.t), 95 %",
}

RATE_KEYS = ("success_rate", "collision_rate", "out_of_bounds_rate", "budget_spent_rate")
MEAN_KEYS = (
    "targets_captured_mean", "delta_v_mean", "time_mean", "path_length_mean", "task_score_mean"
)  # fmt: skip


def _z(confidence: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(0.5 + confidence / 2.0))


def wilson_interval(successes: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval [Wilson27] of a binomial proportion ``successes / n``.

    Unlike the normal ("Wald") interval it stays inside [0, 1] and is not empty at 0/n or n/n;
    there its outer end is exactly 0 (or 1), not a rounding residue.

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
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


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


def is_constant(values: Sequence[float] | np.ndarray) -> bool:
    """Whether every value equals the first (True for one value; False for none)."""
    x = np.asarray(values, dtype=float)
    return bool(x.size >= 1 and np.all(x == x[0]))


def bootstrap_interval(
    values: Sequence[float],
    low: float | None = None,
    high: float | None = None,
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float | None, float | None]:
    """Percentile bootstrap interval [Efron93] of the mean of ``values``, deterministic.

    Episodes are resampled with replacement ``resamples`` times (a generator seeded with
    ``seed``); the interval is the central ``confidence`` quantile range of the resampled means.
    A mean of values lies between their minimum and maximum, so the ends do too — the interval
    cannot leave a metric's range; they are also clamped to ``[low, high]`` against rounding.
    A constant column gives ``(value, value)``.

    Args:
        values: one number per episode.
        low, high: the metric's range (None = unbounded on that side); every value must lie in
            it.

    Returns:
        ``(lower, upper)``; (None, None) for fewer than 2 values or a non-finite one.

    Raises:
        ValueError: ``resamples`` < 1, ``confidence`` outside (0, 1), or a value outside
            ``[low, high]``.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    if isinstance(resamples, bool) or int(resamples) != resamples or resamples < 1:
        raise ValueError(f"resamples must be an integer >= 1, got {resamples!r}")
    x = np.asarray(values, dtype=float)
    if x.size < 2 or not np.all(np.isfinite(x)):
        return None, None
    lo_range = -math.inf if low is None else float(low)
    hi_range = math.inf if high is None else float(high)
    if x.min() < lo_range or x.max() > hi_range:
        raise ValueError(
            f"values must lie in [{low}, {high}] (the metric's range), got {x.min():g}…{x.max():g}"
        )
    if is_constant(x):
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    means = np.empty(int(resamples))
    block = max(1, 1_000_000 // x.size)  # bounds the index array's memory
    for start in range(0, int(resamples), block):
        stop = min(int(resamples), start + block)
        means[start:stop] = x[rng.integers(0, x.size, size=(stop - start, x.size))].mean(axis=1)
    tail = (1.0 - confidence) / 2.0
    lower, upper = np.quantile(means, [tail, 1.0 - tail])
    floor, ceiling = max(lo_range, float(x.min())), min(hi_range, float(x.max()))
    return float(min(max(lower, floor), ceiling)), float(min(max(upper, floor), ceiling))


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar test [McNemar47] from the discordant pair counts.

    Under the null hypothesis (both agents succeed equally often) each of the ``b + c``
    discordant pairs falls either way with probability 1/2, so ``min(b, c)`` is
    Binomial(b + c, 1/2); the p-value is ``min(1, 2·P(X ≤ min(b, c)))``, 1 when ``b + c = 0``.
    Computed exactly in integers.

    Args:
        b: pairs where the agent succeeds and the reference fails.
        c: pairs where the reference succeeds and the agent fails.

    Raises:
        ValueError: ``b`` or ``c`` not an integer >= 0.
    """
    for name, value in (("b", b), ("c", c)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise ValueError(f"{name} must be an integer >= 0 (a count of pairs), got {value!r}")
    n, k = int(b) + int(c), min(int(b), int(c))
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(k + 1))
    return min(1.0, 2 * tail / 2**n)


def _mean(values: Sequence[float]) -> float | None:
    return float(np.mean(values)) if len(values) else None


PAIRED_REFERENCE = "apf-mpc"
"""The agent the others are paired against when it is evaluated (else the first agent)."""

PAIRED_SUCCESS_TEST = "exact McNemar"
"""Name of the paired success test in ``summary.json``."""


def _reference(results: EvaluationResults, reference: str | None) -> str:
    labels = [spec.label for spec in results.agents]
    if reference is None:
        reference = PAIRED_REFERENCE if PAIRED_REFERENCE in labels else labels[0]
    if reference not in labels:
        raise ValueError(f"reference={reference!r} is not an evaluated agent; agents: {labels}")
    return reference


def paired_delta_v(results: EvaluationResults, reference: str | None = None) -> dict[str, Any]:
    """Each agent's Δv and time of flight against ``reference`` on the episodes that both
    complete, paired by seed.

    Means over all episodes mix fuel with failure (a crash can be cheap: it ends early), and
    means over each agent's own successes compare different fields. Here an agent is compared
    with the reference only where both succeed on the same field: per episode the difference
    agent − reference (Δv in m/s, negative = the agent spends less; time in s, negative = the
    agent is done sooner), its mean and a Student t interval.

    Args:
        reference: an agent label; default :data:`PAIRED_REFERENCE` if evaluated, else the
            first agent.

    Returns:
        ``{"reference": label, "agents": {label: {"both_succeeded", "delta_v_mean",
        "reference_delta_v_mean", "difference_mean", "difference_mean_ci95", "time_mean",
        "reference_time_mean", "time_difference_mean", "time_difference_mean_ci95"}}}``
        (means None where no episode qualifies); ``agents`` is empty with fewer than two agents.

    Raises:
        ValueError: ``reference`` is not one of the evaluated agents.
    """
    reference = _reference(results, reference)
    ref = {r.episode: r for r in results.for_agent(reference)}
    paired: dict[str, Any] = {}
    for spec in results.agents:
        if spec.label == reference:
            continue
        both = [
            (r, ref[r.episode])
            for r in results.for_agent(spec.label)
            if r.success and r.episode in ref and ref[r.episode].success
        ]
        diff = [a.delta_v - b.delta_v for a, b in both]
        time_diff = [a.time - b.time for a, b in both]
        paired[spec.label] = {
            "both_succeeded": len(both),
            "delta_v_mean": _mean([a.delta_v for a, _ in both]),
            "reference_delta_v_mean": _mean([b.delta_v for _, b in both]),
            "difference_mean": _mean(diff),
            "difference_mean_ci95": list(t_interval(diff)),
            "time_mean": _mean([a.time for a, _ in both]),
            "reference_time_mean": _mean([b.time for _, b in both]),
            "time_difference_mean": _mean(time_diff),
            "time_difference_mean_ci95": list(t_interval(time_diff)),
        }
    return {"reference": reference, "agents": paired}


def paired_success(results: EvaluationResults, reference: str | None = None) -> dict[str, Any]:
    """Each agent's success against ``reference`` on the same seeds: the exact McNemar test.

    Only the discordant episodes carry information on which agent succeeds more often: ``b``
    where the agent succeeds and the reference fails, ``c`` the other way round. The p-value is
    :func:`mcnemar_exact` of (b, c) (two-sided; 1 when no episode is discordant).

    Returns:
        ``{"test": "exact McNemar", "reference": label, "agents": {label: {"pairs", "b", "c",
        "both_succeeded", "neither_succeeded", "p_value"}}}``.

    Raises:
        ValueError: ``reference`` is not one of the evaluated agents.
    """
    reference = _reference(results, reference)
    ref = {r.episode: r.success for r in results.for_agent(reference)}
    paired: dict[str, Any] = {}
    for spec in results.agents:
        if spec.label == reference:
            continue
        pairs = [
            (r.success, ref[r.episode]) for r in results.for_agent(spec.label) if r.episode in ref
        ]
        b = sum(a and not r for a, r in pairs)
        c = sum(r and not a for a, r in pairs)
        paired[spec.label] = {
            "pairs": len(pairs),
            "b": b,
            "c": c,
            "both_succeeded": sum(a and r for a, r in pairs),
            "neither_succeeded": sum(not a and not r for a, r in pairs),
            "p_value": mcnemar_exact(b, c),
        }
    return {"test": PAIRED_SUCCESS_TEST, "reference": reference, "agents": paired}


def _suite_entry(results: EvaluationResults) -> dict[str, Any] | None:
    if results.suite is None:
        return None
    return {
        "name": results.suite,
        "hash": results.suite_hash,
        "missions_flown": results.episodes,
        "missions_in_suite": results.suite_size,
    }


def _shield_entry(recs: Sequence[Any], decisions: int) -> dict[str, Any]:
    """An agent's shield interventions: per episode (mean, bootstrap interval), their share of
    all decisions, and their size (‖u_safe − u_cmd‖ / max_accel) over all interventions."""
    counts = [r.shield_interventions for r in recs]
    total = sum(counts)
    size_sum = sum(r.shield_size_mean * r.shield_interventions for r in recs)
    return {
        "shield_interventions_mean": _mean(counts),
        "shield_interventions_mean_ci95": list(bootstrap_interval(counts, 0.0, None)),
        "shield_intervention_share": total / decisions if decisions else None,
        "shield_size_mean": size_sum / total if total else 0.0,
        "shield_size_max": max((r.shield_size_max for r in recs), default=0.0),
    }


def summarize(results: EvaluationResults, reference: str | None = None) -> dict[str, Any]:
    """Per-agent summary (DESIGN §6 keys, confidence intervals) plus how the run was made, and
    the paired comparisons against ``reference`` (:func:`paired_success`,
    :func:`paired_delta_v`).

    Rates get a Wilson score interval, means a percentile bootstrap inside the metric's range
    (``ci_method`` names them). ``constant_columns`` lists the mean columns equal in every
    episode (their interval is the value itself). ``decision_ms_p50/p95`` are over all
    decisions of the agent, across episodes. ``delta_v_mean_success`` and
    ``time_mean_success`` average over successful episodes only (None without any): a failed
    episode can be cheap because it ended early. With the safety shield on (``shield``: its
    parameters) each agent also gets ``shield_interventions_mean`` (per episode, bootstrap
    interval), ``shield_intervention_share`` (of all decisions) and ``shield_size_mean`` /
    ``shield_size_max`` (‖u_safe − u_cmd‖ / max_accel over the interventions).
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
            "budget_spent_rate": sum(r.budget_spent for r in recs),
        }
        for key, k in counts.items():
            entry[key] = k / n
            entry[f"{key}_ci95"] = list(wilson_interval(k, n))
        n_targets = max((r.n_targets for r in recs), default=None)
        # key: (per-episode values, the metric's range)
        columns: dict[str, tuple[list[float], tuple[float | None, float | None]]] = {
            "targets_captured_mean": ([r.targets_captured for r in recs], (0, n_targets)),
            "delta_v_mean": ([r.delta_v for r in recs], (0.0, None)),
            "time_mean": ([r.time for r in recs], (0.0, None)),
            "path_length_mean": ([r.path_length for r in recs], (0.0, None)),
            "task_score_mean": ([r.task_score for r in recs], (None, None)),
        }
        constant = []
        for key, (values, (low, high)) in columns.items():
            entry[key] = _mean(values)
            entry[f"{key}_ci95"] = list(bootstrap_interval(values, low, high))
            if n > 1 and is_constant(values):
                constant.append(key)
        entry["constant_columns"] = constant
        entry["n_targets"] = recs[0].n_targets if recs else None
        entry["delta_v_mean_success"] = _mean([r.delta_v for r in ok])
        entry["time_mean_success"] = _mean([r.time for r in ok])
        entry["min_clearance_min"] = min(r.min_clearance for r in recs)
        entry["decision_ms_p50"] = float(np.percentile(ms, 50))
        entry["decision_ms_p95"] = float(np.percentile(ms, 95))
        entry["decision_ms_max"] = float(ms.max())
        entry["decisions"] = int(ms.size)
        if results.shield is not None:
            entry |= _shield_entry(recs, int(ms.size))
        agents[spec.label] = entry
    ci_method = {f"{k}_ci95": CI_METHODS["wilson"] for k in RATE_KEYS}
    ci_method |= {f"{k}_ci95": CI_METHODS["bootstrap"] for k in MEAN_KEYS}
    ci_method |= {
        f"paired_delta_v.{k}": CI_METHODS["t"]
        for k in ("difference_mean_ci95", "time_difference_mean_ci95")
    }
    summary: dict[str, Any] = {
        "env_id": results.env_id,
        "env_kwargs": results.env_kwargs,
        "max_episode_steps": results.max_episode_steps,
        "episodes": results.episodes,
        "seed": results.seed,
    }
    suite = _suite_entry(results)
    if suite is not None:
        summary["suite"] = suite
    summary["shield"] = results.shield
    summary |= {
        "reset_seeds": results.reset_seeds,
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
        "paired_success": paired_success(results, reference),
        "paired_delta_v": paired_delta_v(results, reference),
    }
    return summary
