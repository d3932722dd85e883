"""evaluate.py's output directory as a transaction: --out checked before
anything runs, one run per directory, outputs landing as one set, Ctrl-C keeping the finished
episodes, and --resume DIR finishing the run as if it had never stopped."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents.experiments.evaluation import command, report, runner
from agents.experiments.evaluation.journal import (
    EvaluationJournal,
    JournalError,
    record_from_json,
    record_to_json,
)
from agents.experiments.evaluation.records import scenario_fingerprint
from agents.experiments.run_directory import MANIFEST, RunDirectoryBusy, RunDirectoryLock
from tests.helpers import flies_old_ids, load_script
from tests.helpers_evaluate import SCRIPT, episode_rows, run_evaluate, script_env, usage_error

QUICK = [
    "--env-kwargs", '{"n_obstacles": 5}', "--max-steps", "30", "--no-progress", "--workers", "1",
]  # fmt: skip
"""A small run in this process (the tests that count or stop episodes patch this process)."""


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


def _count_episodes(monkeypatch, interrupt_at: int | None = None) -> list[int]:
    """Count the episodes flown (in ``calls[0]``); Ctrl-C at the start of episode
    ``interrupt_at`` (1-based) if given."""
    calls = [0]
    fly = runner.run_episode

    def counted(*args, **kwargs):
        calls[0] += 1
        if calls[0] == interrupt_at:
            raise KeyboardInterrupt
        return fly(*args, **kwargs)

    monkeypatch.setattr(runner, "run_episode", counted)
    return calls


# --- --out is checked before anything runs --------------------------------------------------


def _never_evaluate(monkeypatch):
    def fail(*args, **kwargs):
        raise AssertionError("an episode ran before --out was checked")

    monkeypatch.setattr(command, "evaluate_agents", fail)


def test_out_naming_a_file_or_a_path_under_one_is_a_usage_error(cli, capsys, monkeypatch, tmp_path):
    _never_evaluate(monkeypatch)
    afile = tmp_path / "afile"
    afile.write_text("mine")
    err = usage_error(cli, capsys, ["--agents", "zero", "--out", str(afile)])
    assert "argument --out" in err and str(afile) in err and "is a file" in err
    err = usage_error(cli, capsys, ["--agents", "zero", "--out", str(afile / "x")])
    assert "argument --out" in err and "lies under" in err
    assert afile.read_text() == "mine"


def test_an_empty_out_is_refused_instead_of_writing_into_the_current_directory(
    cli, capsys, monkeypatch, tmp_path
):
    _never_evaluate(monkeypatch)
    monkeypatch.chdir(tmp_path)
    err = usage_error(cli, capsys, ["--agents", "zero", "--out", ""])
    assert "argument --out" in err and "empty" in err
    assert not list(tmp_path.iterdir())


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_an_unwritable_out_is_a_usage_error(cli, capsys, monkeypatch, tmp_path):
    _never_evaluate(monkeypatch)
    locked = tmp_path / "ro"
    locked.mkdir(mode=0o500)
    err = usage_error(cli, capsys, ["--agents", "zero", "--out", str(locked / "out")])
    assert "argument --out" in err and "permission denied" in err


def test_a_second_run_on_a_directory_is_refused_naming_the_first(
    cli, capsys, monkeypatch, tmp_path
):
    _never_evaluate(monkeypatch)
    out = tmp_path / "eval"
    with RunDirectoryLock(out):  # the first run, still going
        err = usage_error(cli, capsys, ["--agents", "zero", *QUICK, "--out", str(out)])
        assert sorted(p.name for p in out.iterdir()) == [".lock"]  # the first run's only
    assert "argument --out" in err and f"process {os.getpid()}" in err
    assert list(out.iterdir()) == []  # the first run's lock file goes when it ends


# --- the outputs land as one set ------------------------------------------------------------


def test_plots_of_an_earlier_run_are_removed_with_its_set(cli, tmp_path):
    out = tmp_path / "eval"
    base = ["--agents", "zero", "--episodes", "3", *QUICK, "--out", str(out)]
    assert cli.main([*base, "--plots", "3"]) == 0
    assert len(list(out.glob("trajectories_ep*.png"))) == 3
    (out / "notes.txt").write_text("the user's own file")
    assert cli.main([*base, "--plots", "1", "--seed", "5"]) == 0
    assert [p.name for p in out.glob("trajectories_ep*.png")] == ["trajectories_ep000.png"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["files"] == [
        "episodes.csv", "summary.json", "summary.md", "trajectories_ep000.png",
    ]  # fmt: skip
    assert manifest["evaluation"]["seed"] == 5
    assert (out / "notes.txt").read_text() == "the user's own file"
    assert not (out / "unfinished").exists()  # a finished run leaves no journal


def test_ctrl_c_while_the_outputs_are_written_leaves_the_previous_set_whole(
    cli, capsys, monkeypatch, tmp_path
):
    out = tmp_path / "eval"
    base = ["--agents", "zero,random", "--episodes", "2", "--plots", "2", *QUICK, "--out", str(out)]
    assert cli.main(base) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()

    plot = report.plot_episode
    plotted = []

    def plot_then_ctrl_c(results, episode):
        plotted.append(episode)
        if len(plotted) == 2:
            raise KeyboardInterrupt
        return plot(results, episode)

    monkeypatch.setattr(report, "plot_episode", plot_then_ctrl_c)
    assert cli.main([*base, "--seed", "3"]) == 130
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "all 4 episodes finished but the outputs were not written" in err
    assert f"resume with: python evaluate.py --resume {out}" in err
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    # the first run's set, whole: no CSV of one run beside the PNGs of another
    assert after == before

    monkeypatch.setattr(report, "plot_episode", plot)
    calls = _count_episodes(monkeypatch)
    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    assert calls[0] == 0  # every episode had finished: only the outputs are written
    assert {r["seed"] for r in episode_rows(out)} == {"3", "4"}
    assert len(list(out.glob("trajectories_ep*.png"))) == 2


def test_paper_tables_are_part_of_the_set(cli, monkeypatch, tmp_path):
    import agents

    for name in ("apf", "apf-mpc", "astar"):  # stand-ins: the set is what is tested
        monkeypatch.setitem(agents.BASELINES, name, "agents.policies.simple:ZeroAgent")
    out = tmp_path / "paper"
    argv = ["--paper", "--max-steps", "20", "--no-progress", "--workers", "1"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    assert {"paper_table.md", "paper_table.json"} <= set(manifest["files"])
    assert cli.main(["--agents", "zero", "--episodes", "1", *QUICK, "--out", str(out)]) == 0
    assert not (out / "paper_table.md").exists() and not (out / "paper_table.json").exists()


# --- Ctrl-C keeps the finished episodes; --resume finishes the run --------------------------


def test_an_interrupted_run_resumes_to_the_uninterrupted_result(cli, capsys, monkeypatch, tmp_path):
    base = ["--agents", "zero,random,apf", "--episodes", "3", "--plots", "1", *QUICK]
    whole = tmp_path / "whole"
    assert cli.main([*base, "--out", str(whole)]) == 0

    out = tmp_path / "stopped"
    _count_episodes(monkeypatch, interrupt_at=5)  # Ctrl-C in random's episode 1
    assert cli.main([*base, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "4 of 9 episodes finished" in err
    assert f"resume with: python evaluate.py --resume {out}\n" in err
    journal = EvaluationJournal(out)
    assert [(r.agent, r.episode) for r in journal.read_records()] == [
        ("zero", 0), ("zero", 1), ("zero", 2), ("random", 0),
    ]  # fmt: skip
    assert not (out / "episodes.csv").exists()

    calls = _count_episodes(monkeypatch)
    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    # zero is skipped; random re-flies episode 0 (its generator carries over), then 1 and 2
    assert calls[0] == 3 + 3
    assert episode_rows(out) == episode_rows(whole)
    assert not journal.exists()
    whole_summary = json.loads((whole / "summary.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    for label, entry in whole_summary["agents"].items():
        for key in ("success_rate", "delta_v_mean", "path_length_mean", "min_clearance_min"):
            assert summary["agents"][label][key] == entry[key]


SLOW_POLICY = """
import time
import numpy as np

