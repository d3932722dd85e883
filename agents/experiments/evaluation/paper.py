"""[APF-MPC] Table I beside our measurement of the same metrics on its world (``--paper``)."""

from __future__ import annotations

from typing import Any

from agents.experiments.evaluation.records import EvaluationResults
from agents.experiments.evaluation.report import format_number

__all__ = [
    "PAPER_AGENTS",
    "PAPER_ENV_ID",
    "PAPER_TABLE_I",
    "TABLE_I_ROWS",
    "paper_table",
    "paper_table_markdown",
]

PAPER_ENV_ID = "DebrisGym/PaperField2D-v0"
"""The [APF-MPC] world (fixed: one episode is enough)."""

PAPER_AGENTS = ("apf", "apf-mpc", "astar")
"""Our agents compared with [APF-MPC] Table I: its potential planner, APF-MPC, and A*."""

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
"""[APF-MPC] Table I as printed ("Potential Planner" → apf, "Integrated APF-MPC" → apf-mpc; the
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
    """[APF-MPC] Table I beside our measurement of the same metrics on its world (episode 0).

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
        return format_number(value, 5) if isinstance(value, float) else format_number(value)

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
        f"Ours: one episode of `{table['env_id']}` (the [APF-MPC] world, double integrator). "
        "Fuel is Δv; smoothness is our definition (the paper gives none); time is simulated "
        "mission time (the paper's 8379 s for APF-MPC matches its reported computing time).",
    ]
    for agent, reason in table.get("skipped", {}).items():
        notes.append(f"Not run: {agent} — {reason}")
    return "\n".join(lines + notes) + "\n"
