"""Tests of the bench's ``swarm`` section: the swarm core's rows at tiny sizes (no VMAS needed),
the VMAS rows and their paired ratios (where VMAS is installed), and the rows that report VMAS
missing instead of crashing.

No assertions on speed itself: the magnitude bounds are orders of magnitude wide and only catch
a wrong unit.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

import bench
from bench import swarm
from bench.config import TINY
from bench.harness import RANDOM
from debris_gym.swarm import SWARM_SPECS
from debris_gym.swarm.core import SwarmCore

STEPS = 20
REPEATS = 3  # bench.run's quick default


def tiny_swarm(sizes: dict | None = None) -> list[dict]:
    return bench.run(
        quick=True, steps=STEPS, progress=False, sections=["swarm"], sizes=sizes or TINY
    )


@pytest.fixture(scope="module")
def swarm_rows():
    return tiny_swarm()


def _obs_size(chasers: int) -> int:
    spec = SWARM_SPECS[swarm.SWARM_ID]
    core = SwarmCore(1, spec["max_episode_steps"], **{**spec["kwargs"], "n_chasers": chasers})
    try:
        return int(core.observation_space.shape[0])
    finally:
        core.close()


def test_the_swarm_core_is_measured_at_every_k_with_both_kinds_of_actions(swarm_rows):
    assert {r["section"] for r in swarm_rows} == {"swarm"}
    native = [r for r in swarm_rows if r["level"] == "native"]
    total = TINY["swarm_chasers_total"]
    expected = {
        (k, total // k, kind) for k in TINY["swarm_chasers"] for kind in ("gentle", "random")
    }
    assert {(r["chasers"], r["num_envs"], r["actions"]) for r in native} == expected
    for row in native:
        assert row["error"] is None, row["error"]
        assert row["env_id"] == swarm.SWARM_ID
        assert row["variant"] == (RANDOM if row["actions"] == "random" else "")
        assert row["count"] == STEPS and row["repeats"] == REPEATS
        assert row["warmup_steps"] == TINY["swarm_warmup_steps"]
        assert 1e1 < row["chaser_steps_per_s"] < 1e9, row  # 1 ns to 0.1 s a chaser-step
        assert row["chaser_steps_per_s_best"] >= row["chaser_steps_per_s"]
        assert row["us_per_chaser_step"] == pytest.approx(1e6 / row["chaser_steps_per_s"])
        assert 0 < row["flying_share"] <= 1
        assert 0 <= row["resets_per_1000"] <= row["ends_per_1000"] <= 1000
        assert 0 <= row["reset_share"] < 1
        assert (row["reset_share"] > 0) == (row["resets_per_1000"] > 0)
        assert row["obs_size"] == _obs_size(row["chasers"])
        assert 0 < row["reset_ms_per_field"] < 1e4
        assert row["n_obstacles"] == SWARM_SPECS[swarm.SWARM_ID]["kwargs"]["n_obstacles"]


def test_the_swarm_report_has_a_line_per_row_and_the_goal(swarm_rows):
    measured = [r for r in swarm_rows if r["error"] is None]
    report = bench.format_report(measured, command="x", elapsed=1.0)
    assert "## Swarm throughput" in report and "## Errors" not in report
    assert report.count("| swarm core") == len([r for r in measured if r["level"] == "native"])
    assert "Goal: swarm core ≥ 5× VMAS" in report
    random_rows = [r for r in measured if r["level"] == "native" and r["variant"] == RANDOM]
    assert report.count("(goal ≥ 5×)") == len(random_rows)


def test_the_vmas_rows_and_the_paired_ratios(swarm_rows):
    pytest.importorskip("vmas")
    vmas = [r for r in swarm_rows if r["level"] == "vmas"]
    total = TINY["swarm_chasers_total"]
    assert {(r["chasers"], r["num_envs"]) for r in vmas} == {
        (k, total // k) for k in TINY["swarm_chasers"]
    }
    for row in vmas:
        assert row["error"] is None, row["error"]
        assert row["env_id"] == swarm.VMAS_LABEL and row["actions"] == "random"
        assert row["count"] == STEPS and row["repeats"] == REPEATS
        assert row["warmup_steps"] == TINY["vmas_warmup_steps"]
        assert 1e0 < row["chaser_steps_per_s"] < 1e9, row
        assert row["flying_share"] == 1.0  # every agent moves every step
        assert row["ends_per_1000"] == pytest.approx(row["chasers"] * row["resets_per_1000"])
        assert row["obs_size"] > 0
        assert math.isnan(row["ratio_vmas"])
    for row in swarm_rows:
        if row["level"] != "native":
            continue
        (ref,) = [
            r for r in vmas if (r["chasers"], r["num_envs"]) == (row["chasers"], row["num_envs"])
        ]
        want = row["chaser_steps_per_s"] / ref["chaser_steps_per_s"]
        assert row["ratio_vmas"] == pytest.approx(want)
        low, high = row["ratio_vmas_range"]
        assert low <= row["ratio_vmas"] <= high  # the ratio of medians lies within the pairs
        assert row["ratio_vmas_flying"] == pytest.approx(want * row["flying_share"])


@pytest.mark.parametrize("ahead", [0, 2])
def test_vmas_envs_that_are_done_are_reset_inside_the_timed_steps(ahead, monkeypatch):
    """With a time limit of 5 steps every VMAS env is done every fifth step and reset there:
    all together by ``env.reset()``; with env 0 pushed ``ahead`` steps, each by ``reset_at``."""
    pytest.importorskip("vmas")
    monkeypatch.setitem(swarm.VMAS_TASK, "max_steps", 5)
    m = swarm.SwarmMeasurement("vmas", 2, 3, warmup=1, fixed=20)
    m.set_up()  # reset, then 1 warm-up step: every env at step 1
    try:
        m.env.steps[0] += ahead
        calls = []
        reset_at = m.env.reset_at
        monkeypatch.setattr(m.env, "reset_at", lambda i, **kw: calls.append(i) or reset_at(i, **kw))
        m.measure()
    finally:
        m.tear_down()
    # 20 timed steps: envs 1 and 2 done at the 4th, 9th, 14th and 19th; env 0 at the same
    # steps, or 2 steps sooner when pushed ahead
    assert m.resets == [4 * 3]
    assert m.ends == [4 * 3 * 2]  # both agents of each env
    assert m.flew == [20 * 6]
    assert 0 < m.reset_times[0] < m.times[0]
    assert calls == ([0, 1, 2] * 4 if ahead else [])


class _Spy(SwarmCore):
    """A swarm core that checks the bench's loop: every step observed, every ended field
    restarted before the observation."""

    log: list = []

    def step(self, commands):
        out = super().step(commands)
        self.log.append(("step", out.field_over.copy()))
        return out

    def restart(self, fields):
        self.log.append(("restart", np.asarray(fields).copy()))
        super().restart(fields)

    def observe(self):
        self.log.append(("observe", self.flying.copy()))
        return super().observe()


def test_a_timed_swarm_step_restarts_ended_fields_and_observes(monkeypatch):
    monkeypatch.setattr(swarm, "SwarmCore", _Spy)
    _Spy.log = []
    m = swarm.SwarmMeasurement("native", 2, 3, "random", warmup=2, fixed=40)
    m.set_up()
    try:
        _Spy.log.clear()
        m.measure()
    finally:
        m.tear_down()
    log = _Spy.log
    steps = [i for i, (what, _) in enumerate(log) if what == "step"]
    assert len(steps) == 40 and m.count == 40
    for i in steps:
        over = log[i][1]
        if over.any():  # the ended fields restart, then every chaser is observed
            assert log[i + 1][0] == "restart" and np.array_equal(log[i + 1][1], over)
            assert log[i + 2][0] == "observe"
            assert log[i + 2][1].reshape(3, 2)[over].all()  # the restarted chasers fly again
        else:
            assert log[i + 1][0] == "observe"
    assert sum(over.sum() for what, over in log if what == "restart") == m.resets[0]
    assert m.resets[0] > 0  # random thrust ends chasers within 40 steps
    assert 0 < m.reset_times[0] < m.times[0]


def test_without_vmas_its_rows_carry_the_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "vmas", None)  # importing it raises ImportError
    rows = tiny_swarm({**TINY, "swarm_chasers": (2,), "swarm_chasers_total": 4})
    (gentle, random_, vmas) = rows
    assert (gentle["level"], random_["level"], vmas["level"]) == ("native", "native", "vmas")
    assert gentle["error"] is None and random_["error"] is None
    assert "pip install 'debris-gym[bench]'" in vmas["error"]
    assert math.isnan(vmas["chaser_steps_per_s"]) and vmas["repeats"] == 0
    assert math.isnan(random_["ratio_vmas"])
    report = bench.format_report(rows, command="x", elapsed=1.0)
    assert "| VMAS navigation actions=random | 2 | 2 | error: " in report
    assert "## Errors" in report and "not measured" in report


def test_fields_and_spawn_square():
    assert [swarm.swarm_fields(k, 1024) for k in (1, 8, 48, 256)] == [1024, 128, 21, 4]
    assert swarm.swarm_fields(300, 256) == 1
    assert swarm.vmas_half_width(3) == 1.0 and swarm.vmas_half_width(1) == 1.0
    # constant density: K agents in (2 w)² as BenchMARL's 3 in VMAS's default 2 × 2 square
    for k in (12, 48, 256):
        assert k / (2 * swarm.vmas_half_width(k)) ** 2 == pytest.approx(3 / 4)
