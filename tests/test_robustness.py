"""The robustness table: each condition is a real evaluation with its options, gathered."""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest

from agents.experiments.evaluation.command import run_evaluation
from agents.experiments.evaluation.plan import EvaluateOptions, UsageError
from agents.experiments.evaluation.robustness import CONDITIONS, run_robustness


def _pick(*names: str):
    by_name = {c.name: c for c in CONDITIONS}
    return tuple(by_name[n] for n in names)


def _suite_options(agents: str, episodes: int = 1) -> EvaluateOptions:
    """A one-worker evaluation of ``agents`` on the standard 2D suite's first ``episodes``
    missions."""
    return EvaluateOptions(
        suite="standard-2d-v2", agents=agents, episodes=episodes, workers=1, progress=False
    )


def _noted_run(flown: list[dict[str, object]]) -> Callable[[EvaluateOptions], object]:
    """``run_evaluation`` that first notes each evaluation's env options in ``flown``."""

    def run(options: EvaluateOptions) -> object:
        flown.append(dict(options.env_kwargs or {}))
        return run_evaluation(options)

    return run


def test_every_condition_is_flown_with_its_options_and_gathered(tmp_path):
    conditions = _pick("exact", "navigation-high", "actuation-high", "sensing-high")
    options = _suite_options("apf-mpc,zero", episodes=2)
    table = run_robustness(options, tmp_path, run_evaluation, conditions, echo=lambda _: None)
    for condition in conditions:
        summary = json.loads((tmp_path / condition.name / "summary.json").read_text())
        for key, value in condition.options.items():
            assert summary["env_kwargs"][key] == value
        assert summary["episodes"] == 2
    header = next(line for line in table.splitlines() if line.startswith("| agent"))
    assert header.split(" | ")[1:] == [c.name for c in conditions[:-1]] + [
        conditions[-1].name + " |"
    ]
    rows = [line for line in table.splitlines() if line.startswith("| apf-mpc")]
    assert len(rows) == 1 and rows[0].count(" / ") == 3 * len(conditions)
    payload = json.loads((tmp_path / "robustness.json").read_text())
    assert set(payload["agents"]) == {c.name for c in conditions}
    exact = payload["agents"]["exact"]["zero"]
    assert exact["success_rate"] == 0.0  # zero thrust never captures: the cells are real


def test_a_condition_option_given_by_the_user_is_refused(tmp_path):
    options = EvaluateOptions(
        env_kwargs={"sensor_range": 10.0}, agents="zero", episodes=1, workers=1, progress=False
    )
    with pytest.raises(UsageError, match="sensor_range"):
        run_robustness(options, tmp_path, run_evaluation, _pick("sensing-low"))


def test_a_suite_takes_only_the_uncertain_worlds_options(tmp_path):
    bad = EvaluateOptions(
        suite="standard-2d-v2", env_kwargs={"n_obstacles": 3}, agents="zero", episodes=1,
        out=tmp_path, workers=1, progress=False,
    )  # fmt: skip
    with pytest.raises(UsageError, match="n_obstacles"):
        run_evaluation(bad)


def test_a_condition_already_flown_is_kept_and_a_changed_one_flown_again(tmp_path):
    flown = []
    run = _noted_run(flown)
    conditions = _pick("exact", "sensing-high")
    options = _suite_options("zero")
    run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    assert len(flown) == 2
    first = (tmp_path / "robustness.md").read_text()
    run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    assert len(flown) == 2  # both kept
    assert (tmp_path / "robustness.md").read_text() == first
    more = _suite_options("zero", episodes=2)
    run_robustness(more, tmp_path, run, conditions, echo=lambda _: None)
    assert len(flown) == 4  # other episodes: flown again


def test_an_agent_that_cannot_fly_an_error_is_left_out_of_it_with_the_reason(tmp_path):
    """The base law and the residual `pretrained` read the true state, so neither flies with
    navigation errors: they are left out of those conditions (the cells say so and the reason
    is listed), flown in the others, and a table stopped there is kept when run again."""
    flown = []
    run = _noted_run(flown)
    conditions = _pick("exact", "navigation-low")
    options = _suite_options("zero,base-law,pretrained")
    table = run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    rows = {line.split(" | ")[0][2:]: line for line in table.splitlines() if line[:2] == "| "}
    for agent in ("base-law", "pretrained"):
        exact, navigation = rows[agent].strip(" |").split(" | ")[1:]
        assert exact.startswith("100% / 0% /")  # flown, and the mission completed
        assert navigation == "not flown"
        assert f"- **{agent}** in navigation-low: " in table
    assert rows["zero"].count("not flown") == 0
    payload = json.loads((tmp_path / "robustness.json").read_text())
    assert set(payload["skipped"]["navigation-low"]) == {"base-law", "pretrained"}
    assert "true state" in payload["skipped"]["navigation-low"]["base-law"]
    assert payload["skipped"]["exact"] == {}
    run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    assert len(flown) == 2  # the conditions with agents left out are kept too


def test_an_explicit_agent_that_cannot_fly_is_still_refused_outside_the_table(tmp_path):
    options = EvaluateOptions(
        suite="standard-2d-v2", agents="zero,base-law", episodes=1, workers=1, progress=False,
        env_kwargs={"nav_sigma_position": 1.0}, out=tmp_path,
    )  # fmt: skip
    with pytest.raises(UsageError, match="true state"):
        run_evaluation(options)


def test_the_default_agents_leave_out_those_that_cannot_fly_navigation_errors(tmp_path):
    """Without --agents, the base law and the residual `pretrained` are skipped with their
    reasons in a world with navigation errors (the env for the residual policy refuses them)."""
    options = EvaluateOptions(
        env_kwargs={"nav_sigma_position": 1.0}, episodes=1, max_steps=3, workers=1,
        progress=False, out=tmp_path,
    )  # fmt: skip
    run_evaluation(options)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary["skipped"]) == {"base-law", "pretrained"}
    assert "apf-mpc" in summary["agents"] and "zero" in summary["agents"]


def test_a_condition_no_agent_can_fly_is_noted_and_kept(tmp_path):
    """Only agents that read the true state: the navigation condition flies no one; its cells
    say so, its reasons are listed, and a second run keeps it."""
    flown = []
    run = _noted_run(flown)
    conditions = _pick("exact", "navigation-high")
    options = _suite_options("base-law")
    table = run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    row = next(line for line in table.splitlines() if line.startswith("| base-law"))
    assert row.strip(" |").split(" | ")[2] == "not flown"
    assert "- **base-law** in navigation-high: " in table
    summary = json.loads((tmp_path / "navigation-high" / "summary.json").read_text())
    assert summary["agents"] == {} and "true state" in summary["skipped"]["base-law"]
    run_robustness(options, tmp_path, run, conditions, echo=lambda _: None)
    assert len(flown) == 2  # both kept: neither is flown again
