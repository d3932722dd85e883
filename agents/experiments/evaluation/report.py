"""Reports of an evaluation: the Markdown table, strict JSON, the episodes CSV, and the files.

The outputs (``episodes.csv``, ``summary.json``, ``summary.md``, ``trajectories_epNNN.png``, and
``paper_table.*`` with ``--paper``) are written as one set (:func:`write_outputs`): staged, then
moved into place together, so a directory never holds one run's tables beside another's plots.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.evaluation.plots import plot_episode
from agents.experiments.evaluation.records import CSV_COLUMNS, EpisodeRecord, EvaluationResults
from agents.experiments.evaluation.statistics import summarize
from agents.experiments.run_directory import OutputSet
from debris_gym.files import write_atomic

__all__ = [
    "OWNED_OUTPUTS",
    "episodes_csv",
    "format_number",
    "markdown_cell",
    "shield_table",
    "summary_markdown",
    "to_json",
    "write_outputs",
]


def format_number(value: Any, digits: int = 3) -> str:
    """``value`` for a table: 3 significant digits (``digits``), ``—`` for None and non-finite."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 10**digits else f"{value:.0f}"
    return str(value)


def markdown_cell(text: str) -> str:
    """``text`` safe inside a Markdown table cell: ``|`` escaped (it would end the cell) and
    line breaks made spaces (they would end the row)."""
    return " ".join(str(text).replace("\\", "\\\\").replace("|", "\\|").splitlines())


_COLUMN_TITLES = {
    "targets_captured_mean": "targets captured",
    "delta_v_mean": "Δv",
    "time_mean": "time",
    "path_length_mean": "path",
    "task_score_mean": "task score",
}


def _with_ci(entry: dict[str, Any], key: str, digits: int = 3) -> str:
    """``value [low, high]``; ``value (constant)`` for a column equal in every episode."""
    text = format_number(entry[key], digits)
    if key in (entry.get("constant_columns") or ()):
        return f"{text} (constant)"
    lo, hi = entry.get(f"{key}_ci95", (None, None))
    if lo is None or hi is None:
        return text
    return f"{text} [{format_number(lo, digits)}, {format_number(hi, digits)}]"


def _title(summary: dict[str, Any]) -> str:
    """The table's first line: what was flown (suite, env, options, episodes, seeds, shield)."""
    shield = summary.get("shield")
    if shield is None:
        return _plain_title(summary)
    margin = "the chaser's radius" if shield["margin"] is None else f"{shield['margin']} m"
    return (
        f"{_plain_title(summary)} **Shielded**: every agent flies behind the safety shield "
        f"(run-time assurance: {shield['horizon_steps']}-step horizon, margin {margin} from "
        f"debris, {shield['target_margin']} m from targets; docs/baselines.md)."
    )


def _plain_title(summary: dict[str, Any]) -> str:
    """The title without the shield's note."""
    n = summary["episodes"]
    suite = summary.get("suite")
    env = f"env `{summary['env_id']}`" + (
        f" with `{json.dumps(summary['env_kwargs'])}`" if summary["env_kwargs"] else ""
    )
    limit = (
        f", time limit {summary['max_episode_steps']} steps"
        if summary.get("max_episode_steps")
        else ""
    )
    if suite is not None:
        size = suite["missions_in_suite"]
        which = f"all {size} missions" if n == size else f"its first {n} of {size} missions"
        return (
            f"Suite `{suite['name']}` (content hash {suite['hash']}): {which}, {env}{limit}; "
            f"every agent flies the same pinned fields."
        )
    seeds = (
        f"reset seeds {summary['seed']}…{summary['seed'] + n - 1}."
        if n > 1
        else f"reset seed {summary['seed']}."
    )
    return (
        f"{env[0].upper()}{env[1:]}{limit}; {n} episode{'s' if n != 1 else ''} per agent, {seeds}"
    )


