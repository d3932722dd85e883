"""The swarm envs through other multi-agent libraries: SuperSuit's vector env under SB3, TorchRL's
PettingZoo wrapper (both in the ``multiagent`` extra: skipped where they are not installed; CI
runs them in its optional-extras venv)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from debris_gym import swarm
from debris_gym.swarm.wrappers import FlatInfos

EASY = "DebrisGym/Swarm2D-Easy-v0"


def test_flat_infos_spread_the_reward_terms_and_keep_the_rest():
    env = FlatInfos(swarm.make(EASY))
    _, infos = env.reset(seed=0)
    _, rewards, _, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    for agent, info in infos.items():
        assert "reward_terms" not in info and "team_success" in info
        terms = [v for k, v in info.items() if k.startswith("reward_") and k != "reward_team"]
        assert len(terms) == 8
        assert sum(terms) + info["reward_team"] == pytest.approx(rewards[agent])


def _black_death_ends_episodes() -> bool:
    """Whether the installed SuperSuit's ``black_death`` ends an episode once every agent has
    ended: up to 3.11.0 it asks every agent to be terminated *and* truncated at once, so an
    episode whose agents end one way or the other never ends (SuperSuit pull request #265)."""
    import inspect

    from supersuit.multiagent_wrappers.black_death import black_death_par

    return "terminations & truncations" not in inspect.getsource(black_death_par.step)


def test_supersuit_vector_env_trains_sb3_ppo():
    ss = pytest.importorskip("supersuit")
    from stable_baselines3 import PPO

    if not _black_death_ends_episodes():
        pytest.xfail("this SuperSuit's black_death never ends an episode (SuperSuit PR #265)")
    env = ss.black_death_v3(swarm.make(EASY))  # ended chasers: zero observations
    venv = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(env), 2, num_cpus=0, base_class="stable_baselines3"
    )
    assert venv.num_envs == 4  # 2 copies of 2 chasers
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, device="cpu")
    model.learn(512)  # random actions: chasers collide and episodes end within it
    assert model.num_timesteps == 512


def test_the_supersuit_black_death_bug_is_what_stops_it():
    """With this SuperSuit, the episode of two chasers that collided in one step does not end:
    the wrapper keeps both in its agents after the swarm has none (its AND of terminations and
    truncations), and the next step finds no chaser flying."""
    ss = pytest.importorskip("supersuit")
    if _black_death_ends_episodes():
        pytest.skip("the installed SuperSuit ends black-death episodes")
    env = ss.black_death_v3(swarm.make(EASY, dock_spacing=3.0))  # 3 m apart: 1 m from contact
    env.reset(seed=0)
    toward = {"chaser_0": np.array([1.0, 0.0]), "chaser_1": np.array([-1.0, 0.0])}
    _, _, terms, _, infos = env.step(toward)  # chaser 1 sits at +x from chaser 0: they collide
    assert all(info["teammate_collision"] for info in infos.values())
    assert not any(terms.values()) and env.agents == ["chaser_0", "chaser_1"]
    with pytest.raises(RuntimeError, match="no agent is flying"):
        env.step(toward)


def test_torchrl_rollout_equals_the_pettingzoo_env():
    pytest.importorskip("torchrl")
    import torch

    from debris_gym.integrations.torchrl import torchrl_env

    torch.manual_seed(0)
    env = torchrl_env(EASY)
    start = env.reset(seed=3)
    rollout = env.rollout(6, auto_reset=False, tensordict=start, break_when_any_done=False)
    assert rollout.batch_size == torch.Size([6])
    actions = rollout["chaser", "action"].numpy()
    rewards = rollout["next", "chaser", "reward"].numpy()[..., 0]
    assert actions.shape == (6, 2, 2)
    # the same actions in the PettingZoo env from the same seed give the same rewards
    plain = swarm.make(EASY)
    plain.reset(seed=3)
    for step in range(6):
        if not plain.agents:
            break
        out = plain.step({a: actions[step, k] for k, a in enumerate(plain.possible_agents)
                          if a in plain.agents})  # fmt: skip
        for k, agent in enumerate(plain.possible_agents):
            if agent in out[1]:
                assert out[1][agent] == pytest.approx(rewards[step, k], rel=1e-5, abs=1e-5)
