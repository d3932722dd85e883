"""Checks behind :meth:`TrainConfig.from_dict`: keys, types and ranges of a config mapping, and
the curriculum, policy and algorithm keyword arguments (against the SB3 signatures).

Every problem raises :class:`~agents.policies.model_files.ConfigError` naming the key and the file.
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import math
import re
import typing
from collections.abc import Iterable, Sequence
from types import NoneType
from typing import Any

from agents.policies.model_files import ConfigError

ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")
"""``policy_kwargs.activation_fn`` values (names of ``torch.nn`` activations, lower case)."""

RESERVED_ALGO_KWARGS = {
    "policy": "top-level key 'policy'",
    "env": "top-level keys 'env_id' and 'env_kwargs'",
    "policy_kwargs": "top-level key 'policy_kwargs'",
    "seed": "train.py --seed",
    "device": "train.py --device",
    "verbose": "train.py (it sets SB3's verbosity itself)",
    "tensorboard_log": "the run directory (DIR/tb, automatic)",
    "_init_setup_model": "nothing (internal)",
}


def config_error(source: str, key: str, problem: str) -> ConfigError:
    return ConfigError(f"{source}: config key {key!r} {problem}")


def _suggest(key: str, known: Iterable[str]) -> str:
    match = difflib.get_close_matches(key, list(known), n=1)
    return f" (did you mean {match[0]!r}?)" if match else ""


def check_keys(data: Any, known: Sequence[str], prefix: str, source: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        where = prefix.rstrip(".") or "the top level"
        raise ConfigError(f"{source}: {where} must be a mapping, got {type(data).__name__}")
    for key in data:
        if key not in known:
            raise config_error(
                source,
                f"{prefix}{key}",
                f"is unknown{_suggest(str(key), known)}; known keys here: {', '.join(known)}",
            )
    return data


_FLOAT_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def number(value: Any) -> Any:
    """YAML 1.1 reads ``3e-4`` as a string; turn numeric strings into floats."""
    if isinstance(value, str) and _FLOAT_RE.match(value.strip()):
        return float(value)
    return value


def typed(value: Any, kind: type, key: str, source: str, optional: bool = False) -> Any:
    value = number(value)
    if value is None:
        if optional:
            return None
        raise config_error(source, key, "must not be null")
    if kind is bool:
        if not isinstance(value, bool):
            raise config_error(source, key, f"must be true or false, got {value!r}")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
            raise config_error(source, key, f"must be an integer, got {value!r}")
        return int(value)
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise config_error(source, key, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise config_error(source, key, f"must be finite, got {value!r}")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise config_error(source, key, f"must be a string, got {value!r}")
        return value
    if kind is dict:
        if not isinstance(value, dict):
            raise config_error(source, key, f"must be a mapping, got {value!r}")
        return dict(value)
    if kind is list:
        if not isinstance(value, list):
            raise config_error(source, key, f"must be a list, got {value!r}")
        return list(value)
    raise TypeError(kind)  # pragma: no cover


def at_least(value: float | None, low: float, key: str, source: str) -> None:
    if value is not None and value < low:
        raise config_error(source, key, f"must be >= {low}, got {value!r}")


def section(cls: type, data: Any, prefix: str, source: str) -> Any:
    """Build a flat dataclass section, each value checked against its field's annotation
    (``bool``, ``int``, ``float`` or ``str``, optionally ``| None``)."""
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    data = check_keys({} if data is None else data, names, prefix, source)
    values = {}
    for name in names:
        if name in data:
            args = typing.get_args(hints[name])  # (float, NoneType) for ``float | None``
            kind = next(k for k in args or (hints[name],) if k is not NoneType)
            values[name] = typed(data[name], kind, f"{prefix}{name}", source, NoneType in args)
    return cls(**values)


def validate_curriculum(
    data: Any, env_kwargs: dict[str, Any], spec_kwargs: dict[str, Any], final: Any, source: str
) -> list[dict[str, Any]]:
    """Curriculum stages: ``until`` strictly increasing, env options valid, same spaces."""
    from debris_gym.config import EnvConfig
    from debris_gym.envs.common import observation_names

    stages = typed(data if data is not None else [], list, "curriculum", source)
    out: list[dict[str, Any]] = []
    previous = 0
    for k, stage in enumerate(stages):
        where = f"curriculum[{k}]"
        stage = check_keys(stage, ["until", "env_kwargs"], f"{where}.", source)
        if "until" not in stage:
            raise config_error(source, f"{where}.until", "is missing (required)")
        until = typed(stage["until"], int, f"{where}.until", source)
        if until <= previous:
            raise config_error(
                source, f"{where}.until", f"must be > {previous} (stages in increasing order)"
            )
        previous = until
        kwargs = typed(stage.get("env_kwargs") or {}, dict, f"{where}.env_kwargs", source)
        options = {k2: v for k2, v in {**env_kwargs, **kwargs}.items() if k2 != "max_episode_steps"}
        try:
            cfg = EnvConfig.from_kwargs(**{**spec_kwargs, **options})
        except (TypeError, ValueError) as exc:
            raise config_error(source, f"{where}.env_kwargs", f"is invalid: {exc}") from None
        if len(observation_names(cfg)) != len(observation_names(final)) or (
            cfg.action,
            cfg.dim,
        ) != (final.action, final.dim):
            raise config_error(
                source,
                f"{where}.env_kwargs",
                "changes the observation or action space (keep obs_targets, obs_obstacles, "
                "observation, lidar_rays, obs_goal, action and dim as in env_kwargs)",
            )
        out.append({"until": until, "env_kwargs": kwargs})
    return out


def validate_policy_kwargs(data: Any, policy_cls: type, source: str) -> dict[str, Any]:
    params = inspect.signature(policy_cls.__init__).parameters
    known = [p for p in params if p not in ("self", "observation_space", "action_space")]
    known = [p for p in known if p != "lr_schedule"]
    kwargs = dict(check_keys({} if data is None else data, known, "policy_kwargs.", source))
    for key, value in kwargs.items():
        kwargs[key] = number(value)
    if "activation_fn" in kwargs:
        name = kwargs["activation_fn"]
        if name not in ACTIVATIONS:
            raise config_error(
                source,
                "policy_kwargs.activation_fn",
                f"must be one of {', '.join(ACTIVATIONS)}, got {name!r}",
            )
    for key in ("features_extractor_class", "optimizer_class"):
        if key in kwargs:
            raise config_error(source, f"policy_kwargs.{key}", "cannot be set from a config file")
    if "net_arch" in kwargs:
        arch = kwargs["net_arch"]

        def layers(value: Any, key: str) -> list[int]:
            if not isinstance(value, list) or not all(
                isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in value
            ):
                raise config_error(
                    source, key, f"must be a list of layer sizes >= 1, got {value!r}"
                )
            return list(value)

        if isinstance(arch, dict):
            heads = ("pi", "vf", "qf")
            check_keys(arch, heads, "policy_kwargs.net_arch.", source)
            kwargs["net_arch"] = {
                k: layers(v, f"policy_kwargs.net_arch.{k}") for k, v in arch.items()
            }
        else:
            kwargs["net_arch"] = layers(arch, "policy_kwargs.net_arch")
    return kwargs


def validate_algo_kwargs(data: Any, cls: type, algo: str, source: str) -> dict[str, Any]:
    params = inspect.signature(cls.__init__).parameters
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: algo_kwargs must be a mapping, got {type(data).__name__}")
    for key in data:
        if key in RESERVED_ALGO_KWARGS:
            raise config_error(
                source, f"algo_kwargs.{key}", f"is not set here; use {RESERVED_ALGO_KWARGS[key]}"
            )
    known = [p for p in params if p != "self" and p not in RESERVED_ALGO_KWARGS]
    kwargs = dict(check_keys(data, known, "algo_kwargs.", source))
    for key, value in list(kwargs.items()):
        value = number(value)
        default = params[key].default
        if isinstance(default, int) and not isinstance(default, bool) and isinstance(value, float):
            if value != int(value):
                raise config_error(
                    source, f"algo_kwargs.{key}", f"must be an integer, got {value!r}"
                )
            value = int(value)
        kwargs[key] = value
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str):
            if not (value.startswith("lin_") and _FLOAT_RE.match(value[4:])):
                raise config_error(
                    source,
                    f"algo_kwargs.{key}",
                    f"must be a number or 'lin_<number>' (linear decay), got {value!r}",
                )
        elif value is not None:
            typed(value, float, f"algo_kwargs.{key}", source)
    if "gamma" in kwargs:
        gamma = typed(kwargs["gamma"], float, "algo_kwargs.gamma", source)
        if not 0.0 <= gamma <= 1.0:
            raise config_error(source, "algo_kwargs.gamma", f"must lie in [0, 1], got {gamma}")
    if "train_freq" in kwargs and isinstance(kwargs["train_freq"], list):
        freq = kwargs["train_freq"]
        if len(freq) != 2 or freq[1] not in ("step", "episode"):
            raise config_error(
                source, "algo_kwargs.train_freq", f"must be n or [n, step|episode], got {freq!r}"
            )
    if "action_noise" in kwargs and kwargs["action_noise"] is not None:
        noise = check_keys(
            kwargs["action_noise"], ("type", "sigma"), "algo_kwargs.action_noise.", source
        )
        if noise.get("type") not in ("normal", "ornstein_uhlenbeck"):
            raise config_error(
                source,
                "algo_kwargs.action_noise.type",
                f"must be 'normal' or 'ornstein_uhlenbeck', got {noise.get('type')!r}",
            )
        sigma = typed(noise.get("sigma"), float, "algo_kwargs.action_noise.sigma", source)
        at_least(sigma, 0.0, "algo_kwargs.action_noise.sigma", source)
        kwargs["action_noise"] = {"type": noise["type"], "sigma": sigma}
    return kwargs
