"""The checked-in experiment configs and ``--set`` overrides, shared by training and imitation.

Configs live in ``agents/configs/`` as ``<env>_<algo>.yaml`` (training) and
``<env>_imitation.yaml`` (imitation); :func:`~agents.policies.model_files.load_config_file`
reads them.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from agents.policies.model_files import ConfigError

__all__ = ["CONFIG_DIR", "apply_overrides", "env_stub"]

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"
"""The checked-in configs, ``<env>_<algo>.yaml`` (e.g. ``rendezvous2d_ppo.yaml``)."""


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
        value = yaml.safe_load(text) if text.strip() else None
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
