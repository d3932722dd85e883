"""The ``VecEnv`` methods the SB3 views of debris-gym answer the same way
(:class:`~debris_gym.integrations.sb3.NativeVecEnv`,
:class:`~debris_gym.integrations.sb3_swarm.SwarmVecEnv`). Requires ``stable-baselines3``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

try:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices
except ImportError as exc:  # pragma: no cover - exercised only without SB3
    raise ImportError(
        "debris_gym.integrations needs stable-baselines3: pip install 'debris-gym[rl]'"
    ) from exc

__all__ = ["BatchVecEnv"]


class BatchVecEnv(VecEnv):
    """The ``VecEnv`` methods of a view over one batched env object (:meth:`_batch`): every
    sub-env shares its attributes and methods, none is wrapped, none renders."""

    _what = "this vector env"

    def _batch(self) -> Any:
        """The object every sub-env's attributes are read from."""
        raise NotImplementedError

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self._batch(), attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError(f"{self._what} does not support setting {attr_name!r}")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        result = getattr(self._batch(), method_name)(*method_args, **kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]
