"""The SB3 keyword arguments of a recipe: its ``policy_kwargs`` and ``algo_kwargs`` as the SB3
classes take them (activation functions, schedules, action noise and the set encoder built from
their names in the config)."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.experiments.training.config import TrainConfig
from agents.policies.base import unwrap

__all__ = ["algo_kwargs", "policy_kwargs", "set_encoder_kwargs"]


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
