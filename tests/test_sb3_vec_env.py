"""SB3 trains on the native vector env through the NativeVecEnv adapter."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv

from debris_gym.integrations.sb3 import NativeVecEnv
from tests.helpers import flies_old_ids

# the SB3 adapter on the frozen-world default field (v0)
pytestmark = flies_old_ids


def test_adapter_matches_sb3_dummy_vec_env():
    """Same seeds and actions: identical obs, rewards, dones and terminal observations."""
    n = 3
    ours = NativeVecEnv("DebrisGym/Rendezvous2D-v0", num_envs=n, max_episode_steps=25)
    ref = DummyVecEnv(
        [lambda: gym.make("DebrisGym/Rendezvous2D-v0", max_episode_steps=25) for _ in range(n)]
    )
    ours.seed(5)
    ref.seed(5)
    np.testing.assert_allclose(ours.reset(), ref.reset(), rtol=1e-6)
    rng = np.random.default_rng(0)
    dones_seen = 0
    for _ in range(80):
        actions = rng.uniform(-0.3, 0.3, (n, 2)).astype(np.float32)
        o1, r1, d1, i1 = ours.step(actions)
        o2, r2, d2, i2 = ref.step(actions)
        np.testing.assert_allclose(o1, o2, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(r1, r2, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(d1, d2)
        for a, b in zip(i1, i2):
            assert a["is_success"] == b["is_success"]
            if "terminal_observation" in b:
                np.testing.assert_allclose(
                    a["terminal_observation"], b["terminal_observation"], rtol=1e-6, atol=1e-6
                )
                assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
        dones_seen += int(d1.sum())
    assert dones_seen > 0


def test_ppo_learns_a_few_steps_on_the_native_vector_env():
    venv = NativeVecEnv("DebrisGym/Rendezvous2D-v0", num_envs=8)
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=64, n_epochs=1, seed=0, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(256)
    assert model.num_timesteps == 256
    after = list(model.policy.parameters())
    assert any(not (a == b).all() for a, b in zip(after, before))  # the update reached the net
    obs = venv.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (8, 2) and np.all(np.isfinite(actions))
