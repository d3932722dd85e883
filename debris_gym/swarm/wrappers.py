"""PettingZoo wrappers of the swarm envs for libraries with stricter contracts.

:class:`FlatInfos` turns each agent's ``reward_terms`` dict into ``reward_<term>`` entries, so
every info value is a number or an array: TorchRL's ``PettingZooWrapper`` builds a tensor spec
per info key and cannot take a nested dict (:func:`debris_gym.integrations.torchrl.torchrl_env`
applies it).

:class:`CentralState` gives each agent the team's state beside its own observation, for
learners whose centralised critic can only read what arrives as an observation (RLlib's
MAPPO of ``agents.experiments.distributed.rllib``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo.utils import BaseParallelWrapper

__all__ = ["CentralState", "FlatInfos"]


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


class CentralState(BaseParallelWrapper):
    """A swarm ``ParallelEnv`` whose observations are dicts ``{"obs": own, "state": team}``:
    ``own`` the agent's observation as the env gives it, ``team`` the env's ``state()`` (every
    chaser's observation, in agent order) read after the same reset or step.

    Args:
        env: a swarm env (:func:`debris_gym.swarm.make`), whose ``state()`` is its agents'
            observations one after the other.
        own_first: True: each agent's ``state`` entry starts with its own block, the other
            blocks following in agent order after it, wrapping round (the team seen from the
            agent's seat: one critic shared by every chaser then knows whose return it
            predicts); False: ``state()`` as it is, the same for every agent.

    Every agent has the same observation space object, ``Dict(obs=…, state=env.state_space)``.

    Raises:
        ValueError: ``own_first`` is not a bool, or ``env.state_space`` is not one block of
            an agent's observation size per agent.
    """

    OBS = "obs"
    """Key of the agent's own observation (what a decentralised actor reads)."""
    STATE = "state"
    """Key of the team's state (what a centralised critic reads)."""

    def __init__(self, env: Any, own_first: bool = True) -> None:
        super().__init__(env)
        if not isinstance(own_first, bool):
            raise ValueError(f"own_first must be True or False, got {own_first!r}")
        agents = list(env.possible_agents)
        own = env.observation_space(agents[0])
        if env.state_space.shape != (len(agents) * own.shape[0],):
            raise ValueError(
                f"env.state_space must hold one observation of {own.shape[0]} values per agent "
                f"({len(agents)} agents), got shape {env.state_space.shape}"
            )
        self.own_first = own_first
        self._index = {agent: j for j, agent in enumerate(agents)}
        self._space = spaces.Dict({self.OBS: own, self.STATE: env.state_space})

    def observation_space(self, agent: str) -> spaces.Dict:
        """The observation space of ``agent`` (the same object for every agent)."""
        self.env.observation_space(agent)  # the env names an unknown agent
        return self._space

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        return self._with_state(observations), infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        return self._with_state(observations), rewards, terminations, truncations, infos

    def _with_state(self, observations: dict[str, np.ndarray]) -> dict[str, dict[str, Any]]:
        state = np.asarray(self.env.state())
        blocks = state.reshape(len(self._index), -1)
        out = {}
        for agent, own in observations.items():
            team = np.roll(blocks, -self._index[agent], axis=0).ravel() if self.own_first else state
            out[agent] = {self.OBS: own, self.STATE: team.copy()}
        return out
