"""Floor baselines: coast forever, or thrust at random."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.policies.base import ClassicalAgent


class ZeroAgent(ClassicalAgent):
    """Never thrusts (the chaser stays at the dock): the floor every method must beat."""

    name = "zero"

    def act(self) -> np.ndarray:
        return np.zeros(self.env.dim)


class RandomAgent(ClassicalAgent):
    """Uniform random actions from its own seeded generator.

    Args:
        env: the env.
        seed: seed of the agent's generator (actions do not touch the env's).
    """

    name = "random"

    episode_independent = False  # one generator runs on from episode to episode

    def __init__(self, env: Any, seed: int = 0) -> None:
        super().__init__(env)
        self.rng = np.random.default_rng(seed)

    def act(self) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, size=self.env.dim)


class FunctionPolicy:
    """A plain function ``obs -> action`` behind SB3's ``predict`` interface.

    ``predict`` calls the function on the observation (on each row of a batch, stacking the
    answers) and hands ``state`` back unchanged; ``episode_start`` and ``deterministic`` are not
    passed on. A plain function has no episode state the evaluation could reset: one that keeps
    some (a closure, a global) sees its episodes in order, since the function's
    ``episode_independent`` attribute, when it has none, counts as False. Write a policy object
    for memory across steps (``state``) or episodes.

    Args:
        function: ``function(obs) -> action``.
        observation_space: the env's observation space (to tell a batch from one observation).
    """

    def __init__(self, function: Any, observation_space: Any) -> None:
        self.function = function
        self.observation_space = observation_space
        self.episode_independent = bool(getattr(function, "episode_independent", False))

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """``(function(observation), state)``; a batch is answered row by row."""
        obs = np.asarray(observation)
        shape = getattr(self.observation_space, "shape", None)
        if shape is not None and obs.shape != shape and obs.shape[1:] == shape:
            return np.stack([np.asarray(self.function(row)) for row in obs]), state
        return self.function(observation), state

    def __repr__(self) -> str:
        return f"FunctionPolicy({getattr(self.function, '__qualname__', self.function)!r})"
