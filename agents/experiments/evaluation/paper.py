"""[APF-MPC] Table I side by side with our measurement of the same metrics (``--paper``).

A side-by-side, *not* a reproduction: :data:`NOT_A_REPRODUCTION` lists why the numbers cannot
be compared one for one. Every output of ``--paper`` (the printed title, ``paper_table.md``,
``paper_table.json``) carries the label and the reasons.
"""

from __future__ import annotations

from typing import Any

from agents.experiments.evaluation.records import EvaluationResults
from agents.experiments.evaluation.report import format_number

__all__ = [
    "NOT_A_REPRODUCTION",
    "PAPER_AGENTS",
    "PAPER_ENV_ID",
    "PAPER_TABLE_I",
    "PAPER_TITLE",
    "TABLE_I_ROWS",
    "paper_table",
    "paper_table_markdown",
]

PAPER_ENV_ID = "DebrisGym/PaperField2D-v0"
"""The [APF-MPC] world (fixed: one episode is enough)."""

PAPER_AGENTS = ("apf", "apf-mpc", "astar")
"""Our agents compared with [APF-MPC] Table I: its potential planner, APF-MPC, and A*."""

PAPER_TITLE = "[APF-MPC] Table I side by side with ours — not a reproduction"
"""Title of the ``--paper`` table wherever it appears."""

NOT_A_REPRODUCTION: tuple[str, ...] = (
    "The world is our reconstruction: the paper's obstacle file (sphereWorld1.mat) is not "
    "published, so DebrisGym/PaperField2D-v0 places the dock, four targets and nine spherical "
    "obstacles after the paper's description and figures; the paper's own field differs.",
    "Units: the paper's world is a 20 x 20 square in unstated units that its table calls "
    "metres, and it reports fuel in undefined 'units of fuel'; ours reports Δv in units/s of "
    "the same square.",
    "Time step and dynamics: the paper's potential planner takes 400 gradient steps of size "
    "0.01 with no dynamics, and its MPC (horizon 20, dt = 0.1, fminunc, no thrust limit) "
    "follows that path on a kinematic model; ours flies every agent through the env at "
    "dt = 0.1 as a double integrator with a 1 unit/s² thrust limit, so our accelerations "
    "cannot reach the paper's 361 or 21.8.",
    "Metric definitions: the paper defines neither smoothness nor fuel (ours: mean squared "
    "change of the acceleration command, and Δv); its 'total time' of 8379 s for APF-MPC "
    "matches its reported computing time, ours is simulated flight time; its waypoints are "
    "path points (2 for the potential planner, whose row also has zero curvature), ours are "
    "env steps; its maximum deceleration (2.2e-7 for APF-MPC) is not defined the way ours is "
    "(commanded acceleration against the motion).",
    "The paper prints no A* row and reports one run with no success criterion; ours reports "
    "mission success and summed decision time as extra rows.",
)
"""Why the ``--paper`` table is a side-by-side and not a reproduction of [APF-MPC] Table I."""

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
        "title": PAPER_TITLE,
        "not_a_reproduction": list(NOT_A_REPRODUCTION),
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
        f"**{PAPER_TITLE}.** The numbers stand side by side; they do not measure the same "
        "things (reasons below the table).",
        "",
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
        f"Ours: one episode of `{table['env_id']}` (our reconstruction of the [APF-MPC] world, "
        "double integrator). Not a reproduction, because:",
        "",
        *(f"- {reason}" for reason in table.get("not_a_reproduction", NOT_A_REPRODUCTION)),
    ]
    for agent, reason in table.get("skipped", {}).items():
        notes.append(f"Not run: {agent} — {reason}")
    return "\n".join(lines + notes) + "\n"
