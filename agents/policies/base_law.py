"""The base law flown alone: the compiled CW guidance of ``action="residual"`` as a baseline.

:class:`BaseLawAgent` flies, in the ordinary continuous env, exactly the command the residual
mode adds the policy's action to (:mod:`debris_gym.base_law`: a one-step CW deadbeat law on
the velocity toward the current goal's hold point, bent around bodies within 30 m). So a
residual policy's gain over its base is measured against this agent, on the same seeds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.policies.base import ClassicalAgent
from debris_gym.envs import DebrisFieldEnv

_FIRST_ROW = np.zeros(1, dtype=np.int64)


class BaseLawAgent(ClassicalAgent):
    """The base law's command at every step (no planning, no parameters).

    It reads the env's mission batch (:attr:`DebrisFieldEnv.batch
    <debris_gym.envs.shell.ShellView.batch>`: the chaser's true state, its gaps, capture
    flags and the bodies now) through :meth:`~debris_gym.mission_batch.MissionBatch.
    base_commands`, the same compiled code and arrays as the residual mode's step, and answers
    in float64 so that the env flies the command unrounded.

    Args:
        env: a single DebrisGym env (wrapped or not) with ``action="continuous"`` and no
            navigation errors.

    Raises:
        ValueError: another action mode; navigation errors (the law reads the true state);
            not a single env (one chaser of a swarm).
    """

    name = "base-law"
    action_dtype = np.float64

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        if not isinstance(self.env, DebrisFieldEnv):
            what = (
                "navigation errors (the law reads the true state)"
                if self.env.config.navigation_errors
                else f"a {type(self.env).__name__}"
            )
            raise ValueError(
                f"the {self.name!r} baseline flies a single env without navigation errors, "
                f"got {what}"
            )
        self._env = self.env

    def act(self) -> np.ndarray:
        batch = self._env.batch
        if batch is None:
            raise RuntimeError("reset the env before calling predict()")
        return batch.base_commands(_FIRST_ROW)[0]