class Slow:
    episode_independent = {independent}

    def __init__(self, env):
        self.dim = env.unwrapped.dim

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        time.sleep(0.02)
        return np.zeros(self.dim, dtype=np.float32), state
"""
"""An agent that coasts 20 ms a step, slow enough to be stopped mid-run; ``episode_independent``
(its episodes may fly on any worker) or not (one worker flies them in order)."""


def _start_slow_run(
    out: Path, episodes: int, independent: bool, *argv: str, **popen: Any
) -> tuple[subprocess.Popen[str], EvaluationJournal]:
    """Start evaluate.py on zero and :data:`SLOW_POLICY` (``argv`` added) into ``out`` as a
    command in its parent directory, its output piped; the process and the journal of its run."""
    (out.parent / "slowpolicy.py").write_text(SLOW_POLICY.format(independent=independent))
    command = [
        sys.executable, str(SCRIPT), "--agents", "zero,slow=slowpolicy:Slow",
        "--episodes", str(episodes), "--env-kwargs", '{"n_obstacles": 3}', "--max-steps", "25",
        "--plots", "0", "--no-progress", *argv, "--out", str(out),
    ]  # fmt: skip
    proc = subprocess.Popen(
        command, cwd=out.parent, env=script_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, **popen,
    )  # fmt: skip
    return proc, EvaluationJournal(out)


def _wait_until_journaled(
    proc: subprocess.Popen[str], journal: EvaluationJournal, lines: int, timeout: float
) -> None:
    """Wait until the journal holds more than ``lines`` lines, the run ends or ``timeout`` s
    pass."""
    path, deadline = journal.episodes_path, time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if path.is_file() and path.read_text().count("\n") > lines:
            return
        time.sleep(0.05)


def _assert_resumes_every_episode(out: Path, episodes: int, timeout: float) -> None:
    """``evaluate.py --resume out`` as a command finishes the run of :func:`_start_slow_run`:
    both agents' episodes, in order."""
    resumed = run_evaluate(out.parent, "--resume", str(out), "--no-progress", timeout=timeout)
    assert resumed.returncode == 0, resumed.stderr
    pairs = [(r["agent"], int(r["episode"])) for r in episode_rows(out)]
    assert pairs == [(a, i) for a in ("zero", "slow") for i in range(episodes)]


