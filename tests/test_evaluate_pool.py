"""evaluate.py on every core: the local process pool gives the records of one process, row for
row (timing columns aside), journals them as they arrive, resumes an interrupted run, builds each
agent once per worker for the whole run, and reports a worker that dies."""

from __future__ import annotations

import os
import subprocess
import textwrap
from pathlib import Path

import pytest

from agents.experiments.evaluation.failures import AgentFailure
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.pool import ProcessBackend, available_cores
from agents.experiments.evaluation.runner import evaluate_agents
from tests.helpers import flies_old_ids, load_script
from tests.helpers_evaluate import (
    assert_backend_flies_the_local_records,
    episode_rows,
    run_evaluate,
)

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
QUICK = ["--env", EASY, "--max-steps", "40", "--plots", "0", "--no-progress"]


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


@flies_old_ids
def test_pooled_records_equal_one_process_records():
    """Two workers give the records of one process (random, a stateful agent, flown in order by
    one worker; pretrained, a learned one)."""
    assert_backend_flies_the_local_records(ProcessBackend(workers=2), episodes=4, max_steps=40)


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
    assert episode_rows(tmp_path / "every") == episode_rows(tmp_path / "one")


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
    # random's finished episodes were re-flown in order
    assert episode_rows(out) == episode_rows(whole)
    assert not EvaluationJournal(out).exists()


def _write(path: Path, text: str) -> None:
    path.write_text(textwrap.dedent(text))


def _run_pooled(
    cwd: Path, agents: str, episodes: int, out: Path
) -> subprocess.CompletedProcess[str]:
    """evaluate.py as a command in ``cwd`` (where the test wrote its agents' modules): the quick
    run of ``agents`` on two workers into ``out``."""
    argv = ["--agents", agents, "--episodes", str(episodes), *QUICK, "--workers", "2"]
    return run_evaluate(cwd, *argv, "--out", str(out))


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
    proc = _run_pooled(tmp_path, "coast=counted:Coast", 8, out)
    assert proc.returncode == 0, proc.stderr
    pids = log.read_text().split()
    assert len(pids) == len(set(pids)) == 3  # the main process's check and two workers
    assert len(episode_rows(out)) == 8


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
    proc = _run_pooled(tmp_path, "zero,f=fragile:Fragile", 5, out)
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
    proc = _run_pooled(tmp_path, "zero,m=flaky:Flaky", 4, out)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "agent 'm' failed in episode 1 (reset seed 1) at step 4" in proc.stderr
    assert "of 8 episodes finished" in proc.stderr
    assert ("m", 0) in {(r.agent, r.episode) for r in EvaluationJournal(out).read_records()}
