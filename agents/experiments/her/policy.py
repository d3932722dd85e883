"""Fly a SAC model trained by :mod:`agents.experiments.her` on the env's own flat observation.

``evaluate.py`` (and :func:`agents.experiments.evaluation.evaluate_agents`) hand a policy the
env's flat observation. A SAC+HER model wants the goal ``Dict`` of
:class:`~agents.experiments.her.goal_env.GoalConditionedEnv`; :class:`GoalPolicy` builds it from
the flat observation with the same :class:`~agents.experiments.her.goal_env.GoalLayout`, so the
model sees exactly what it was trained on. A plain SAC model (the control run, flat observation)
is passed the observation as it is.

Two ways in:

* from Python, :func:`load_policy(path) <load_policy>` returns a factory ``f(env) -> policy``::

      evaluate_agents("DebrisGym/Rendezvous2D-Easy-v2", {"her": load_policy("runs/her/model.zip")},
                      episodes=30, seed=0)

* from ``evaluate.py``, the factory :func:`policy` reads the model path from the environment
  variable ``DEBRIS_HER_MODEL``::

      DEBRIS_HER_MODEL=runs/her/model.zip python evaluate.py \\
          --env DebrisGym/Rendezvous2D-Easy-v2 --agents her=agents.experiments.her.policy:policy
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3 import SAC
from stable_baselines3.common.base_class import BaseAlgorithm

from agents.experiments.her.goal_env import GoalLayout

__all__ = ["MODEL_ENV_VAR", "GoalPolicy", "load_policy", "policy"]

MODEL_ENV_VAR = "DEBRIS_HER_MODEL"
"""Environment variable :func:`policy` reads the model path from."""


class GoalPolicy:
    """SB3-style ``predict`` over flat observations for a (goal-conditioned or plain) SAC model.

    Args:
        model: a loaded SAC model; a ``Dict`` observation space means goal-conditioned.
        env: the env it flies (its unwrapped debris-gym env gives the goal layout).
    """

    def __init__(self, model: BaseAlgorithm, env: gym.Env[Any, Any]) -> None:
        self.model = model
        space = model.observation_space
        self.goal_conditioned = isinstance(space, spaces.Dict)
        self.layout = GoalLayout(env) if self.goal_conditioned else None
        expected = space["observation"].shape if isinstance(space, spaces.Dict) else space.shape
        if expected != env.observation_space.shape:
            raise ValueError(
                f"env: observation shape {env.observation_space.shape} differs from the model's "
                f"{expected} (another env or other observation options?)"
            )

    def model_input(self, obs: np.ndarray) -> np.ndarray | dict[str, np.ndarray]:
        """What the model is fed for flat observation(s) ``obs``."""
        if self.layout is None:
            return np.asarray(obs, dtype=np.float32)
        return self.layout.goal_observation(obs)

    def predict(
        self,
        observation: np.ndarray,
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
        """SB3's ``predict``: action(s) for flat observation(s) (batched or not)."""
        return self.model.predict(
            self.model_input(observation),
            state=state,
            episode_start=episode_start,
            deterministic=deterministic,
        )


def load_policy(path: str | os.PathLike[str]) -> Callable[[gym.Env[Any, Any]], GoalPolicy]:
    """A factory ``f(env) -> GoalPolicy`` for the SAC model saved at ``path`` (a ``.zip``).

    The model is loaded once, on CPU, when the factory is made, without its replay buffer.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"path: no model file at {str(path)!r}")
    # Only the policy flies: no replay buffer (a HER buffer would need the training env, and
    # a full-size one the memory), so SB3 picks a one-transition plain buffer.
    model = SAC.load(
        path,
        device="cpu",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )

    def factory(env: gym.Env[Any, Any]) -> GoalPolicy:
        return GoalPolicy(model, env)

    return factory


def policy(env: gym.Env[Any, Any]) -> GoalPolicy:
    """Factory for ``evaluate.py``'s ``LABEL=MODULE:ATTR``: the model at ``$DEBRIS_HER_MODEL``."""
    path = os.environ.get(MODEL_ENV_VAR)
    if not path:
        raise ValueError(
            f"{MODEL_ENV_VAR}: set it to the model's path, e.g. "
            f"{MODEL_ENV_VAR}=runs/her/model.zip python evaluate.py "
            "--agents her=agents.experiments.her.policy:policy ..."
        )
    return load_policy(path)(env)
