"""The env's rules that agents reuse: the natural CWH acceleration (debris_gym.dynamics) and the
inverse thrust model (debris_gym.thrust), checked against the textbook equations and as the
inverse of the forward thrust model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from debris_gym.dynamics import cwh_acceleration
from debris_gym.thrust import action_for_accel, commanded_accel
from tests.helpers import cw_closed_form

N_LEO = 1.1313666536110223e-3  # rad/s


def _textbook(state: np.ndarray, n: float) -> np.ndarray:
    """CWH ([Curtis14] §7.4): ẍ = 3n²x + 2nẏ, ÿ = −2nẋ, z̈ = −n²z, written out term by term."""
    dim = len(state) // 2
    x, vx, vy = state[0], state[dim], state[dim + 1]
    out = [3.0 * n**2 * x + 2.0 * n * vy, -2.0 * n * vx]
    if dim == 3:
        out.append(-(n**2) * state[2])
    return np.array(out)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("n", [0.0, N_LEO, 0.05])
def test_cwh_acceleration_is_the_textbook_equations(dim, n):
    rng = np.random.default_rng(dim)
    for _ in range(50):
        state = rng.normal(scale=[300.0] * dim + [1.0] * dim)
        np.testing.assert_allclose(
            cwh_acceleration(state, n), _textbook(state, n), rtol=1e-13, atol=1e-18
        )


@pytest.mark.parametrize("dim", [2, 3])
def test_cwh_acceleration_is_the_rate_of_the_closed_form_velocity(dim):
    # central difference of the closed-form coast solution's velocity at t = 0
    state = np.array([120.0, -340.0, 55.0][:dim] + [0.4, -0.7, 0.2][:dim])
    h = 1.0e-2
    rate = (cw_closed_form(state, h, N_LEO) - cw_closed_form(state, -h, N_LEO)) / (2 * h)
    np.testing.assert_allclose(cwh_acceleration(state, N_LEO), rate[dim:], rtol=1e-6)


def test_cwh_acceleration_takes_a_batch_and_rejects_bad_states():
    states = np.random.default_rng(1).normal(size=(5, 3, 6))
    out = cwh_acceleration(states, N_LEO)
    assert out.shape == (5, 3, 3)
    np.testing.assert_allclose(out[2, 1], _textbook(states[2, 1], N_LEO), rtol=1e-13)
    with pytest.raises(ValueError, match="state"):
        cwh_acceleration(np.zeros(5), N_LEO)
    with pytest.raises(ValueError, match="mean motion"):
        cwh_acceleration(np.zeros(4), -1.0)


_vectors = st.integers(2, 3).flatmap(
    lambda d: arrays(np.float64, d, elements=st.floats(-3.0, 3.0, allow_nan=False))
)


@settings(max_examples=300, deadline=None)
@given(action=_vectors, max_accel=st.floats(1e-4, 10.0), model=st.sampled_from(["ball", "box"]))
def test_action_for_accel_inverts_commanded_accel_inside_the_limit(action, max_accel, model):
    feasible = action / max(1.0, float(np.linalg.norm(action)))
    if model == "box":
        feasible = np.clip(action, -1.0, 1.0)
    accel = commanded_accel(feasible, max_accel, model)
    back = action_for_accel(accel, max_accel, model)
    np.testing.assert_allclose(back, feasible, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        commanded_accel(back, max_accel, model), accel, rtol=1e-12, atol=1e-15
    )


@settings(max_examples=300, deadline=None)
@given(accel=_vectors, max_accel=st.floats(1e-4, 10.0), model=st.sampled_from(["ball", "box"]))
def test_action_for_accel_returns_the_nearest_feasible_action(accel, max_accel, model):
    accel = accel * max_accel  # up to three times the limit
    action = action_for_accel(accel, max_accel, model)
    want = accel / max_accel
    if model == "box":
        np.testing.assert_array_equal(action, np.clip(want, -1.0, 1.0))
        return
    norm = float(np.linalg.norm(want))
    assert float(np.linalg.norm(action)) <= 1.0 + 1e-12
    if norm > 1.0:  # on the unit sphere, same direction
        assert math.isclose(float(np.linalg.norm(action)), 1.0, rel_tol=1e-12)
        np.testing.assert_allclose(action * norm, want, rtol=1e-12, atol=1e-12)
    else:
        np.testing.assert_array_equal(action, want)


def test_action_for_accel_takes_a_batch_and_rejects_bad_input():
    accels = np.array([[0.1, 0.0], [0.01, -0.02], [0.0, 0.0]])
    out = action_for_accel(accels, 0.05, "ball")
    np.testing.assert_allclose(out, [[1.0, 0.0], [0.2, -0.4], [0.0, 0.0]])
    with pytest.raises(ValueError, match="thrust_model"):
        action_for_accel(accels, 0.05, "cone")
    with pytest.raises(ValueError, match="max_accel"):
        action_for_accel(accels, 0.0, "box")
    with pytest.raises(ValueError, match="accel"):
        action_for_accel(1.0, 0.05, "box")
