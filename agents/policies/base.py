"""The one policy interface of debris-gym, and the base class of the classical baselines.

Every policy — classical or learned — answers SB3's protocol::

    action, state = policy.predict(observation, state=None, episode_start=None, deterministic=True)

for a single observation or a batch, in the same shape. Classical baselines are full-state
feedback on a known field (the source papers' assumption; in a moving field, the v1 world, they
know the bodies' motion too: :class:`agents.planners.motion.FieldMotion`): they are built with
the env (:func:`agents.make_agent`) and read the field from ``env.unwrapped.scenario`` and the
chaser's state and capture flags from the env's read-only properties. So they act for the env
they were built with; SB3's ``evaluate_policy`` works on a one-env ``DummyVecEnv`` around that env.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Scenario
from debris_gym.thrust import action_for_accel


def unwrap(env: Any) -> DebrisFieldEnv:
    """The :class:`DebrisFieldEnv` inside ``env`` (gymnasium wrappers, or a one-env VecEnv)."""
    base = env
    if hasattr(base, "envs") and len(base.envs) == 1:  # SB3 DummyVecEnv
        base = base.envs[0]
    base = getattr(base, "unwrapped", base)
    if not isinstance(base, DebrisFieldEnv):
        raise TypeError(f"expected a DebrisGym env, got {type(base).__name__}")
    return base


class ClassicalAgent:
    """Base of the classical baselines: re-plans when the field changes, acts on the true state.

    Subclasses implement :meth:`plan` (called at the start of every episode with the current
    field; cache expensive work per scenario there) and :meth:`act` (one normalised action from
    the current state).

    Args:
        env: the DebrisGym env (wrapped or not) the agent flies; needs ``action="continuous"``.
    """

    name = "classical"

    episode_independent = True
    """Whether an episode's actions depend only on that episode (:meth:`plan` starts every
    episode afresh, random generators reseeded): episodes may then be flown in any order, by
    any copy of the agent (the Ray backend does; :mod:`agents.experiments.distributed`)."""

    def __init__(self, env: Any) -> None:
        self.env = unwrap(env)
        if self.env.config.action != "continuous":
            raise ValueError(
                f"the {self.name!r} baseline needs action='continuous', got "
                f"action={self.env.config.action!r}"
            )
        self._scenario: Scenario | None = None
        self._episode_time: float | None = None

    # --- the shared interface -----------------------------------------------------------------

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3-style ``predict``: one action per observation, same batch shape."""
        obs = np.asarray(observation)
        single_shape = self.env.observation_space.shape
        batched = obs.shape != single_shape
        if batched and obs.shape[1:] != single_shape:
            raise ValueError(f"observation shape {obs.shape} does not match {single_shape}")
        if batched and obs.shape[0] != 1:
            raise ValueError(
                f"a classical agent flies the one env it was built with; got a batch of "
                f"{obs.shape[0]} observations"
            )
        scenario = self.scenario
        new_episode = self.env.elapsed == 0.0 and self._episode_time != 0.0
        if scenario is not self._scenario or new_episode:
            self._scenario = scenario
            self.plan(scenario)
        self._episode_time = self.env.elapsed
        action = np.asarray(self.act(), dtype=np.float32)
        if not np.all(np.isfinite(action)):
            raise FloatingPointError(f"{self.name} produced a non-finite action {action}")
        return (action[None] if batched else action), state

    @property
    def scenario(self) -> Scenario:
        """The env's current field.

        Raises:
            RuntimeError: the env has not been reset yet (it has no field).
        """
        scenario = self.env.scenario
        if scenario is None:
            raise RuntimeError("reset the env before calling predict()")
        return scenario

    # --- hooks --------------------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        """Prepare an episode on ``scenario`` (new field, or a new episode on the same one)."""

    def act(self) -> np.ndarray:
        """Normalised action in [-1, 1]^dim for the env's current state."""
        raise NotImplementedError

    # --- helpers for subclasses ---------------------------------------------------------------

    def accel_to_action(self, accel: np.ndarray) -> np.ndarray:
        """Acceleration (m/s²) → normalised action, by the env's own inverse thrust model
        (:func:`debris_gym.thrust.action_for_accel`)."""
        return action_for_accel(accel, self.scenario.max_accel, self.env.config.thrust_model)
