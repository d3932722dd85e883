"""PettingZoo wrappers of the swarm envs for libraries with stricter contracts.

:class:`FlatInfos` turns each agent's ``reward_terms`` dict into ``reward_<term>`` entries, so
every info value is a number or an array: TorchRL's ``PettingZooWrapper`` builds a tensor spec
per info key and cannot take a nested dict (:func:`debris_gym.integrations.torchrl.torchrl_env`
applies it).
"""

from __future__ import annotations

from typing import Any

from pettingzoo.utils import BaseParallelWrapper

__all__ = ["FlatInfos"]


class FlatInfos(BaseParallelWrapper):
    """A swarm ``ParallelEnv`` whose infos are flat: ``reward_terms`` becomes ``reward_<term>``
    keys (the same values); every other key as it was."""

    @staticmethod
    def flat(infos: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
        """``infos`` with each agent's ``reward_terms`` spread into ``reward_<term>`` keys."""
        out = {}
        for agent, info in infos.items():
            info = dict(info)
            terms = info.pop("reward_terms", {})
            info.update({f"reward_{name}": value for name, value in terms.items()})
            out[agent] = info
        return out

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        return observations, self.flat(infos)

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        return observations, rewards, terminations, truncations, self.flat(infos)
