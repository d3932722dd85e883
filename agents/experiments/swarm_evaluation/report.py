"""The tables of a swarm evaluation: ``episodes.csv``, ``assignments.csv``, the summary (JSON and
Markdown) with confidence intervals, and the assignment-gap table.

Intervals are those of the single-agent evaluation
(:mod:`agents.experiments.evaluation.statistics`): Wilson for rates, a seeded percentile
bootstrap for means; team success is paired by seed with the exact McNemar test against the
reference team. The chaser success rate counts chaser-episodes, which are not independent
within an episode: its interval is narrower than it should be, and it is labelled so.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from typing import Any

import numpy as np

from agents.experiments.evaluation.report import format_number, markdown_cell, shield_table
from agents.experiments.evaluation.statistics import (
    bootstrap_interval,
    mcnemar_exact,
    wilson_interval,
)
from agents.experiments.swarm_evaluation.episode import CHASER_OUTCOMES, TeamEpisode
from agents.planners.team_assignment import ASSIGNMENT_RULES, TeamAssignment

__all__ = [
    "assignment_gaps",
    "assignments_csv",
    "episode_columns",
    "episodes_csv",
    "summarize_teams",
    "summary_markdown",
]


def episode_columns(n_chasers: int) -> list[str]:
    """The columns of ``episodes.csv`` for ``n_chasers`` chasers (docs/swarm.md lists them)."""
    head = [
        "agent", "episode", "seed", "field", "team_success", "clean_success", "team_captures",
        "n_targets",
        "chasers_succeeded", "collisions", "debris_collisions", "teammate_collisions",
        "out_of_bounds", "budget_spent", "time_limit", "min_separation", "delta_v_total",
        "delta_v_max", "time", "steps", "assignment", "assignment_targets", "assignment_cost",
        "assignment_longest", "optimal_cost", "assignment_gap", "assignment_gap_pct",
        "minmax_longest", "decision_ms_mean", "decision_ms_p95", "wall_s",
        "shield_interventions", "shield_size_mean", "shield_size_max",
    ]  # fmt: skip
    for k in range(n_chasers):
        head += [f"chaser{k}_outcome", f"chaser{k}_captures", f"chaser{k}_delta_v",
                 f"chaser{k}_end_time", f"chaser{k}_shield_interventions"]  # fmt: skip
    return head


def _targets_text(targets: Sequence[Sequence[int]]) -> str:
    """Each chaser's targets, chasers separated by ``|``: ``0 4|1 2|3 5``."""
    return "|".join(" ".join(str(j) for j in t) for t in targets)


def _row(r: TeamEpisode) -> list[Any]:
    ms = np.asarray(r.decision_ms, dtype=float)
    row: list[Any] = [
        r.agent, r.episode, r.seed, r.field_hash, r.team_success, r.clean_success,
        r.team_captures, r.n_targets,
        r.count("success"), r.collisions, r.count("debris_collision"),
        r.count("teammate_collision"), r.count("out_of_bounds"), r.count("delta_v_budget"),
        r.count("time_limit"), r.min_separation, sum(r.delta_v), max(r.delta_v), r.time,
        r.steps, r.assignment, _targets_text(r.targets), r.cost, r.longest, r.optimal_cost,
        r.gap, r.gap_pct, r.minmax_longest,
        float(ms.mean()) if ms.size else None,
        float(np.percentile(ms, 95)) if ms.size else None, r.wall_s,
        r.shield_interventions, r.shield_size_mean, r.shield_size_max,
    ]  # fmt: skip
    for k in range(r.n_chasers):
        replaced = r.shield[k].interventions if r.shield else 0
        row += [r.outcomes[k], r.captures[k], r.delta_v[k], r.end_time[k], replaced]
    return row


