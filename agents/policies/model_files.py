"""Where a trained model's files live, and how to read them, without importing the trainer.

A run directory written by ``train.py`` (or ``imitate.py``) holds ``model.zip``, its
VecNormalize statistics beside it (:func:`sidecar_path`) and the resolved ``config.yaml``
(:func:`load_config_file`). Both the loader of learned policies and the trainer use these names,
so they live here, below both.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

ALGOS = ("ppo", "sac", "td3", "dqn", "recurrent_ppo")
"""Algorithms ``train.py`` trains: the SB3 classes of the same name, and sb3-contrib's
``RecurrentPPO`` (an LSTM policy)."""

ON_POLICY_ALGOS = ("ppo", "recurrent_ppo")
"""Algorithms that learn from rollouts (``n_steps`` × envs samples per update)."""

FINAL_MODEL = "model.zip"
"""File name of a run's final model inside its directory."""

CHECKPOINT_RE = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps$")
"""The stem of an SB3 checkpoint, ``rl_model_N_steps``."""


class ConfigError(ValueError):
    """A config problem; the message names the key and the file."""


def algo_class(algo: str) -> type:
    """The Stable-Baselines3 class of ``algo`` (one of :data:`ALGOS`).

    Raises:
        ConfigError: ``recurrent_ppo`` without the sb3-contrib package installed.
    """
    import stable_baselines3 as sb3

    if algo == "recurrent_ppo":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError:
            raise ConfigError(
                "algo 'recurrent_ppo' needs the sb3-contrib package: pip install sb3-contrib "
                '(or pip install -e ".[rl]")'
            ) from None
        return RecurrentPPO
    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3, "dqn": sb3.DQN}[algo]


def sidecar_path(model_path: str | Path, kind: str) -> Path:
    """Where the ``kind`` ("vecnormalize" or "replay_buffer") file of a model lives.

    ``DIR/model.zip`` → ``DIR/vecnormalize.pkl``; SB3 checkpoints ``rl_model_N_steps.zip`` →
    ``rl_model_vecnormalize_N_steps.pkl``; any other ``NAME.zip`` → ``NAME_vecnormalize.pkl``.
    """
    path = Path(model_path)
    stem = path.name[: -len(".zip")] if path.name.endswith(".zip") else path.name
    if path.name == FINAL_MODEL:
        return path.with_name(f"{kind}.pkl")
    match = CHECKPOINT_RE.match(stem)
    if match:
        return path.with_name(f"{match['prefix']}_{kind}_{match['steps']}_steps.pkl")
    return path.with_name(f"{stem}_{kind}.pkl")


def load_config_file(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read a config YAML: ``(config mapping, run metadata)`` — the ``run`` section of a resolved
    ``config.yaml`` is split off (checked-in configs have none).

    Raises:
        FileNotFoundError: no such file.
        ConfigError: not YAML, or not a mapping.
    """
    import yaml

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file {str(path)!r} not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: must hold a mapping of config keys")
    run = data.pop("run", None) or {}
    return data, run
