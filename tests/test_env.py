"""Behaviour of DebrisFieldEnv: API checks, determinism, Δv accounting, collisions, captures."""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import debris_gym
from debris_gym.dynamics import discretize
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Body
from tests.helpers import flies_old_ids, integrate_cwh, simple_scenario

# many tests fly the free-space simple_scenario in envs with the default LEO orbit on purpose;
# every registered ID is checked, the old versions (v0, v1) included
pytestmark = [
    pytest.mark.filterwarnings("ignore:the pinned scenario's physics differ"),
    flies_old_ids,
]

ALL_IDS = list(debris_gym.ENV_SPECS)
INFO_KEYS = {
    "chaser_state",
    "time",
    "delta_v",
    "targets_captured",
    "n_targets",
    "min_clearance",
    "collision",
    "is_success",
    "reward_terms",
}


@pytest.mark.parametrize("env_id", ALL_IDS)
@pytest.mark.parametrize("observation", ["kinematics", "lidar"])
@pytest.mark.parametrize("action", ["continuous", "discrete"])
def test_check_env_passes_without_warnings(env_id, observation, action, display):
    """Gymnasium's and SB3's checkers, warnings turned into errors.

    Gymnasium's render check opens every declared render mode, "human" included, which needs a
    display: with one (yours, or the Xvfb the ``display`` fixture starts) the full check runs;
    without, the render check covers "rgb_array" only.
    """
    from gymnasium.utils.passive_env_checker import env_render_passive_checker
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # gymnasium's notice that a newer version of an old ID exists (they stay on purpose)
        warnings.filterwarnings("ignore", ".*is out of date", DeprecationWarning)
        env = gym.make(env_id, observation=observation, action=action)
        gym_check_env(env.unwrapped, skip_render_check=display is None)
        sb3_check_env(env.unwrapped, warn=True)
        env.close()
        if display is None:
            env = gym.make(env_id, observation=observation, action=action, render_mode="rgb_array")
            env.reset(seed=0)
            env_render_passive_checker(env.unwrapped)
            env.close()


