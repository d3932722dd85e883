"""The SB3 keyword arguments of a recipe: its ``policy_kwargs`` and ``algo_kwargs`` as the SB3
classes take them (activation functions, schedules, action noise and the set encoder built from
their names in the config), and an SB3 model built with them (:func:`construct_model`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.experiments.config_files import ConfigError
from agents.experiments.training.config import TrainConfig
from agents.policies.base import unwrap

__all__ = ["algo_kwargs", "construct_model", "policy_kwargs", "set_encoder_kwargs"]


def policy_kwargs(config: TrainConfig) -> dict[str, Any]:
    """The SB3 ``policy_kwargs`` of ``config``: ``activation_fn`` as its torch class, and the set
    encoder's feature extractor when ``encoder.kind`` is ``"set"``."""
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
        context, slots = slot_layout(unwrap(env).observation_names())
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
    """The SB3 algorithm keyword arguments of ``config``: ``lin_<value>`` as a linear schedule
    to 0, ``train_freq`` as a tuple, ``action_noise`` as SB3's noise object for ``action_dim``
    action elements."""
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


def construct_model(
    cls: Any,
    config: TrainConfig,
    train_env: Any,
    source: str,
    policy: dict[str, Any],
    name: str | None = None,
    **settings: Any,
) -> Any:
    """An SB3 model of class ``cls`` on ``train_env``: the recipe's policy, ``policy`` as its
    ``policy_kwargs``, the recipe's :func:`algo_kwargs` (action noise sized to the env's action
    elements) and ``settings`` (``seed``, ``device``, ``tensorboard_log``, and whatever else
    ``cls`` takes), without SB3's console output.

    Args:
        cls: the SB3 algorithm class.
        config: the recipe.
        train_env: the training env (an SB3 VecEnv).
        source: what the recipe came from, named in the errors.
        policy: the ``policy_kwargs`` as ``cls`` takes them (:func:`policy_kwargs`, or the
            fine-tune's).
        name: the algorithm the errors name (default: ``cls``'s name).
        **settings: further keyword arguments of ``cls``.

    Raises:
        ConfigError: SB3 rejects the recipe's keyword arguments (its own asserts and checks,
            which the ranges of :mod:`~agents.experiments.training.validation` do not cover), or
            the model does not fit in this machine's memory.
    """
    name = cls.__name__ if name is None else name
    action_dim = int(np.prod(train_env.action_space.shape or (1,)))
    try:
        return cls(
            config.policy,
            train_env,
            policy_kwargs=policy,
            verbose=0,
            **settings,
            **algo_kwargs(config, action_dim),
        )
    except (AssertionError, ValueError, TypeError, KeyError) as exc:
        raise ConfigError(
            f"{source}: SB3 {name} rejects config keys 'algo_kwargs' / 'policy_kwargs' "
            f"({config.algo_kwargs} / {config.policy_kwargs}): {exc}"
        ) from None
    except (MemoryError, RuntimeError) as exc:  # torch's allocator raises RuntimeError
        if isinstance(exc, RuntimeError) and "allocate" not in str(exc):
            raise
        raise ConfigError(
            f"{source}: the {name} model of config keys 'policy_kwargs' / 'algo_kwargs' "
            f"({config.policy_kwargs} / {config.algo_kwargs}) does not fit in this machine's "
            f"memory ({str(exc).splitlines()[0]}); use smaller layers (policy_kwargs.net_arch) "
            "or a smaller buffer_size"
        ) from None
