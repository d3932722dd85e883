"""The CBBA auction of targets among chasers (agents/planners/auction.py)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.planners.auction import cbba
from agents.planners.team_assignment import TeamField, assign, optimal_assignment, tour_costs


def _line(chasers, targets):
    """Legs of chasers and targets as points on a line (m)."""
    c, t = np.asarray(chasers, float), np.asarray(targets, float)
    return np.abs(c[:, None] - t[None]), np.abs(t[:, None] - t[None])


def test_chasers_at_both_ends_of_a_line_win_their_own_end():
    start, legs = _line([0.0, 100.0], [10.0, 20.0, 90.0, 80.0])
    result = cbba(start, legs, back=True)
    assert result.bundles == [[0, 1], [2, 3]]
    assert result.rounds >= 1


def test_one_chaser_builds_the_greedy_insertion_route():
    # from 0 and back: 5 first (route 10 m), then 20 (route 40 m: +30, against +50 for 30),
    # then 30 (route 60 m: +20)
    start, legs = _line([0.0], [30.0, 5.0, 20.0])
    result = cbba(start, legs, back=True)
    assert result.bundles == [[1, 2, 0]]
    assert result.table.tolist() == [[True, True, True]]


def test_a_contested_target_goes_to_the_cheaper_chaser():
    # both want the target at 40; chaser 1 (at 50) reaches it for less than chaser 0 (at 0)
    start, legs = _line([0.0, 50.0], [40.0, 5.0])
    result = cbba(start, legs, back=False, max_bundle=1)
    assert result.bundles == [[1], [0]]


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 4),
    t=st.integers(1, 6),
    seed=st.integers(0, 2**31 - 1),
    back=st.booleans(),
)
def test_the_auction_gives_every_target_to_one_chaser_within_the_bundle_limit(k, t, seed, back):
    rng = np.random.default_rng(seed)
    docks, centers = rng.uniform(-100, 100, (k, 2)), rng.uniform(-100, 100, (t, 2))
    field = TeamField(docks, centers, rng.uniform(0, 5, t), back)
    result = cbba(field.dock_legs(), field.target_legs(), back)
    assert (result.table.sum(axis=0) == 1).all()
    assert (result.table.sum(axis=1) <= -(-t // k)).all()
    for row, bundle in zip(result.table, result.bundles):
        assert sorted(np.flatnonzero(row).tolist()) == sorted(bundle)
    auction = assign("auction", field)
    best = optimal_assignment(field, tour_costs(field))
    assert auction.cost >= best.cost - 1e-9  # an auction is no better than the optimum


@settings(max_examples=30, deadline=None)
@given(k=st.integers(1, 5), seed=st.integers(0, 2**31 - 1))
def test_one_slot_each_is_a_permutation(k, seed):
    rng = np.random.default_rng(seed)
    field = TeamField(rng.uniform(-50, 50, (k, 3)), rng.uniform(-50, 50, (k, 3)), np.zeros(k),
                      False, one_each=True)  # fmt: skip
    auction = assign("auction", field)
    assert (auction.table.sum(axis=0) == 1).all() and (auction.table.sum(axis=1) == 1).all()
    legs = field.dock_legs()
    best = min(legs[np.arange(k), list(p)].sum() for p in itertools.permutations(range(k)))
    assert auction.cost >= best - 1e-9


def test_no_targets_is_an_empty_auction():
    result = cbba(np.zeros((3, 0)), np.zeros((0, 0)), back=True)
    assert result.table.shape == (3, 0) and result.bundles == [[], [], []]


@pytest.mark.parametrize(
    ("start", "legs", "kwargs", "match"),
    [(np.ones((2, 3)), np.ones((2, 2)), {}, "legs"),
     (np.ones((2, 3)), np.full((3, 3), np.nan), {}, "finite"),
     (-np.ones((2, 3)), np.zeros((3, 3)), {}, ">= 0"),
     (np.ones((2, 3)), np.zeros((3, 3)), {"max_bundle": 1}, "max_bundle=1")],
)  # fmt: skip
def test_bad_auction_inputs_are_named(start, legs, kwargs, match):
    with pytest.raises(ValueError, match=match):
        cbba(start, legs, back=True, **kwargs)
