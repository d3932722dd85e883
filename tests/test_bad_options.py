"""Bad env options, reset options and actions: each gets a ``ValueError`` naming the key before
anything runs or changes (docs/validation.md, "Env options, actions and reset")."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from fractions import Fraction
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import debris_gym  # noqa: F401  (registers the IDs)
from debris_gym import solvability
from debris_gym.config import MAX_WEIGHT, OPTIONS, EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.debris_field import TRAIL_LENGTH
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.generators import FieldSpec, random_field
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Body, Scenario
from debris_gym.solvability import occupancy_grid
from tests.helpers import flies_old_ids, simple_scenario

ID = "DebrisGym/Rendezvous2D-v0"
ROOT = Path(__file__).resolve().parents[1]
PUSH = np.array([0.6, -0.3])
WEIGHTS = [k for k in OPTIONS if k.startswith("reward_")]
WEIGHTS += ["shaping_speed", "shaping_clearance", "shaping_closing"]


# --- whole numbers, order of checks, upper bounds --------------------------------------------


def test_a_whole_float_for_an_integer_key_is_stored_as_the_integer():
    cfg = EnvConfig(n_targets=3.0, n_obstacles=np.float64(20.0), dim=2.0, obs_targets=np.int64(3))
    for key in ("n_targets", "n_obstacles", "dim", "obs_targets"):
        assert type(getattr(cfg, key)) is int, key
    assert cfg == EnvConfig()
    a, b = DebrisFieldEnv(n_targets=3.0), DebrisFieldEnv()
    obs_a, _ = a.reset(seed=5)
    obs_b, _ = b.reset(seed=5)
    assert a.scenario == b.scenario  # the same seeded field
    np.testing.assert_array_equal(obs_a, obs_b)


def test_a_whole_float_does_not_poison_later_envs_in_the_process():
    # a fresh process: the generator's caches start empty, as in the reproducer
    script = textwrap.dedent(
        f"""
        import gymnasium as gym
        import debris_gym
        gym.make({ID!r}, n_targets=3.0).reset(seed=0)
        gym.make({ID!r}).reset(seed=0)
        gym.make({ID!r}, n_targets=3).reset(seed=0)
        print("three resets")
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    assert "three resets" in proc.stdout


def test_a_field_spec_with_a_float_count_is_refused():
    with pytest.raises(ValueError, match="n_targets"):
        FieldSpec(n_targets=3.0)


@flies_old_ids
@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("n_targets", math.inf),
        ("n_targets", -math.inf),
        ("n_targets", math.nan),
        ("n_targets", 2.5),
        ("n_targets", "3"),
        ("n_targets", None),
        ("n_targets", True),
        ("n_targets", 3 + 0j),
        ("n_targets", 10**400),
        ("n_obstacles", -1),
        ("obs_targets", 3.5),
        ("dim", 2.5),
        ("dim", 4.0),
        ("collision_substeps", 1e300),
        ("obstacle_radius_max", 1e200),
        ("target_radius_max", 1e200),
        ("capture_radius", 1e300),
        ("chaser_radius", 1e300),
        ("lidar_range", 1e300),
        ("capture_speed", 1e300),
        ("delta_v_budget", 1e300),
        ("dt", Fraction(10**400)),
        ("dt", np.float32("nan")),
        ("field_size", [1000.0]),
        ("return_to_dock", 1),
        ("observation", 3),
        *((key, 1e308) for key in WEIGHTS),
    ],
)
def test_a_bad_value_is_a_value_error_naming_the_key_and_the_range(key, value):
    with pytest.raises(ValueError, match=rf"{key}.*allowed") as caught:
        gym.make(ID, **{key: value})
    assert len(str(caught.value)) < 400  # readable, even for a 400-digit integer


def test_every_numeric_option_has_an_upper_bound():
    unbounded = [k for k, o in OPTIONS.items() if o.choices is None and o.high is None]
    assert unbounded == []