def test_make_with_module_prefix_needs_no_import():
    import subprocess
    import sys

    code = (
        "import gymnasium as gym\n"
        "env = gym.make('debris_gym:DebrisGym/Rendezvous2D-v0')\n"
        "obs, info = env.reset(seed=1)\n"
        "print(env.spec.max_episode_steps, obs.shape)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split()[0] == "1000"


def _newest(env_id):
    """``env_id`` at the newest version registered (gymnasium names IDs ``…-vN``)."""
    stem, _, version = env_id.rpartition("-v")
    newer = [int(i.rpartition("-v")[2]) for i in ALL_IDS if i.rpartition("-v")[0] == stem]
    return f"{stem}-v{max(newer)}" if int(version) < max(newer) else env_id


OUT_OF_DATE = [i for i in ALL_IDS if _newest(i) != i]


@pytest.mark.parametrize("env_id", OUT_OF_DATE)
def test_an_old_id_warns_that_it_is_out_of_date(env_id):
    """Gymnasium's notice: the frozen-world v0 IDs and the v1 IDs stay for reproducing earlier
    numbers, and whoever makes one is told v2 exists (tests that fly them on purpose filter the
    notice with ``tests.helpers.flies_old_ids``); the v2 IDs and the paper's world do not warn."""
    assert set(OUT_OF_DATE) == {
        "DebrisGym/Rendezvous2D-v0", "DebrisGym/Rendezvous3D-v0",
        "DebrisGym/Rendezvous2D-v1", "DebrisGym/Rendezvous3D-v1",
        "DebrisGym/Rendezvous2D-Easy-v1", "DebrisGym/Rendezvous2D-Medium-v1",
        "DebrisGym/Rendezvous3D-Easy-v1", "DebrisGym/Rendezvous3D-Medium-v1",
    }  # fmt: skip
    assert _newest(env_id).endswith("-v2")
    for make in (gym.make, lambda i: gym.make_vec(i, 2, vectorization_mode="vector_entry_point")):
        with pytest.warns(DeprecationWarning, match=rf"{env_id} is out of date.*`v2`"):
            make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # neither v2 nor the paper's world warns
        gym.make(_newest(env_id))
        gym.make_vec(_newest(env_id), 2, vectorization_mode="vector_entry_point")
        gym.make("DebrisGym/PaperField2D-v0")


def rollout(env_id, seed, steps=150, **kwargs):
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    record = [obs.tobytes()]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        record.append(
            (obs.tobytes(), reward, terminated, truncated, info["chaser_state"].tobytes())
        )
        if terminated or truncated:
            obs, info = env.reset()
            record.append(obs.tobytes())
    scenario = env.unwrapped.scenario
    env.close()
    return record, scenario


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_same_seed_gives_bit_identical_episodes(env_id):
    first, scen1 = rollout(env_id, seed=3)
    second, scen2 = rollout(env_id, seed=3)
    assert first == second
    assert scen1 == scen2


@pytest.mark.parametrize("env_id", ["DebrisGym/Rendezvous2D-v0", "DebrisGym/Rendezvous3D-v0"])
def test_different_seeds_give_different_fields(env_id):
    env = gym.make(env_id)
    env.reset(seed=1)
    a = env.unwrapped.scenario
    env.reset(seed=2)
    b = env.unwrapped.scenario
    assert a != b
    assert not np.allclose(a.body_positions(), b.body_positions())


def test_default_difficulty_matches_design():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    env.reset(seed=0)
    scen = env.unwrapped.scenario
    assert len(scen.targets) == 3 and len(scen.obstacles) == 20
    radii = [b.radius for b in scen.obstacles]
    assert 2.0 <= min(radii) and max(radii) <= 25.0
    assert any(b.is_polygon for b in scen.obstacles) and not all(
        b.is_polygon for b in scen.obstacles
    )
    assert scen.size == pytest.approx(1000.0)
    assert scen.mean_motion == pytest.approx(1.1314e-3, rel=1e-4)
    assert env.unwrapped.config.return_to_dock


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_info_keys_on_reset_and_step(env_id):
    env = gym.make(env_id)
    _, info = env.reset(seed=0)
    assert INFO_KEYS <= set(info)
    assert set(info["reward_terms"]) == set(REWARD_TERMS)
    _, reward, _, _, info = env.step(env.action_space.sample())
    assert INFO_KEYS <= set(info)
    assert reward == pytest.approx(sum(info["reward_terms"].values()))
    dim = env.unwrapped.dim
    assert info["chaser_state"].shape == (2 * dim,)


def test_coasting_and_thrusting_follow_exact_dynamics():
    """Env states equal the independent ODE solution of the CWH equations
    (``tests.helpers.integrate_cwh``)."""
    env = DebrisFieldEnv(dim=3, thrust_model="box", delta_v_budget=None, n_obstacles=0)
    env.reset(seed=0)
    scen = env.scenario
    n, dt, amax = scen.mean_motion, scen.dt, scen.max_accel
    state = np.array([1.0, -2.0, 3.0, 0.01, 0.02, -0.01])
    env.reset(seed=0, options={"scenario": scen, "chaser_state": state})
    actions = [np.zeros(3), np.array([1.0, -0.5, 0.25]), np.array([-0.3, 0.9, -1.0])] * 3
    truth = state.copy()
    for a in actions:
        _, _, terminated, _, info = env.step(a.astype(np.float32))
        truth = integrate_cwh(n, 3, truth, amax * a.astype(np.float32).astype(float), dt)
        got = info["chaser_state"]
        assert np.linalg.norm(got - truth) <= 1e-6 * np.linalg.norm(truth)
        assert not terminated


@pytest.mark.parametrize("thrust_model", ["box", "ball"])
def test_delta_v_accounting_is_exact(thrust_model):
    env = DebrisFieldEnv(thrust_model=thrust_model, delta_v_budget=None)
    env.reset(seed=0)
    scen = env.scenario
    actions = np.array([[1.0, 1.0], [0.3, -0.4], [0.0, 0.0], [-2.0, 0.5], [0.6, 0.8]])
    expected = 0.0
    for a in actions:
        _, _, _, _, info = env.step(a.astype(np.float32))
        a32 = a.astype(np.float32).astype(float)
        if thrust_model == "box":
            u = scen.max_accel * np.clip(a32, -1, 1)
            expected += np.abs(u).sum() * scen.dt
        else:
            u = scen.max_accel * a32 / max(1.0, np.linalg.norm(a32))
            expected += np.linalg.norm(u) * scen.dt
        assert info["delta_v"] == pytest.approx(expected, rel=1e-12, abs=1e-15)
    # hand-computed: ball, [1, 1] → |u| = max_accel, Δv = 0.05 · 10 = 0.5 m/s for the first step
    if thrust_model == "ball":
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
        assert info["delta_v"] == pytest.approx(0.5, rel=1e-12)


def test_budget_is_spent_exactly_and_ends_the_episode():
    env = DebrisFieldEnv(thrust_model="ball", delta_v_budget=1.2)
    env.reset(seed=0, options={"scenario": simple_scenario()})
    deltas = []
    for _ in range(5):
        _, _, terminated, _, info = env.step(np.array([0.0, -1.0], dtype=np.float32))
        deltas.append(info["delta_v"])
        if terminated:
            break
    assert deltas == pytest.approx([0.5, 1.0, 1.2])
    assert terminated and not info["collision"]


def test_long_step_through_a_body_is_a_collision():
    """Both ends of the step lie outside the obstacle, but the straight path crosses it."""
    scen = simple_scenario(
        obstacles=(Body(position=(0.0, 50.0), radius=5.0, velocity=(0.0, 0.0)),),
        targets=(Body(position=(300.0, 300.0), radius=5.0, velocity=(0.0, 0.0)),),
        dt=100.0,
    )
    env = DebrisFieldEnv(mean_motion=0.0, delta_v_budget=None)
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 0.0, 0.0, 1.0]})
    _, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["chaser_state"][1] == pytest.approx(100.0)  # ended 45 m beyond the obstacle
    assert info["collision"] and terminated
    assert info["reward_terms"]["collision"] == -env.config.reward_collision
    # the same step beside the obstacle is clean
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [7.0, 0.0, 0.0, 1.0]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert not info["collision"] and not terminated


