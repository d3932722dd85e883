"""MAPPO's network for RLlib's new API stack: a decentralised actor on each chaser's own
observation and a centralised critic on the team's state.

The swarm env reaches RLlib through :class:`debris_gym.swarm.wrappers.CentralState`: each
agent's observation is a dict ``{"obs": own, "state": team}``, RLlib batches it as a dict of
tensors, and :class:`MAPPOTorchModule` reads ``obs`` in its forward pass (the action
distribution) and ``state`` in :meth:`~MAPPOTorchModule.compute_values` (the value PPO's
advantage estimate and value loss call for). Sampling feeds the module the whole dict, so the
team's state is in every batch the learner gets; the actor never sees it.

This module imports Ray and torch: import it only where RLlib is installed
(:func:`agents.experiments.distributed.rllib.swarm_mappo_config` does so on first use).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule
from torch import nn

from debris_gym.swarm.wrappers import CentralState

__all__ = ["MAPPOTorchModule"]

ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU}
"""``fcnet_activation`` values the module takes."""


def _mlp(inputs: int, hidden: list[int], outputs: int, activation: type[nn.Module]) -> nn.Module:
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(inputs, width), activation()]
        inputs = width
    layers.append(nn.Linear(inputs, outputs))
    return nn.Sequential(*layers)


class MAPPOTorchModule(TorchRLModule, ValueFunctionAPI):
    """Actor MLP on ``obs`` → the mean of a diagonal Gaussian over the action (its log
    standard deviation a learned vector, one per action dimension, starting at 0); critic MLP
    on ``state`` → the value.

    Model config (RLlib's ``DefaultModelConfig`` names): ``fcnet_hiddens`` the hidden layer
    sizes of both networks, ``fcnet_activation`` ``"tanh"`` or ``"relu"``.

    Raises:
        ValueError: the observation space is not ``CentralState``'s dict, the action space
            not a Box, or a bad model setting.
    """

    def setup(self) -> None:
        space = self.observation_space
        keys = (CentralState.OBS, CentralState.STATE)
        if not isinstance(space, gym.spaces.Dict) or set(space.spaces) != set(keys):
            raise ValueError(
                f"the observation space must be a Dict with keys {keys} (the swarm env "
                f"behind debris_gym.swarm.wrappers.CentralState), got {space}"
            )
        if not isinstance(self.action_space, gym.spaces.Box):
            raise ValueError(f"the action space must be a Box, got {self.action_space}")
        config = self.model_config
        settings = config if isinstance(config, Mapping) else vars(config)
        hidden = [int(w) for w in settings.get("fcnet_hiddens", (128, 128))]
        if not hidden or min(hidden) < 1:
            raise ValueError(f"fcnet_hiddens must be sizes >= 1, got {hidden!r}")
        name = settings.get("fcnet_activation", "tanh")
        if name not in ACTIVATIONS:
            raise ValueError(
                f"fcnet_activation must be one of {', '.join(ACTIVATIONS)}, got {name!r}"
            )
        own = gym.spaces.flatdim(space[CentralState.OBS])
        team = gym.spaces.flatdim(space[CentralState.STATE])
        actions = gym.spaces.flatdim(self.action_space)
        self.actor = _mlp(own, hidden, actions, ACTIVATIONS[name])
        self.log_std = nn.Parameter(torch.zeros(actions))
        self.critic = _mlp(team, hidden, 1, ACTIVATIONS[name])

    def _forward(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        """The action distribution's inputs (mean, log std) from the own observation only."""
        mean = self.actor(batch[Columns.OBS][CentralState.OBS])
        return {Columns.ACTION_DIST_INPUTS: torch.cat([mean, self.log_std.expand_as(mean)], -1)}

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        """The value of each row from the team's state only, shape (B,) (or (B, T))."""
        return self.critic(batch[Columns.OBS][CentralState.STATE]).squeeze(-1)