@pytest.mark.parametrize(
    "key", ["obstacle_radius_max", "target_radius_max", "min_gap", "capture_radius"]
)
def test_random_field_lengths_are_bounded_by_the_world(key):
    kwargs = {"field_size": 200.0, "obstacle_radius_max": 25.0, "min_gap": 10.0, key: 50.5}
    if key == "target_radius_max":
        kwargs["target_radius_min"] = 3.0
    with pytest.raises(ValueError, match=rf"{key}=50.5 m is too large for field_size=200.0") as e:
        EnvConfig(**kwargs)
    assert "[" in str(e.value) and "50" in str(e.value)  # the allowed range, up to 50 m
    EnvConfig(**{**kwargs, key: 50.0})  # a quarter of the world is still allowed


def test_the_paper_world_ignores_the_random_field_lengths():
    env = gym.make("DebrisGym/PaperField2D-v0")  # field_size 20 with 25 m obstacle radii
    env.reset(seed=0)
    assert env.unwrapped.config.obstacle_radius_max > env.unwrapped.config.field_size / 4


def test_rewards_stay_finite_at_the_largest_weights():
    weights = dict.fromkeys(WEIGHTS, MAX_WEIGHT)
    env = DebrisFieldEnv(max_accel=100.0, dt=600.0, delta_v_budget=None, **weights)
    env.reset(seed=1)
    rewards = []
    for _ in range(20):
        _, reward, terminated, _, info = env.step(PUSH)
        rewards.append(reward)
        assert all(math.isfinite(v) for v in info["reward_terms"].values())
        if terminated:
            break
    assert np.isfinite(rewards).all()


# --- the crowded field: same grid, bounded cost ----------------------------------------------


def all_cells_against_all_bodies(scenario, inflate, cell):
    """The occupancy grid by testing every cell against every body (the reference)."""
    axes = [np.arange(lo + cell / 2.0, hi, cell) for lo, hi in scenario.bounds]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    gaps = FieldGeometry(scenario).signed_distance(points.reshape(-1, scenario.dim))
    return (gaps <= inflate).any(axis=1).reshape(points.shape[:-1])


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_the_tiled_occupancy_grid_is_the_all_pairs_grid(dim, seed):
    spec = FieldSpec(dim=dim, n_obstacles=40, field_size=600.0, min_gap=0.0, chaser_radius=0.0)
    scen = random_field(
        np.random.default_rng(seed), spec, mean_motion=0.0, dt=1.0, max_accel=1.0,
        capture_radius=5.0,
    )  # fmt: skip
    cells = 150 if dim == 2 else 30
    for inflate in (0.0, 3.0, 40.0):
        grid, _ = occupancy_grid(scen, inflate, scen.size / cells)
        reference = all_cells_against_all_bodies(scen, inflate, scen.size / cells)
        np.testing.assert_array_equal(grid, reference)
        assert grid.any() and not grid.all()


def test_the_route_proof_in_chunks_answers_each_field_as_alone(monkeypatch):
    rng = np.random.default_rng(3)
    centers = rng.uniform(-400.0, 400.0, (9, 12, 2))
    radii = rng.uniform(2.0, 30.0, (9, 12))
    args = (3, np.full(2, -500.0), np.full(2, 500.0), np.zeros(2), 1.0, 5.0)
    whole = solvability.route_proof(centers, radii, *args)
    monkeypatch.setattr(solvability, "PROOF_PAIRS", 2 * 12 * 12)  # two fields per chunk
    np.testing.assert_array_equal(solvability.route_proof(centers, radii, *args), whole)
    assert whole.any() and not whole.all()


