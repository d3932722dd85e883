"""Long random-action rollouts: no NaN or inf anywhere, and no memory growth (``slow``; a short
rollout per env stays in the default run)."""

from __future__ import annotations

import gc
import os

import gymnasium as gym
import numpy as np
import pytest

import debris_gym  # noqa: F401
from tests.helpers import flies_old_ids

pytestmark = flies_old_ids  # the frozen-world IDs (v0) among the rollouts


def rss_bytes() -> int:
    """Resident set size of this process (Linux /proc; cheap enough to sample often)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def run_random(env_id: str, steps: int, seed: int = 0) -> tuple[int, list[int]]:
    """Step random actions, checking every value; return episodes run and memory samples (B)."""
    env = gym.make(env_id)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    episodes, samples = 0, []
    for k in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and np.isfinite(reward)
        assert np.isfinite(info["chaser_state"]).all() and np.isfinite(info["delta_v"])
        if terminated or truncated:
            episodes += 1
            obs, info = env.reset()
            assert np.isfinite(obs).all()
        if k % (steps // 10) == 0:
            gc.collect()
            samples.append(rss_bytes())
    env.close()
    return episodes, samples


@pytest.mark.parametrize(
    "env_id",
    ["DebrisGym/Rendezvous2D-v0", "DebrisGym/Rendezvous3D-v0", "DebrisGym/PaperField2D-v0"],
)
def test_short_random_rollout_stays_finite(env_id):
    """The default run's short version of the long rollouts below (finite values only)."""
    episodes, _ = run_random(env_id, 3_000, seed=1)
    assert episodes >= 1


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_id, steps",
    [
        ("DebrisGym/Rendezvous2D-v0", 100_000),
        ("DebrisGym/Rendezvous3D-v0", 30_000),
        ("DebrisGym/PaperField2D-v0", 30_000),
    ],
)
def test_random_rollout_has_no_nan_and_no_memory_growth(env_id, steps):
    episodes, samples = run_random(env_id, steps)
    assert episodes > 10
    # after warm-up, resident memory must not trend upward: allow 4 MiB of allocator jitter, far
    # below what even a 64-byte-per-step leak would add over 100 000 steps (6 MiB)
    settled = samples[2:]
    assert max(settled) - min(settled) < 4 << 20, samples
