"""debris_gym.relative_orbits against the CWH equations typed here from the textbook
(ẍ = 3n²x + 2nẏ, ÿ = −2nẋ, z̈ = −n²z; [Curtis14] §7.4), integrated numerically, and against the
textbook closed form typed into ``tests.helpers.cw_closed_form`` (itself checked against
[Vallado13]'s arrangement in test_dynamics.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from debris_gym.relative_orbits import RelativeOrbit
from tests.helpers import cw_closed_form

N = math.sqrt(3.986004418e14 / 6_778_137.0**3)  # LEO mean motion, rad/s
PERIOD = 2.0 * math.pi / N


def unforced_cwh(_t: float, s: np.ndarray) -> np.ndarray:
    x, _y, z, vx, vy, vz = s
    return np.array([vx, vy, vz, 3 * N * N * x + 2 * N * vy, -2 * N * vx, -N * N * z])


def integrate(state0: np.ndarray, times: np.ndarray) -> np.ndarray:
    sol = solve_ivp(
        unforced_cwh, (0.0, times[-1]), state0, t_eval=times, rtol=1e-12, atol=1e-10,
        method="DOP853",
    )  # fmt: skip
    return sol.y.T


orbits = st.builds(
    RelativeOrbit,
    n=st.just(N),
    rho=st.floats(0.0, 300.0),
    alpha=st.floats(-math.pi, math.pi),
    x_center=st.one_of(st.just(0.0), st.floats(-50.0, 50.0)),
    y_center=st.floats(-400.0, 400.0),
    rho_z=st.floats(0.0, 200.0),
    beta=st.floats(-math.pi, math.pi),
)


def test_a_bounded_orbit_follows_the_integrated_equations_for_a_period():
    orbit = RelativeOrbit(N, rho=200.0, alpha=0.7, y_center=-100.0, rho_z=80.0, beta=-1.2)
    times = np.linspace(0.0, 1.5 * PERIOD, 400)
    truth = integrate(orbit.state(0.0), times)
    np.testing.assert_allclose(orbit.state(times)[:, :3], truth[:, :3], rtol=0, atol=1e-6)
    np.testing.assert_allclose(orbit.state(times)[:, 3:], truth[:, 3:], rtol=0, atol=1e-9)


def test_a_drifting_orbit_follows_the_integrated_equations():
    orbit = RelativeOrbit(N, rho=120.0, alpha=2.0, x_center=30.0, y_center=250.0)
    times = np.linspace(0.0, 2.0 * PERIOD, 300)
    truth = integrate(orbit.state(0.0), times)
    np.testing.assert_allclose(orbit.state(times)[:, :3], truth[:, :3], rtol=0, atol=1e-6)
    # the centre drifts by −(3/2) n x_c per second: after two periods 6π x_c behind
    drift = orbit.state(2.0 * PERIOD)[1] - orbit.state(0.0)[1]
    assert drift == pytest.approx(-1.5 * N * 30.0 * 2.0 * PERIOD, abs=1e-6)
    assert drift == pytest.approx(-6.0 * math.pi * 30.0, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(orbit=orbits, t=st.floats(0.0, 3.0 * PERIOD))
def test_elements_and_the_closed_form_agree(orbit, t):
    for dim in (2, 3):
        start = orbit.state(0.0, dim)
        np.testing.assert_allclose(
            orbit.state(t, dim), cw_closed_form(start, t, N), rtol=0, atol=1e-6
        )


@settings(max_examples=100, deadline=None)
@given(
    state=st.lists(st.floats(-500.0, 500.0), min_size=3, max_size=3).map(np.array),
    velocity=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array),
    t=st.floats(0.0, 2.0 * PERIOD),
)
def test_from_state_reproduces_the_trajectory_through_any_state(state, velocity, t):
    start = np.concatenate([state, velocity])
    orbit = RelativeOrbit.from_state(start, N)
    np.testing.assert_allclose(orbit.state(0.0), start, rtol=0, atol=1e-9)
    np.testing.assert_allclose(orbit.state(t), cw_closed_form(start, t, N), rtol=0, atol=1e-6)
    in_plane = RelativeOrbit.from_state(start[[0, 1, 3, 4]], N)
    np.testing.assert_allclose(in_plane.state(t, dim=2), orbit.state(t)[[0, 1, 3, 4]], atol=1e-9)


def test_the_drift_free_condition_closes_the_orbit():
    x0 = 120.0
    start = np.array([x0, 40.0, 0.0, 0.05, -2.0 * N * x0, 0.0])  # ẏ₀ = −2n x₀
    orbit = RelativeOrbit.from_state(start, N)
    assert orbit.x_center == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(cw_closed_form(start, PERIOD, N), start, atol=1e-6)
    # the along-track half-width is twice the radial one (the 2:1 ellipse)
    track = orbit.state(np.linspace(0.0, PERIOD, 2001))
    x_span = track[:, 0].max() - track[:, 0].min()
    y_span = track[:, 1].max() - track[:, 1].min()
    assert y_span == pytest.approx(2.0 * x_span, rel=1e-5)


@settings(max_examples=100, deadline=None)
@given(orbit=orbits, duration=st.floats(0.0, 2.0 * PERIOD))
def test_the_extent_holds_the_whole_trajectory(orbit, duration):
    low, high = orbit.extent(duration)
    track = orbit.state(np.linspace(0.0, duration, 500))[:, :3]
    assert np.all(track >= low - 1e-9) and np.all(track <= high + 1e-9)


def test_the_extent_is_tight_for_a_bounded_orbit_over_a_period():
    orbit = RelativeOrbit(N, rho=100.0, alpha=0.3, y_center=50.0, rho_z=30.0, beta=1.0)
    low, high = orbit.extent(PERIOD)
    track = orbit.state(np.linspace(0.0, PERIOD, 20001))[:, :3]
    np.testing.assert_allclose(track.min(axis=0), low, atol=1e-3)
    np.testing.assert_allclose(track.max(axis=0), high, atol=1e-3)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"n": 0.0, "rho": 1.0}, "n"),
        ({"n": -N, "rho": 1.0}, "n"),
        ({"n": N, "rho": -1.0}, "rho"),
        ({"n": N, "rho": 1.0, "rho_z": -2.0}, "rho_z"),
        ({"n": N, "rho": math.nan}, "rho"),
        ({"n": N, "rho": 1.0, "y_center": math.inf}, "y_center"),
    ],
)
def test_bad_elements_are_refused_by_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        RelativeOrbit(**kwargs)


def test_bad_inputs_to_the_constructors_and_queries_are_refused():
    with pytest.raises(ValueError, match="state"):
        RelativeOrbit.from_state(np.zeros(5), N)
    with pytest.raises(ValueError, match="state"):
        RelativeOrbit.from_state(np.array([np.nan, 0, 0, 0]), N)
    with pytest.raises(ValueError, match="n must be"):
        RelativeOrbit.from_state(np.zeros(4), 0.0)
    orbit = RelativeOrbit(N, rho=1.0)
    with pytest.raises(ValueError, match="dim"):
        orbit.state(0.0, dim=4)
    with pytest.raises(ValueError, match="duration"):
        orbit.extent(-1.0)
