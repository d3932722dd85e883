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


def test_supersuit_vector_env_trains_sb3_ppo():
    ss = pytest.importorskip("supersuit")
    from stable_baselines3 import PPO

    env = ss.black_death_v3(swarm.make(EASY))  # ended chasers: zero observations
    venv = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(env), 2, num_cpus=0, base_class="stable_baselines3"
    )
    assert venv.num_envs == 4  # 2 copies of 2 chasers
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, device="cpu")
    model.learn(128)
    assert model.num_timesteps == 128


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
