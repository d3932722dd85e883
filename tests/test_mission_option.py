"""The difficulty rungs of v2 (and of v1) and the ``reset(options={"mission": ...})`` that moves an
env between them: a curriculum is an env feature of the single env, the native vector env and
its SB3 adapter."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import debris_gym
from debris_gym.integrations.sb3 import NativeVecEnv
from debris_gym.registration import EASY_MISSION, MEDIUM_MISSION
from tests.helpers import flies_old_ids

DEFAULT = "DebrisGym/Rendezvous2D-v2"
RUNGS = {
    "DebrisGym/Rendezvous2D-Easy-v2": EASY_MISSION,
    "DebrisGym/Rendezvous2D-Medium-v2": MEDIUM_MISSION,
    "DebrisGym/Rendezvous3D-Easy-v2": EASY_MISSION,
    "DebrisGym/Rendezvous3D-Medium-v2": MEDIUM_MISSION,
}
OLD_RUNGS = {rung.replace("-v2", "-v1"): mission for rung, mission in RUNGS.items()}
"""The v1 rungs, kept for reproducing v1 figures."""


def fly(env, actions, **reset):
    """Observations, rewards and ends of a fixed action sequence (stops at the episode's end)."""
    obs, info = env.reset(**reset)
    trace = [obs.copy()]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        trace += [obs.copy(), reward, terminated, truncated]
        if terminated or truncated:
            break
    return trace, info


def same(a, b) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize(
    "rung, mission",
    [*RUNGS.items(), *(pytest.param(*item, marks=flies_old_ids) for item in OLD_RUNGS.items())],
)
def test_a_rung_is_its_world_with_a_mission_option(rung, mission):
    """The rung's ID and its version's default ID reset with the rung's mission fly
    bit-identical episodes."""
    base = rung.replace("-Easy", "").replace("-Medium", "")
    dim = 2 if "2D" in rung else 3
    actions = np.random.default_rng(3).uniform(-1, 1, (150, dim)).astype(np.float32)
    ladder, info = fly(gym.make(rung), actions, seed=11)
    pinned, _ = fly(gym.make(base), actions, seed=11, options={"mission": mission})
    assert same(ladder, pinned)
    assert info["n_targets"] == mission["n_targets"]


def test_the_rungs_change_only_the_mission():
    """Physics, rules, reward weights and spaces are those of the default ID; only the mission
    keys differ."""
    default = gym.make(DEFAULT)
    for rung, mission in RUNGS.items():
        if "3D" in rung:
            continue
        env = gym.make(rung)
        differ = {
            key for key, value in env.unwrapped.config.to_dict().items()
            if value != default.unwrapped.config.to_dict()[key]
        }  # fmt: skip
        assert differ == {
            k for k, v in mission.items() if default.unwrapped.config.to_dict()[k] != v
        }
        assert env.observation_space == default.observation_space
        assert env.action_space == default.action_space


def test_a_mission_holds_until_another_is_named():
    env = gym.make(DEFAULT)
    _, info = env.reset(seed=0)
    assert (info["n_targets"], len(env.unwrapped.scenario.obstacles)) == (3, 20)
    _, info = env.reset(seed=0, options={"mission": EASY_MISSION})
    assert (info["n_targets"], len(env.unwrapped.scenario.obstacles)) == (1, 5)
    assert not env.unwrapped.config.return_to_dock
    _, info = env.reset(seed=1)  # no option: the rung stays
    assert info["n_targets"] == 1
    _, info = env.reset(seed=1, options={"mission": {"n_targets": 2}})  # keys not named: made
    assert (info["n_targets"], len(env.unwrapped.scenario.obstacles)) == (2, 20)
    assert env.unwrapped.config.return_to_dock
    _, info = env.reset(seed=0, options={"mission": {}})
    assert info["n_targets"] == 3
    assert env.unwrapped.config == env.unwrapped.made_config


def test_the_easy_mission_ends_at_the_capture_without_returning():
    """Easy's success is one capture: the rung's rule, seen from outside through `is_success`."""
    env = gym.make("DebrisGym/Rendezvous2D-Easy-v2")
    from agents import make_agent

    agent = make_agent("apf-mpc", env)
    obs, info = env.reset(seed=4)
    for _ in range(1000):
        obs, _, terminated, truncated, info = env.step(agent.predict(obs)[0])
        if terminated or truncated:
            break
    assert info["is_success"] and info["targets_captured"] == 1
    assert np.linalg.norm(info["chaser_state"][:2]) > 50.0  # far from the dock at the end


@pytest.mark.parametrize(
    "mission, message",
    [
        ({"dt": 5.0}, "may change only n_targets, n_obstacles, return_to_dock"),
        ({"n_targets": 0}, "n_targets=0 is out of range"),
        ({"n_obstacles": 1.5}, "n_obstacles must be a whole number"),
        ({"return_to_dock": "no"}, "return_to_dock='no' is not allowed"),
        ([1, 2], "options['mission'] must be a dict"),
    ],
)
def test_bad_missions_are_refused_and_leave_the_env_as_it_was(mission, message):
    env = gym.make(DEFAULT)
    env.reset(seed=2)
    reference = gym.make(DEFAULT)
    reference.reset(seed=2)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        env.reset(seed=9, options={"mission": mission})
    action = np.array([0.3, -0.2], dtype=np.float32)
    for _ in range(20):  # the env steps on exactly as an untouched one
        a, b = env.step(action), reference.step(action)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]


