"""A swarm evaluation keeps every finished episode in its journal: a run stopped by Ctrl-C or a
failing team is finished by ``evaluate.py --resume DIR`` with the tables of an unbroken run, and
``--workers N`` flies the same episodes as one process."""

from __future__ import annotations

import csv
import json

import pytest

pytest.importorskip("pettingzoo")

from agents.experiments.swarm_evaluation import flight as flight_module
from agents.experiments.swarm_evaluation.journal import (
    SwarmJournal,
    episode_from_json,
    episode_to_json,
    is_swarm_journal,
)
from tests.helpers import load_script

SWARM = "DebrisGym/Swarm2D-v0"
TIMING = ("decision_ms_mean", "decision_ms_p95", "wall_s")
"""The columns of ``episodes.csv`` that are clock readings."""

COMMON = [
    "--env", SWARM, "--env-kwargs", '{"n_chasers": 2, "n_targets": 2, "n_obstacles": 2}',
    "--max-steps", "12", "--episodes", "3", "--seed", "5", "--no-progress",
    "--agents", "team-apf-mpc@balanced,team-zero", "--plots", "1",
]  # fmt: skip


@pytest.fixture(scope="module")
def evaluate():
    return load_script("evaluate.py", "evaluate_swarm_resume_script")


def _rows(out) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(fh)]


def _stop_after(monkeypatch, calls: int, error: Exception) -> list[tuple[str, int]]:
    """Make the in-process flight raise ``error`` when its episode number ``calls`` begins;
    returns the (team, episode) of every episode begun."""
    begun: list[tuple[str, int]] = []
    real = flight_module.fly_one

    def fly_one(built, flight, i):
        begun.append((built.spec.label, i))
        if len(begun) == calls:
            raise error
        return real(built, flight, i)

    monkeypatch.setattr(flight_module, "fly_one", fly_one)
    return begun


@pytest.fixture(scope="module")
def unbroken(evaluate, tmp_path_factory):
    """The tables of the run flown in one go, in this process."""
    out = tmp_path_factory.mktemp("unbroken") / "eval"
    assert evaluate.main([*COMMON, "--out", str(out), "--workers", "1"]) == 0
    return out


def test_an_interrupted_swarm_run_resumes_to_the_tables_of_an_unbroken_one(
    evaluate, unbroken, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "eval"
    begun = _stop_after(monkeypatch, 4, KeyboardInterrupt())
    assert evaluate.main([*COMMON, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "interrupted: 3 of 6 episodes are kept" in err
    assert f"python evaluate.py --resume {out}" in err
    assert not (out / "episodes.csv").exists()
    assert is_swarm_journal(out)
    journal = SwarmJournal(out)
    kept = [(f.record.agent, f.record.episode) for f in journal.read_episodes()]
    assert kept == begun[:3]
    monkeypatch.undo()

    assert evaluate.main(["--resume", str(out), "--no-progress"]) == 0
    assert _rows(out) == _rows(unbroken)
    with open(out / "assignments.csv") as a, open(unbroken / "assignments.csv") as b:
        assert a.read() == b.read()
    plots = sorted(p.name for p in out.glob("trajectories_ep*.png"))
    assert plots == sorted(p.name for p in unbroken.glob("trajectories_ep*.png"))
    assert len(plots) == 2  # --plots 1: episode 0 of each team
    assert not (out / "unfinished").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["resumed_episodes"] == 3 and summary["episodes"] == 3


def test_a_failing_team_stops_the_run_with_its_episodes_kept(
    evaluate, unbroken, tmp_path, capsys, monkeypatch
):
    out = tmp_path / "eval"
    _stop_after(monkeypatch, 2, flight_module.TeamFailed("team-x failed in episode 1"))
    assert evaluate.main([*COMMON, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "error: team-x failed in episode 1" in err
    assert "1 of 6 episodes are kept" in err and "--resume" in err
    monkeypatch.undo()
    assert evaluate.main(["--resume", str(out), "--no-progress", "--workers", "2"]) == 0
    assert _rows(out) == _rows(unbroken)


def test_two_workers_fly_the_records_of_one_process(evaluate, unbroken, tmp_path):
    out = tmp_path / "eval"
    assert evaluate.main([*COMMON, "--out", str(out), "--workers", "2"]) == 0
    assert _rows(out) == _rows(unbroken)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["workers"] == 2 and "2 worker processes" in summary["title"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--episodes", "4"], "takes no --episodes"),
        (["--env", SWARM], "takes no --env"),
        (["--shield"], "takes no --shield"),
    ],
)
def test_resume_refuses_the_options_the_journal_fixes(
    evaluate, tmp_path, capsys, monkeypatch, extra, message
):
    out = tmp_path / "eval"
    _stop_after(monkeypatch, 2, KeyboardInterrupt())
    assert evaluate.main([*COMMON, "--out", str(out)]) == 130
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        evaluate.main(["--resume", str(out), *extra])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --resume" in err and message in err
    assert SwarmJournal(out).read_episodes()  # the journal is untouched


def test_a_journaled_swarm_episode_reads_back_equal(evaluate, tmp_path, monkeypatch):
    """Exploration records (ma-se-scp) and shield counters survive the round trip."""
    out = tmp_path / "eval"
    _stop_after(monkeypatch, 2, KeyboardInterrupt())
    argv = [
        "--env", "DebrisGym/Reconfigure2D-v0", "--env-kwargs", '{"n_chasers": 2}',
        "--max-steps", "3", "--episodes", "2", "--no-progress", "--agents", "ma-se-scp",
        "--shield", "--plots", "0", "--out", str(out),
    ]  # fmt: skip
    assert evaluate.main(argv) == 130
    (finished,) = SwarmJournal(out).read_episodes()
    record = finished.record
    assert record.exploration is not None and len(record.shield) == 2
    again = episode_from_json(json.loads(json.dumps(episode_to_json(finished))))
    assert again.record == record
    assert again.rules.keys() == finished.rules.keys()
    for rule, a in finished.rules.items():
        b = again.rules[rule]
        assert (a.rule, a.cost) == (b.rule, b.cost)
        assert (a.table == b.table).all() and (a.tours == b.tours).all()


def test_resuming_a_directory_without_a_journal_says_so(evaluate, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit) as exc:
        evaluate.main(["--resume", str(tmp_path / "empty")])
    assert exc.value.code == 2
    assert "nothing to resume" in capsys.readouterr().err
