"""The uncertain world's navigation, actuation and sensing errors, against independent truth:
a pure-Python SplitMix64, the statistics of many draws, the same missions flown without errors,
and hand-built geometry."""

from __future__ import annotations

import math

import gymnasium as gym
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.config import UNCERTAINTY_KEYS, EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.registration import V2_WORLD
from debris_gym.uncertainty import (
    BIAS_STEP,
    STREAM_NAVIGATION,
    navigation_errors,
    standard_normal,
    unit_uniform,
)

MASK = (1 << 64) - 1
SMALL = {**V2_WORLD, "n_obstacles": 8}


def _mix(x: int) -> int:
    """SplitMix64's output function, written from its definition with Python integers."""
    z = (x + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def _uniform(key: int, stream: int, step: int, index: int) -> float:
    h = _mix(key ^ _mix(stream))
    h = _mix(h ^ _mix((step + 1) & MASK))
    h = _mix((h + index * 0x9E3779B97F4A7C15) & MASK)
    return ((h >> 11) + 1) / 2.0**53


@numba.njit
def _compiled_uniform(key, stream, step, index):
    return unit_uniform(key, stream, step, index)


@numba.njit
def _compiled_normal(key, stream, step, index):
    return standard_normal(key, stream, step, index)


@settings(max_examples=60, deadline=None)
@given(
    key=st.integers(0, MASK),
    stream=st.integers(0, 8),
    step=st.integers(-1, 10**6),
    index=st.integers(0, 10**5),
)
def test_the_compiled_generator_is_splitmix64_bit_for_bit(key, stream, step, index):
    got = _compiled_uniform(np.uint64(key), stream, step, index)
    assert got == _uniform(key, stream, step, index)
    assert 0.0 < got <= 1.0


def _errors(key: int, step: int, rows: int, dim: int, sp: float, sv: float) -> np.ndarray:
    out = np.empty((rows, 2 * dim))
    navigation_errors(np.uint64(key), step, sp, sv, out)
    return out


def test_navigation_errors_have_the_stated_mean_and_covariance():
    sp, sv, dim = 2.0, 0.05, 3
    draws = np.stack([_errors(7, t, 4, dim, sp, sv) for t in range(3000)])  # (3000, 4, 6)
    samples = draws.reshape(-1, 2 * dim)  # 12 000 draws of 6 elements
    n = samples.shape[0]
    sigma = np.array([sp] * dim + [sv] * dim)
    # mean within 4 standard errors, standard deviation within 4 % (4 SE of a σ estimate ≈ 2.6 %)
    assert np.all(np.abs(samples.mean(0)) < 4 * sigma / math.sqrt(n))
    np.testing.assert_allclose(samples.std(0), sigma, rtol=0.04)
    corr = np.corrcoef(samples.T)
    assert np.all(np.abs(corr - np.eye(2 * dim)) < 0.04)  # independent elements
    # independent from step to step (white): lag-1 correlation of one element
    x = draws[:, 1, 0]
    assert abs(np.corrcoef(x[1:], x[:-1])[0, 1]) < 0.08
    # normal: the share beyond 2σ is 4.55 %
    beyond = np.mean(np.abs(samples[:, 0]) > 2 * sp)
    assert abs(beyond - 0.0455) < 0.01


def test_standard_normal_is_a_pure_function_of_its_arguments():
    a = _compiled_normal(np.uint64(5), STREAM_NAVIGATION, 3, 4)
    assert a == _compiled_normal(np.uint64(5), STREAM_NAVIGATION, 3, 4)
    assert a != _compiled_normal(np.uint64(6), STREAM_NAVIGATION, 3, 4)
    assert a != _compiled_normal(np.uint64(5), STREAM_NAVIGATION, 4, 4)


def _rollout(env, seed: int, steps: int, actions_seed: int = 0):
    rng = np.random.default_rng(actions_seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, False, info)]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append((obs, r, term, info))
        if term or trunc:
            break
    return out


def test_every_option_at_zero_is_the_exact_world_and_draws_no_keys():
    zeros = {key: EnvConfig.__dataclass_fields__[key].default for key in UNCERTAINTY_KEYS}
    plain = _rollout(DebrisFieldEnv(dim=2, **SMALL), 4, 80)
    zeroed_env = DebrisFieldEnv(dim=2, **SMALL, **zeros)
    zeroed = _rollout(zeroed_env, 4, 80)
    assert len(plain) == len(zeroed)
    for (o1, r1, t1, i1), (o2, r2, t2, i2) in zip(plain, zeroed):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and t1 == t2 and i1["task_score"] == i2["task_score"]
    assert zeroed_env.unwrapped.batch.missions.noise_key[0] == 0