@flies_old_ids
@pytest.mark.slow
def test_a_crowded_field_without_gaps_resets():
    # seconds, not minutes, per reset of a field this crowded (docs/validation.md)
    env = gym.make(ID, n_obstacles=2000, field_size=2e4, min_gap=0.0)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_an_integer_key_as_a_json_float_runs_through_evaluate(tmp_path):
    proc = subprocess.run(
        [
            sys.executable, "evaluate.py", "--episodes", "1", "--agents", "zero",
            "--max-steps", "3", "--plots", "0", "--no-progress", "--out", str(tmp_path / "out"),
            "--env-kwargs", json.dumps({"n_targets": 3.0, "n_obstacles": 5}),
        ],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr


# --- transactional reset ---------------------------------------------------------------------


def stepped_single(seed: int = 0) -> DebrisFieldEnv:
    env = DebrisFieldEnv()
    env.reset(seed=seed)
    for _ in range(3):
        env.step(PUSH)
    return env


def bad_reset_options(env_config: EnvConfig) -> list[dict]:
    pinned = simple_scenario(mean_motion=env_config.n)  # the env's physics: no warning
    target = Body(position=(0.0, 100.0, 0.0), radius=5.0, velocity=(0.0, 0.0, 0.0))
    space = Scenario(
        dim=3, bounds=((-500.0, 500.0),) * 3, dock=(0.0,) * 3, targets=(target,),
        mean_motion=env_config.n, dt=env_config.dt, max_accel=env_config.max_accel,
    )  # fmt: skip
    return [
        {"chaser_state": [9999.0, 0.0, 0.0, 0.0]},  # outside the new field's bounds
        {"chaser_state": [0.0, 0.0, 1e300, 0.0]},  # far too fast
        {"chaser_state": [0.0, 0.0, 0.0, 0.0], "scenario": space},  # a 3D field
        {"chaser_state": [200.0, 0.0, 0.0, 0.0], "scenario": pinned},  # inside its obstacle
        {"chaser_state": [0.0, 0.0, 0.0]},
        {"chaser_state": ["a", "b", "c", "d"]},
        {"chaser_state": [0.0, 0.0, 0.0, 0.0], "bogus": 1},
    ]


@pytest.mark.parametrize("case", range(7))
def test_a_failed_reset_leaves_the_single_env_as_it_was(case):
    env, twin = stepped_single(), stepped_single()
    options = bad_reset_options(env.config)[case]
    scenario, state, clock = env.scenario, env.chaser_state, env.elapsed
    with pytest.raises(ValueError, match=r"chaser_state|dim|bogus"):
        env.reset(seed=123, options=options)
    assert env.scenario is scenario and env.elapsed == clock
    np.testing.assert_array_equal(env.chaser_state, state)  # nothing propagated
    for _ in range(5):  # stepping goes on exactly as in the env that never saw the reset
        got, want = env.step(PUSH), twin.step(PUSH)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1:4] == want[1:4]
    env.reset()  # the generator too: the same next field as the twin's
    twin.reset()
    assert env.scenario == twin.scenario


def test_a_pinned_field_whose_dock_touches_the_chaser_is_refused():
    # the dock is 2 m from an obstacle's surface, inside a 5 m chaser: the episode would start
    # in contact (it was accepted, with a negative clearance, and collided on the first step)
    near = Body(position=(22.0, 0.0), radius=20.0, velocity=(0.0, 0.0))
    for env in (DebrisFieldEnv(chaser_radius=5.0), DebrisFieldVectorEnv(2, chaser_radius=5.0)):
        scen = simple_scenario(mean_motion=env.config.n, obstacles=(near,))
        with pytest.raises(ValueError, match=r"dock.*chaser radius 5\.0 m"):
            env.reset(seed=0, options={"scenario": scen})
        env.reset(seed=0, options={"scenario": scen, "chaser_state": [-10.0, 0.0, 0.0, 0.0]})


def test_a_failed_first_reset_leaves_the_env_unreset():
    env = DebrisFieldEnv()
    with pytest.raises(ValueError, match="chaser_state"):
        env.reset(seed=0, options={"chaser_state": [9999.0, 0.0, 0.0, 0.0]})
    with pytest.raises(RuntimeError, match="reset"):
        env.step(PUSH)


