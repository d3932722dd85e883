"""The env under ``truth_model="j2_drag"`` against an independent integration of absolute orbits
(tests/orbit_oracle.py), and the size of the CW approximation left in the contact sweep."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from debris_gym.dynamics import discretize
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.registration import V2_WORLD
from tests import orbit_oracle

TRUTH = {**V2_WORLD, "truth_model": "j2_drag", "n_obstacles": 6}


def _inverse_ballistic(env: DebrisFieldEnv) -> np.ndarray:
    cfg, t = env.config, env.config.n_targets
    b = np.full(len(env.scenario.bodies), 1.0 / cfg.ballistic_coefficient)
    b[:t] = 1.0 / cfg.target_ballistic_coefficient
    return b


def _as_3d(states: np.ndarray, dim: int) -> np.ndarray:
    out = np.zeros((len(states), 6))
    out[:, :dim], out[:, 3 : 3 + dim] = states[:, :dim], states[:, dim:]
    return out


def test_the_bodies_fly_as_an_independent_integration_of_their_orbits():
    env = DebrisFieldEnv(dim=3, **TRUTH)
    env.reset(seed=2)
    start = env.body_states.copy()
    steps = 100
    for _ in range(steps):
        env.step(np.zeros(3))
    cfg = env.config
    expected = orbit_oracle.oracle(
        start, _inverse_ballistic(env), 1.0 / cfg.chaser_ballistic_coefficient, True,
        steps * cfg.dt,
    )  # fmt: skip
    error = np.abs(env.body_states - expected)
    assert error[:, :3].max() < 0.01  # m, over 1 000 s
    assert error[:, 3:].max() < 1e-5  # m/s
    # and the truth is not the CW model: the bodies have moved off their CW motion
    cw = start @ discretize(cfg.n, steps * cfg.dt, 3).ad.T
    assert np.abs(env.body_states[:, :3] - cw[:, :3]).max() > 0.05


def test_a_thrusting_chaser_flies_as_the_independent_integration():
    """Constant LVLH thrust over each step: the oracle flies it one step at a time, the thrust
    turned with the reference's frame, and the env matches it."""
    env = DebrisFieldEnv(dim=3, **TRUTH, delta_v_budget=None)
    env.reset(seed=4)
    action = np.array([0.3, -0.2, 0.1])
    accel = action * env.config.max_accel
    b_ref = 1.0 / env.config.chaser_ballistic_coefficient
    ref = orbit_oracle.circular_start()
    chaser = np.zeros(6)
    for _ in range(20):
        env.step(action)
        chaser, ref = _oracle_thrust_step(ref, chaser, accel, b_ref, env.config.dt)
    np.testing.assert_allclose(env.chaser_state, chaser, atol=1e-4)


def _oracle_thrust_step(ref, rel, accel, b_ref, dt):
    """One step of a thrusting body by DOP853: the thrust held in the LVLH axes of the
    reference as it flies, both integrated together as absolute orbits."""
    from scipy.integrate import solve_ivp

    body0 = orbit_oracle.from_lvlh(ref, rel, b_ref, True)

    def rhs(_t, y):
        r_ref, v_ref, r, v = y[:3], y[3:6], y[6:9], y[9:]
        x = r_ref / np.linalg.norm(r_ref)
        z = np.cross(r_ref, v_ref)
        z /= np.linalg.norm(z)
        axes = np.array([x, np.cross(z, x), z])
        return np.concatenate([
            v_ref, orbit_oracle.acceleration(r_ref, v_ref, b_ref, True),
            v, orbit_oracle.acceleration(r, v, b_ref, True) + axes.T @ accel,
        ])  # fmt: skip

    sol = solve_ivp(rhs, (0.0, dt), np.concatenate([ref, body0]), method="DOP853",
                    rtol=1e-12, atol=1e-9)  # fmt: skip
    end = sol.y[:, -1]
    return orbit_oracle.to_lvlh(end[:6], end[6:], b_ref, True), end[:6]


def test_an_idle_chaser_keeps_its_place_and_a_reset_starts_the_orbit_again():
    env = DebrisFieldEnv(dim=2, **TRUTH)
    env.reset(seed=1)
    for _ in range(50):
        *_, info = env.step(np.zeros(2))
    assert np.all(info["chaser_state"] == 0.0)  # the reference carries the chaser's B
    first = env.body_states.copy()
    env.reset(seed=1)
    for _ in range(50):
        env.step(np.zeros(2))
    np.testing.assert_array_equal(env.body_states, first)


def test_the_vector_env_flies_the_truth_like_the_single_env():
    env, venv = DebrisFieldEnv(dim=2, **TRUTH), DebrisFieldVectorEnv(2, dim=2, **TRUTH)
    obs, _ = env.reset(seed=3)
    vobs, _ = venv.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-1, 1, 2)
        obs, r, term, _, _ = env.step(a)
        vobs, vr, *_ = venv.step(np.stack([a, a]))
        np.testing.assert_array_equal(vobs[0], obs)
        assert vr[0] == r
        if term:
            break


def test_within_a_step_the_truth_leaves_the_cw_sweep_by_under_a_millimetre():
    """Contacts are swept along the CW motion within each step; the truth's end states differ
    from the CW step of the same start states by the perturbations over one step only."""
    env = DebrisFieldEnv(dim=3, **{**TRUTH, "n_obstacles": 20})
    env.reset(seed=5)
    model = discretize(env.config.n, env.config.dt, 3)
    worst = 0.0
    for _ in range(300):
        before = env.body_states.copy()
        env.step(np.zeros(3))
        worst = max(worst, np.abs(env.body_states[:, :3] - before @ model.ad[:3].T).max())
    assert worst < 1e-3
    assert worst > 0.0


def test_the_uncertain_ids_fly_every_error():
    env = gym.make("DebrisGym/Rendezvous2D-Uncertain-v2")
    cfg = env.unwrapped.config
    assert cfg.navigation_errors and cfg.actuation_errors and cfg.truth_model == "j2_drag"
    assert cfg.sensor_range == 250.0
    obs, info = env.reset(seed=0)
    assert not np.array_equal(env.unwrapped.estimated_chaser_state, info["chaser_state"])
    assert math.isfinite(float(np.sum(obs)))


@pytest.mark.parametrize("dim", [2, 3])
def test_the_truth_needs_one_chaser_per_field(dim):
    from debris_gym import swarm

    with pytest.raises(ValueError, match="truth_model"):
        swarm.make("DebrisGym/Swarm2D-v0" if dim == 2 else "DebrisGym/Swarm3D-v0",
                   truth_model="j2_drag")  # fmt: skip
