"""Policies importable as ``example_policies:ATTR`` for the ``MODULE:ATTR`` agent specs of
evaluate.py (the tests run the script from this directory, so the module is found)."""

from __future__ import annotations

from typing import Any

import numpy as np


class CoastPolicy:
    """Never thrusts: the zero action of a continuous action space, in SB3's ``predict`` form."""

    def __init__(self, env: Any) -> None:
        self.shape = env.action_space.shape

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        return np.zeros(self.shape, dtype=np.float32), state


def make_policy(env: Any) -> CoastPolicy:
    """A factory ``f(env) -> policy``."""
    return CoastPolicy(env)


NOT_A_POLICY = 42
"""An attribute that is neither a policy nor a factory."""


def make_nothing(env: Any) -> object:
    """A factory whose product has no ``predict``."""
    return object()