def test_polygon_is_hit_between_substeps_too():
    square = ((-3.0, -3.0), (3.0, -3.0), (3.0, 3.0), (-3.0, 3.0))
    scen = simple_scenario(
        obstacles=(
            Body(position=(0.0, 55.0), radius=math.sqrt(18), velocity=(0.0, 0.0), vertices=square),
        ),
        targets=(Body(position=(300.0, 300.0), radius=5.0, velocity=(0.0, 0.0)),),
        dt=100.0,
    )
    env = DebrisFieldEnv(collision_substeps=1, delta_v_budget=None)
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 0.0, 0.0, 1.0]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["collision"] and terminated


def test_capture_requires_distance_and_low_speed():
    scen = simple_scenario()
    env = DebrisFieldEnv(return_to_dock=True, delta_v_budget=None, capture_radius=5.0)
    # 3 m from the target surface (chaser radius 1 → surface gap 2 m), at rest: captured
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    _, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 1 and not terminated
    assert info["reward_terms"]["capture"] == env.config.reward_capture
    # same place but drifting at 1 m/s (> capture_speed 0.5): not captured
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 82.0, 1.0, 0.0]})
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 0
    # then come home to the dock slowly: success
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 1
    # double integrator: 5 steps at -a then 5 at +a would cover a·dt²·5² = 90 m and stop 2 m
    # from the dock (a = 0.036 m/s²); success comes once within 5 m of the dock at <= 0.5 m/s
    for sign in [-1.0] * 5 + [1.0] * 5:
        assert not info["is_success"]
        _, reward, terminated, _, info = env.step(np.array([0.0, 0.72 * sign], dtype=np.float32))
        if terminated:
            break
    position, velocity = info["chaser_state"][:2], info["chaser_state"][2:]
    assert np.linalg.norm(position) <= 5.0 and np.linalg.norm(velocity) <= 0.5
    assert info["is_success"] and terminated
    assert info["reward_terms"]["success"] == env.config.reward_success


def test_touching_a_target_too_fast_is_a_collision():
    scen = simple_scenario()
    env = DebrisFieldEnv(delta_v_budget=None)
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 80.0, 0.0, 2.0]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["collision"] and terminated and info["targets_captured"] == 0


def test_queued_order_only_counts_the_current_target():
    targets = (
        Body(position=(0.0, 100.0), radius=5.0, velocity=(0.0, 0.0)),
        Body(position=(0.0, -100.0), radius=5.0, velocity=(0.0, 0.0)),
    )
    scen = simple_scenario(targets=targets)
    for order, expected in (("queued", 0), ("any", 1)):
        env = DebrisFieldEnv(target_order=order, delta_v_budget=None)
        env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, -92.0, 0.0, 0.0]})
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
        assert info["targets_captured"] == expected, order


