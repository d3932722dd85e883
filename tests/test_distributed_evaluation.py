"""evaluate.py --backend ray: episodes fanned out to Ray workers give the local
run's records, are journaled as they arrive, and an interrupted Ray run resumes without flying
its finished episodes again. The Ray tests run only where Ray is installed (the [distributed]
extra); the argument checks and the work plan run everywhere."""

from __future__ import annotations

import importlib.util

import pytest

from agents.experiments.distributed.evaluation import RayBackend, Unit, plan_units
from agents.experiments.evaluation.journal import EvaluationJournal
from agents.experiments.evaluation.runner import EvaluationJob
from agents.experiments.evaluation.specs import parse_agent_specs
from tests.helpers import flies_old_ids, load_script
from tests.helpers_evaluate import (
    assert_backend_flies_the_local_records,
    episode_rows,
    usage_error,
)

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
QUICK = ["--env", EASY, "--max-steps", "60", "--plots", "0", "--no-progress"]
HAS_RAY = importlib.util.find_spec("ray") is not None


@pytest.fixture(scope="module")
def cli():
    return load_script("evaluate.py")


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray with 2 CPUs for the module (the backend joins it and leaves it running)."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    yield ray
    ray.shutdown()


def test_backend_options_are_checked_before_anything_runs(cli, capsys, tmp_path):
    out = tmp_path / "eval"
    err = usage_error(cli, capsys, [*QUICK, "--address", "auto", "--out", str(out)])
    assert "argument --address: needs --backend ray" in err
    err = usage_error(cli, capsys, [*QUICK, "--backend", "ray", "--workers", "0"])
    assert "argument --workers: must be an integer >= 1" in err
    err = usage_error(cli, capsys, [*QUICK, "--backend", "dask"])
    assert "argument --backend: invalid choice: 'dask'" in err
    if HAS_RAY:
        err = usage_error(cli, capsys, [*QUICK, "--backend", "ray", "--video", "1"])
        assert "argument --video: records on the local backend only" in err
    assert not out.exists()
    with pytest.raises(ValueError, match="workers must be an integer >= 1, got 0"):
        RayBackend(workers=0)


def test_the_ray_backend_without_ray_names_the_extra(cli, capsys, monkeypatch, tmp_path):
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name)
    )
    err = usage_error(cli, capsys, [*QUICK, "--backend", "ray", "--out", str(tmp_path / "e")])
    assert "argument --backend: ray needs Ray, which is not installed" in err
    assert "pip install 'debris-gym[distributed]'" in err


def test_stateful_agents_fly_in_order_with_their_finished_episodes_replayed():
    specs = tuple(parse_agent_specs("apf,random"))
    job = EvaluationJob(EASY, {}, None, specs, tuple((i, None) for i in range(4)))
    done = {("apf", 1): None, ("random", 0): None, ("random", 2): None}
    shared, streams = plan_units(job, done, {"apf": True, "random": False})
    assert shared == [Unit("apf", 0), Unit("apf", 2), Unit("apf", 3)]
    assert streams == [
        [Unit("random", 0, True), Unit("random", 1), Unit("random", 2, True), Unit("random", 3)]
    ]
    done = {**done, ("random", 1): None, ("random", 3): None}
    assert plan_units(job, done, {"apf": True, "random": False})[1] == []


@pytest.mark.skipif(not HAS_RAY, reason="needs ray (pip install 'debris-gym[distributed]')")
@flies_old_ids
def test_ray_records_equal_the_local_records(local_ray):
    assert_backend_flies_the_local_records(RayBackend(workers=2), episodes=5, max_steps=60)


@pytest.mark.skipif(not HAS_RAY, reason="needs ray (pip install 'debris-gym[distributed]')")
def test_an_interrupted_ray_run_resumes_without_flying_its_finished_episodes(
    cli, capsys, monkeypatch, tmp_path, local_ray
):
    base = ["--agents", "zero,random,apf", "--episodes", "4", *QUICK]
    whole = tmp_path / "whole"
    assert cli.main([*base, "--out", str(whole)]) == 0  # the local backend

    appended = [0]
    append = EvaluationJournal.append

    def counted(self, record, stop_at=None):
        append(self, record)
        appended[0] += 1
        if appended[0] == stop_at:
            raise KeyboardInterrupt

    out = tmp_path / "stopped"
    monkeypatch.setattr(EvaluationJournal, "append", lambda s, r: counted(s, r, stop_at=5))
    ray_args = ["--backend", "ray", "--workers", "2"]
    assert cli.main([*base, *ray_args, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "5 of 12 episodes finished" in err
    assert f"resume with: python evaluate.py --resume {out}" in err
    finished = {(r.agent, r.episode) for r in EvaluationJournal(out).read_records()}
    assert len(finished) == 5

    appended[0] = 0
    monkeypatch.setattr(EvaluationJournal, "append", lambda s, r: counted(s, r))
    assert cli.main(["--resume", str(out), "--no-progress", *ray_args]) == 0
    assert appended[0] == 12 - 5  # the finished episodes were not journaled (flown) again
    assert episode_rows(out) == episode_rows(whole)
    assert not EvaluationJournal(out).exists()
