"""Helpers of the tests that run evaluate.py: in this process (its ``main``), as a command, or
through :func:`~agents.experiments.evaluation.runner.evaluate_agents` on a backend."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

from agents.experiments.evaluation.records import RECORD_FIELDS, TIMING_COLUMNS
from agents.experiments.evaluation.runner import EpisodeBackend, evaluate_agents
from tests.helpers import ROOT

SCRIPT = ROOT / "evaluate.py"

LEARNED_EASY = "DebrisGym/Rendezvous2D-Easy-v1"
"""The Easy rung with a shipped pretrained policy (a learned agent to fly on a backend)."""


def usage_error(cli: ModuleType, capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    """``cli.main(argv)`` must stop with a usage error (exit code 2, no traceback): its stderr."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def episode_rows(out: Path) -> list[dict[str, str]]:
    """The rows of ``out``'s episodes.csv without its wall-clock columns (the rest is a function
    of the seeds)."""
    with open(out / "episodes.csv", newline="") as fh:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(fh)]


def script_env() -> dict[str, str]:
    """This process's environment with the repository on ``PYTHONPATH``, for evaluate.py run as
    a command from a test's own directory."""
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def run_evaluate(cwd: Path, *argv: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """``python evaluate.py ARGV`` run in ``cwd`` to its end: exit code, stdout and stderr."""
    return subprocess.run(
        [sys.executable, str(SCRIPT), *argv], cwd=cwd, env=script_env(), capture_output=True,
        text=True, timeout=timeout,
    )  # fmt: skip


def assert_backend_flies_the_local_records(
    backend: EpisodeBackend, episodes: int, max_steps: int
) -> None:
    """Four agents (apf; random, stateful: flown in order; zero; pretrained, a learned one) on
    :data:`LEARNED_EASY` through ``backend`` give the records of one process, in the same order,
    timing columns aside, each handed on as it arrived."""
    agents = "apf,random,zero,pretrained"
    kwargs = {"env_kwargs": {}, "max_episode_steps": max_steps, "progress": False}
    local = evaluate_agents(LEARNED_EASY, agents, episodes=episodes, seed=7, **kwargs)
    arrived = []
    remote = evaluate_agents(
        LEARNED_EASY, agents, episodes=episodes, seed=7, on_episode=arrived.append,
        backend=backend, **kwargs,
    )  # fmt: skip
    assert len(arrived) == 4 * episodes
    assert [(r.agent, r.episode) for r in remote.records] == [
        (r.agent, r.episode) for r in local.records
    ]
    fields = [f for f in RECORD_FIELDS if f not in TIMING_COLUMNS]
    for a, b in zip(local.records, remote.records, strict=True):
        assert [getattr(a, f) for f in fields] == [getattr(b, f) for f in fields]
        assert (a.trajectory.positions == b.trajectory.positions).all()
        assert (a.trajectory.accelerations == b.trajectory.accelerations).all()
    assert local.max_episode_steps == remote.max_episode_steps == max_steps