def _paired_tables(summary: dict[str, Any], n: int) -> list[str]:
    """The paired comparisons: success (McNemar) and Δv / time on the missions both complete."""
    lines: list[str] = []
    success = summary.get("paired_success") or {}
    if success.get("agents"):
        ref = markdown_cell(success["reference"])
        lines += [
            "",
            f"Success paired with {ref} by seed ({success['test']} test, two-sided): b = "
            f"episodes only the agent completes, c = episodes only {ref} completes.",
            "",
            f"| agent | pairs | both complete | b (agent only) | c ({ref} only) | p-value |",
            "|---|---|---|---|---|---|",
        ]
        for label, e in success["agents"].items():
            lines.append(
                f"| {markdown_cell(label)} | {e['pairs']} | {e['both_succeeded']} | {e['b']} "
                f"| {e['c']} "
                f"| {format_number(e['p_value'])} |"
            )
    paired = summary.get("paired_delta_v") or {}
    if paired.get("agents"):
        ref = markdown_cell(paired["reference"])
        lines += [
            "",
            f"Δv and time of flight on the missions both complete, paired with {ref} by seed "
            "(differences with Student t 95 % intervals):",
            "",
            f"| agent | both complete | agent Δv [m/s] | {ref} Δv [m/s] | agent − {ref} Δv [m/s] "
            f"| agent time [s] | {ref} time [s] | agent − {ref} time [s] |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for label, e in paired["agents"].items():
            lines.append(
                f"| {markdown_cell(label)} | {e['both_succeeded']} / {n} "
                f"| {format_number(e['delta_v_mean'])} "
                f"| {format_number(e['reference_delta_v_mean'])} "
                f"| {_with_ci(e, 'difference_mean')} | {format_number(e.get('time_mean'))} "
                f"| {format_number(e.get('reference_time_mean'))} "
                f"| {_with_ci(e, 'time_difference_mean') if 'time_difference_mean' in e else '—'} |"
            )
    return lines


def shield_table(
    entries: Mapping[str, dict[str, Any]],
    who: str = "agent",
    over: str = "",
    decisions: str = "all decisions",
) -> list[str]:
    """The shield's interventions as Markdown lines (a blank line first): one row per entry
    (label → its summary entry with the ``shield_*`` keys).

    Args:
        entries: the rows, in order.
        who: the first column's title (what a row is: an agent, a team).
        over: words after "per episode" saying what a count sums over (a team: its chasers).
        decisions: whose decisions the share is of.
    """
    lines = [
        "",
        f"Safety shield: commands replaced per episode{over} (95 % bootstrap interval), their "
        f"share of {decisions}, and their size ‖u_safe − u_cmd‖ / max_accel (a fraction of the "
        "thrust limit; decision times above include the shield).",
        "",
        f"| {who} | interventions / episode | share of decisions | mean size | max size |",
        "|---|---|---|---|---|",
    ]
    for label, e in entries.items():
        lines.append(
            f"| {markdown_cell(label)} | {_with_ci(e, 'shield_interventions_mean')} "
            f"| {format_number(e['shield_intervention_share'])} "
            f"| {format_number(e['shield_size_mean'])} | {format_number(e['shield_size_max'])} |"
        )
    return lines


def summary_markdown(summary: dict[str, Any]) -> str:
    """The summary as Markdown: one row per agent with 95 % intervals in brackets, then the
    paired comparisons with the reference agent, the agents' warnings and the agents left out
    (``skipped``: a default agent that cannot fly this env, with the reason)."""
    n = summary["episodes"]
    lines = [
        _title(summary),
        "",
        "| agent | success | targets captured | task score | Δv [m/s] | time [s] | path [m] "
        "| collision | Δv budget spent | min clearance [m] | decision p50 / p95 [ms] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, e in summary["agents"].items():
        captured = _with_ci(e, "targets_captured_mean")
        if e.get("n_targets") is not None:
            captured += f" / {e['n_targets']}"
        lines.append(
            f"| {markdown_cell(label)} | {_with_ci(e, 'success_rate', 2)} | {captured} "
            f"| {_with_ci(e, 'task_score_mean')} | {_with_ci(e, 'delta_v_mean')} "
            f"| {_with_ci(e, 'time_mean')} "
            f"| {_with_ci(e, 'path_length_mean')} | {_with_ci(e, 'collision_rate', 2)} "
            f"| {_with_ci(e, 'budget_spent_rate', 2)} | {format_number(e['min_clearance_min'])} "
            f"| {format_number(e['decision_ms_p50'])} / {format_number(e['decision_ms_p95'])} |"
        )
    lines += [
        "",
        "Brackets: 95 % confidence intervals — Wilson score for rates; for means a percentile "
        "bootstrap over episodes (seeded), which stays inside the metric's range (means are "
        "over all episodes, failed ones included). Δv budget spent: the episodes that ended "
        "because the Δv budget ran out (a failure). Task score: the env's unshaped score per "
        "episode (captures and success minus Δv, collision, bounds and time penalties; the "
        "shaping left out).",
    ]
    constant = {
        label: [_COLUMN_TITLES.get(k, k) for k in e.get("constant_columns") or ()]
        for label, e in summary["agents"].items()
    }
    constant = {label: cols for label, cols in constant.items() if cols}
    if constant:
        lines += [
            "",
            "Constant across episodes (the same value every episode: no interval to speak of): "
            + "; ".join(f"{label}: {', '.join(cols)}" for label, cols in constant.items())
            + ".",
        ]
    if summary.get("shield") is not None:
        lines += shield_table(summary["agents"])
    lines += _paired_tables(summary, n)
    for label, message in (summary.get("warnings") or {}).items():
        lines += ["", f"Warning — {label}: {message}"]
    for label, reason in (summary.get("skipped") or {}).items():
        lines += ["", f"Not evaluated — {markdown_cell(label)}: {reason}"]
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


OWNED_OUTPUTS: tuple[str, ...] = (
    "episodes.csv",
    "summary.json",
    "summary.md",
    "trajectories_ep*.png",
    "paper_table.md",
    "paper_table.json",
)
"""Name patterns of the files an evaluation writes: an earlier set's files of these names that a
new set does not contain (a plot of an episode no longer plotted) are removed at commit."""


def write_outputs(
    results: EvaluationResults,
    out_dir: str | os.PathLike[str],
    plots: int = 3,
    summary: dict[str, Any] | None = None,
    extra: Mapping[str, str | bytes] | None = None,
    manifest: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write episodes.csv, summary.json, summary.md, ``plots`` trajectory PNGs and the
    ``extra`` files ({name: content}, e.g. ``paper_table.md``) into ``out_dir`` as one set.

    The files are staged in a scratch directory and moved into place together
    (:class:`~agents.experiments.run_directory.OutputSet`): an error or Ctrl-C while they are
    written leaves ``out_dir`` as it was, and the files of an earlier evaluation that this one
    does not write (:data:`OWNED_OUTPUTS`) are removed. ``DIR/manifest.json`` names the set,
    with the ``manifest`` items beside the file list. ``out_dir`` is created if needed.

    Returns:
        The paths written, in the order above.
    """
    out = Path(out_dir)
    summary = summarize(results) if summary is None else summary
    contents: list[tuple[str, str | bytes]] = [
        ("episodes.csv", episodes_csv(results.records)),
        ("summary.json", to_json(summary)),
        ("summary.md", summary_markdown(summary)),
    ]
    with OutputSet(out, owned=OWNED_OUTPUTS) as files:
        for name, content in contents:
            write_atomic(files.path(name), content)
        names = [name for name, _ in contents]
        for i in range(min(max(plots, 0), results.episodes)):
            name = f"trajectories_ep{i:03d}.png"
            write_atomic(files.path(name), plot_episode(results, i))
            names.append(name)
        for name, content in (extra or {}).items():
            write_atomic(files.path(name), content)
            names.append(name)
        files.commit(**dict(manifest or {}))
    return [out / name for name in names]