def test_ctrl_c_for_real_in_a_run_started_with_sigint_ignored(tmp_path):
    def ignore_sigint() -> None:  # what a shell does for a job started with '&'
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    out = tmp_path / "eval"
    proc, journal = _start_slow_run(out, 6, False, preexec_fn=ignore_sigint)
    _wait_until_journaled(proc, journal, 6, timeout=120)  # zero is done and slow is on its way
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    finished = len(journal.read_records())
    assert 7 <= finished < 12
    assert f"{finished} of 12 episodes finished" in err
    assert f"resume with: python evaluate.py --resume {out}" in err
    _assert_resumes_every_episode(out, 6, timeout=120)


def test_resume_takes_no_other_options_and_needs_an_unfinished_run(cli, capsys, tmp_path):
    err = usage_error(cli, capsys, ["--resume", str(tmp_path), "--seed", "3"])
    assert "argument --seed" in err and "--resume" in err
    err = usage_error(cli, capsys, ["--resume", str(tmp_path)])
    assert "argument --resume" in err and "nothing to resume" in err
    err = usage_error(cli, capsys, ["--resume", str(tmp_path / "nowhere")])
    assert "argument --resume" in err and "not a directory" in err


def test_a_damaged_journal_line_is_named_and_a_cut_last_line_dropped(
    cli, capsys, monkeypatch, tmp_path
):
    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(command, "write_outputs", stop)  # keep the journal of a whole run
    out = tmp_path / "eval"
    argv = ["--agents", "zero", "--episodes", "2", "--plots", "0", *QUICK, "--out", str(out)]
    assert cli.main(argv) == 130
    journal = EvaluationJournal(out)
    records = journal.read_records()
    assert [r.episode for r in records] == [0, 1]

    journal.start({"x": 1})
    journal.append(records[0])
    with open(journal.episodes_path, "ab") as fh:
        fh.write(b'{"agent": "zero", "epi')  # a kill in the middle of a write
    assert len(journal.read_records()) == 1
    journal.drop_partial_line()
    journal.append(records[1])
    assert [r.episode for r in journal.read_records()] == [0, 1]

    with open(journal.episodes_path, "ab") as fh:
        fh.write(b"garbage\n")
    journal.append(records[1])
    with pytest.raises(JournalError, match=r"episodes\.jsonl, line 3"):
        journal.read_records()


