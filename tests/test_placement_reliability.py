"""A random-field configuration the env accepts places on every seed; one the generator cannot
place reliably is refused when it is made or set, never in the middle of a run."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401 - registers the IDs
from debris_gym.config import EnvConfig
from debris_gym.envs.common import field_spec
from debris_gym.integrations.sb3 import NativeVecEnv
from debris_gym.orbit_fields import orbit_drawer
from debris_gym.registration import ENV_SPECS

V2 = {2: "DebrisGym/Rendezvous2D-v2", 3: "DebrisGym/Rendezvous3D-v2"}
V0 = {2: "DebrisGym/Rendezvous2D-v0", 3: "DebrisGym/Rendezvous3D-v0"}


def test_the_documented_lidar_example_places_every_seed():
    env = gym.make(V2[2], n_obstacles=50, observation="lidar")
    for seed in range(40):
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs)
    vector = gym.make_vec(
        V2[2], num_envs=16, vectorization_mode="vector_entry_point", n_obstacles=50,
        observation="lidar",
    )  # fmt: skip
    obs, _ = vector.reset(seed=0)
    assert obs.shape[0] == 16


def _crowded_drawer(wide_tries: int):
    cfg = EnvConfig.from_kwargs(**{**ENV_SPECS[V2[2]]["kwargs"], "n_obstacles": 50})
    return orbit_drawer(field_spec(cfg), cfg.capture_radius, wide_tries=wide_tries)


def test_wide_tries_place_what_the_narrow_ones_miss_and_change_nothing_else():
    words = np.random.SeedSequence(2024).generate_state(60, dtype=np.uint64)
    narrow = _crowded_drawer(wide_tries=0).place(words)
    wide = _crowded_drawer(wide_tries=32).place(words)
    assert not narrow.placed.all()  # 50 obstacles: 64 candidates miss on many seeds
    assert wide.placed.all()
    same = narrow.placed  # a field the narrow tries placed is the very same field
    for name in ("centers", "velocities", "radii", "vertices", "n_vertices", "spins"):
        np.testing.assert_array_equal(getattr(narrow, name)[same], getattr(wide, name)[same])


@pytest.mark.parametrize(("dim", "count"), [(2, 80), (3, 2000)])
def test_a_crowd_the_generator_cannot_place_is_refused_when_made_or_set(dim, count):
    with pytest.raises(ValueError, match=rf"cannot place.*n_obstacles={count}.*reliably"):
        gym.make(V2[dim], n_obstacles=count)
    env = gym.make(V2[dim])
    env.reset(seed=3)
    before = env.unwrapped.scenario
    with pytest.raises(ValueError, match="reliably"):
        env.reset(seed=4, options={"mission": {"n_obstacles": count}})
    assert env.unwrapped.scenario is before  # the refused reset changed nothing
    env.step(env.action_space.sample())


MISSIONS = st.tuples(
    st.sampled_from([2, 3]),
    st.sampled_from(["v0", "v2"]),
    st.integers(1, 20),
    st.one_of(st.integers(0, 150), st.integers(0, 2000)),
)


@settings(max_examples=24, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mission=MISSIONS)
def test_a_mission_size_the_env_accepts_resets_on_every_seed(mission):
    dim, version, n_targets, n_obstacles = mission
    env_id = (V2 if version == "v2" else V0)[dim]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the v0 IDs say they are old
        try:
            env = gym.make(env_id, n_targets=n_targets, n_obstacles=n_obstacles)
        except ValueError as err:
            assert "reliably" in str(err) or "no room" in str(err) or "cannot place" in str(err)
            return
    for seed in range(6):
        env.reset(seed=seed)
        assert len(env.unwrapped.scenario.obstacles) == n_obstacles


def test_set_mission_refuses_a_crowd_now_and_takes_one_that_places():
    venv = NativeVecEnv(V2[2], 4)
    venv.reset()
    with pytest.raises(ValueError, match="reliably"):
        venv.set_mission({"n_obstacles": 80})
    venv.step(np.zeros((4, 2), dtype=np.float32))  # still on its own mission
    venv.set_mission({"n_obstacles": 50})
    for _ in range(3):  # the restart on the crowded mission places every sub-env's field
        venv.step(np.zeros((4, 2), dtype=np.float32))
    venv.close()