def test_options_must_be_a_dict():
    with pytest.raises(ValueError, match="options must be a dict"):
        DebrisFieldEnv().reset(seed=0, options=[("chaser_state", [0, 0, 0, 0])])


@pytest.mark.parametrize("seed", ["a", -1, 1.5, True])
def test_a_bad_seed_is_a_value_error_and_changes_nothing(seed):
    env, twin = stepped_single(), stepped_single()
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=seed)
    np.testing.assert_array_equal(env.step(PUSH)[0], twin.step(PUSH)[0])
    vector = stepped_vector()
    with pytest.raises(ValueError, match="seed"):
        vector.reset(seed=seed)
    with pytest.raises(ValueError, match=r"seed\[1\]"):
        vector.reset(seed=[0, seed])


def test_chaser_speed_is_bounded_by_the_world_over_dt():
    env = DebrisFieldEnv()  # 1000 m world, dt 10 s: at most 100 m/s
    env.reset(seed=0, options={"chaser_state": [0.0, 0.0, 60.0, -79.0]})  # 99.4 m/s
    with pytest.raises(ValueError, match=r"chaser_state velocity .* allowed: speed <= 100 m/s"):
        env.reset(seed=0, options={"chaser_state": [0.0, 0.0, 60.0, -81.0]})  # 100.8 m/s


def stepped_vector(n: int = 2) -> DebrisFieldVectorEnv:
    env = DebrisFieldVectorEnv(num_envs=n)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.tile(PUSH, (n, 1)))
    return env


@pytest.mark.parametrize("case", range(7))
def test_a_failed_reset_leaves_the_vector_env_as_it_was(case):
    env, twin = stepped_vector(), stepped_vector()
    options = bad_reset_options(env.config)[case]
    batch = env.batch
    before = {k: getattr(batch.missions, k).copy() for k in ("state", "time", "captured")}
    centers = batch.field.centers.copy()
    with pytest.raises(ValueError, match=r"chaser_state|dim|bogus|must share"):
        env.reset(seed=123, options=options)
    assert env.batch is batch
    for key, value in before.items():
        np.testing.assert_array_equal(getattr(batch.missions, key), value)
    np.testing.assert_array_equal(batch.field.centers, centers)
    actions = np.tile(PUSH, (2, 1))
    for _ in range(5):
        got, want = env.step(actions), twin.step(actions)
        for g, w in zip(got[:4], want[:4]):
            np.testing.assert_array_equal(g, w)
    env.reset()
    twin.reset()
    np.testing.assert_array_equal(env.batch.field.centers, twin.batch.field.centers)


def test_a_vector_reset_with_one_bad_state_of_many_names_the_sub_env():
    env = stepped_vector(3)
    states = np.zeros((3, 4))
    states[2, 2] = 1e300
    with pytest.raises(ValueError, match="chaser_state of sub-env 2 velocity"):
        env.reset(seed=1, options={"chaser_state": states})


def test_a_vector_reset_refuses_a_bad_seed_list():
    env = stepped_vector(2)
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed="12")
    with pytest.raises(ValueError, match="seed list"):
        env.reset(seed=[1, 2, 3])


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"num_envs": True}, "num_envs"),
        ({"num_envs": 2.0}, "num_envs"),
        ({"max_episode_steps": "5"}, "max_episode_steps"),
        ({"max_episode_steps": 2.5}, "max_episode_steps"),
        ({"autoreset_mode": "sometimes"}, "autoreset_mode"),
    ],
)
def test_bad_vector_env_arguments_are_value_errors_naming_them(kwargs, key):
    with pytest.raises(ValueError, match=key):
        DebrisFieldVectorEnv(**{"num_envs": 2, **kwargs})


# --- bounded trail, action types -------------------------------------------------------------


