"""agents.experiments.her: the goal-conditioned wrapper's spaces and reward (against the env's own
capture rule on real steps, vectorised, on random goals), bad input, and a tiny SAC+HER run
flown through evaluate_agents and the ``LABEL=MODULE:ATTR`` route of evaluate.py."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

pytest.importorskip("stable_baselines3")

import debris_gym  # noqa: F401
from agents.experiments.evaluation import build_agent, evaluate_agents
from agents.experiments.her import (
    DEFAULT_CRASH_PENALTY,
    MODEL_ENV_VAR,
    GoalConditionedEnv,
    GoalPolicy,
    load_policy,
    policy,
)
from agents.experiments.her.__main__ import main
from agents.experiments.her.train import CURVE_COLUMNS, SacOptions, train_sac

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
SMALL = float(np.float32(0.01))  # hypothesis wants float32 bounds exactly representable


@pytest.fixture(scope="module")
def goal_env() -> GoalConditionedEnv:
    env = GoalConditionedEnv(gym.make(EASY))
    yield env
    env.close()


def fly(env: GoalConditionedEnv, act, seed: int):
    """One episode through the wrapper: rewards, achieved and desired goals, infos."""
    obs, _ = env.reset(seed=seed)
    rewards, achieved, desired, infos = [], [], [], []
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(act(obs))
        rewards.append(reward)
        achieved.append(obs["achieved_goal"])
        desired.append(obs["desired_goal"])
        infos.append(info)
        done = terminated or truncated
    return np.array(rewards, np.float32), np.array(achieved), np.array(desired), infos


@pytest.mark.parametrize("env_id, size", [(EASY, 5), ("DebrisGym/Rendezvous3D-Easy-v2", 7)])
def test_spaces(env_id, size):
    env = GoalConditionedEnv(gym.make(env_id))
    assert isinstance(env.observation_space, gym.spaces.Dict)
    assert set(env.observation_space.spaces) == {"observation", "achieved_goal", "desired_goal"}
    assert env.observation_space["observation"] == env.env.observation_space
    assert env.observation_space["desired_goal"].shape == (size,)
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert obs["achieved_goal"][-1] == 0.0  # the chaser is a point goal
    assert obs["desired_goal"][-1] > 0.0  # the target's radius / L
    # the desired goal is the target's state: the env's own, scaled like the observation
    base = env.unwrapped
    dim, half = base.config.dim, base.config.field_size / 2
    bodies = np.asarray(base.body_states)[:, :dim]
    gaps = np.linalg.norm(bodies - obs["desired_goal"][:dim] * half, axis=1)
    assert gaps.min() < 1e-2  # one of the bodies: the target
    np.testing.assert_allclose(
        obs["achieved_goal"][:dim] * half, base.chaser_state[:dim], atol=1e-2
    )
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    env.close()


def test_reward_is_the_capture_rule_on_real_steps(goal_env):
    """APF flies to captures: the step reward is 0 exactly on the step ends the env counts
    toward a hold (``info["hold"]`` ≥ 1: in capture range and speed; v2 starts the count again
    when the chaser drifts from where the hold began), -1 elsewhere, and the episode ends with
    the capture's 4 held step ends (capture_hold 30 s at dt 10 s); compute_reward over the whole
    episode at once gives the same rewards."""
    for seed in range(3):
        agent = build_agent("apf", goal_env.env)
        rewards, achieved, desired, infos = fly(
            goal_env, lambda o, a=agent: a.predict(o["observation"], deterministic=True)[0], seed
        )
        assert infos[-1]["is_success"]
        held = np.array([info["hold"][0] for info in infos])
        assert list(held[-4:]) == [1, 2, 3, 4]
        expected = np.where(held >= 1, 0.0, -1.0).astype(np.float32)
        np.testing.assert_array_equal(rewards, expected)
        batch = goal_env.compute_reward(achieved, desired, infos)
        assert batch.shape == rewards.shape and batch.dtype == np.float32
        np.testing.assert_array_equal(batch, rewards)
        # one pair at a time gives the same
        for i in (0, len(rewards) - 1):
            assert goal_env.compute_reward(achieved[i], desired[i], infos[i]) == rewards[i]


def test_crash_is_penalised_whatever_the_goal(goal_env):
    """Full thrust away from the field ends in a collision or out of bounds: -penalty on that
    step, and on that step with any goal (relabelled to the achieved goal itself included)."""
    found = False
    for seed in range(10):
        rewards, achieved, desired, infos = fly(goal_env, lambda o: np.array([1.0, 1.0]), seed)
        last = infos[-1]
        if last["collision"] or last["out_of_bounds"]:
            found = True
            assert rewards[-1] == -DEFAULT_CRASH_PENALTY
            assert set(np.unique(rewards[:-1])) <= {-1.0, 0.0}
            relabelled = goal_env.compute_reward(achieved, achieved, infos)
            assert relabelled[-1] == -DEFAULT_CRASH_PENALTY
            assert np.all(relabelled[:-1] == 0.0)  # a goal the chaser is at is reached
            break
    assert found, "no crash in 10 full-thrust episodes"


@settings(max_examples=60, deadline=None)
@given(
    data=st.data(),
    batch=hnp.array_shapes(min_dims=1, max_dims=2, max_side=6),
)
def test_compute_reward_on_random_goals(goal_env, data, batch):
    goals = hnp.arrays(
        np.float32,
        (*batch, 5),
        elements=st.floats(-1.0, 1.0, width=32),
    )
    achieved, desired = data.draw(goals), data.draw(goals)
    # near pairs too, so 0 rewards occur
    near = data.draw(hnp.arrays(np.bool_, batch))
    desired[near] = (
        achieved[near]
        + data.draw(
            hnp.arrays(np.float32, (*batch, 5), elements=st.floats(-SMALL, SMALL, width=32))
        )[near]
    )
    crashed = data.draw(hnp.arrays(np.bool_, batch))
    infos = np.array([{"collision": bool(c), "out_of_bounds": False} for c in crashed.ravel()])
    reward = goal_env.compute_reward(achieved, desired, infos)
    assert reward.shape == batch and reward.dtype == np.float32
    assert set(np.unique(reward)) <= {-DEFAULT_CRASH_PENALTY, -1.0, 0.0}
    assert np.all(reward[crashed] == -DEFAULT_CRASH_PENALTY)
    # vectorised = one pair at a time
    flat_a, flat_d = achieved.reshape(-1, 5), desired.reshape(-1, 5)
    one_by_one = [
        goal_env.compute_reward(a, d, info)
        for a, d, info in zip(flat_a, flat_d, infos, strict=True)
    ]
    np.testing.assert_array_equal(reward.ravel(), np.array(one_by_one, np.float32))
    # without infos: no penalty; a goal equal to the achieved one is reached
    plain = goal_env.compute_reward(achieved, desired, None)
    assert set(np.unique(plain)) <= {-1.0, 0.0}
    assert np.all(goal_env.compute_reward(achieved, achieved, None) == 0.0)


def test_bad_input(goal_env):
    good = np.zeros((3, 5), np.float32)
    with pytest.raises(ValueError, match="achieved_goal: last axis of length 5"):
        goal_env.compute_reward(np.zeros((3, 4)), good, None)
    with pytest.raises(ValueError, match="desired_goal: last axis"):
        goal_env.compute_reward(good, np.float32(0.0), None)
    with pytest.raises(ValueError, match="desired_goal: shape"):
        goal_env.compute_reward(good, np.zeros((2, 5)), None)
    with pytest.raises(ValueError, match="achieved_goal: finite"):
        goal_env.compute_reward(np.full((3, 5), np.nan), good, None)
    with pytest.raises(ValueError, match="info: 3 dicts needed"):
        goal_env.compute_reward(good, good, [{}, {}])
    with pytest.raises(ValueError, match="info: one dict goes with one goal pair"):
        goal_env.compute_reward(good, good, {})
    with pytest.raises(ValueError, match=r"info\[1\]: a dict"):
        goal_env.compute_reward(good, good, [{}, 3, {}])
    with pytest.raises(ValueError, match="info: a dict, a sequence"):
        goal_env.compute_reward(good, good, 7)
    for penalty in (1.0, 0.5, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="crash_penalty"):
            GoalConditionedEnv(gym.make(EASY), crash_penalty=penalty)
    with pytest.raises(ValueError, match="env: one target and no return"):
        GoalConditionedEnv(gym.make("DebrisGym/Rendezvous2D-Medium-v2"))
    with pytest.raises(ValueError, match="env: a debris-gym env"):
        GoalConditionedEnv(gym.make("Pendulum-v1"))
    with pytest.raises(ValueError, match="obs: last axis"):
        goal_env.layout.goals(np.zeros(3))


def test_policy_adapter_errors(monkeypatch, tmp_path):
    monkeypatch.delenv(MODEL_ENV_VAR, raising=False)
    with pytest.raises(ValueError, match=MODEL_ENV_VAR):
        policy(gym.make(EASY))
    with pytest.raises(ValueError, match="path: no model file"):
        load_policy(tmp_path / "none.zip")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(timesteps=0), "timesteps: an integer >= 1"),
        (dict(timesteps=10, seed=-1), "seed: an integer >= 0"),
        (dict(timesteps=10, seed=1_000_000), "seed: 0 <= seed < 1000000"),
        (dict(timesteps=10, eval_freq=0), "eval_freq"),
        (dict(timesteps=10, eval_episodes=0), "eval_episodes"),
    ],
)
def test_train_bad_input(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        train_sac(tmp_path / "run", **kwargs)


def test_tiny_run_flies_through_evaluate_agents(tmp_path, monkeypatch):
    """A few hundred steps of SAC+HER; the model flies one episode through evaluate_agents, from
    Python (load_policy) and the evaluate.py route (MODULE:ATTR, path from the env var)."""
    out = tmp_path / "her"
    options = SacOptions(learning_starts=100, batch_size=32, net_arch=(16, 16))
    log = train_sac(
        out, 300, seed=1, options=options, eval_freq=200, eval_episodes=1, progress=False
    )
    assert (out / "model.zip").is_file()
    assert log["timesteps"] == 300 and log["her"] is True
    assert json.loads((out / "train_log.json").read_text())["timesteps"] == 300
    lines = (out / "curve.csv").read_text().splitlines()
    assert lines[0].split(",") == list(CURVE_COLUMNS)
    assert [line.split(",")[0] for line in lines[1:]] == ["200", "300"]  # every 200, and the end
    results = evaluate_agents(EASY, {"her": load_policy(out / "model.zip")}, 1, 0, progress=False)
    assert len(results.records) == 1 and results.records[0].agent == "her"
    monkeypatch.setenv(MODEL_ENV_VAR, str(out / "model.zip"))
    results = evaluate_agents(
        EASY, "her=agents.experiments.her.policy:policy", 1, 0, progress=False
    )
    assert len(results.records) == 1 and results.records[0].agent == "her"
    # the adapter refuses an env of another observation layout
    model = load_policy(out / "model.zip")
    with pytest.raises(ValueError, match="observation shape"):
        model(gym.make(EASY, obs_goal=True))
    with pytest.raises(ValueError, match=r"already holds a model\.zip"):
        train_sac(out, 10)


def test_cli_control_run(tmp_path, capsys):
    """The control through the command line: plain SAC, flat observation, the same adapter."""
    out = tmp_path / "sac"
    code = main(
        [
            "--timesteps", "150", "--seed", "2", "--out", str(out), "--no-her",
            "--eval-freq", "150", "--eval-episodes", "1", "--no-progress",
        ]
    )  # fmt: skip
    assert code == 0
    assert "150 steps" in capsys.readouterr().out
    factory = load_policy(out / "model.zip")
    adapter = factory(gym.make(EASY))
    assert isinstance(adapter, GoalPolicy) and not adapter.goal_conditioned
    with pytest.raises(SystemExit) as exc:
        main(["--timesteps", "0", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2
    assert "argument --timesteps: must be an integer >= 1" in capsys.readouterr().err
