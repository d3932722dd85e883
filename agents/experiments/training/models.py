"""The envs and the SB3 model of a training run, built from its :class:`TrainConfig`.

Training envs are :class:`~debris_gym.integrations.sb3.NativeVecEnv` (the native vector env) in
SB3's ``VecMonitor`` and, optionally, ``VecNormalize``. Sub-env ``i`` is seeded with
``seed + i``; evaluation uses seeds ``EVAL_SEED + i`` so it never flies a training field first.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.config_files import ConfigError
from agents.experiments.training.config import EVAL_SEED, OFF_POLICY, TrainConfig
from agents.experiments.training.finetune import build_finetune_model, finetune_train_env
from agents.experiments.training.sb3_kwargs import construct_model, policy_kwargs
from agents.policies.model_files import algo_class

__all__ = [
    "DEVICES",
    "build_model",
    "make_eval_env",
    "make_train_env",
    "resolve_device",
    "tensorboard_dir",
]

DEVICES = ("cpu", "auto", "cuda", "cuda:<N>", "mps")
"""The ``--device`` values train.py knows; GPU ones only where that GPU is present."""


SHIELD_KEYS = ("shield", "shield_penalty")
"""Env options of the safety shield in the training loop: the evaluation env leaves them out,
so that model selection sees the policy fly alone."""


def _vec_env(config: TrainConfig, n_envs: int, shielded: bool = True) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor

    from debris_gym.integrations.sb3 import make_vec_env

    kwargs = config.env_kwargs
    if not shielded:
        kwargs = {k: v for k, v in kwargs.items() if k not in SHIELD_KEYS}
    # swarm IDs: one SB3 env per chaser, one policy for all (parameter sharing, IPPO)
    venv = make_vec_env(config.env_id, n_envs, **kwargs)
    return VecMonitor(venv, info_keywords=("is_success", "targets_captured"))


def make_train_env(config: TrainConfig, seed: int, stats: Path | None = None) -> Any:
    """Training VecEnv: NativeVecEnv → VecMonitor → VecNormalize (if enabled; stats restored from
    ``stats`` when given). Sub-env ``i`` is seeded with ``seed + i`` on the next reset."""
    from stable_baselines3.common.vec_env import VecNormalize

    venv = _vec_env(config, config.n_envs)
    if config.starts.bank is not None:
        attach_start_sampler(venv.venv, config)
    norm = config.normalize
    if config.init.path is not None:  # fine-tuning: the init run's statistics, frozen
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


def attach_start_sampler(native: Any, config: TrainConfig) -> Any:
    """Give the native training env ``native`` a :class:`~agents.experiments.starts.LegSampler`
    over the config's start bank (its missions restart part-way from then on); returns it.

    Raises:
        ConfigError: the bank cannot be read, or was recorded in another env.
    """
    from agents.experiments.starts import LegSampler, SamplerParams
    from debris_gym.start_bank import StartBank

    starts = config.starts
    assert starts.bank is not None
    try:
        bank = StartBank.load(starts.bank)
        bank.check_config(native.venv.config)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"starts.bank: {exc}") from None
    shell = native.venv.shell
    params = SamplerParams(starts.usual, starts.temperature, starts.staleness, starts.smoothing)
    sampler = LegSampler(bank, shell.num, shell.batch_n_targets(), params)
    native.set_start_sampler(sampler)
    return sampler


def make_eval_env(config: TrainConfig) -> Any:
    """Evaluation VecEnv (seeds ``EVAL_SEED + i``; VecNormalize frozen, synced from training;
    without the safety shield even when training flies with it)."""
    venv = _vec_env(config, config.eval.n_envs, shielded=False)
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
        return build_finetune_model(
            config,
            train_env,
            seed=seed,
            device=device,
            tensorboard_log=tensorboard_log,
            source=source,
        )
    cls = algo_class(config.algo)
    check_replay_buffer_fits(config, train_env, source)
    return construct_model(
        cls,
        config,
        train_env,
        source,
        policy_kwargs(config),
        seed=seed,
        device=device,
        tensorboard_log=tensorboard_log,
    )


def machine_memory_bytes() -> int | None:
    """This machine's physical memory (bytes), or None where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def replay_buffer_bytes(config: TrainConfig, train_env: Any) -> int:
    """The bytes of the replay buffer SB3 allocates for ``config`` on ``train_env`` (0 for an
    on-policy algorithm): observations (twice, unless ``optimize_memory_usage``), actions,
    rewards, dones and time-out flags per transition."""
    import inspect

    if config.algo not in OFF_POLICY:
        return 0
    params = inspect.signature(algo_class(config.algo).__init__).parameters
    size = int(config.algo_kwargs.get("buffer_size", params["buffer_size"].default))
    obs, act = train_env.observation_space, train_env.action_space
    obs_bytes = int(np.prod(obs.shape)) * obs.dtype.itemsize
    act_bytes = int(np.prod(act.shape or (1,))) * max(act.dtype.itemsize, 4)
    copies = 1 if config.algo_kwargs.get("optimize_memory_usage") else 2
    return size * (copies * obs_bytes + act_bytes + 3 * 4)


def check_replay_buffer_fits(config: TrainConfig, train_env: Any, source: str) -> None:
    """Refuse a replay buffer larger than this machine's memory (numpy would fail to allocate
    it, or the system would swap until the run is killed).

    Raises:
        ConfigError: naming ``algo_kwargs.buffer_size``, the bytes it needs and the memory.
    """
    need, have = replay_buffer_bytes(config, train_env), machine_memory_bytes()
    if have is not None and need > have:
        raise ConfigError(
            f"{source}: config key 'algo_kwargs.buffer_size' asks for a replay buffer of "
            f"{need / 2**30:,.1f} GiB; this machine has {have / 2**30:,.1f} GiB of memory. "
            "Lower buffer_size"
        )
