"""Tests of the sequential convex programme through a sphere chain (agents.planners.scp): every
point in its sphere(s), the dynamics against a propagation with scipy.linalg.expm of the CWH
matrix typed here, the thrust bound, and the fuel against a two-impulse CW transfer computed
here; plus the se-scp agent flying a frozen mission."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import scipy.linalg
from hypothesis import example, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401  (registers the IDs)
from agents import make_agent
from agents.planners.scp import SCPParams, scp_trajectory
from tests.helpers import flies_old_ids

N_MEAN = 1.1313666536110223e-3  # default LEO mean motion (rad/s)
A_MAX = 0.05
DT = 10.0


def _cwh_a(n: float) -> np.ndarray:
    """In-plane CWH: ẍ = 3n²x + 2nẏ, ÿ = −2nẋ (x radial, y along-track)."""
    a = np.zeros((4, 4))
    a[0, 2] = a[1, 3] = 1.0
    a[2, 0] = 3 * n * n
    a[2, 3] = 2 * n
    a[3, 2] = -2 * n
    return a


def _propagate(x0: np.ndarray, controls: np.ndarray, n: float, step: float) -> np.ndarray:
    """States under piecewise-constant thrust, by the matrix exponential of [[A, B], [0, 0]]."""
    aug = np.zeros((6, 6))
    aug[:4, :4] = _cwh_a(n)
    aug[2:4, 4:6] = np.eye(2)
    m = scipy.linalg.expm(aug * step)
    out = [np.asarray(x0, float)]
    for u in controls:
        out.append(m[:4, :4] @ out[-1] + m[:4, 4:] @ u)
    return np.array(out)


# a chain of three spheres bending round a corner, start and goal at the ends
CENTERS = np.array([[0.0, 0.0], [60.0, 10.0], [110.0, 70.0], [120.0, 140.0]])
RADII = np.array([30.0, 45.0, 45.0, 35.0])


def _solve(**kwargs):
    options = {"mean_motion": N_MEAN, "dt": DT, "max_accel": A_MAX, "thrust_model": "ball"}
    options.update(kwargs)
    params = options.pop("params", SCPParams(step=20.0))
    state = options.pop("state", np.zeros(4))
    return scp_trajectory(state, CENTERS, RADII, params=params, **options)


@pytest.mark.parametrize("thrust_model", ["ball", "box"])
def test_every_point_lies_in_its_spheres_and_every_chord_in_one(thrust_model):
    result = _solve(thrust_model=thrust_model)
    assert result.success
    pos = result.states[:, :2]
    sigma = result.assignment
    assert sigma[0] == 0 and sigma[-1] == len(RADII) - 1
    assert np.all(np.diff(sigma) >= 0) and np.all(np.diff(sigma) <= 1)
    for k, p in enumerate(pos):
        assert np.linalg.norm(p - CENTERS[sigma[k]]) <= RADII[sigma[k]] + 1e-6
        if k + 1 < len(pos):  # both ends of the chord in one sphere: the chord is in it
            j = sigma[k + 1]
            assert np.linalg.norm(p - CENTERS[j]) <= RADII[j] + 1e-6
    assert np.linalg.norm(pos[-1] - CENTERS[-1]) < 1e-3
    assert np.linalg.norm(result.states[-1, 2:]) < 1e-4


@pytest.mark.parametrize("n", [0.0, N_MEAN])
def test_trajectory_obeys_the_exact_zoh_dynamics(n):
    result = _solve(mean_motion=n, state=np.array([0.0, 0.0, 0.1, -0.05]))
    assert result.success
    mine = _propagate(result.states[0], result.controls, n, result.step)
    np.testing.assert_allclose(result.states, mine, atol=1e-8)


@pytest.mark.parametrize("thrust_model", ["ball", "box"])
def test_thrust_stays_inside_the_bound_and_delta_v_is_the_env_rule(thrust_model):
    params = SCPParams(step=20.0, thrust_fraction=1.0, cruise_speed=2.0)
    result = _solve(thrust_model=thrust_model, params=params)
    assert result.success
    u = result.controls
    if thrust_model == "ball":
        assert np.all(np.linalg.norm(u, axis=1) <= A_MAX * (1 + 1e-9))
        rate = np.linalg.norm(u, axis=1)
    else:
        assert np.all(np.abs(u) <= A_MAX * (1 + 1e-9))
        rate = np.abs(u).sum(axis=1)
    assert result.delta_v == pytest.approx(rate.sum() * result.step, rel=1e-12)


def _two_impulse(r0: np.ndarray, rf: np.ndarray, n: float, t: float) -> tuple[float, float]:
    """The two impulses (m/s) of the rest-to-rest two-impulse CW transfer ([Curtis14] §7.5),
    in-plane."""
    s, c = math.sin(n * t), math.cos(n * t)
    phi_rr = np.array([[4 - 3 * c, 0.0], [6 * (s - n * t), 1.0]])
    phi_rv = np.array([[s / n, 2 / n * (1 - c)], [2 / n * (c - 1), (4 * s - 3 * n * t) / n]])
    phi_vr = np.array([[3 * n * s, 0.0], [6 * n * (c - 1), 0.0]])
    phi_vv = np.array([[c, 2 * s], [-2 * s, 4 * c - 3]])
    v0 = np.linalg.solve(phi_rv, rf - phi_rr @ r0)
    vf = phi_vr @ r0 + phi_vv @ v0
    return float(np.linalg.norm(v0)), float(np.linalg.norm(vf))


@settings(max_examples=30, deadline=None)
@given(
    x=st.floats(-300, 300),
    y=st.floats(-300, 300),
    steps=st.integers(20, 40),
)
@example(x=285.0, y=286.0, steps=20)  # regression: an impulse beyond one step's thrust (CI)
def test_free_space_fuel_is_no_more_than_a_two_impulse_transfer(x, y, steps):
    goal = np.array([x, y])
    if np.linalg.norm(goal) < 20.0:
        goal = goal + 40.0
    big = 10 * float(np.linalg.norm(goal)) + 100.0  # one sphere holding everything: free space
    centers = np.array([[0.0, 0.0], goal])
    radii = np.array([big, big])
    step = 20.0
    params = SCPParams(step=step, thrust_fraction=1.0)
    result = scp_trajectory(
        np.zeros(4), centers, radii, mean_motion=N_MEAN, dt=DT, max_accel=A_MAX,
        params=params, steps=steps,
    )  # fmt: skip
    assert result.success
    t = len(result.controls) * step
    first, last = _two_impulse(np.zeros(2), goal, N_MEAN, t)
    # each impulse becomes a burn held over whole steps Δ, as many as the thrust limit needs
    # (one when the impulse fits in a·Δ), which costs T / (T − d) more for a burn of length d
    # (the double-integrator limit: v (T − d) = L instead of v T = L); the polygon epigraph of
    # ‖u‖ may under-weigh a burn by at most cos(π/16)
    burn = step * max(math.ceil(max(first, last) / (A_MAX * step) - 1e-9), 1)
    bound = (first + last) * t / (t - burn) / math.cos(math.pi / 16)
    assert result.delta_v <= bound + 1e-3


def test_free_space_double_integrator_fuel_is_at_least_the_bang_coast_bang_optimum():
    goal = np.array([200.0, 0.0])
    step, steps = 20.0, 30
    params = SCPParams(step=step, thrust_fraction=1.0)
    result = scp_trajectory(
        np.zeros(4), np.array([[0.0, 0.0], goal]), np.array([1e4, 1e4]), mean_motion=0.0,
        dt=DT, max_accel=A_MAX, params=params, steps=steps,
    )  # fmt: skip
    assert result.success
    total = steps * step
    # continuous rest-to-rest optimum over a distance L in time T at thrust a: Δv = 2v with
    # L = v (T − v / a); discrete held thrust can only do as well or worse
    a, length = A_MAX, 200.0
    v = (a * total - math.sqrt((a * total) ** 2 - 4 * a * length)) / 2
    assert result.delta_v >= 2 * v - 1e-6
    assert result.delta_v <= 2 * v * 1.1


def test_hard_spheres_fail_and_soft_spheres_report_the_violation():
    # moving fast out of a 2 m start sphere: no thrust can keep the next point inside it
    fast = np.array([0.0, 0.0, 2.0, 0.0])
    centers = np.array([[0.0, 0.0], [0.0, 5.0]])
    radii = np.array([2.0, 4.0])
    hard = scp_trajectory(
        fast, centers, radii, mean_motion=0.0, dt=DT, max_accel=A_MAX,
        params=SCPParams(step=20.0, max_growths=0),
    )  # fmt: skip
    assert not hard.success
    soft = scp_trajectory(
        fast, centers, radii, mean_motion=0.0, dt=DT, max_accel=A_MAX,
        params=SCPParams(step=20.0, max_growths=0, sphere_penalty=100.0),
    )  # fmt: skip
    assert soft.success and soft.info["violation"] > 1.0


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("cruise_speed", 0.0),
        ("accel_fraction", 1.5),
        ("thrust_fraction", 0.0),
        ("step", -1.0),
        ("max_iterations", 0),
        ("time_growth", 1.0),
        ("max_growths", -1),
        ("sphere_facets", 3),
        ("sphere_penalty", 0.0),
        ("solver", "cvx"),
    ],
)
def test_bad_parameters_are_refused_by_name(name, value):
    with pytest.raises(ValueError, match=name):
        SCPParams(**{name: value})


def test_bad_inputs_are_refused_by_name():
    with pytest.raises(ValueError, match="thrust_model"):
        _solve(thrust_model="jet")
    with pytest.raises(ValueError, match="max_accel"):
        _solve(max_accel=0.0)
    with pytest.raises(ValueError, match="radii"):
        scp_trajectory(np.zeros(4), CENTERS, -RADII, mean_motion=0.0, dt=DT, max_accel=A_MAX)
    with pytest.raises(ValueError, match="steps"):
        _solve(steps=0)


@flies_old_ids
def test_se_scp_agent_completes_a_frozen_mission_without_collision():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    agent = make_agent("se-scp", env)
    obs, info = env.reset(seed=0)
    for _ in range(1000):
        action, _ = agent.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["is_success"] and not info["collision"]
    assert agent.stats["scp_failures"] == 0