@flies_old_ids
def test_a_journaled_record_reads_back_bit_for_bit():
    results = runner.evaluate_agents(
        "DebrisGym/Rendezvous3D-v0", "random", episodes=1, seed=11,
        env_kwargs={"n_obstacles": 4}, progress=False, max_episode_steps=25,
    )  # fmt: skip
    record = results.records[0]
    back = record_from_json(json.loads(json.dumps(record_to_json(record))))
    for name in ("delta_v", "path_length", "min_clearance", "episode_return", "scenario_id"):
        assert getattr(back, name) == getattr(record, name)
    for name in ("positions", "velocities", "accelerations", "decision_ms"):
        np.testing.assert_array_equal(
            getattr(back.trajectory, name), getattr(record.trajectory, name)
        )
    assert scenario_fingerprint(back.scenario) == record.scenario_id


def test_resume_refuses_a_journal_of_another_evaluation(cli, capsys, monkeypatch, tmp_path):
    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(command, "write_outputs", stop)
    out = tmp_path / "eval"
    argv = ["--agents", "zero", "--episodes", "2", "--plots", "0", *QUICK, "--out", str(out)]
    assert cli.main(argv) == 130
    journal = EvaluationJournal(out)
    options = json.loads(journal.options_path.read_text())
    journal.options_path.write_text(json.dumps({**options, "seed": 7}))  # not what was flown
    err = usage_error(cli, capsys, ["--resume", str(out)])
    assert "argument --resume" in err and "episodes.jsonl" in err and "reset seed 0" in err
    journal.options_path.write_text("{not json")
    err = usage_error(cli, capsys, ["--resume", str(out)])
    assert "argument --resume" in err and "options.json" in err


def test_video_records_each_agents_first_episodes(cli, tmp_path):
    """--video N: RecordVideo mp4s of the first N episodes of every agent, every frame of the
    episode in them (the reset frame and one per step; moviepy may drop the last)."""
    pytest.importorskip("moviepy", reason="--video needs moviepy: pip install -e '.[video]'")
    from moviepy import VideoFileClip

    out = tmp_path / "eval"
    argv = ["--agents", "zero,apf", "--episodes", "2", "--max-steps", "12", "--video", "1"]
    assert cli.main([*argv, "--out", str(out), "--plots", "0", "--no-progress"]) == 0
    for agent in ("zero", "apf"):
        videos = sorted((out / "videos" / agent).glob("*.mp4"))
        assert [v.name for v in videos] == [f"{agent}-episode-0.mp4"]
        rows = [r for r in episode_rows(out) if r["agent"] == agent and r["episode"] == "0"]
        steps = int(rows[0]["steps"])
        with VideoFileClip(str(videos[0])) as clip:
            frames = sum(1 for _ in clip.iter_frames())
        assert steps <= frames <= steps + 1


def test_a_bad_video_count_is_a_usage_error(cli, capsys):
    err = usage_error(cli, capsys, ["--agents", "zero", "--video", "-1"])
    assert "argument --video" in err and "must be an integer >= 0" in err


# --- a file that cannot be written stops the run with the resume line -----------------------


