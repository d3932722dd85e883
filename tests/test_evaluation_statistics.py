"""Statistics for publishing: the exact McNemar test, intervals inside each metric's range, the
constant-column note, and the paired tables (checked against hand computation and scipy)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from agents.experiments import evaluation as ev
from tests.helpers import flies_old_ids

SMALL = {"n_obstacles": 5}


@pytest.fixture(scope="module")
def results():
    return ev.evaluate_agents(
        "DebrisGym/Rendezvous2D-v0",
        "zero,random",
        episodes=2,
        seed=3,
        env_kwargs=SMALL,
        progress=False,
        max_episode_steps=20,
    )


# --- the exact McNemar test -----------------------------------------------------------------


def test_mcnemar_hand_computed():
    # b = 1, c = 6: p = 2 · (C(7,0) + C(7,1)) / 2^7 = 2 · 8 / 128
    assert ev.mcnemar_exact(1, 6) == pytest.approx(0.125, abs=1e-15)
    assert ev.mcnemar_exact(6, 1) == pytest.approx(0.125, abs=1e-15)
    # b = 0, c = 5: 2 / 32; b = 3, c = 10: 2 · (1 + 13 + 78 + 286) / 8192
    assert ev.mcnemar_exact(0, 5) == pytest.approx(0.0625, abs=1e-15)
    assert ev.mcnemar_exact(3, 10) == pytest.approx(756 / 8192, abs=1e-15)
    # no discordant pair, and a balanced split, give 1 (the doubled tail is capped)
    assert ev.mcnemar_exact(0, 0) == 1.0
    assert ev.mcnemar_exact(4, 4) == 1.0
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="b must be an integer >= 0"):
            ev.mcnemar_exact(bad, 2)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 60), st.integers(0, 60))
def test_mcnemar_matches_scipy_binomial_test(b, c):
    expected = 1.0 if b + c == 0 else stats.binomtest(b, b + c, 0.5).pvalue
    assert ev.mcnemar_exact(b, c) == pytest.approx(expected, rel=1e-9, abs=1e-300)


def _rigged(results, outcomes: dict[str, list[tuple[bool, float, float]]]):
    """``results`` remade with one record per (agent, episode): (success, Δv, time)."""
    template = {r.agent: r for r in results.records if r.episode == 0}
    n = len(next(iter(outcomes.values())))
    records = [
        dataclasses.replace(
            template[agent], episode=i, seed=100 + i, success=ok, delta_v=dv, time=t
        )
        for agent, rows in outcomes.items()
        for i, (ok, dv, t) in enumerate(rows)
    ]
    scenario = results.scenarios[0]
    return dataclasses.replace(
        results, episodes=n, seed=100, records=records, scenarios=[scenario] * n
    )


@flies_old_ids
def test_paired_success_counts_discordant_episodes_and_reaches_the_table(results):
    # reference "zero" succeeds on episodes 0-5, "random" on 0 and 6: b = 1 (6), c = 5 (1-5)
    zero = [(True, 10.0, 100.0)] * 6 + [(False, 0.0, 50.0)]
    rnd = [(True, 12.0, 90.0)] + [(False, 1.0, 10.0)] * 5 + [(True, 5.0, 70.0)]
    rigged = _rigged(results, {"zero": zero, "random": rnd})
    summary = ev.summarize(rigged, reference="zero")
    paired = summary["paired_success"]
    assert paired["test"] == "exact McNemar" and paired["reference"] == "zero"
    e = paired["agents"]["random"]
    assert (e["pairs"], e["b"], e["c"], e["both_succeeded"], e["neither_succeeded"]) == (
        7, 1, 5, 1, 0,
    )  # fmt: skip
    # b = 1, c = 5: p = 2 · (1 + 6) / 64
    assert e["p_value"] == pytest.approx(14 / 64)
    # beside paired_delta_v, whose pairing also carries the time of flight (episode 0 only)
    d = summary["paired_delta_v"]["agents"]["random"]
    assert d["both_succeeded"] == 1
    assert d["difference_mean"] == pytest.approx(2.0)
    assert d["time_mean"] == 90.0 and d["reference_time_mean"] == 100.0
    assert d["time_difference_mean"] == pytest.approx(-10.0)
    md = ev.summary_markdown(summary)
    assert "exact McNemar" in md
    assert "| random | 7 | 1 | 1 | 5 | 0.219 |" in md
    assert "| random | 1 / 7 | 12 | 10 | 2 | 90 | 100 | -10 |" in md
    json.loads(ev.to_json(summary))


# --- intervals inside the metric's range ----------------------------------------------------


def test_wilson_ends_are_exact_at_zero_and_all():
    low, high = ev.wilson_interval(0, 100)
    assert low == 0.0  # not a rounding residue such as 3.5e-18
    # upper end at 0/n: z² / (n + z²), z = 1.959964
    assert high == pytest.approx(3.841459 / 103.841459, rel=1e-6)
    low, high = ev.wilson_interval(100, 100)
    assert high == 1.0 and low == pytest.approx(100 / 103.841459, rel=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 200), st.data())
def test_wilson_interval_inside_unit_range(n, data):
    k = data.draw(st.integers(0, n))
    low, high = ev.wilson_interval(k, n)
    assert 0.0 <= low <= k / n <= high <= 1.0


finite = st.floats(0.0, 1e4, allow_nan=False, allow_infinity=False)
samples = st.one_of(
    st.lists(finite, min_size=0, max_size=40),
    st.builds(lambda v, n: [v] * n, finite, st.integers(1, 30)),  # constant
    st.builds(lambda n: [0.0] * n, st.integers(1, 30)),  # all zero
    st.lists(finite, min_size=1, max_size=1),  # one element
)


@settings(max_examples=80, deadline=None)
@given(samples)
def test_bootstrap_interval_never_leaves_a_non_negative_range(values):
    low, high = ev.bootstrap_interval(values, 0.0, None, resamples=500)
    if len(values) < 2:
        assert (low, high) == (None, None)
        return
    assert 0.0 <= low <= high
    assert min(values) <= low and high <= max(values)
    if len(set(values)) == 1:
        assert low == high == values[0]
    # seeded: the same episodes always give the same interval
    assert ev.bootstrap_interval(values, 0.0, None, resamples=500) == (low, high)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5), st.data())
def test_bootstrap_interval_of_counts_stays_in_zero_to_n_targets(n_targets, data):
    counts = data.draw(st.lists(st.integers(0, n_targets), min_size=2, max_size=40))
    low, high = ev.bootstrap_interval(counts, 0, n_targets, resamples=500)
    assert 0 <= low <= high <= n_targets


def test_bootstrap_interval_agrees_with_the_t_interval_on_a_large_normal_sample():
    # for many roughly normal values both are ≈ mean ± 1.96 · s / √n (an independent check)
    x = np.random.default_rng(5).normal(50.0, 10.0, size=400)
    t_low, t_high = stats.t.interval(0.95, x.size - 1, loc=x.mean(), scale=stats.sem(x))
    low, high = ev.bootstrap_interval(x)
    width = t_high - t_low
    assert abs(low - t_low) < 0.06 * width and abs(high - t_high) < 0.06 * width


def test_bootstrap_interval_refuses_values_outside_the_range():
    with pytest.raises(ValueError, match=r"values must lie in \[0.0, None\]"):
        ev.bootstrap_interval([1.0, -2.0], 0.0, None)
    with pytest.raises(ValueError, match="resamples must be an integer >= 1"):
        ev.bootstrap_interval([1.0, 2.0], resamples=0)
    assert ev.bootstrap_interval([1.0, math.nan]) == (None, None)


# --- the constant-column note ---------------------------------------------------------------


def test_constant_columns_are_noted_in_summary_and_table(results):
    # 5 episodes: every one captures 0 targets and spends no Δv; time varies
    rows = [(False, 0.0, 10.0 * (i + 1)) for i in range(5)]
    rigged = _rigged(results, {"zero": rows, "random": rows})
    rigged = dataclasses.replace(
        rigged, records=[dataclasses.replace(r, targets_captured=0) for r in rigged.records]
    )
    summary = ev.summarize(rigged)
    entry = summary["agents"]["zero"]
    assert "targets_captured_mean" in entry["constant_columns"]
    assert "delta_v_mean" in entry["constant_columns"]
    assert "time_mean" not in entry["constant_columns"]
    assert entry["delta_v_mean_ci95"] == [0.0, 0.0]
    assert entry["success_rate_ci95"][0] == 0.0
    md = ev.summary_markdown(summary)
    assert "| zero | 0 [0, 0.43] | 0 (constant) / " in md
    assert "Constant across episodes" in md and "zero: targets captured, Δv" in md
    assert "bootstrap" in summary["ci_method"]["delta_v_mean_ci95"]
