"""The envs and the SB3 model of a training run, built from its :class:`TrainConfig`.

Training envs are :class:`~debris_gym.integrations.sb3.NativeVecEnv` (the native vector env) in
SB3's ``VecMonitor`` and, optionally, ``VecNormalize``. Sub-env ``i`` is seeded with
``seed + i``; evaluation uses seeds ``EVAL_SEED + i`` so it never flies a training field first.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.training.config import EVAL_SEED, TrainConfig

__all__ = ["algo_kwargs", "make_eval_env", "make_train_env", "policy_kwargs", "tensorboard_dir"]


def _vec_env(config: TrainConfig, n_envs: int) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor

    from debris_gym.integrations.sb3 import NativeVecEnv

    venv = NativeVecEnv(config.env_id, n_envs, **config.env_kwargs)
    return VecMonitor(venv, info_keywords=("is_success", "targets_captured"))


def make_train_env(config: TrainConfig, seed: int, stats: Path | None = None) -> Any:
    """Training VecEnv: NativeVecEnv → VecMonitor → VecNormalize (if enabled; stats restored from
    ``stats`` when given). Sub-env ``i`` is seeded with ``seed + i`` on the next reset."""
    from stable_baselines3.common.vec_env import VecNormalize

    venv = _vec_env(config, config.n_envs)
    norm = config.normalize
    if norm.enabled:
        if stats is not None:
            venv = VecNormalize.load(str(stats), venv)
            venv.training = True
            venv.norm_obs, venv.norm_reward = norm.norm_obs, norm.norm_reward
        else:
            venv = _vec_normalize(venv, config, training=True)
    venv.seed(seed)
    return venv


def make_eval_env(config: TrainConfig) -> Any:
    """Evaluation VecEnv (seeds ``EVAL_SEED + i``; VecNormalize frozen, synced from training)."""
    venv = _vec_env(config, config.eval.n_envs)
    if config.normalize.enabled:
        venv = _vec_normalize(venv, config, training=False)
    venv.seed(EVAL_SEED)
    return venv


def _vec_normalize(venv: Any, config: TrainConfig, training: bool) -> Any:
    """``venv`` in a fresh VecNormalize with the config's options; rewards are scaled only in
    training (evaluation reports the env's own returns)."""
    from stable_baselines3.common.vec_env import VecNormalize

    norm = config.normalize
    return VecNormalize(
        venv,
        training=training,
        norm_obs=norm.norm_obs,
        norm_reward=norm.norm_reward and training,
        clip_obs=norm.clip_obs,
        clip_reward=norm.clip_reward,
        gamma=norm.gamma if norm.gamma is not None else config.gamma,
        epsilon=norm.epsilon,
    )


def policy_kwargs(config: TrainConfig) -> dict[str, Any]:
    import torch.nn as nn

    kwargs = dict(config.policy_kwargs)
    if "activation_fn" in kwargs:
        kwargs["activation_fn"] = {
            "tanh": nn.Tanh,
            "relu": nn.ReLU,
            "elu": nn.ELU,
            "leaky_relu": nn.LeakyReLU,
            "gelu": nn.GELU,
            "silu": nn.SiLU,
        }[kwargs["activation_fn"]]
    return kwargs


def algo_kwargs(config: TrainConfig, action_dim: int) -> dict[str, Any]:
    from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise
    from stable_baselines3.common.utils import LinearSchedule

    kwargs = dict(config.algo_kwargs)
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str):  # "lin_3e-4": linear decay to 0 over the run
            kwargs[key] = LinearSchedule(float(value[4:]), 0.0, 1.0)
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = (int(kwargs["train_freq"][0]), kwargs["train_freq"][1])
    noise = kwargs.get("action_noise")
    if isinstance(noise, dict):
        cls = NormalActionNoise if noise["type"] == "normal" else OrnsteinUhlenbeckActionNoise
        kwargs["action_noise"] = cls(np.zeros(action_dim), noise["sigma"] * np.ones(action_dim))
    return kwargs


def tensorboard_dir(out: Path) -> str | None:
    if importlib.util.find_spec("tensorboard") is None:
        print(
            "note: TensorBoard logging off (the 'tensorboard' package is not installed; "
            "pip install tensorboard)",
            file=sys.stderr,
        )
        return None
    return str(out / "tb")
