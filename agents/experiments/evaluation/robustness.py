"""The robustness table: every agent of an evaluation flown again under each error of the
uncertain world at three levels, on the same missions.

Each condition is one ordinary evaluation (:func:`~agents.experiments.evaluation.command.
run_evaluation`) with the condition's options added to the env's (a frozen suite keeps its
fields: the uncertain world's options do not change them), written to ``OUT/<condition>/``;
the table gathers their ``summary.json`` into ``OUT/robustness.md`` and ``robustness.json``.
A condition already flown into ``OUT/<condition>/`` with the same suite, episodes, agents and
options is kept, not flown again (a table stopped part-way finishes where it stopped; delete a
condition's directory to fly it again).
The levels are stated in :data:`CONDITIONS` and docs/baselines.md.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.experiments.evaluation.plan import EvaluateOptions, NoAgentFits, UsageError
from debris_gym.config import UNCERTAINTY_KEYS
from debris_gym.files import write_atomic


@dataclass(frozen=True)
class Condition:
    """One column group of the table: an error at a level, as env options."""

    error: str
    """What errs: "none", "navigation", "actuation", "truth model" or "sensing"."""
    level: str
    """"" (none), "low", "medium" or "high"."""
    options: dict[str, Any]
    """The env options that make it (added to the evaluation's own)."""

    @property
    def name(self) -> str:
        """Directory and column name, e.g. ``navigation-high``."""
        return "exact" if not self.level else f"{self.error.replace(' ', '_')}-{self.level}"


CONDITIONS: tuple[Condition, ...] = (
    Condition("none", "", {}),
    Condition("navigation", "low", {"nav_sigma_position": 0.3, "nav_sigma_velocity": 0.003}),
    Condition("navigation", "medium", {"nav_sigma_position": 1.0, "nav_sigma_velocity": 0.01}),
    Condition("navigation", "high", {"nav_sigma_position": 3.0, "nav_sigma_velocity": 0.03}),
    Condition(
        "actuation",
        "low",
        {
            "thrust_sigma_magnitude": 0.02,
            "thrust_sigma_pointing": 0.01,
            "thrust_miss_probability": 0.01,
        },
    ),
    Condition(
        "actuation",
        "medium",
        {
            "thrust_sigma_magnitude": 0.05,
            "thrust_sigma_pointing": 0.03,
            "thrust_miss_probability": 0.03,
        },
    ),
    Condition(
        "actuation",
        "high",
        {
            "thrust_sigma_magnitude": 0.1,
            "thrust_sigma_pointing": 0.1,
            "thrust_miss_probability": 0.1,
        },
    ),
    Condition("truth model", "low", {"truth_model": "j2_drag", "ballistic_coefficient": 100.0}),
    Condition("truth model", "medium", {"truth_model": "j2_drag", "ballistic_coefficient": 30.0}),
    Condition("truth model", "high", {"truth_model": "j2_drag", "ballistic_coefficient": 10.0}),
    Condition("sensing", "low", {"sensor_range": 300.0}),
    Condition("sensing", "medium", {"sensor_range": 150.0}),
    Condition("sensing", "high", {"sensor_range": 75.0}),
)
"""The conditions of the table, the world without errors first. Truth-model levels vary the
debris' ballistic coefficient (kg/m²) against the chaser's and the targets' 100: the lower, the
faster the debris drift from where the CW model puts them."""

METRICS = (
    ("success_rate", "success", "{:.0%}"),
    ("collision_rate", "collisions", "{:.0%}"),
    ("delta_v_mean_success", "Δv (m/s)", "{:.1f}"),
    ("time_mean_success", "time (s)", "{:.0f}"),
)
"""The summary metrics of each cell: (summary key, column title, format). Δv and time are
over the successful episodes."""


def run_robustness(
    options: EvaluateOptions,
    out: Path,
    run: Callable[[EvaluateOptions], str],
    conditions: Sequence[Condition] = CONDITIONS,
    echo: Callable[[str], None] = print,
) -> str:
    """Fly ``options``' evaluation under every condition into ``out/<condition>/`` (``run``:
    :func:`~agents.experiments.evaluation.command.run_evaluation`), write
    ``out/robustness.md`` and ``out/robustness.json``, and return the Markdown.

    Raises:
        UsageError: ``options`` already sets an option a condition sets.
    """
    base = dict(options.env_kwargs or {})
    for condition in conditions:
        clash = sorted(set(base) & set(condition.options))
        if clash:
            raise UsageError(
                "--env-kwargs", f"{', '.join(clash)} is set by the robustness conditions"
            )
    summaries: dict[str, dict[str, Any]] = {}
    for condition in conditions:
        target = out / condition.name
        done = _finished(target, options, {**base, **condition.options})
        if done is not None:
            echo(f"robustness: {condition.name} already in {target}: kept")
            summaries[condition.name] = done
            continue
        echo(f"robustness: {condition.name} {condition.options or ''}")
        added = {**base, **condition.options}
        try:
            run(
                dataclasses.replace(
                    options,
                    out=target,
                    env_kwargs=added or None,
                    plots=0,
                    video=0,
                    skip_unfit=True,
                )
            )
        except NoAgentFits as exc:  # a condition none of the agents flies: noted, kept
            _write_unflown(target, options, added, exc.skipped)
        summaries[condition.name] = json.loads((target / "summary.json").read_text())
    table = robustness_table(conditions, summaries)
    write_atomic(out / "robustness.md", table)
    payload = {
        "conditions": [dataclasses.asdict(c) | {"name": c.name} for c in conditions],
        "agents": {
            name: {
                agent: {key: entry.get(key) for key, _, _ in METRICS}
                for agent, entry in summary["agents"].items()
            }
            for name, summary in summaries.items()
        },
        "skipped": {name: summary.get("skipped") or {} for name, summary in summaries.items()},
    }
    write_atomic(out / "robustness.json", json.dumps(payload, indent=2) + "\n")
    return table


def _write_unflown(
    target: Path, options: EvaluateOptions, added: dict[str, Any], skipped: dict[str, str]
) -> None:
    """A condition's ``summary.json`` when none of the agents can fly it: no agent flown,
    each one's reason in ``skipped`` (what :func:`_finished` reads to keep it)."""
    target.mkdir(parents=True, exist_ok=True)
    summary = {
        "suite": {"name": options.suite},
        "episodes": options.episodes,
        "env_kwargs": added,
        "agents": {},
        "skipped": skipped,
    }
    write_atomic(target / "summary.json", json.dumps(summary, indent=2) + "\n")


def _finished(
    target: Path, options: EvaluateOptions, added: dict[str, Any]
) -> dict[str, Any] | None:
    """The summary of a condition already flown into ``target`` with the same episodes,
    agents and added options (a table stopped part-way, or extended), else None."""
    path = target / "summary.json"
    if not path.is_file():
        return None
    summary = json.loads(path.read_text())
    wanted_agents = None if options.agents is None else options.agents.split(",")
    flown = summary.get("env_kwargs") or {}
    same = (
        (summary.get("suite") or {}).get("name") == options.suite
        and (options.episodes is None or summary.get("episodes") == options.episodes)
        and all(flown.get(k) == added.get(k) for k in set(added) | set(UNCERTAINTY_KEYS))
        and (wanted_agents is None or _flown_or_skipped(summary) == set(wanted_agents))
    )
    return summary if same else None


def _flown_or_skipped(summary: dict[str, Any]) -> set[str]:
    """The agents a condition's evaluation flew or left out with a reason."""
    return set(summary.get("agents", {})) | set(summary.get("skipped") or {})


NOT_FLOWN = "not flown"
"""The cell of an agent left out of a condition (it cannot fly that error; the reason is
listed under the table)."""


def _cell(entry: dict[str, Any]) -> str:
    parts = []
    for key, _, fmt in METRICS:
        value = entry.get(key)
        parts.append("–" if value is None else fmt.format(value))
    return " / ".join(parts)


def robustness_table(conditions: Sequence[Condition], summaries: dict[str, dict[str, Any]]) -> str:
    """The Markdown table: one row per agent, one column per condition, each cell
    success / collisions / Δv / time (:data:`METRICS`)."""
    first = next(
        (summaries[c.name] for c in conditions if summaries[c.name]["agents"]),
        summaries[conditions[0].name],
    )
    agents = list(dict.fromkeys(a for c in conditions for a in summaries[c.name]["agents"]))
    names = [c.name for c in conditions]
    title = " / ".join(title for _, title, _ in METRICS)
    lines = [
        f"Each cell: {title} (Δv and time over the successful episodes); "
        f"{first['episodes']} episodes of `{first.get('env_id') or first['suite']['name']}`.",
        "",
        "| agent | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    unfit: dict[tuple[str, str], list[str]] = {}  # (agent, reason) -> conditions
    for agent in agents:
        cells = []
        for n in names:
            entry = summaries[n]["agents"].get(agent)
            if entry is None:
                reason = (summaries[n].get("skipped") or {}).get(agent, "not in this run")
                reason = reason.split("; agents that can act")[0]
                unfit.setdefault((agent, reason), []).append(n)
                cells.append(NOT_FLOWN)
            else:
                cells.append(_cell(entry))
        lines.append(f"| {agent} | " + " | ".join(cells) + " |")
    if unfit:
        lines += ["", "Not flown:", ""]
        for (agent, reason), where in unfit.items():
            lines.append(f"- **{agent}** in {', '.join(where)}: {reason}")
    lines += ["", "Conditions:", ""]
    for c in conditions:
        shown = ", ".join(f"`{k}={v}`" for k, v in c.options.items()) or "every error off"
        lines.append(f"- **{c.name}**: {shown}")
    return "\n".join(lines) + "\n"