def test_leaving_bounds_terminates():
    env = DebrisFieldEnv(delta_v_budget=None)
    env.reset(seed=0, options={"scenario": simple_scenario(), "chaser_state": [0, 495, 0, 1.0]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and info["out_of_bounds"] and not info["collision"]
    assert info["reward_terms"]["out_of_bounds"] == -env.config.reward_out_of_bounds


def discounted_progress(
    env: DebrisFieldEnv, gamma: float, steps: int
) -> tuple[float, float, float, bool]:
    """Fly seeded random thrust from ``env.reset(seed=4)`` for ``steps`` steps or until it
    terminates: Φ(s_0), Σ γ^t F_t of the progress terms, γ^T, and whether it terminated."""
    env.reset(seed=4)
    phi0 = env.potential
    total, discount, terminated = 0.0, 1.0, False
    rng = np.random.default_rng(0)
    for _ in range(steps):
        _, _, terminated, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        total += discount * info["reward_terms"]["progress"]
        discount *= gamma
        if terminated:
            break
    return phi0, total, discount, terminated


def test_progress_shaping_telescopes_to_potential_difference():
    """Σ γ^t F_t = γ^T Φ(s_T) − Φ(s_0): the shaping is potential-based."""
    gamma = 0.9
    env = DebrisFieldEnv(shaping_gamma=gamma, reward_progress=1.0, delta_v_budget=None)
    phi0, total, discount, terminated = discounted_progress(env, gamma, 60)
    phi_end = 0.0 if terminated else env.potential
    assert total == pytest.approx(discount * phi_end - phi0, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("gamma", [0.9, 1.0])
def test_held_terminal_potential_telescopes_to_progress_made(gamma):
    """shaping_terminal='hold': no refund at termination, Σ γ^t F_t = γ^T Φ(s_T) − Φ(s_0)."""
    env = DebrisFieldEnv(
        shaping_gamma=gamma, shaping_terminal="hold", reward_progress=1.0, delta_v_budget=None
    )
    phi0, total, discount, terminated = discounted_progress(env, gamma, 200)
    assert terminated  # random thrust ends the episode (a crash or leaving the bounds)
    assert env.potential < -0.5  # far from done: the refund would have been large
    assert total == pytest.approx(discount * env.potential - phi0, rel=1e-9, abs=1e-9)


def test_observation_is_normalised_and_named():
    env = DebrisFieldEnv()
    obs, _ = env.reset(seed=0)
    names = env.observation_names()
    assert len(names) == obs.shape[0] == env.observation_space.shape[0]
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert np.all(np.abs(obs) <= 1.5)
    values = dict(zip(names, obs))
    assert values["delta_v_remaining"] == 1.0 and values["time_remaining"] == 1.0
    # slot 0 is the nearest uncaptured target, matching the scenario geometry
    scen = env.scenario
    gaps = [np.linalg.norm(t.position) - t.radius for t in scen.targets]
    nearest = scen.targets[int(np.argmin(gaps))]
    half = scen.size / 2
    assert values["target0_rel_pos_x"] == pytest.approx(nearest.position[0] / half, rel=1e-5)
    assert values["target0_radius"] == pytest.approx(nearest.radius / half, rel=1e-5)


def test_obstacle_slots_hold_nearest_gaps():
    env = DebrisFieldEnv(obs_obstacles=4)
    obs, _ = env.reset(seed=2)
    values = dict(zip(env.observation_names(), obs))
    geom = env.geometry
    gaps = geom.signed_distance(np.zeros(2))[len(env.scenario.targets) :]
    half = env.scenario.size / 2
    expected = np.sort(gaps)[:4] / half
    got = [values[f"obstacle{k}_gap"] for k in range(4)]
    np.testing.assert_allclose(got, expected, rtol=1e-5)


def test_lidar_observation_sees_an_obstacle_ahead():
    scen = simple_scenario()
    env = DebrisFieldEnv(observation="lidar", lidar_rays=4, lidar_range=250.0)
    obs, _ = env.reset(seed=0, options={"scenario": scen})
    values = dict(zip(env.observation_names(), obs))
    # rays: +x, +y, -x, -y. Obstacle at x = 200 (r 20): 180 m; target at y = 100 (r 5): 95 m.
    assert values["lidar0"] == pytest.approx(180 / 250, rel=1e-5)
    assert values["lidar1"] == pytest.approx(95 / 250, rel=1e-5)
    assert values["lidar2"] == 1.0 and values["lidar3"] == 1.0


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"dt": 0}, "dt"),
        ({"dt": 1e4}, "dt"),
        ({"max_accel": -1}, "max_accel"),
        ({"n_targets": 0}, "n_targets"),
        ({"observation": "pixels"}, "observation"),
        ({"thrust_model": "rocket"}, "thrust_model"),
        ({"capture_radius": float("nan")}, "capture_radius"),
        ({"n_tragets": 3}, "n_tragets"),
        ({"obstacle_radius_min": 30.0}, "obstacle_radius_min"),
        ({"dim": 3, "scenario": "paper"}, "paper"),
    ],
)
def test_bad_kwargs_raise_value_error_naming_the_key(kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        gym.make("DebrisGym/Rendezvous2D-v0", **kwargs)


@pytest.mark.parametrize("action", [5, -1, 2.5, np.array([1, 2])])
def test_bad_discrete_actions_raise(action):
    env = DebrisFieldEnv(action="discrete")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


def test_discrete_actions_map_to_full_thrust_axes():
    env = DebrisFieldEnv(action="discrete", delta_v_budget=None)
    env.reset(seed=0, options={"scenario": simple_scenario()})
    model = discretize(0.0, 10.0, 2)
    _, _, _, _, info = env.step(3)  # +y
    expected = model.step(np.zeros(4), np.array([0.0, 0.05]))
    np.testing.assert_allclose(info["chaser_state"], expected, rtol=1e-12)
    assert info["delta_v"] == pytest.approx(0.5)


def test_reset_options_validation(tmp_path):
    env = DebrisFieldEnv()
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"scenaro": None})
    with pytest.raises(ValueError, match="chaser_state"):
        env.reset(seed=0, options={"scenario": simple_scenario(), "chaser_state": [0, 0, 0]})
    with pytest.raises(ValueError, match="touches debris"):
        env.reset(seed=0, options={"scenario": simple_scenario(), "chaser_state": [200, 0, 0, 0]})
    with pytest.raises(ValueError, match="outside the bounds"):
        env.reset(seed=0, options={"scenario": simple_scenario(), "chaser_state": [900, 0, 0, 0]})
    with pytest.raises(ValueError, match="dim"):
        DebrisFieldEnv(dim=3).reset(options={"scenario": simple_scenario()})
    # a scenario as dict and as a path work and pin the field
    scen = simple_scenario()
    path = tmp_path / "field.json"
    scen.save(path)
    for value in (scen, scen.to_dict(), str(path), path):
        env.reset(seed=9, options={"scenario": value})
        assert env.scenario == scen