def test_navigation_errors_change_what_is_seen_and_nothing_that_is_judged():
    """The truth judges: with navigation errors the same seed and actions give the same
    rewards, flags and true states; only the observation differs, by the drawn errors."""
    plain = _rollout(DebrisFieldEnv(dim=2, **SMALL), 9, 120)
    noisy_env = DebrisFieldEnv(dim=2, **SMALL, nav_sigma_position=3.0, nav_sigma_velocity=0.05)
    noisy = _rollout(noisy_env, 9, 120)
    assert len(plain) == len(noisy)
    differ = 0
    for (o1, r1, t1, i1), (o2, r2, t2, i2) in zip(plain, noisy):
        assert r1 == r2 and t1 == t2
        np.testing.assert_array_equal(i1["chaser_state"], i2["chaser_state"])
        differ += not np.array_equal(o1, o2)
    assert differ == len(plain)


def test_the_observation_is_written_from_the_navigated_state():
    env = DebrisFieldEnv(dim=2, **SMALL, nav_sigma_position=3.0, nav_sigma_velocity=0.05)
    obs, info = env.reset(seed=2)
    names = env.observation_names()
    truth = info["chaser_state"]
    seen = env.estimated_chaser_state
    error = seen - truth
    assert np.all(error != 0.0)
    scale = env.batch.length_scale[0]
    i = names.index("chaser_pos_x")
    assert obs[i] == pytest.approx(seen[0] / scale, rel=1e-6)
    # the observed position error is the drawn one of row 0 (the chaser) of this step
    table = np.empty((1 + env.batch.field.n_bodies, 4))
    navigation_errors(env.batch.missions.noise_key[0], 0, 3.0, 0.05, table)
    np.testing.assert_allclose(error, table[0], rtol=1e-12, atol=1e-12)
    # the planners' field: every body's initial state plus the same step's errors
    est = env.estimated_scenario.initial_body_states()
    true = env.scenario.initial_body_states()
    np.testing.assert_allclose(est - true, table[1:], atol=1e-9)


def test_a_held_bias_stays_for_the_episode_and_changes_between_episodes():
    env = DebrisFieldEnv(dim=2, **SMALL, nav_sigma_position=2.0, nav_bias=True)
    _, info = env.reset(seed=3)
    first = env.estimated_chaser_state - info["chaser_state"]
    for _ in range(5):
        *_, info = env.step(np.zeros(2))
        np.testing.assert_allclose(
            env.estimated_chaser_state - info["chaser_state"], first, atol=1e-9
        )
    _, info = env.reset()
    assert not np.allclose(env.estimated_chaser_state - info["chaser_state"], first)
    table = np.empty((1, 4))
    navigation_errors(env.batch.missions.noise_key[0], BIAS_STEP, 2.0, 0.0, table)
    np.testing.assert_allclose(env.estimated_chaser_state - env.chaser_state, table[0], atol=1e-9)


def test_the_same_seed_gives_the_same_errors_in_the_single_and_the_vector_env():
    kw = {**SMALL, "nav_sigma_position": 2.0, "nav_sigma_velocity": 0.02,
          "thrust_sigma_magnitude": 0.1, "thrust_sigma_pointing": 0.05}  # fmt: skip
    env = DebrisFieldEnv(dim=2, **kw)
    venv = DebrisFieldVectorEnv(2, dim=2, **kw)
    obs, _ = env.reset(seed=11)
    vobs, _ = venv.reset(seed=11)
    np.testing.assert_array_equal(vobs[0], obs)
    rng = np.random.default_rng(0)
    for _ in range(40):
        a = rng.uniform(-1, 1, 2)
        obs, r, term, _, _ = env.step(a)
        vobs, vr, vterm, _, _ = venv.step(np.stack([a, a]))
        np.testing.assert_array_equal(vobs[0], obs)
        assert vr[0] == r
        if term:
            break
    env2 = DebrisFieldEnv(dim=2, **kw)
    other, _ = env2.reset(seed=12)
    assert env2.batch.missions.noise_key[0] != env.batch.missions.noise_key[0]


