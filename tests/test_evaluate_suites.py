"""evaluate.py --suite: flies a frozen suite's first N missions, records the suite's name and
content hash, refuses options that would change the suite, and resumes."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from agents.experiments.evaluation import runner
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.records import scenario_fingerprint
from debris_gym.suites import load_suite
from tests.helpers import load_script

SUITE = "standard-2d-v2"
QUICK = ["--max-steps", "4", "--plots", "0", "--no-progress", "--workers", "1"]


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as f:
        return list(csv.DictReader(f))


def _usage_error(cli, capsys, argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_suite_flies_its_first_n_missions_and_records_name_and_hash(cli, tmp_path, capsys):
    out = tmp_path / "suite"
    argv = ["--suite", SUITE, "--agents", "zero,random", "--episodes", "3", *QUICK]
    assert cli.main([*argv, "--out", str(out)]) == 0
    suite = load_suite(SUITE)
    rows = _rows(out)
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
    err = _usage_error(
        cli, capsys, ["--suite", SUITE, "--agents", "zero", *extra, "--out", str(tmp_path / "o")]
    )
    assert f"argument {flag}:" in err and text in err
    assert not (tmp_path / "o" / "episodes.csv").exists()


def test_an_unknown_suite_lists_the_shipped_ones(cli, capsys, tmp_path):
    err = _usage_error(cli, capsys, ["--suite", "nope", "--out", str(tmp_path / "o")])
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
    err = _usage_error(cli, capsys, ["--resume", str(out), "--no-progress"])
    assert "argument --resume:" in err and "has changed since the run started" in err
    journal.options_path.write_text(json.dumps(options))

    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    timing = {"decision_ms_p50", "decision_ms_p95", "decision_ms_max"}

    def untimed(rows):
        return [{k: v for k, v in row.items() if k not in timing} for row in rows]

    assert untimed(_rows(out)) == untimed(_rows(whole))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["suite"]["hash"] == load_suite(SUITE).content_hash