def test_step_before_reset_raises():
    with pytest.raises(RuntimeError, match="reset"):
        DebrisFieldEnv().step(np.zeros(2, dtype=np.float32))


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_pickles_mid_episode(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    clone = pickle.loads(pickle.dumps(env))
    action = env.action_space.sample()
    a = env.step(action)
    b = clone.step(action)
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1] == b[1]


def test_min_clearance_is_running_minimum():
    env = DebrisFieldEnv(delta_v_budget=None)
    env.reset(seed=0, options={"scenario": simple_scenario(), "chaser_state": [100, 0, 1.0, 0]})
    seen = []
    for _ in range(6):
        _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
        seen.append(info["min_clearance"])
    # moving +x at 1 m/s toward the obstacle at x=200 (r=20): gap 180 - 10 k - chaser radius
    assert seen == pytest.approx([80 - 10 * k - 1 for k in range(1, 7)])
    assert all(a >= b for a, b in zip(seen, seen[1:]))


def test_min_clearance_ignores_targets():
    """Approaching a target for capture does not count as losing clearance to debris."""
    env = DebrisFieldEnv(delta_v_budget=None)
    _, info = env.reset(
        seed=0, options={"scenario": simple_scenario(), "chaser_state": [0, 92.0, 0, 0]}
    )
    # 2 m from the target's surface, 180-odd m from the obstacle at (200, 0)
    expected = math.hypot(200.0, 92.0) - 20.0 - 1.0
    assert info["min_clearance"] == pytest.approx(expected)


def test_gentle_target_touch_then_debris_in_one_step_is_a_collision():
    """Regression: only the first body along the path was checked, so brushing a target gently
    and then entering debris within the same step went unreported."""
    scen = simple_scenario(
        targets=(Body(position=(0.0, 10.0), radius=2.0, velocity=(0.0, 0.0)),),
        obstacles=(Body(position=(0.0, 16.0), radius=2.0, velocity=(0.0, 0.0)),),
        dt=40.0,
    )
    env = DebrisFieldEnv(delta_v_budget=None)
    # 0.4 m/s along +y from the origin: touches the target (y 7..13) then the obstacle (y 13..19)
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 0.0, 0.0, 0.4]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["collision"] and terminated


def test_time_remaining_uses_the_registered_limit():
    """Regression: the unwrapped env's spec has no max_episode_steps, so the observation used
    1000 steps for every ID (PaperField2D-v0 is limited to 2000)."""
    env = gym.make("DebrisGym/PaperField2D-v0")
    env.reset(seed=0)
    obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    index = env.unwrapped.observation_names().index("time_remaining")
    assert obs[index] == pytest.approx((2000 - 1) / 2000)


def test_leaving_a_target_after_gentle_contact_is_not_a_collision():
    """Regression: after a gentle contact (a capture), thrusting away faster than capture_speed
    was reported as a collision, although the chaser moved away from the target."""
    scen = simple_scenario(
        targets=(
            Body(position=(50.0, 0.0), radius=5.0, velocity=(0.0, 0.0)),
            Body(position=(-300.0, 0.0), radius=5.0, velocity=(0.0, 0.0)),
        ),
        obstacles=(),
    )
    env = DebrisFieldEnv(delta_v_budget=None)
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [43.5, 0.0, 0.2, 0.0]})
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 1 and not info["collision"]
    for _ in range(2):
        _, _, terminated, _, info = env.step(np.array([-1.0, 0.0], dtype=np.float32))
        assert not info["collision"] and not terminated
    # ramming a target at speed is still a collision
    env.reset(seed=0, options={"scenario": scen, "chaser_state": [30.0, 0.0, 2.0, 0.0]})
    _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["collision"] and terminated