def test_a_full_disk_while_journaling_stops_the_run_with_the_resume_line(
    cli, capsys, monkeypatch, tmp_path
):
    """Regression: a full disk (or a directory made read-only) mid-run gave a traceback and no
    resume line."""
    base = ["--agents", "zero,random", "--episodes", "3", "--plots", "0", *QUICK]
    whole = tmp_path / "whole"
    assert cli.main([*base, "--out", str(whole)]) == 0

    append = EvaluationJournal.append
    calls = [0]

    def full_at_fourth(self, record):
        calls[0] += 1
        if calls[0] == 4:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        append(self, record)

    out = tmp_path / "eval"
    monkeypatch.setattr(EvaluationJournal, "append", full_at_fourth)
    assert cli.main([*base, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"cannot write {out / 'unfinished' / 'episodes.jsonl'} (No space left on device)" in err
    assert "3 of 6 episodes finished" in err
    assert f"make room or restore write access in {out}, then resume with: python evaluate.py " \
        f"--resume {out}" in err  # fmt: skip
    monkeypatch.setattr(EvaluationJournal, "append", append)
    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "1"]) == 0
    assert episode_rows(out) == episode_rows(whole)


def test_a_full_disk_while_the_outputs_are_written_keeps_every_episode(
    cli, capsys, monkeypatch, tmp_path
):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "summary.json")

    monkeypatch.setattr(command, "write_outputs", full)
    out = tmp_path / "eval"
    argv = ["--agents", "zero", "--episodes", "2", "--plots", "0", *QUICK, "--out", str(out)]
    assert cli.main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "No space left on device" in err
    assert "all 2 episodes finished but the outputs were not written" in err
    assert f"resume with: python evaluate.py --resume {out}" in err
    assert len(EvaluationJournal(out).read_records()) == 2


# --- without --out, a run never replaces another run's results ------------------------------


def test_runs_without_out_never_replace_each_other(cli, capsys, monkeypatch, tmp_path):
    """Regression: a plain `python evaluate.py` silently replaced runs/eval/ of the run before."""
    monkeypatch.chdir(tmp_path)
    base = ["--agents", "zero", "--episodes", "1", "--plots", "0", *QUICK]
    assert cli.main([*base, "--seed", "1"]) == 0
    first = {p.name: p.read_bytes() for p in (tmp_path / "runs/eval").iterdir()}
    assert "runs/eval/episodes.csv" in capsys.readouterr().out
    assert cli.main([*base, "--seed", "2"]) == 0
    captured = capsys.readouterr()
    assert "runs/eval-2/episodes.csv" in captured.out
    assert "runs/eval holds an earlier evaluation, kept; this one writes to runs/eval-2" in (
        captured.err
    )
    assert {p.name: p.read_bytes() for p in (tmp_path / "runs/eval").iterdir()} == first
    assert [r["seed"] for r in episode_rows(tmp_path / "runs/eval-2")] == ["2"]
    assert [p.name for p in sorted((tmp_path / "runs").iterdir())] == ["eval", "eval-2"]


def test_an_explicit_out_holding_results_is_replaced_with_a_note(cli, capsys, tmp_path):
    out = tmp_path / "eval"
    base = ["--agents", "zero", "--episodes", "1", "--plots", "0", *QUICK, "--out", str(out)]
    assert cli.main(base) == 0
    assert "replaced" not in capsys.readouterr().err
    assert cli.main([*base, "--seed", "4"]) == 0
    assert f"{out} holds an earlier evaluation's results; they are replaced" in (
        capsys.readouterr().err
    )


def test_a_finished_run_leaves_no_lock_file(cli, tmp_path):
    """Regression: every finished run left DIR/.lock behind."""
    out = tmp_path / "eval"
    assert cli.main(["--agents", "zero", "--episodes", "1", *QUICK, "--out", str(out)]) == 0
    assert not (out / ".lock").exists()
    lock = RunDirectoryLock(out)
    lock.acquire()
    assert (out / ".lock").is_file()
    with pytest.raises(RunDirectoryBusy):
        RunDirectoryLock(out).acquire()
    lock.release()
    assert not (out / ".lock").exists()
    with RunDirectoryLock(out):  # the directory can be locked again
        pass


