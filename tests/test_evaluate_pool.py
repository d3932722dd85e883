"""evaluate.py on every core: the local process pool gives the records of one process, row for
row (timing columns aside), journals them as they arrive, resumes an interrupted run, builds each
agent once per worker for the whole run, and reports a worker that dies."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from agents.experiments.evaluation.failures import AgentFailure
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.pool import ProcessBackend, available_cores
from agents.experiments.evaluation.records import RECORD_FIELDS, TIMING_COLUMNS
from agents.experiments.evaluation.runner import evaluate_agents
from tests.helpers import flies_old_ids, load_script

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "evaluate.py"
EASY = "DebrisGym/Rendezvous2D-Easy-v2"
LEARNED_EASY = "DebrisGym/Rendezvous2D-Easy-v1"
"""The Easy rung with a shipped pretrained policy (a learned agent to pool)."""
QUICK = ["--env", EASY, "--max-steps", "40", "--plots", "0", "--no-progress"]


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as fh:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(fh)]


@flies_old_ids
def test_pooled_records_equal_one_process_records():
    """Regression: evaluate.py flew every episode in one process; two workers must give the same
    records (random: a stateful agent, flown in order by one worker; pretrained: a learned one)."""
    agents = "apf,random,zero,pretrained"
    kwargs = {"env_kwargs": {}, "max_episode_steps": 40, "progress": False}
    local = evaluate_agents(LEARNED_EASY, agents, episodes=4, seed=7, **kwargs)
    arrived = []
    pooled = evaluate_agents(
        LEARNED_EASY, agents, episodes=4, seed=7, on_episode=arrived.append,
        backend=ProcessBackend(workers=2), **kwargs,
    )  # fmt: skip
    assert len(arrived) == 16  # each record handed on as it arrived
    assert [(r.agent, r.episode) for r in pooled.records] == [
        (r.agent, r.episode) for r in local.records
    ]
    fields = [f for f in RECORD_FIELDS if f not in TIMING_COLUMNS]
    for a, b in zip(local.records, pooled.records, strict=True):
        assert [getattr(a, f) for f in fields] == [getattr(b, f) for f in fields]
        assert (a.trajectory.positions == b.trajectory.positions).all()
    assert pooled.max_episode_steps == 40


def test_the_default_run_uses_every_core_and_writes_the_one_process_csv(cli, monkeypatch, tmp_path):
    used = []
    fly = ProcessBackend.fly

    def counted(self, *args, **kwargs):
        used.append(self.workers)
        return fly(self, *args, **kwargs)

    monkeypatch.setattr(ProcessBackend, "fly", counted)
    base = ["--agents", "zero,random,apf", "--episodes", "3", *QUICK]
    assert cli.main([*base, "--out", str(tmp_path / "one"), "--workers", "1"]) == 0
    assert used == []  # one worker: this process alone
    assert cli.main([*base, "--out", str(tmp_path / "every")]) == 0
    if available_cores() > 1:
        assert used == [available_cores()]
    assert _rows(tmp_path / "every") == _rows(tmp_path / "one")


def test_an_interrupted_pooled_run_resumes_to_the_one_process_result(
    cli, capsys, monkeypatch, tmp_path
):
    base = ["--agents", "zero,random,apf", "--episodes", "4", *QUICK]
    whole = tmp_path / "whole"
    assert cli.main([*base, "--out", str(whole), "--workers", "1"]) == 0

    append = EvaluationJournal.append
    appended = [0]

    def stop_at_fifth(self, record):
        append(self, record)
        appended[0] += 1
        if appended[0] == 5:
            raise KeyboardInterrupt  # Ctrl-C in this process while the workers fly

    out = tmp_path / "stopped"
    monkeypatch.setattr(EvaluationJournal, "append", stop_at_fifth)
    assert cli.main([*base, "--out", str(out), "--workers", "2"]) == 130
    err = capsys.readouterr().err
    assert "Traceback" not in err and "5 of 12 episodes finished" in err
    assert f"resume with: python evaluate.py --resume {out}" in err
    finished = EvaluationJournal(out).read_records()
    assert len(finished) == 5

    monkeypatch.setattr(EvaluationJournal, "append", append)
    assert cli.main(["--resume", str(out), "--no-progress", "--workers", "2"]) == 0
    assert _rows(out) == _rows(whole)  # random's finished episodes were re-flown in order
    assert not EvaluationJournal(out).exists()


def _write(path: Path, text: str) -> None:
    path.write_text(textwrap.dedent(text))


def test_workers_build_each_agent_once_for_the_whole_run(tmp_path):
    """Envs and agents live as long as their worker: one build per worker (plus the check in the
    main process), never one per episode, so no episode pays a compile or a model load."""
    log = tmp_path / "builds.txt"
    _write(
        tmp_path / "counted.py",
        f"""
        import os
        import numpy as np

        class Coast:
            episode_independent = True

            def __init__(self, env):
                with open({str(log)!r}, "a") as fh:
                    fh.write(f"{{os.getpid()}}\\n")
                self.dim = env.unwrapped.dim

            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                return np.zeros(self.dim, dtype=np.float32), state
        """,
    )
    out = tmp_path / "eval"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--agents", "coast=counted:Coast", "--episodes", "8",
         *QUICK, "--workers", "2", "--out", str(out)],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
        text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    pids = log.read_text().split()
    assert len(pids) == len(set(pids)) == 3  # the main process's check and two workers
    assert len(_rows(out)) == 8


def test_a_worker_that_dies_stops_the_run_naming_the_agent_and_episode(tmp_path):
    _write(
        tmp_path / "fragile.py",
        """
        import os
        import signal
        import numpy as np

        class Fragile:
            episode_independent = True

            def __init__(self, env):
                self.env = env

            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                if self.env.unwrapped.np_random_seed == 3:
                    os.kill(os.getpid(), signal.SIGKILL)  # as the OOM killer would
                return np.zeros(2, dtype=np.float32), state
        """,
    )
    out = tmp_path / "eval"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--agents", "zero,f=fragile:Fragile", "--episodes", "5",
         *QUICK, "--workers", "2", "--out", str(out)],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
        text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "agent 'f' failed in episode 3 (reset seed 3): the worker process" in proc.stderr
    assert "worker process flying it died (killed by signal 9" in proc.stderr
    assert f"resume with: python evaluate.py --resume {out}" in proc.stderr
    assert EvaluationJournal(out).read_records()  # what finished is kept


def test_an_agent_that_fails_in_a_worker_is_named_with_its_episode_and_step(tmp_path):
    _write(
        tmp_path / "nan_policy.py",
        """
        import numpy as np

        def act(obs):
            act.calls = getattr(act, "calls", 0) + 1
            return np.full(2, np.nan) if act.calls == 6 else np.zeros(2)
        """,
    )
    with pytest.raises(AgentFailure) as caught:
        old = os.getcwd()
        os.chdir(tmp_path)
        try:
            evaluate_agents(
                EASY, "bad=nan_policy:act", episodes=2, seed=0, progress=False,
                max_episode_steps=40, backend=ProcessBackend(workers=1),
            )  # fmt: skip
        finally:
            os.chdir(old)
    failure = caught.value
    # one call probes the function when it is built: the 6th call is episode 0's step 4
    assert (failure.agent, failure.episode, failure.step) == ("bad", 0, 4)
    assert "the env refused its action" in failure.reason and "finite" in failure.reason


def test_a_policy_failing_mid_run_in_the_pool_stops_the_run_cleanly(tmp_path):
    """Regression: the worker stopped after reporting the failure while the main process sent it
    its next episode, which ended in a BrokenPipeError traceback."""
    _write(
        tmp_path / "flaky.py",
        """
        import numpy as np

        class Flaky:  # stateful (no episode_independent): one worker flies it in order
            def __init__(self, env):
                self.env = env

            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                u = self.env.unwrapped
                if u.np_random_seed == 1 and u.elapsed >= 4 * u.scenario.dt:
                    return np.full(2, np.nan), state
                return np.zeros(2, dtype=np.float32), state
        """,
    )
    out = tmp_path / "eval"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--agents", "zero,m=flaky:Flaky", "--episodes", "4",
         *QUICK, "--workers", "2", "--out", str(out)],
        cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
        text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "agent 'm' failed in episode 1 (reset seed 1) at step 4" in proc.stderr
    assert "of 8 episodes finished" in proc.stderr
    assert ("m", 0) in {(r.agent, r.episode) for r in EvaluationJournal(out).read_records()}