def test_thrusting_into_a_target_from_rest_is_a_collision():
    """Regression: a chaser at rest in gentle contact that thrusts into the target is in a
    collision, also when the step ends past the target's centre (it was not: the rule only
    looked at the velocities at the two ends of the step)."""
    scen = simple_scenario(
        targets=(
            Body(position=(50.0, 0.0), radius=5.0, velocity=(0.0, 0.0)),
            Body(position=(-300.0, 0.0), radius=5.0, velocity=(0.0, 0.0)),
        ),
        obstacles=(),
        max_accel=0.1,
    )
    env = DebrisFieldEnv(delta_v_budget=None)
    for thrust in (0.6, 1.0):  # ends closing in at 0.6 m/s; ends past the centre at 1 m/s
        env.reset(seed=0, options={"scenario": scen, "chaser_state": [43.5, 0.0, 0.2, 0.0]})
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))  # drifts into gentle contact
        assert info["targets_captured"] == 1 and not info["collision"]
        _, _, _, _, info = env.step(np.array([-0.2, 0.0], dtype=np.float32))  # brakes to rest
        assert not info["collision"] and abs(info["chaser_state"][2]) < 1e-6  # float32 action
        _, _, terminated, _, info = env.step(np.array([thrust, 0.0], dtype=np.float32))
        assert info["collision"] and terminated, thrust


def test_capture_at_just_under_capture_speed():
    """Capture needs speed <= capture_speed (0.5 m/s) — 0.48 m/s counts, 0.52 m/s does not."""
    scen = simple_scenario()
    for speed, captured in ((0.48, 1), (0.52, 0)):
        env = DebrisFieldEnv(delta_v_budget=None)
        env.reset(options={"scenario": scen, "chaser_state": [0.0, 86.0, 0.0, speed]})
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))  # to ~4 m from the surface
        assert info["targets_captured"] == captured and not info["collision"], speed


@pytest.mark.parametrize("other_targets", [False, True])
def test_obstacle_slots_with_other_targets(other_targets):
    """obs_other_targets: the slots hold the nearest bodies except the current goal, so a
    captured target the chaser sits beside is seen (regression: the shipped policy, blind to
    it, ran into the target it had just captured in 8 of 40 collisions)."""
    scen = simple_scenario(
        targets=(
            Body(position=(0.0, 100.0), radius=5.0),
            Body(position=(300.0, 300.0), radius=8.0),
        )
    )
    env = DebrisFieldEnv(obs_other_targets=other_targets, obs_obstacles=3)
    names = env.observation_names()
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    obs, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["captured"].tolist() == [True, False]  # the goal is now target 1
    slots = dict(zip(names, obs.tolist()))
    pos = info["chaser_state"][:2]
    L = 500.0

    def expect(slot, center, radius):
        rel = (np.asarray(center) - pos) / L
        gap = (np.linalg.norm(np.asarray(center) - pos) - radius) / L  # from the chaser's centre
        assert slots[f"obstacle{slot}_rel_pos_x"] == pytest.approx(rel[0], rel=1e-6, abs=1e-7)
        assert slots[f"obstacle{slot}_rel_pos_y"] == pytest.approx(rel[1], rel=1e-6, abs=1e-7)
        assert slots[f"obstacle{slot}_radius"] == pytest.approx(radius / L, rel=1e-6)
        assert slots[f"obstacle{slot}_gap"] == pytest.approx(gap, rel=1e-5)

    if other_targets:
        expect(0, (0.0, 100.0), 5.0)  # the captured target, 3 m away
        expect(1, (200.0, 0.0), 20.0)  # then the obstacle; the goal itself is not listed
        empty = [2]
    else:
        expect(0, (200.0, 0.0), 20.0)  # obstacles only
        empty = [1, 2]
    for slot in empty:  # empty slots read as far away
        assert slots[f"obstacle{slot}_gap"] == 1.0
        assert slots[f"obstacle{slot}_radius"] == 0.0


def test_goal_observation_at_a_fine_scale():
    """obs_goal appends the current goal (nearest uncaptured target, then the dock) / (L/10)."""
    env = DebrisFieldEnv(obs_goal=True, delta_v_budget=None)
    names = env.observation_names()
    assert names[-5:] == ["goal_rel_pos_x", "goal_rel_pos_y", "goal_rel_vel_x",
                          "goal_rel_vel_y", "goal_gap"]  # fmt: skip
    scen = simple_scenario()  # target at (0, 100), radius 5; L = 500 m, V = 5 m/s
    obs, _ = env.reset(options={"scenario": scen, "chaser_state": [0.0, 80.0, 0.1, 0.2]})
    goal = dict(zip(names[-5:], obs[-5:].tolist()))
    assert goal["goal_rel_pos_x"] == pytest.approx(0.0, abs=1e-7)
    assert goal["goal_rel_pos_y"] == pytest.approx(20.0 / 50.0)
    assert goal["goal_rel_vel_x"] == pytest.approx(-0.1 / 0.5)
    assert goal["goal_rel_vel_y"] == pytest.approx(-0.2 / 0.5)
    assert goal["goal_gap"] == pytest.approx((20.0 - 5.0 - 1.0) / 50.0)  # surface to surface
    # once the only target is captured, the goal is the dock
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    obs, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 1
    goal = dict(zip(names[-5:], obs[-5:].tolist()))
    pos = info["chaser_state"][:2]
    assert goal["goal_rel_pos_y"] == pytest.approx(-pos[1] / 50.0, rel=1e-6)
    assert goal["goal_gap"] == pytest.approx(np.linalg.norm(pos) / 50.0, rel=1e-6)


