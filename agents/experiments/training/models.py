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
from agents.policies.model_files import ConfigError, algo_class

__all__ = [
    "DEVICES",
    "algo_kwargs",
    "build_model",
    "make_eval_env",
    "make_train_env",
    "policy_kwargs",
    "resolve_device",
    "set_encoder_kwargs",
    "tensorboard_dir",
]

DEVICES = ("cpu", "auto", "cuda", "cuda:<N>", "mps")
"""The ``--device`` values train.py knows; GPU ones only where that GPU is present."""


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
    if config.init.path is not None:  # fine-tuning: the init run's statistics, frozen
        from agents.experiments.training.finetune import finetune_train_env

        venv = finetune_train_env(venv, config, stats)
    elif norm.enabled:
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
    if config.encoder.kind == "set":
        kwargs.update(set_encoder_kwargs(config))
    return kwargs


def set_encoder_kwargs(config: TrainConfig) -> dict[str, Any]:
    """``policy_kwargs`` of a set encoder over the slots of the run's observation (its layout
    from the env's ``observation_names()``, stored in the model file with the weights)."""
    import gymnasium as gym

    from agents.policies.set_encoder import SlotSetExtractor, slot_layout

    options = {k: v for k, v in config.env_kwargs.items() if k != "max_episode_steps"}
    env = gym.make(config.env_id, **options)
    try:
        context, slots = slot_layout(env.unwrapped.observation_names())
    finally:
        env.close()
    return {
        "features_extractor_class": SlotSetExtractor,
        "features_extractor_kwargs": {
            "context": context,
            "slots": slots,
            "embed_dim": config.encoder.embed_dim,
            "hidden_dim": config.encoder.hidden_dim,
        },
    }


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


def _available_devices() -> list[str]:
    import torch

    found = ["cpu", "auto"]
    if torch.cuda.is_available():
        found += ["cuda", *(f"cuda:{i}" for i in range(torch.cuda.device_count()))]
    if torch.backends.mps.is_available():
        found.append("mps")
    return found


def resolve_device(text: str, flag: str = "--device") -> str:
    """The torch device a run uses for ``--device text``: ``auto`` becomes ``cuda`` when a CUDA
    GPU is present and ``cpu`` otherwise (SB3's rule), so the run records where it really ran.

    Raises:
        ValueError: an unknown device name, or a GPU this machine does not have (SB3 would run
            on the CPU instead and the run would record the GPU).
    """
    import torch

    name = str(text).strip().lower()
    here = _available_devices()
    allowed = f"allowed: {', '.join(DEVICES)}; available on this machine: {', '.join(here)}"
    kind, _, index = name.partition(":")
    known = name in ("cpu", "auto", "mps", "cuda") or (kind == "cuda" and index.isdigit())
    if not known:
        raise ValueError(f"{flag} {text!r} is not a device; {allowed}")
    if name not in here:
        raise ValueError(f"{flag} {text!r}: no such GPU on this machine; {allowed}")
    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    return name


def build_model(
    config: TrainConfig,
    train_env: Any,
    *,
    seed: int,
    device: str,
    tensorboard_log: str | None,
    source: str = "config",
) -> Any:
    """A fresh SB3 model of the recipe on ``train_env`` (nothing is written: SB3 makes its
    TensorBoard folder only when learning starts); with ``init.path`` an
    :class:`~agents.experiments.training.anchored.AnchoredPPO` started from that run's policy.

    Raises:
        ConfigError: SB3 rejects the recipe's keyword arguments (its own asserts and checks, which
            the ranges of :mod:`~agents.experiments.training.validation` do not cover).
    """
    if config.init.path is not None:
        from agents.experiments.training.finetune import build_finetune_model

        return build_finetune_model(
            config,
            train_env,
            seed=seed,
            device=device,
            tensorboard_log=tensorboard_log,
            source=source,
        )
    cls = algo_class(config.algo)
    try:
        return cls(
            config.policy,
            train_env,
            policy_kwargs=policy_kwargs(config),
            seed=seed,
            device=device,
            tensorboard_log=tensorboard_log,
            verbose=0,
            **algo_kwargs(config, int(np.prod(train_env.action_space.shape or (1,)))),
        )
    except (AssertionError, ValueError, TypeError, KeyError) as exc:
        raise ConfigError(
            f"{source}: SB3 {cls.__name__} rejects config keys 'algo_kwargs' / 'policy_kwargs' "
            f"({config.algo_kwargs} / {config.policy_kwargs}): {exc}"
        ) from None