def _csv_text(header: list[str], rows: list[list[Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def episodes_csv(records: Sequence[TeamEpisode]) -> str:
    """``episodes.csv``: one row per team × episode."""
    k = max((r.n_chasers for r in records), default=0)
    return _csv_text(episode_columns(k), [_row(r) for r in records])


ASSIGNMENT_COLUMNS = (
    "episode", "seed", "rule", "targets", "cost", "longest", "gap", "gap_pct", "longest_gap",
)  # fmt: skip


def assignments_csv(fields: dict[int, tuple[int, dict[str, TeamAssignment]]]) -> str:
    """``assignments.csv``: every rule on every episode's field (``fields``: episode →
    (seed, rule → assignment)), with its gaps to the optimal total and the least longest
    tour (m; ``gap_pct`` in %)."""
    rows = []
    for episode in sorted(fields):
        seed, rules = fields[episode]
        best, least = rules["optimal"].cost, rules["minmax"].longest
        for rule in ASSIGNMENT_RULES:
            a = rules[rule]
            pct = 100.0 * (a.cost - best) / best if best > 0 else 0.0
            rows.append([episode, seed, rule, _targets_text(a.targets()), a.cost, a.longest,
                         a.cost - best, pct, a.longest - least])  # fmt: skip
    return _csv_text(list(ASSIGNMENT_COLUMNS), rows)


def _mean_ci(values: Sequence[float], low: float | None = None, high: float | None = None):
    x = [float(v) for v in values]
    return (float(np.mean(x)) if x else None), list(bootstrap_interval(x, low, high))


def _rate(count: int, n: int) -> tuple[float, list[float]]:
    return count / n, list(wilson_interval(count, n))


def summarize_teams(
    records: Sequence[TeamEpisode], labels: Sequence[str], reference: str | None = None
) -> dict[str, Any]:
    """Per team (in ``labels`` order): rates with Wilson intervals, means with bootstrap
    intervals, decision times, and team success paired with ``reference`` (default: the first
    team) by seed (exact McNemar)."""
    teams: dict[str, Any] = {}
    by_label = {label: [r for r in records if r.agent == label] for label in labels}
    for label, recs in by_label.items():
        if not recs:
            continue
        n, k, t = len(recs), recs[0].n_chasers, recs[0].n_targets
        ms = np.concatenate([np.asarray(r.decision_ms, dtype=float) for r in recs])
        entry: dict[str, Any] = {"episodes": n, "n_chasers": k, "n_targets": t}
        for key, hits in (
            ("team_success_rate", sum(r.team_success for r in recs)),
            ("clean_success_rate", sum(r.clean_success for r in recs)),
            ("collision_rate", sum(r.collisions > 0 for r in recs)),
            ("teammate_collision_rate", sum(r.count("teammate_collision") > 0 for r in recs)),
            ("debris_collision_rate", sum(r.count("debris_collision") > 0 for r in recs)),
        ):
            entry[key], entry[f"{key}_ci95"] = _rate(int(hits), n)
        entry["chaser_success_rate"], entry["chaser_success_rate_ci95"] = _rate(
            sum(r.count("success") for r in recs), n * k
        )
        entry["chaser_outcomes"] = {o: sum(r.count(o) for r in recs) for o in CHASER_OUTCOMES}
        for key, values, lo, hi in (
            ("team_captures_mean", [r.team_captures for r in recs], 0.0, float(t)),
            ("delta_v_total_mean", [sum(r.delta_v) for r in recs], 0.0, None),
            ("delta_v_max_mean", [max(r.delta_v) for r in recs], 0.0, None),
            ("time_mean", [r.time for r in recs], 0.0, None),
            ("assignment_cost_mean", [r.cost for r in recs], 0.0, None),
            ("assignment_gap_pct_mean", [r.gap_pct for r in recs], 0.0, None),
        ):
            entry[key], entry[f"{key}_ci95"] = _mean_ci(values, lo, hi)
        entry["min_separation_min"] = float(min(r.min_separation for r in recs))
        explored = [r.exploration for r in recs if r.exploration is not None]
        if explored:
            entry["exploration"] = _exploration_summary(explored)
        entry["wall_s_mean"] = float(np.mean([r.wall_s for r in recs]))
        entry["decision_ms_p50"] = float(np.percentile(ms, 50)) if ms.size else None
        entry["decision_ms_p95"] = float(np.percentile(ms, 95)) if ms.size else None
        if any(r.shield for r in recs):
            entry |= _shield_entry(recs)
        teams[label] = entry
    ref = reference if reference is not None else (labels[0] if labels else None)
    paired: dict[str, Any] = {}
    if ref in by_label:
        base = {r.episode: r.team_success for r in by_label[ref]}
        for label, recs in by_label.items():
            if label == ref:
                continue
            pairs = [(r.team_success, base[r.episode]) for r in recs if r.episode in base]
            b = sum(a and not o for a, o in pairs)
            c = sum(o and not a for a, o in pairs)
            paired[label] = {"n": len(pairs), "b": b, "c": c, "p_value": mcnemar_exact(b, c)}
    return {"teams": teams, "reference": ref, "paired_team_success": paired}


def _shield_entry(recs: Sequence[TeamEpisode]) -> dict[str, Any]:
    """A shielded team's interventions: the commands replaced per episode (over the chasers;
    mean, bootstrap interval), their share of the chasers' decisions, and their size
    ‖u_safe − u_cmd‖ / max_accel over all of them (mean, largest)."""
    counts = [r.shield_interventions for r in recs]
    total, decisions = sum(counts), sum(r.shield_decisions for r in recs)
    mean, ci = _mean_ci(counts, 0.0, None)
    return {
        "shield_interventions_mean": mean,
        "shield_interventions_mean_ci95": ci,
        "shield_intervention_share": total / decisions if decisions else None,
        "shield_size_mean": (
            sum(r.shield_size_mean * r.shield_interventions for r in recs) / total if total else 0.0
        ),
        "shield_size_max": max(r.shield_size_max for r in recs),
    }


def _shielded_title(summary: dict[str, Any]) -> str:
    """The title, with the shield's note when the run was shielded."""
    title, shield = summary.get("title", ""), summary.get("shield")
    if shield is None:
        return title
    margin = "the chaser's radius" if shield["margin"] is None else f"{shield['margin']} m"
    return (
        f"{title} **Shielded**: every team flies behind the safety shield, one per chaser, "
        f"its teammates bodies on their predicted tracks (run-time assurance: "
        f"{shield['horizon_steps']}-step horizon, margin {margin} from debris and teammates, "
        f"{shield['target_margin']} m from targets; docs/swarm.md)."
    ).strip()


def _shield_lines(summary: dict[str, Any]) -> list[str]:
    """The shield's table of the teams it flew with (nothing for an unshielded run)."""
    if summary.get("shield") is None:
        return []
    shielded = {k: e for k, e in summary["teams"].items() if "shield_interventions_mean" in e}
    return shield_table(shielded, "team", " over the chasers", "the chasers' decisions")


PAPER_CONNECTIVITY = "paper (Fig. 4, N = 6: about 30; Fig. 7, N = 48: 25)"
"""The iterations until every agent's graph is connected that [Bandyopadhyay17] shows."""


def _exploration_summary(explored: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Means over the episodes of the exploration before the first step (iterations until
    every graph is connected, with and without node sharing; nodes per agent)."""
    first = explored[0]
    out: dict[str, Any] = {"episodes": len(explored)}
    out.update({key: first[key] for key in ("agents", "r_col", "r_max")})
    for mode in ("shared", "alone"):
        runs = [e for e in explored if e[f"iterations_{mode}"] is not None]
        if not runs:
            continue
        out[f"iterations_{mode}_mean"] = float(np.mean([e[f"iterations_{mode}"] for e in runs]))
        out[f"iterations_{mode}_max"] = int(max(e[f"iterations_{mode}"] for e in runs))
        out[f"connected_{mode}"] = int(sum(bool(e[f"connected_{mode}"]) for e in runs))
        out[f"runs_{mode}"] = len(runs)
        out[f"nodes_{mode}_mean"] = float(np.mean([np.mean(e[f"nodes_{mode}"]) for e in runs]))
    out["wall_s_mean"] = float(np.mean([e["wall_s"] for e in explored]))
    return out


def exploration_lines(teams: dict[str, Any]) -> list[str]:
    """The connectivity measurement of the teams that explore, one line each, beside the
    paper's figure."""
    lines = []
    for label, entry in teams.items():
        e = entry.get("exploration")
        if not e:
            continue
        parts = []
        for mode, text in (("shared", "with sharing"), ("alone", "without")):
            if f"iterations_{mode}_mean" in e:
                parts.append(
                    f"{text} {format_number(e[f'iterations_{mode}_mean'])} (max "
                    f"{e[f'iterations_{mode}_max']}; connected in {e[f'connected_{mode}']}/"
                    f"{e[f'runs_{mode}']}; nodes per agent "
                    f"{format_number(e[f'nodes_{mode}_mean'])})"
                )
        lines.append(
            f"- {markdown_cell(label)}, N = {e['agents']} (r_col {format_number(e['r_col'])} m, "
            f"r_max {format_number(e['r_max'])} m): iterations until every graph is connected: "
            f"{'; '.join(parts)}; {PAPER_CONNECTIVITY}."
        )
    return lines


def assignment_gaps(fields: dict[int, tuple[int, dict[str, TeamAssignment]]]) -> dict[str, Any]:
    """Per rule over the episodes' fields: mean total cost (m), mean and largest gap to the
    optimal total (m and %), episodes at the optimum, mean longest tour (m) and its mean gap to
    the least longest tour (m)."""
    out: dict[str, Any] = {}
    for rule in ASSIGNMENT_RULES:
        cost, gap, pct, longest, lgap = [], [], [], [], []
        for _, rules in fields.values():
            best, least = rules["optimal"].cost, rules["minmax"].longest
            a = rules[rule]
            cost.append(a.cost)
            gap.append(a.cost - best)
            pct.append(100.0 * (a.cost - best) / best if best > 0 else 0.0)
            longest.append(a.longest)
            lgap.append(a.longest - least)
        if not cost:
            continue
        out[rule] = {
            "episodes": len(cost),
            "cost_mean": float(np.mean(cost)),
            "gap_mean": float(np.mean(gap)),
            "gap_pct_mean": float(np.mean(pct)),
            "gap_pct_max": float(np.max(pct)),
            "at_optimum": int(sum(g <= 1e-9 * max(1.0, c) for g, c in zip(gap, cost))),
            "longest_mean": float(np.mean(longest)),
            "longest_gap_mean": float(np.mean(lgap)),
        }
    return out


def _ci(entry: dict[str, Any], key: str, scale: float = 1.0, digits: int = 3) -> str:
    value = entry.get(key)
    if value is None:
        return "—"
    text = format_number(value * scale, digits)
    lo, hi = entry.get(f"{key}_ci95", (None, None))
    if lo is None or hi is None:
        return text
    return f"{text} [{format_number(lo * scale, digits)}, {format_number(hi * scale, digits)}]"


def summary_markdown(summary: dict[str, Any]) -> str:
    """The team table and the assignment-gap table, as Markdown."""
    teams, title = summary["teams"], _shielded_title(summary)
    lines = [title, ""] if title else []
    lines += [
        "| team | team success % | no collision and team success % | collisions % (debris / "
        "teammate chasers) | chaser success % (chaser-episodes) | captures | Δv total (m/s) | "
        "Δv max chaser (m/s) | time (s) | min separation (m) | tour cost (m) | gap to optimal "
        "% | decision ms p50 / p95 | wall s / episode |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, e in teams.items():
        out = e["chaser_outcomes"]
        lines.append(
            f"| {markdown_cell(label)} | {_ci(e, 'team_success_rate', 100)} | "
            f"{_ci(e, 'clean_success_rate', 100)} | {_ci(e, 'collision_rate', 100)} "
            f"({out['debris_collision']} / "
            f"{out['teammate_collision']}) | {_ci(e, 'chaser_success_rate', 100)} | "
            f"{_ci(e, 'team_captures_mean')} | {_ci(e, 'delta_v_total_mean')} | "
            f"{_ci(e, 'delta_v_max_mean')} | {_ci(e, 'time_mean')} | "
            f"{format_number(e['min_separation_min'])} | "
            f"{format_number(e['assignment_cost_mean'])} | "
            f"{format_number(e['assignment_gap_pct_mean'])} | "
            f"{format_number(e['decision_ms_p50'])} / {format_number(e['decision_ms_p95'])} | "
            f"{format_number(e['wall_s_mean'])} |"
        )
    lines += _shield_lines(summary)
    explored = exploration_lines(teams)
    if explored:
        lines += ["", "Exploration before the first step (mean over the episodes):", "", *explored]
    paired = summary.get("paired_team_success") or {}
    if paired:
        lines += [
            "",
            f"Team success paired by seed with {summary['reference']} (exact McNemar; b: the "
            "team succeeds and the reference fails, c: the reverse):",
            "",
            "| team | episodes | b | c | p |",
            "|---|---|---|---|---|",
        ]
        for label, p in paired.items():
            lines.append(
                f"| {markdown_cell(label)} | {p['n']} | {p['b']} | {p['c']} | "
                f"{format_number(p['p_value'])} |"
            )
    gaps = summary.get("assignment_gaps") or {}
    if gaps:
        lines += [
            "",
            "Assignment rules on the same fields (tour cost: each chaser's shortest tour slot → "
            "its targets (→ slot when the mission returns), surface-to-surface legs at t = 0, "
            "summed over the chasers):",
            "",
            "| rule | tour cost (m) | gap to optimal (m) | gap % mean / max | at optimum | "
            "longest tour (m) | longest above minmax (m) |",
            "|---|---|---|---|---|---|---|",
        ]
        for rule, g in gaps.items():
            lines.append(
                f"| {rule} | {format_number(g['cost_mean'])} | {format_number(g['gap_mean'])} | "
                f"{format_number(g['gap_pct_mean'])} / {format_number(g['gap_pct_max'])} | "
                f"{g['at_optimum']}/{g['episodes']} | {format_number(g['longest_mean'])} | "
                f"{format_number(g['longest_gap_mean'])} |"
            )
    return "\n".join(lines) + "\n"
