"""Pinned moving fields: body speeds bounded, and the motion checked over the episode, not only at
t = 0 — bodies inside the bounds and apart at every instant, refused by name (or flown with a
warning the scenario asked for), and never an inf or NaN reward.

Independent truth: the textbook CW closed form typed into ``tests.helpers.cw_positions``
([Curtis14] eq. 7.53, not the library's state-transition matrix nor the check's element bounds)
propagates the bodies on a fine time grid.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401 - registers the IDs
from debris_gym.config import EnvConfig
from debris_gym.horizon_checks import first_motion_fault
from debris_gym.scenario import Scenario
from debris_gym.scenario_checks import max_body_speed
from tests.helpers import cw_positions

N = EnvConfig().n  # rad/s, the default IDs' mean motion
IDS = {2: "DebrisGym/Rendezvous2D-v2", 3: "DebrisGym/Rendezvous3D-v2"}
EPISODE = 1000  # steps: the default IDs' registered time limit


def worst_violation(states, radii, low, high, n, t) -> tuple[float, float]:
    """On the grid ``t``: how far (m) the worst ball sticks out of the bounds, and how deep the
    worst pair overlaps (0 when none does)."""
    pos = cw_positions(states, n, t)
    out = np.maximum(pos + radii[None, :, None] - high, low - (pos - radii[None, :, None]))
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=3)
    need = radii[:, None] + radii[None]
    depth = need - gaps
    depth[:, np.arange(len(radii)), np.arange(len(radii))] = -np.inf
    return max(float(out.max()), 0.0), max(float(depth.max(initial=-np.inf)), 0.0)


@st.composite
def moving_bodies(draw):
    """A few balls with random CW states in a random world, random step and horizon: most
    examples leave the bounds or overlap somewhere, many only between two step ends."""
    dim = draw(st.sampled_from([2, 3]))
    half = draw(st.floats(50.0, 1000.0))
    count = draw(st.integers(1, 6))
    n = draw(st.sampled_from([0.0, N, 4e-3]))
    dt = draw(st.floats(1.0, 400.0))
    steps = draw(st.integers(0, 60))
    unit = st.floats(-1.0, 1.0)
    pos = np.array([[draw(unit) for _ in range(dim)] for _ in range(count)]) * half * 0.8
    speed = draw(st.floats(0.0, 3.0))
    vel = np.array([[draw(unit) for _ in range(dim)] for _ in range(count)]) * speed
    radii = np.array([draw(st.floats(0.5, 0.2 * half)) for _ in range(count)])
    low, high = np.full(dim, -half), np.full(dim, half)
    return np.concatenate([pos, vel], axis=1), radii, low, high, n, dt, steps


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=moving_bodies())
def test_the_horizon_check_agrees_with_the_closed_form_on_a_fine_grid(case):
    states, radii, low, high, n, dt, steps = case
    fault = first_motion_fault(states, radii, low, high, n, dt, steps)
    horizon = steps * dt
    t = np.linspace(0.0, horizon, max(2, int(horizon / min(dt / 40.0, 1.0)) + 2))
    out, depth = worst_violation(states, radii, low, high, n, t)
    slack = 1e-6 * float(high[0] - low[0])
    if fault is None:
        assert out <= slack and depth <= slack, (out, depth)
        return
    # the fault is real: at its time the closed form shows it
    assert 0.0 <= fault.time <= horizon * (1 + 1e-12)
    pos = cw_positions(states, n, np.array([fault.time]))[0]
    np.testing.assert_allclose(fault.positions[0], pos[fault.first], atol=1e-6 * (1 + horizon))
    if fault.second < 0:
        b = fault.first
        sticks = np.maximum(pos[b] + radii[b] - high, low - (pos[b] - radii[b])).max()
        assert sticks > -slack, sticks
    else:
        i, j = fault.first, fault.second
        assert np.linalg.norm(pos[i] - pos[j]) < radii[i] + radii[j] + slack


def test_a_swing_out_of_the_bounds_between_two_step_ends_is_found():
    # a drift-free orbit of along-track half-width 2ρ = 400 m about y_c = 0 in a ±390 m box:
    # with 10 steps per orbit, the step ends never reach y = ±400 but the orbit does
    period = 2.0 * math.pi / N
    rho, phase = 200.0, 0.5 * (2.0 * math.pi / 10.0)
    x0, y0 = rho * math.sin(phase), 2.0 * rho * math.cos(phase)
    state = np.array([[x0, y0, N * rho * math.cos(phase), -2.0 * N * x0]])
    args = (np.array([1.0]), np.full(2, -390.0), np.full(2, 390.0), N, period / 10.0)
    t = np.arange(11) * period / 10.0
    assert np.abs(cw_positions(state, N, t)[:, 0, 1]).max() + 1.0 < 390.0  # every step end in
    fault = first_motion_fault(state, *args, 10)
    assert fault is not None and fault.second == -1 and fault.time % (period / 10.0) > 1.0


# --- the env: refused by name, or flown with the warning the scenario asked for ---------------


def drawn(dim: int, seed: int = 0, **kwargs) -> dict:
    env = gym.make(IDS[dim], **kwargs)
    env.reset(seed=seed)
    data = env.unwrapped.scenario.to_dict()
    env.close()
    return data


@pytest.mark.parametrize(
    ("dim", "kwargs"), [(2, {}), (3, {}), (2, {"debris_motion": "drifting", "spin_max": 0.02})]
)
def test_fields_the_env_draws_pass_when_pinned(dim, kwargs):
    env = gym.make(IDS[dim], **kwargs)
    for seed in range(4):
        env.reset(seed=seed)
        data = env.unwrapped.scenario.to_dict()
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no warning either
            env.reset(seed=seed, options={"scenario": data})
        assert env.unwrapped.scenario.to_dict() == data


@pytest.mark.parametrize(
    ("kind", "speed"),
    [("targets", 1e3), ("targets", 1e153), ("obstacles", 1e155), ("obstacles", 101.0)],
)
def test_a_body_faster_than_the_world_per_step_is_refused_by_name(kind, speed):
    data = drawn(2)
    data[kind][0]["velocity"] = [0.0, -speed]
    env = gym.make(IDS[2])
    with pytest.raises(
        ValueError, match=rf"{kind}\[0\]\.velocity.*too fast; allowed: speed <= 100 m/s"
    ):
        env.reset(options={"scenario": data})


def test_the_speed_limit_is_the_chasers_own_rule_or_a_fast_orbits():
    scenario = Scenario.from_dict(drawn(2))
    assert max_body_speed(scenario) == pytest.approx(1000.0 / 10.0)  # world size / dt
    fast_orbit = dataclasses.replace(scenario, mean_motion=0.01, dt=600.0)
    assert max_body_speed(fast_orbit) == pytest.approx(2.0 * 0.01 * 1000.0)


def _kicked() -> dict:
    """A target at rest on the V-bar pushed along-track at 2 m/s (out of the world within a few
    minutes) and an obstacle at rest far from its path: every rule holds at t = 0."""
    return {
        "dim": 2, "bounds": [[-500.0, 500.0], [-500.0, 500.0]], "dock": [0.0, 0.0],
        "targets": [{"position": [0.0, 300.0], "radius": 5.0, "velocity": [0.0, 2.0]}],
        "obstacles": [{"position": [0.0, -300.0], "radius": 10.0}],
        "mean_motion": N, "dt": 10.0, "max_accel": 0.05, "motion": "cwh",
    }  # fmt: skip


def test_a_target_that_leaves_the_world_is_refused_by_name():
    data = _kicked()
    Scenario.from_dict(data)  # every rule at t = 0 holds
    env = gym.make(IDS[2])
    with pytest.raises(ValueError, match=r"targets\[0\].*leaves the bounds at t = .*motion_faults"):
        env.reset(options={"scenario": data})
    vector = gym.make_vec(IDS[2], num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match=r"targets\[0\].*leaves the bounds"):
        vector.reset(options={"scenario": data})


def test_bodies_that_meet_later_are_refused_naming_both():
    # obstacle 1 on a drift-free ellipse about (0, 50) (ρ = 100 m, along-track half-width
    # 200 m) whose top, (0, 250), obstacle 0 sits on at rest: apart at t = 0, they meet a
    # quarter orbit later (≈ 1 388 s)
    rho, x0 = 100.0, -100.0
    data = {
        "dim": 2, "bounds": [[-500.0, 500.0], [-500.0, 500.0]], "dock": [0.0, 0.0],
        "targets": [{"position": [0.0, -300.0], "radius": 5.0}],
        "obstacles": [
            {"position": [0.0, 250.0], "radius": 10.0},
            {"position": [x0, 50.0], "radius": 10.0, "velocity": [0.0, -2.0 * N * x0]},
        ],
        "mean_motion": N, "dt": 10.0, "max_accel": 0.05, "motion": "cwh",
    }  # fmt: skip
    assert rho == abs(x0)
    Scenario.from_dict(data)  # every rule at t = 0 holds
    env = gym.make(IDS[2])
    with pytest.raises(
        ValueError, match=r"obstacles\[0\] and obstacles\[1\] overlap at t = 1[234]"
    ):
        env.reset(options={"scenario": data})
    fault = first_motion_fault(
        Scenario.from_dict(data).initial_body_states(), np.array([5.0, 10.0, 10.0]),
        np.full(2, -500.0), np.full(2, 500.0), N, 10.0, EPISODE,
    )  # fmt: skip
    quarter = 0.5 * math.pi / N
    assert (fault.first, fault.second) == (1, 2) and quarter - 200.0 < fault.time < quarter


def test_motion_faults_warn_flies_with_a_warning_and_finite_rewards():
    data = {**_kicked(), "motion_faults": "warn"}
    env = gym.make(IDS[2])
    with pytest.warns(UserWarning, match=r"targets\[0\].*leaves the bounds.*flown anyway"):
        env.reset(options={"scenario": data})
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert math.isfinite(reward)
        assert all(math.isfinite(v) for v in info["reward_terms"].values())
        if terminated or truncated:
            break
    assert Scenario.from_dict(data).to_dict()["motion_faults"] == "warn"
    assert "motion_faults" not in Scenario.from_dict(_kicked()).to_dict()


def test_motion_faults_is_checked_by_name():
    data = _kicked()
    with pytest.raises(ValueError, match="motion_faults must be one of"):
        Scenario.from_dict({**data, "motion_faults": "ignore"})
    frozen = drawn(2)
    frozen.update(motion="frozen")
    for body in frozen["targets"] + frozen["obstacles"]:
        body["velocity"] = [0.0, 0.0]
        body.pop("spin", None)
    with pytest.raises(ValueError, match="motion_faults='warn' applies to moving fields only"):
        Scenario.from_dict({**frozen, "motion_faults": "warn"})


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    dim=st.sampled_from([2, 3]),
    body=st.integers(0, 22),
    direction=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    speed=st.one_of(st.floats(0.0, 100.0), st.floats(0.0, 1e300)),
    seed=st.integers(0, 3),
)
def test_a_pinned_moving_field_is_refused_by_name_or_flies_with_finite_rewards(
    dim, body, direction, speed, seed
):
    data = {**drawn(dim, seed), "motion_faults": "warn"}
    bodies = data["targets"] + data["obstacles"]
    key = "targets" if body < len(data["targets"]) else "obstacles"
    index = body if key == "targets" else body - len(data["targets"])
    d = np.array(direction[:dim])
    assume(np.linalg.norm(d) > 1e-3)
    assume(abs(speed - 100.0) > 1e-6)  # at the limit itself rounding decides
    bodies[body]["velocity"] = (d / np.linalg.norm(d) * speed).tolist()
    env = gym.make(IDS[dim])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # motion_faults="warn" asked for them
        try:
            env.reset(options={"scenario": data})
        except ValueError as err:
            assert f"{key}[{index}].velocity" in str(err) and "too fast" in str(err)
            assert speed > 100.0
            return
        assert speed <= 100.0
        rng = np.random.default_rng(seed)
        for _ in range(30):
            _, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, dim))
            assert math.isfinite(reward)
            if terminated or truncated:
                break
