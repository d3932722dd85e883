"""The v1 shaping potential: minus the shortest remaining mission, against a brute force.

The brute force here orders the uncaptured targets every way (``itertools.permutations``) and
measures each tour surface to surface, as the docs define it (docs/environments.md, Rewards).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.envs import DebrisFieldEnv
from debris_gym.goal import EXACT_TOUR_TARGETS, remaining_tour

CHASER_RADIUS = 1.0


def tour_length(seq, chaser, centers, radii, gaps, return_to_dock):
    if not seq:
        return float(np.linalg.norm(chaser)) if return_to_dock else 0.0
    total = max(gaps[seq[0]] - CHASER_RADIUS, 0.0)
    for a, b in itertools.pairwise(seq):
        total += max(np.linalg.norm(centers[a] - centers[b]) - radii[a] - radii[b], 0.0)
    if return_to_dock:
        total += max(np.linalg.norm(centers[seq[-1]]) - radii[seq[-1]], 0.0)
    return total


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_targets=st.integers(1, EXACT_TOUR_TARGETS),
    dim=st.sampled_from([2, 3]),
    queued=st.booleans(),
    return_to_dock=st.booleans(),
)
def test_remaining_tour_is_the_shortest_order(seed, n_targets, dim, queued, return_to_dock):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-500, 500, (1, n_targets + 2, dim))
    radii = rng.uniform(1, 10, (1, n_targets + 2))
    chaser = rng.uniform(-300, 300, 2 * dim)
    gaps = np.linalg.norm(centers[0] - chaser[:dim], axis=1) - radii[0]
    captured = rng.uniform(size=(1, n_targets)) < 0.3
    left = [j for j in range(n_targets) if not captured[0, j]]
    args = (centers[0], radii[0], gaps, return_to_dock)
    if queued:
        want = tour_length(left, chaser[:dim], *args)
    else:
        orders = itertools.permutations(left) if left else [()]
        want = min(tour_length(list(p), chaser[:dim], *args) for p in orders)
    got = remaining_tour(
        0, 0, gaps[None], captured, queued, return_to_dock, CHASER_RADIUS, centers, radii,
        np.zeros((1, dim)), chaser[None], np.zeros(n_targets, np.int64),
        np.zeros(n_targets, np.int64), np.zeros((n_targets, n_targets)), np.zeros(n_targets),
    )  # fmt: skip
    assert abs(got - want) <= 1e-9 * max(1.0, want)


def test_the_v1_env_shapes_with_the_remaining_tour():
    env = DebrisFieldEnv(dim=2, debris_motion="bounded", shaping_potential="tour")
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    for _ in range(30):
        env.step(rng.uniform(-1, 1, 2))
        states = env.body_states
        t = len(env.scenario.targets)
        centers, radii = states[:t, :2], np.array([b.radius for b in env.scenario.targets])
        chaser = env.chaser_state[:2]
        gaps = np.linalg.norm(centers - chaser, axis=1) - radii
        left = [j for j in range(t) if not env.captured[j]]
        orders = itertools.permutations(left) if left else [()]
        best = min(tour_length(list(p), chaser, centers, radii, gaps, True) for p in orders)
        assert env.potential == pytest.approx(-best / (env.scenario.size / 2), rel=1e-12)