def _burns(dim: int, steps: int, **errors) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commanded and applied accelerations and the Δv charged, over ``steps`` steps of a
    field without bodies (n_obstacles=0 is not allowed to hold targets off: one far target)."""
    env = DebrisFieldEnv(
        dim=dim, **{**V2_WORLD, "n_obstacles": 0, "n_targets": 1}, delta_v_budget=None,
        field_size=1e5, **errors,
    )  # fmt: skip
    rng = np.random.default_rng(1)
    commanded, applied, charged = [], [], []
    env.reset(seed=0)
    for t in range(steps):
        if t % 50 == 0:
            env.reset()  # keep far from the walls
        action = rng.uniform(0.3, 1.0, dim) * rng.choice([-1, 1], dim)
        action /= max(1.0, np.linalg.norm(action))
        dv0 = env.batch.missions.delta_v[0]
        *_, info = env.step(action)
        commanded.append(action * env.config.max_accel)
        applied.append(info["applied_accel"])
        charged.append(info["delta_v"] - dv0)
    return np.array(commanded), np.array(applied), np.array(charged)


@pytest.mark.parametrize("dim", [2, 3])
def test_thrust_errors_have_the_stated_distributions(dim):
    sm, sp, p = 0.1, 0.05, 0.2
    cmd, app, dv = _burns(
        dim, 3000, thrust_sigma_magnitude=sm, thrust_sigma_pointing=sp, thrust_miss_probability=p
    )
    dt = 10.0
    np.testing.assert_allclose(dv, np.linalg.norm(app, axis=1) * dt, rtol=1e-9, atol=1e-12)
    missed = np.all(app == 0.0, axis=1)
    n = len(missed)
    assert abs(missed.mean() - p) < 4 * math.sqrt(p * (1 - p) / n)
    fired_c, fired_a = cmd[~missed], app[~missed]
    gain = np.linalg.norm(fired_a, axis=1) / np.linalg.norm(fired_c, axis=1)
    m = len(gain)
    assert abs(gain.mean() - 1.0) < 4 * sm / math.sqrt(m)
    assert gain.std() == pytest.approx(sm, rel=0.06)
    cos = np.sum(fired_a * fired_c, axis=1) / (
        np.linalg.norm(fired_a, axis=1) * np.linalg.norm(fired_c, axis=1)
    )
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    if dim == 2:  # |N(0, σ)|: mean σ·sqrt(2/π)
        expected = sp * math.sqrt(2 / math.pi)
    else:  # the norm of two N(0, σ) angles (Rayleigh): mean σ·sqrt(π/2)
        expected = sp * math.sqrt(math.pi / 2)
    assert angle.mean() == pytest.approx(expected, rel=0.06)


def test_thrusters_that_never_miss_charge_what_they_did_with_a_budget():
    env = DebrisFieldEnv(dim=2, **SMALL, thrust_sigma_magnitude=0.3)
    env.reset(seed=1)
    total = 0.0
    for _ in range(20):
        *_, info = env.step(np.array([1.0, 0.0]))
        total += np.linalg.norm(info["applied_accel"]) * 10.0
        assert info["delta_v"] == pytest.approx(total, rel=1e-9)


def test_sensor_range_empties_the_obstacle_slots_beyond_it_and_keeps_the_targets():
    rng_seed = 5
    full = DebrisFieldEnv(dim=2, **SMALL)
    near = DebrisFieldEnv(dim=2, **SMALL, sensor_range=150.0)
    o_full, _ = full.reset(seed=rng_seed)
    o_near, _ = near.reset(seed=rng_seed)
    names = full.observation_names()
    gaps = full.batch.missions.gaps[0]
    order = full.batch.missions.nearest[0]
    seen = [b for b in order[: full.config.obs_obstacles] if gaps[b] <= 150.0]
    assert 0 < len(seen) < full.config.obs_obstacles  # the seed puts some on each side
    for k in range(full.config.obs_obstacles):
        cols = [names.index(f"obstacle{k}_rel_pos_x"), names.index(f"obstacle{k}_gap")]
        if k < len(seen):
            np.testing.assert_array_equal(o_near[cols], o_full[cols])
        else:
            assert o_near[cols[0]] == 0.0 and o_near[cols[1]] == 1.0
    targets = [i for i, n in enumerate(names) if n.startswith("target")]
    np.testing.assert_array_equal(o_near[targets], o_full[targets])


def test_sensor_range_caps_the_lidar():
    kw = {**V2_WORLD, "observation": "lidar", "lidar_range": 500.0}
    full, short = DebrisFieldEnv(dim=2, **kw), DebrisFieldEnv(dim=2, **kw, sensor_range=200.0)
    rays = [i for i, n in enumerate(full.observation_names()) if n.startswith("lidar")]
    for seed in range(30):  # a field with rays ending on both sides of the sensor range
        o_full, _ = full.reset(seed=seed)
        ranges = o_full[rays] * 500.0
        if np.any(ranges < 200.0) and np.any((ranges > 200.0) & (ranges < 500.0)):
            break
    else:
        pytest.fail("no seed put bodies on both sides of the sensor range")
    o_short, _ = short.reset(seed=seed)
    for r, value in zip(ranges, o_short[rays]):
        assert value == (pytest.approx(r / 500.0, rel=1e-6) if r < 200.0 else 1.0)


@settings(max_examples=40, deadline=None)
@given(
    key=st.sampled_from(
        [
            "nav_sigma_position",
            "nav_sigma_velocity",
            "thrust_sigma_magnitude",
            "thrust_sigma_pointing",
            "thrust_miss_probability",
            "sensor_range",
            "ballistic_coefficient",
            "orbit_inclination",
        ]
    ),
    value=st.one_of(
        st.floats(-1e9, -1e-9), st.floats(1e12, 1e300), st.just(math.nan), st.just(math.inf)
    ),
)
def test_bad_uncertainty_options_name_the_key_and_range(key, value):
    with pytest.raises(ValueError, match=key):
        EnvConfig(**{key: value})


def test_the_truth_model_refuses_a_frozen_world():
    with pytest.raises(ValueError, match="frozen"):
        EnvConfig(truth_model="j2_drag", debris_motion="frozen")


def test_swarms_refuse_the_uncertain_world():
    from debris_gym import swarm

    with pytest.raises(ValueError, match="thrust_miss_probability"):
        swarm.make("DebrisGym/Swarm2D-v0", thrust_miss_probability=0.1)


def test_a_classical_agent_flies_on_what_it_observes():
    import agents
    from agents.policies.base import NavigatedView

    env = gym.make("DebrisGym/Rendezvous2D-v2", nav_sigma_position=2.0)
    agent = agents.make_agent("apf-mpc", env)
    assert isinstance(agent.env, NavigatedView)
    obs, info = env.reset(seed=1)
    agent.predict(obs)
    assert not np.array_equal(agent.env.chaser_state, info["chaser_state"])
    assert agent.env.scenario is env.unwrapped.estimated_scenario
    assert agent.env.scenario != env.unwrapped.scenario


def test_the_shield_widens_its_margin_by_the_navigation_error():
    from agents.policies.shield import SafetyShield

    exact = SafetyShield(DebrisFieldEnv(dim=2, **SMALL))
    noisy = SafetyShield(DebrisFieldEnv(dim=2, **SMALL, nav_sigma_position=2.0))
    assert exact._own_margin() == 1.0
    assert noisy._own_margin() == pytest.approx(1.0 + 3.0 * math.sqrt(2.0) * 2.0)


def test_the_uncertain_ids_are_the_v2_world_with_every_error_on():
    from debris_gym.registration import ENV_SPECS, UNCERTAIN_WORLD

    for dim in (2, 3):
        spec = ENV_SPECS[f"DebrisGym/Rendezvous{dim}D-Uncertain-v2"]
        v2 = ENV_SPECS[f"DebrisGym/Rendezvous{dim}D-v2"]
        added = {k: v for k, v in spec["kwargs"].items() if k not in v2["kwargs"]}
        assert {k: spec["kwargs"][k] for k in v2["kwargs"]} == v2["kwargs"]
        assert added == {k: v for k, v in UNCERTAIN_WORLD.items() if k in UNCERTAINTY_KEYS}
        assert spec["max_episode_steps"] == v2["max_episode_steps"]


def test_a_navigated_view_re_estimates_the_field_from_the_latest_observation():
    from agents.policies.base import NavigatedView
    from debris_gym.dynamics import cw_transition

    env = DebrisFieldEnv(dim=2, **SMALL, nav_sigma_position=2.0, nav_sigma_velocity=0.01)
    view = NavigatedView(env, refresh_steps=5)
    env.reset(seed=6)
    first = view.scenario
    assert first is env.estimated_scenario
    for step in range(1, 12):
        env.step(np.zeros(2))
        estimate = view.scenario
        if step in (5, 10):  # a new field, carried back from this observation
            assert estimate is not first
            back = env.estimated_body_states @ cw_transition(env.config.n, -env.elapsed, 2).T
            np.testing.assert_allclose(estimate.initial_body_states(), back, atol=1e-9)
            now = estimate.body_states(env.elapsed)
            np.testing.assert_allclose(now, env.estimated_body_states, atol=1e-6)
            assert not np.allclose(now, env.body_states)  # never the truth
            first = estimate
        else:
            assert estimate is first
    env.reset(seed=7)
    assert view.scenario is env.estimated_scenario
