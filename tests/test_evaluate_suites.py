"""evaluate.py --suite: flies a frozen suite's first N missions, records the suite's name and
content hash, refuses options that would change the suite, and resumes."""

from __future__ import annotations

import json

import pytest

from agents.experiments.evaluation import runner
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.records import scenario_fingerprint
from debris_gym.suites import load_suite
from tests.helpers import load_script
from tests.helpers_evaluate import episode_rows, usage_error

SUITE = "standard-2d-v2"
QUICK = ["--max-steps", "4", "--plots", "0", "--no-progress", "--workers", "1"]


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


def test_suite_flies_its_first_n_missions_and_records_name_and_hash(cli, tmp_path, capsys):
    out = tmp_path / "suite"
    argv = ["--suite", SUITE, "--agents", "zero,random", "--episodes", "3", *QUICK]
    assert cli.main([*argv, "--out", str(out)]) == 0
    suite = load_suite(SUITE)
    rows = episode_rows(out)
    assert len(rows) == 2 * 3
    for row in rows:
        mission = suite.missions[int(row["episode"])]
        assert int(row["seed"]) == mission.seed
        assert row["scenario_id"] == scenario_fingerprint(mission.scenario)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["suite"] == {
        "name": SUITE,
        "hash": suite.content_hash,
        "missions_flown": 3,
        "missions_in_suite": 100,
    }
    assert summary["env_id"] == suite.env_id and summary["env_kwargs"] == {}
    assert summary["reset_seeds"] == list(suite.seeds[:3])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["evaluation"]["suite"] == SUITE
    assert manifest["evaluation"]["suite_hash"] == suite.content_hash
    title = (out / "summary.md").read_text().splitlines()[0]
    assert f"Suite `{SUITE}` (content hash {suite.content_hash}): its first 3 of 100" in title
    assert title in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "flag", "text"),
    [
        (["--env", "DebrisGym/Rendezvous3D-v2"], "--env", "not allowed with --suite"),
        (["--seed", "5"], "--seed", "not allowed with --suite"),
        (["--env-kwargs", '{"n_obstacles": 4}'], "--env-kwargs", "not allowed with --suite"),
        (["--paper"], "--paper", "not allowed with --suite"),
        (["--episodes", "101"], "--episodes", f"suite '{SUITE}' has 100 missions"),
    ],
)
def test_suite_refuses_options_that_change_it(cli, capsys, tmp_path, extra, flag, text):
    err = usage_error(
        cli, capsys, ["--suite", SUITE, "--agents", "zero", *extra, "--out", str(tmp_path / "o")]
    )
    assert f"argument {flag}:" in err and text in err
    assert not (tmp_path / "o" / "episodes.csv").exists()


def test_an_unknown_suite_lists_the_shipped_ones(cli, capsys, tmp_path):
    err = usage_error(cli, capsys, ["--suite", "nope", "--out", str(tmp_path / "o")])
    assert "argument --suite: suite must be one of" in err and SUITE in err


def test_help_names_the_suites_and_labels_paper_mode(cli):
    text = " ".join(cli.build_parser().format_help().split())
    assert "--suite NAME" in text and SUITE in text
    assert "NOT a reproduction" in text and "paired_success" in text


def test_an_interrupted_suite_run_resumes_and_refuses_a_changed_suite(
    cli, capsys, monkeypatch, tmp_path
):
    base = ["--suite", SUITE, "--agents", "zero,random", "--episodes", "2", *QUICK]
    whole = tmp_path / "whole"
    assert cli.main([*base, "--out", str(whole)]) == 0

    fly = runner.run_episode
    calls = [0]

    def stop_at_third(*args, **kwargs):
        calls[0] += 1
        if calls[0] == 3:
            raise KeyboardInterrupt
        return fly(*args, **kwargs)

    out = tmp_path / "stopped"
    monkeypatch.setattr(runner, "run_episode", stop_at_third)
    assert cli.main([*base, "--out", str(out)]) == 130
    assert "2 of 4 episodes finished" in capsys.readouterr().err
    monkeypatch.setattr(runner, "run_episode", fly)

    # a suite whose content changed since the run started is refused
    journal = EvaluationJournal(out)
    options = json.loads(journal.options_path.read_text())
    changed = {**options, "suite_hash": "0" * 16}
    journal.options_path.write_text(json.dumps(changed))
    err = usage_error(cli, capsys, ["--resume", str(out), "--no-progress"])
    assert "argument --resume:" in err and "has changed since the run started" in err
    journal.options_path.write_text(json.dumps(options))

    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    assert episode_rows(out) == episode_rows(whole)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["suite"]["hash"] == load_suite(SUITE).content_hash
