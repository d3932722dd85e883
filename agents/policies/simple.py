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