@settings(max_examples=25, deadline=None)
@given(
    n_targets=st.integers(1, 5),
    n_obstacles=st.integers(0, 25),
    return_to_dock=st.booleans(),
    seed=st.integers(0, 2**31),
)
def test_any_valid_mission_gives_its_field_and_keeps_the_spaces(
    n_targets, n_obstacles, return_to_dock, seed
):
    env = gym.make(DEFAULT)
    mission = {"n_targets": n_targets, "n_obstacles": n_obstacles, "return_to_dock": return_to_dock}
    obs, info = env.reset(seed=seed, options={"mission": mission})
    scenario = env.unwrapped.scenario
    assert (len(scenario.targets), len(scenario.obstacles)) == (n_targets, n_obstacles)
    assert info["n_targets"] == n_targets
    assert env.observation_space.contains(obs)
    assert env.unwrapped.observation_names() == gym.make(DEFAULT).unwrapped.observation_names()


def vector(n: int, **kwargs):
    return gym.make_vec(DEFAULT, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def test_the_vector_env_takes_a_mission_at_reset_and_keeps_it_through_autoresets():
    venv = vector(3)
    _, info = venv.reset(seed=0, options={"mission": EASY_MISSION})
    assert list(info["n_targets"]) == [1, 1, 1]
    singles = [gym.make("DebrisGym/Rendezvous2D-Easy-v2") for _ in range(3)]
    first = [s.reset(seed=i)[0] for i, s in enumerate(singles)]
    assert np.array_equal(venv.reset(seed=0, options={"mission": EASY_MISSION})[0], first)
    ended = np.zeros(3, dtype=bool)
    for _ in range(1001):  # zero thrust: every episode ends by the limit, then autoresets
        _, _, terminated, truncated, info = venv.step(np.zeros((3, 2), dtype=np.float32))
        ended |= terminated | truncated
    assert ended.all() and list(info["n_targets"]) == [1, 1, 1]
    _, info = venv.reset(options={"mission": {}})
    assert list(info["n_targets"]) == [3, 3, 3]


def test_a_bad_mission_leaves_the_vector_env_as_it_was():
    venv, reference = vector(2), vector(2)
    venv.reset(seed=5, options={"mission": EASY_MISSION})
    reference.reset(seed=5, options={"mission": EASY_MISSION})
    with pytest.raises(ValueError, match="n_obstacles"):
        venv.reset(seed=1, options={"mission": {"n_obstacles": -3}})
    actions = np.full((2, 2), 0.5, dtype=np.float32)
    for _ in range(10):
        assert np.array_equal(venv.step(actions)[0], reference.step(actions)[0])


def test_the_sb3_adapter_changes_rung_at_the_next_step_by_truncating():
    """`set_mission` mid-rollout: every running episode ends truncated (learners bootstrap it)
    with its last observation, and every sub-env goes on in the new rung."""
    venv = NativeVecEnv(DEFAULT, 4)
    venv.seed(0)
    obs = venv.reset()
    actions = np.zeros((4, 2), dtype=np.float32)
    for _ in range(3):
        obs, _, dones, _ = venv.step(actions)
    assert not dones.any()
    running = obs.copy()
    venv.set_mission(EASY_MISSION)
    obs, _, dones, infos = venv.step(actions)
    assert dones.all()
    assert all(info["TimeLimit.truncated"] for info in infos)
    # the terminal observation is the old rung's next observation, not the new one
    assert not np.array_equal(np.stack([i["terminal_observation"] for i in infos]), obs)
    assert np.stack([i["terminal_observation"] for i in infos]).shape == running.shape
    obs, _, dones, infos = venv.step(actions)
    assert [info["n_targets"] for info in infos] == [1, 1, 1, 1]
    with pytest.raises(ValueError, match="n_targets"):
        venv.set_mission({"n_targets": 99})


def test_set_mission_reaches_the_adapter_through_sb3_wrappers():
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    wrapped = VecNormalize(VecMonitor(NativeVecEnv(DEFAULT, 2)))
    wrapped.reset()
    wrapped.set_mission({"n_targets": 2})
    wrapped.step(np.zeros((2, 2), dtype=np.float32))
    _, _, _, infos = wrapped.step(np.zeros((2, 2), dtype=np.float32))
    assert [info["n_targets"] for info in infos] == [2, 2]


def test_every_rung_is_documented_with_its_mission():
    assert set(RUNGS) <= set(debris_gym.ENV_SPECS)


def test_a_mission_where_it_cannot_apply_is_refused_not_ignored():
    """Regression: a mission on the paper world or beside a pinned field was accepted and
    ignored, while ``config`` reported a mission the field did not have."""
    paper = gym.make("DebrisGym/PaperField2D-v0")
    with pytest.raises(ValueError, match="paper world"):
        paper.reset(seed=0, options={"mission": {"n_targets": 1}})
    assert paper.unwrapped.config == paper.unwrapped.made_config
    paper.reset(seed=0, options={"mission": {}})  # the env's own mission: nothing to refuse
    vector = gym.make_vec(
        "DebrisGym/PaperField2D-v0", num_envs=2, vectorization_mode="vector_entry_point"
    )
    with pytest.raises(ValueError, match="paper world"):
        vector.reset(seed=0, options={"mission": {"n_targets": 1}})
    adapter = NativeVecEnv("DebrisGym/PaperField2D-v0", num_envs=2)
    with pytest.raises(ValueError, match="paper world"):
        adapter.set_mission({"n_targets": 1})
    env = gym.make(DEFAULT)
    env.reset(seed=0)
    pinned = env.unwrapped.scenario
    with pytest.raises(ValueError, match="one or the other"):
        env.reset(options={"scenario": pinned, "mission": EASY_MISSION})
    assert env.unwrapped.config == env.unwrapped.made_config