def test_the_trail_keeps_the_last_positions_without_a_time_limit():
    env = DebrisFieldEnv(delta_v_budget=None)  # no TimeLimit: built directly
    env.reset(seed=0)
    for _ in range(TRAIL_LENGTH + 50):
        env.step(np.zeros(2))  # coasting at the dock: the episode never ends
    assert env.trail.shape == (TRAIL_LENGTH, 2)
    np.testing.assert_array_equal(env.trail[-1], env.chaser_state[:2])


BAD_CONTINUOUS = [
    np.array([np.nan, 0.0], dtype=np.float32),
    np.array([np.inf, 0.0], dtype=np.float32),
    np.array([0.0, 0.0, 0.0], dtype=np.float32),
    np.array([[0.1, 0.2]], dtype=np.float32),
    np.array([0.5 + 0.5j, 0.0]),
    np.array(["0.5", "0.0"]),
    ["0.5", 0.0],
    np.ma.masked_array([0.5, 0.0], mask=[False, True]),
    np.array([True, False]),
    np.array([0.5, None], dtype=object),
    [[0.5], 0.0],
    "0.5",
    None,
]


@pytest.mark.parametrize("action", BAD_CONTINUOUS, ids=range(len(BAD_CONTINUOUS)))
def test_a_bad_continuous_action_is_refused_and_changes_nothing(action):
    env = DebrisFieldEnv()
    env.reset(seed=0)
    state = env.chaser_state
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    np.testing.assert_array_equal(env.chaser_state, state)


BAD_DISCRETE = [1 + 0j, "1", np.ma.masked_array([1], mask=[True]), True, np.array([1.5]), None]


@pytest.mark.parametrize("action", BAD_DISCRETE, ids=range(len(BAD_DISCRETE)))
def test_a_non_integer_discrete_action_is_refused(action):
    env = DebrisFieldEnv(action="discrete")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


@pytest.mark.parametrize("action", ["continuous", "discrete"])
def test_the_vector_env_refuses_non_real_actions(action):
    env = DebrisFieldVectorEnv(num_envs=2, action=action)
    env.reset(seed=0)
    state = env.batch.missions.state.copy()
    good = np.zeros((2, 2)) if action == "continuous" else np.zeros(2, dtype=np.int64)
    for bad in (
        good.astype(complex),
        good.astype(str),
        np.ma.masked_array(good, mask=np.ones_like(good, dtype=bool)),
        good.astype(bool),
    ):
        with pytest.raises(ValueError, match="action"):
            env.step(bad)
    np.testing.assert_array_equal(env.batch.missions.state, state)


def test_a_huge_action_is_full_thrust_in_its_direction():
    env, twin = DebrisFieldEnv(), DebrisFieldEnv()
    env.reset(seed=0)
    twin.reset(seed=0)
    _, _, _, _, info = env.step(np.array([1e200, 0.0]))
    _, _, _, _, want = twin.step(np.array([1.0, 0.0]))
    np.testing.assert_array_equal(info["applied_accel"], want["applied_accel"])
    assert info["applied_accel"][0] == env.config.max_accel


def test_the_thrust_model_keeps_a_huge_ball_actions_direction():
    from debris_gym.thrust import commanded_accel

    huge = np.array([[3e200, -4e200], [1e160, 0.0], [0.6, -0.8]])
    np.testing.assert_allclose(
        commanded_accel(huge, 0.05, "ball"), 0.05 * np.array([[0.6, -0.8], [1.0, 0.0], [0.6, -0.8]])
    )


def test_an_option_gives_its_limits_only_when_bounded_on_both_sides():
    """``Option.limits()`` is ``(low, high)`` of a numeric key; a categorical key has none and
    says so with a TypeError instead of handing out None."""
    size = OPTIONS["field_size"]
    assert size.limits() == (size.low, size.high) and size.low is not None
    with pytest.raises(TypeError, match="unbounded"):
        OPTIONS["observation"].limits()