def test_near_field_goal_observation_hand_computed():
    """obs_near appends the goal gap / capture_radius and the closing speed / capture_speed,
    each saturated at ±4; the dock goal's gap is the distance to the dock point."""
    env = DebrisFieldEnv(obs_near=True, capture_radius=5.0, capture_speed=0.2)
    names = env.observation_names()
    assert names[-2:] == ["goal_near_gap", "goal_near_closing"]
    scen = simple_scenario()  # target at (0, 100), radius 5; chaser radius 1
    d = math.hypot(3.0, 10.0)
    cases = [  # chaser state -> (gap / 5 m, closing / 0.2 m/s)
        ([0.0, 80.0, 0.1, 0.2], (14.0 / 5.0, 0.2 / 0.2)),
        ([0.0, 92.0, 0.0, -0.05], (2.0 / 5.0, -0.05 / 0.2)),
        ([3.0, 90.0, 0.3, 0.0], ((d - 6.0) / 5.0, (-3.0 * 0.3 / d) / 0.2)),
        ([0.0, 0.0, 0.0, 3.0], (4.0, 4.0)),  # both saturated
    ]  # fmt: skip
    for chaser, (gap, closing) in cases:
        obs, _ = env.reset(options={"scenario": scen, "chaser_state": chaser})
        assert obs[-2] == pytest.approx(gap, rel=1e-6)
        assert obs[-1] == pytest.approx(closing, rel=1e-6)
    # once the only target is captured, the goal is the dock at the origin
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    obs, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["targets_captured"] == 1
    pos, vel = info["chaser_state"][:2], info["chaser_state"][2:]
    dist = float(np.linalg.norm(pos))
    assert obs[-2] == pytest.approx(min(dist / 5.0, 4.0), rel=1e-6)
    assert obs[-1] == pytest.approx(float(-pos @ vel) / dist / 0.2, rel=1e-5, abs=1e-6)


def assert_progress_telescopes(seed: int, steps: int, **kwargs) -> None:
    """With γ = 1 and 'hold' the progress terms of random flights sum to w · (Φ(end) − Φ(start))."""
    env = DebrisFieldEnv(shaping_gamma=1.0, shaping_terminal="hold", **kwargs)
    env.reset(seed=seed)
    phi0, total, rng = env.potential, 0.0, np.random.default_rng(seed)
    for _ in range(steps):
        _, _, terminated, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        total += info["reward_terms"]["progress"]
        if terminated:
            break
    assert total == pytest.approx(env.config.reward_progress * (env.potential - phi0), rel=1e-9)


def test_clearance_shaping_hand_computed():
    """Φ −= w · max(0, 1 − c / d)², c = chaser surface to the nearest obstacle's surface."""
    scen = simple_scenario()
    kwargs = dict(shaping_clearance=2.0, shaping_clearance_distance=50.0)
    env = DebrisFieldEnv(**kwargs)
    env.reset(options={"scenario": scen, "chaser_state": [150.0, 0.0, 0.0, 0.0]})
    goal_gap = math.hypot(150.0, 100.0) - 5.0 - 1.0  # to the target, surface to surface
    clearance = (200.0 - 150.0) - 20.0 - 1.0  # 29 m to the obstacle circle
    expected = -(goal_gap / 500.0 + 1.0) - 2.0 * (1.0 - clearance / 50.0) ** 2
    assert env.potential == pytest.approx(expected, rel=1e-12)
    # beyond the distance the term is zero: Φ as without it
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 80.0, 0.0, 0.0]})
    assert env.potential == pytest.approx(-((100.0 - 80.0 - 6.0) / 500.0 + 1.0), rel=1e-12)
    # the nearest of several obstacles counts, polygons by their surface
    square = ((-10.0, -10.0), (10.0, -10.0), (10.0, 10.0), (-10.0, 10.0))
    scen = simple_scenario(
        obstacles=(
            Body(position=(200.0, 0.0), radius=20.0),
            Body(position=(-100.0, 0.0), radius=math.sqrt(200.0), vertices=square),
        )
    )
    env.reset(options={"scenario": scen, "chaser_state": [-70.0, 0.0, 0.0, 0.0]})
    goal_gap = math.hypot(70.0, 100.0) - 6.0
    clearance = (100.0 - 70.0) - 10.0 - 1.0  # 19 m to the square's right edge
    expected = -(goal_gap / 500.0 + 1.0) - 2.0 * (1.0 - clearance / 50.0) ** 2
    assert env.potential == pytest.approx(expected, rel=1e-12)
    # with γ = 1 and 'hold' the progress terms still telescope to Φ(end) − Φ(start)
    assert_progress_telescopes(n_obstacles=60, seed=5, steps=80, **kwargs)


