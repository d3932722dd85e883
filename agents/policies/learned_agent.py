"""A loaded SB3 model behind the shared ``predict()`` interface (:class:`LearnedAgent`), and the
VecNormalize observation statistics it applies, read so that a statistics file cannot run code
(:func:`read_vecnormalize`).

The agent normalises observations with the statistics saved next to the model, frozen (never
updated while it flies), before calling the model; a discrete model flying a continuous env
(a DQN policy trained with ``action="discrete"``) has its action k turned into row k of the
env's discrete action table, which the env turns into exactly the same acceleration.
:func:`agents.policies.learned.load_agent` builds it after checking the model against the env.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.policies.model_files import load_vecnormalize_pickle

__all__ = ["LearnedAgent", "read_vecnormalize"]


class LearnedAgent:
    """An SB3 model acting through the shared ``predict()`` interface.

    Args:
        model: the loaded SB3 model.
        algo: its algorithm name (``"ppo"``, …).
        path: the model file.
        obs_normalizer: a VecNormalize object (unpickled, no venv) whose frozen observation
            statistics are applied before the model, or None.
        observation_space: the env's single observation space.
        action_table: for a discrete model in a continuous env, row k = continuous action of
            discrete action k (normalised thrust); else None.
    """

    episode_independent = True
    """A feed-forward policy with frozen statistics: an episode depends on nothing before it."""

    def __init__(
        self,
        model: Any,
        algo: str,
        path: Path,
        obs_normalizer: Any,
        observation_space: spaces.Space,
        action_table: np.ndarray | None = None,
    ) -> None:
        self.model = model
        self.algo = algo
        self.name = algo
        self.path = path
        self.obs_normalizer = obs_normalizer
        self.observation_space = observation_space
        self.action_table = action_table

    def normalize(self, observation: np.ndarray) -> np.ndarray:
        """Observations as the model saw them in training (frozen VecNormalize statistics)."""
        obs = np.asarray(observation, dtype=np.float32)
        if self.obs_normalizer is None:
            return obs
        return np.asarray(self.obs_normalizer.normalize_obs(obs), dtype=np.float32)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3-style ``predict`` for one observation or a batch, answering in the same shape.

        Raises:
            ValueError: an observation whose shape is neither the env's nor a batch of it.
        """
        obs = np.asarray(observation, dtype=np.float32)
        single_shape = self.observation_space.shape
        single = obs.shape == single_shape
        if not single and obs.shape[1:] != single_shape:
            raise ValueError(
                f"observation shape {obs.shape} is neither {single_shape} nor a batch of it"
            )
        batch = self.normalize(obs[None] if single else obs)
        action, state = self.model.predict(
            batch, state=state, episode_start=episode_start, deterministic=deterministic
        )
        if self.action_table is not None:
            action = self.action_table[np.asarray(action, dtype=np.int64)].astype(np.float32)
        return (action[0] if single else action), state

    def __repr__(self) -> str:
        norm = "VecNormalize obs" if self.obs_normalizer is not None else "raw obs"
        return f"LearnedAgent({self.algo}, {self.path}, {norm})"


def read_vecnormalize(stats: Path) -> Any:
    """Unpickle the VecNormalize statistics file ``stats`` (no venv attached), allowing only the
    types such statistics are made of (:func:`~agents.policies.model_files.
    load_vecnormalize_pickle`): a file that names any other function or class is refused before
    anything in it runs.

    Raises:
        ValueError: the file is empty, truncated, not a pickle, or holds something other than
            Stable-Baselines3 VecNormalize statistics (the message names the file).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    fix = (
        "re-copy it from the training run (train.py writes it beside every model it saves), or "
        "delete it if the run did not normalise observations"
    )
    try:
        normalizer = load_vecnormalize_pickle(stats)
    except Exception as exc:  # a damaged pickle fails in many ways (EOFError, UnpicklingError, …)
        raise ValueError(
            f"{stats}: not readable VecNormalize statistics ({type(exc).__name__}: {exc}); {fix}"
        ) from None
    if not isinstance(normalizer, VecNormalize):
        raise ValueError(
            f"{stats}: holds a {type(normalizer).__name__}, not VecNormalize statistics; {fix}"
        )
    # A VecNormalize object whose statistics are missing or corrupt would fail only later, on
    # the first observation; its own attributes are read from vars() because VecNormalize
    # forwards unknown attributes to its (absent) venv.
    state = vars(normalizer)
    try:
        norm_obs = bool(state["norm_obs"])
        if norm_obs:
            mean = np.asarray(state["obs_rms"].mean, dtype=float)
            var = np.asarray(state["obs_rms"].var, dtype=float)
            clip, eps = float(state["clip_obs"]), float(state["epsilon"])
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(
            f"{stats}: incomplete VecNormalize statistics ({type(exc).__name__}: {exc}); {fix}"
        ) from None
    if norm_obs:
        bad = (
            mean.shape != var.shape
            or not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var)))
            or np.any(var < 0)
            or not (clip > 0 and eps > 0)
        )
        if bad:
            raise ValueError(
                f"{stats}: corrupt VecNormalize statistics (observation means and variances must "
                "be finite and of one shape, variances >= 0, clip_obs and epsilon > 0); "
                f"{fix}"
            )
    return normalizer
