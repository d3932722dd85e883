"""Where a trained model's files live, and how to read them, without importing the trainer.

A run directory written by ``train.py`` (or ``imitate.py``) holds ``model.zip``, its
VecNormalize statistics beside it (:func:`sidecar_path`) and the resolved ``config.yaml``
(:func:`read_config_mapping`). Both the loader of learned policies and the trainer use these names,
so they live here, below both.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

LEARNED_ALGOS = ("ppo", "sac", "td3", "dqn", "recurrent_ppo")
"""Algorithms whose saved models :func:`agents.load_agent` loads: the SB3 classes of the same
name, and sb3-contrib's ``RecurrentPPO`` (an LSTM policy)."""

FINAL_MODEL = "model.zip"
"""File name of a run's final model inside its directory."""

CHECKPOINT_RE = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps$")
"""The stem of an SB3 checkpoint, ``rl_model_N_steps``."""


def algo_class(algo: str) -> type:
    """The Stable-Baselines3 class of ``algo`` (one of :data:`LEARNED_ALGOS`).

    Raises:
        ValueError: ``recurrent_ppo`` without the sb3-contrib package installed.
    """
    import stable_baselines3 as sb3

    if algo == "recurrent_ppo":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError:
            raise ValueError(
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


MAX_CONFIG_BYTES = 1_000_000
"""Largest config file read (the checked-in ones are a few kB; a larger one is not a config)."""


def read_config_mapping(path: str | Path) -> dict[str, Any]:
    """The mapping a YAML config file holds (a run's ``config.yaml``, a recipe).

    Any readable file that is not a directory is read (a pipe such as ``<(...)`` too), at most
    :data:`MAX_CONFIG_BYTES` of it.

    Raises:
        FileNotFoundError: no such file.
        ValueError: a directory, unreadable, larger than :data:`MAX_CONFIG_BYTES`, not UTF-8
            text, not YAML, or not a mapping; the message names the file.
    """
    import yaml

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"config file {str(path)!r} not found")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, not a config file")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{path}: cannot be read ({exc.strerror})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ValueError(f"{path}: larger than {MAX_CONFIG_BYTES:,} bytes; not a config file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{path}: not a YAML text file (byte {exc.start} is not UTF-8 text)"
        ) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(data, dict):
        what = "is empty" if data is None else f"holds a {type(data).__name__}"
        raise ValueError(f"{path}: {what}; a config file holds a mapping of config keys")
    return data
