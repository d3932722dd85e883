"""TorchRL view of the swarm envs: ``torchrl_env(ID, **options)`` is TorchRL's
``PettingZooWrapper`` around :func:`debris_gym.swarm.make` (agents grouped as ``"chaser"``, a
``mask`` of the chasers still flying, continuous actions), its infos made flat
(:class:`~debris_gym.swarm.wrappers.FlatInfos`). Requires ``torchrl`` (the ``multiagent``
extra).

    from debris_gym.integrations.torchrl import torchrl_env
    env = torchrl_env("DebrisGym/Swarm2D-Easy-v0", seed=0)
    rollout = env.rollout(100)            # a TensorDict, batch [steps], group "chaser"
"""

from __future__ import annotations

from typing import Any

from debris_gym import swarm
from debris_gym.swarm.wrappers import FlatInfos

__all__ = ["torchrl_env"]


def torchrl_env(
    env_id: str = swarm.DEFAULT_SWARM, *, seed: int | None = None, device: str = "cpu",
    **options: Any,
) -> Any:  # fmt: skip
    """The swarm env ``env_id`` with ``options`` as a TorchRL env (``seed``: its first reset's).

    Raises:
        ValueError: an unknown ID or a bad option (from :func:`debris_gym.swarm.make`).
        ImportError: TorchRL is not installed.
    """
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    env = FlatInfos(swarm.make(env_id, **options))
    return PettingZooWrapper(
        env=env, use_mask=True, categorical_actions=False, seed=seed, device=device
    )