def test_closing_shaping_hand_computed():
    """Φ −= w · max_b max(0, v_b − capture_speed) / V · (1 − c_b / d) over bodies b ≠ goal."""
    scen = simple_scenario()
    kwargs = dict(shaping_closing=2.0, shaping_closing_distance=20.0, delta_v_budget=None)
    env = DebrisFieldEnv(**kwargs)
    env.reset(options={"scenario": scen, "chaser_state": [170.0, 0.0, 2.0, 0.0]})
    goal_gap = math.hypot(170.0, 100.0) - 6.0
    clearance = (200.0 - 170.0) - 20.0 - 1.0  # 9 m to the obstacle, closing at 2 m/s
    term = 2.0 * (2.0 - 0.5) / 5.0 * (1.0 - clearance / 20.0)
    assert env.potential == pytest.approx(-(goal_gap / 500.0 + 1.0) - term, rel=1e-12)
    # moving away from it: no term
    env.reset(options={"scenario": scen, "chaser_state": [170.0, 0.0, -2.0, 0.0]})
    assert env.potential == pytest.approx(-(goal_gap / 500.0 + 1.0), rel=1e-12)
    # closing on the goal itself is the approach-speed term's business, not this one's
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 88.0, 0.0, 2.0]})
    assert env.potential == pytest.approx(-((100.0 - 88.0 - 6.0) / 500.0 + 1.0), rel=1e-12)
    assert_progress_telescopes(n_obstacles=60, seed=9, steps=80, **kwargs)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"shaping_clearance": -1.0}, "shaping_clearance=-1.0 is out of range"),
        ({"shaping_clearance_distance": 0.0}, "shaping_clearance_distance=0.0 m is out of range"),
        ({"shaping_clearance": float("nan")}, "shaping_clearance must be finite"),
        ({"shaping_closing": -0.5}, "shaping_closing=-0.5 is out of range"),
        ({"shaping_closing_distance": 0.0}, "shaping_closing_distance=0.0 m is out of range"),
    ],
)
def test_clearance_shaping_rejects_bad_values(kwargs, message):
    with pytest.raises(ValueError, match=message):
        DebrisFieldEnv(**kwargs)


def test_approach_speed_shaping_hand_computed():
    """Φ −= w · max(0, speed − (capture_speed + slope · gap)) / V."""
    scen = simple_scenario()
    kwargs = dict(delta_v_budget=None, shaping_speed=2.0, shaping_speed_slope=0.01)
    env = DebrisFieldEnv(**kwargs)
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 80.0, 0.0, 3.0]})
    gap = 100.0 - 80.0 - 5.0 - 1.0  # chaser surface to target surface, m
    allowed = 0.5 + 0.01 * gap
    expected = -(gap / 500.0 + 1.0) - 2.0 * (3.0 - allowed) / 5.0  # the dock is the goal after
    assert env.potential == pytest.approx(expected, rel=1e-12)
    env.reset(options={"scenario": scen, "chaser_state": [0.0, 80.0, 0.0, 0.5]})  # under it
    assert env.potential == pytest.approx(-(gap / 500.0 + 1.0), rel=1e-12)
    # with γ = 1 and 'hold', the progress terms still sum to Φ(end) − Φ(start)
    assert_progress_telescopes(seed=3, steps=60, **kwargs)


def test_a_pinned_scenario_with_other_physics_warns_and_flies_its_own():
    """Regression: a hand-built Scenario left at its default physics (free space) flew silently
    in free space in a LEO env. It still flies its own physics (the documented contract of a
    pinned field), with a warning naming each differing parameter and both values."""
    env = DebrisFieldEnv(delta_v_budget=None)
    scen = simple_scenario(dt=5.0)
    with pytest.warns(
        UserWarning, match=r"mean_motion 0\.0 \(env 0\.00113\d*\), dt 5\.0 \(env 10\.0\)"
    ):
        env.reset(seed=0, options={"scenario": scen, "chaser_state": [0.0, 0.0, 1.0, 0.0]})
    env.step(np.zeros(2, dtype=np.float32))
    np.testing.assert_allclose(env.chaser_state, [5.0, 0.0, 1.0, 0.0])  # free space, 5 s
    matching = simple_scenario(mean_motion=env.config.n, dt=env.config.dt)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", ".*is out of date", DeprecationWarning)  # v0 on purpose
        env.reset(seed=0, options={"scenario": matching})
        vector = gym.make_vec(
            "DebrisGym/Rendezvous2D-v0",
            num_envs=2,
            vectorization_mode="vector_entry_point",
            delta_v_budget=None,
            n_obstacles=1,
            n_targets=1,
        )
        vector.reset(seed=0, options={"scenario": matching})
    other = DebrisFieldVectorEnv(num_envs=2, delta_v_budget=None)
    with pytest.warns(UserWarning, match=r"max_accel 0\.2 \(env 0\.05\)"):
        other.reset(
            seed=0, options={"scenario": simple_scenario(max_accel=0.2, mean_motion=env.config.n)}
        )