# --- Ctrl-C at the terminal with worker processes -------------------------------------------


def test_ctrl_c_at_the_terminal_stops_the_workers_and_the_run_resumes(tmp_path):
    """A Ctrl-C at a terminal reaches the whole process group: the workers ignore it, the main
    process journals what finished, stops them and prints the resume command."""
    out = tmp_path / "eval"
    proc, journal = _start_slow_run(
        out, 8, True, "--workers", "2",
        start_new_session=True,  # its own process group, as a terminal job has
    )  # fmt: skip
    _wait_until_journaled(proc, journal, 9, timeout=180)  # zero is done and slow is on its way
    os.killpg(proc.pid, signal.SIGINT)  # what the terminal does on Ctrl-C
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    finished = len(journal.read_records())
    assert 10 <= finished < 16
    assert f"{finished} of 16 episodes finished" in err
    with pytest.raises(ProcessLookupError):  # no worker outlives the run
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            os.killpg(proc.pid, 0)
            time.sleep(0.1)
    _assert_resumes_every_episode(out, 8, timeout=300)


# --- videos ---------------------------------------------------------------------------------


def test_videos_are_listed_with_the_files_and_in_the_manifest(cli, capsys, tmp_path):
    """Regression: the videos were missing from the printed file list and manifest.json."""
    pytest.importorskip("moviepy", reason="--video needs moviepy: pip install -e '.[video]'")
    out = tmp_path / "eval"
    argv = ["--agents", "zero", "--episodes", "1", "--max-steps", "4", "--video", "1"]
    assert cli.main([*argv, "--out", str(out), "--plots", "0", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    video = out / "videos" / "zero" / "zero-episode-0.mp4"
    assert video.is_file() and f"  {video}\n" in printed
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["videos"] == ["videos/zero/zero-episode-0.mp4"]


def test_shielded_frames_show_the_shield_and_its_interventions():
    """Regression: nothing in a video's frames said the shield was on, or when it acted."""
    import gymnasium as gym

    from agents.experiments.evaluation.video import INTERVENED, ON, ShieldFrames

    class Stats:
        interventions = 0

    class Agent:
        stats = Stats()

    env = ShieldFrames(gym.make("DebrisGym/Rendezvous2D-Easy-v2", render_mode="rgb_array"))
    env.agent = Agent()
    env.reset(seed=0)
    plain = env.env.render()
    frame = env.render()
    assert frame.shape == plain.shape and tuple(frame[2, 2]) == ON
    Agent.stats.interventions = 1  # the shield replaced the command of the next step
    env.step(np.zeros(2))
    frame = env.render()
    assert tuple(frame[2, 2]) == INTERVENED and tuple(frame[-2, frame.shape[1] // 2]) == INTERVENED
    env.step(np.zeros(2))  # not replaced this time
    assert tuple(env.render()[2, 2]) == ON
    env.close()


def test_video_records_in_this_process_only(cli, capsys, tmp_path):
    err = usage_error(
        cli, capsys, ["--agents", "zero", "--video", "1", "--workers", "2", "--out", str(tmp_path)]
    )
    assert "argument --workers: --video records in this process: use --workers 1" in err


def test_a_run_without_out_beside_an_unfinished_one_says_how_to_finish_it(
    cli, capsys, monkeypatch, tmp_path
):
    monkeypatch.chdir(tmp_path)
    EvaluationJournal(tmp_path / "runs/eval").start({"stopped": "by Ctrl-C"})
    assert cli.main(["--agents", "zero", "--episodes", "1", "--plots", "0", *QUICK]) == 0
    err = capsys.readouterr().err
    assert "python evaluate.py --resume runs/eval finishes it; this one writes to runs/eval-2" in (
        err
    )
    assert EvaluationJournal(tmp_path / "runs/eval").exists()  # left for --resume
