"""Experiment config files, shared by training and imitation: reading one
(:func:`load_config_file`), the checked-in ones, ``--set`` overrides and :class:`ConfigError`.

Configs live in ``agents/configs/`` as ``<env>_<algo>.yaml`` (training) and
``<env>_imitation.yaml`` (imitation); a run directory's ``config.yaml`` is the resolved config
with a ``run`` section.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from agents.policies.model_files import read_config_mapping

__all__ = [
    "CONFIG_DIR",
    "MAX_LAYERS",
    "MAX_LAYER_WIDTH",
    "ConfigError",
    "apply_overrides",
    "env_stub",
    "load_config_file",
]

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"
"""The checked-in configs, ``<env>_<algo>.yaml`` (e.g. ``rendezvous2d_ppo.yaml``)."""


MAX_LAYER_WIDTH = 4096
"""Widest hidden layer of a policy network (a wider one is a typo, and costs gigabytes)."""

MAX_LAYERS = 16
"""Most hidden layers of a policy network (per head)."""


class ConfigError(ValueError):
    """A config problem; the message names the key and the file."""


def load_config_file(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read a config YAML: ``(config mapping, run metadata)`` — the ``run`` section of a resolved
    ``config.yaml`` is split off (checked-in configs have none).

    Raises:
        FileNotFoundError: no such file.
        ConfigError: not a readable YAML text file of a mapping (the message names the file).
    """
    try:
        data = read_config_mapping(path)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    run = data.pop("run", None) or {}
    if not isinstance(run, dict):
        raise ConfigError(f"{path}: config key 'run' must be a mapping, got {run!r}")
    return data, run


def env_stub(env_id: str) -> str:
    """``"DebrisGym/Rendezvous2D-v0"`` → ``"rendezvous2d"`` (the config file name prefix)."""
    name = env_id.split("/")[-1].split(":")[-1]
    return re.sub(r"-v\d+$", "", name).lower()


def apply_overrides(data: dict[str, Any], overrides: Sequence[str]) -> dict[str, Any]:
    """Apply ``--set key.sub=value`` overrides (values parsed as YAML) to a config mapping.

    Raises:
        ValueError: an override without ``=``, or one that descends into a non-mapping.
    """
    data = json.loads(json.dumps(data))  # deep copy of plain data
    for item in overrides:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. algo_kwargs.batch_size=64")
        try:
            value = yaml.safe_load(text) if text.strip() else None
        except yaml.YAMLError as exc:
            problem = str(exc).splitlines()[0]
            raise ConfigError(
                f"--set {item!r}: the value is not plain YAML ({problem}); give a number, "
                "string, list or mapping"
            ) from None
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                where = ".".join(parts[: i + 1])
                raise ConfigError(f"--set {item!r}: config key {where!r} is not a mapping")
            node = child
        node[parts[-1]] = value
    return data
