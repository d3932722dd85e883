"""Checks behind :meth:`TrainConfig.from_dict`: keys, types and ranges of a config mapping, and
the curriculum, policy and algorithm keyword arguments (against the SB3 signatures).

Every problem raises :class:`~agents.experiments.config_files.ConfigError` naming the key and the
file.
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

from agents.experiments.config_files import MAX_LAYER_WIDTH, MAX_LAYERS, ConfigError

ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")
"""``policy_kwargs.activation_fn`` values (names of ``torch.nn`` activations, lower case)."""

MAX_BUFFER_SIZE = 10**9
"""Largest replay buffer (transitions; at the default env's 74 observation elements, 600 GB):
a larger one is a typo. Whether a buffer fits this machine's memory is checked when the model is
built."""

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
    if isinstance(value, str):
        text = value.strip()  # str.strip knows more white space than float() does ("0\x1f")
        if _FLOAT_RE.match(text):
            return float(text)
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
        whole = (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and math.isfinite(value)
            and value == int(value)
        )
        if not whole:
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


def at_most(value: float | None, high: float, key: str, source: str) -> None:
    if value is not None and value > high:
        raise config_error(source, key, f"must be <= {high:_}, got {value!r}")


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
    """Curriculum stages ``{until: N, mission: {...}}``: ``until`` strictly increasing, each
    mission a valid ``reset(options={"mission": ...})`` of the final task's env (only
    :data:`~debris_gym.envs.common.MISSION_KEYS`; the spaces stay). ``env_kwargs`` is read as
    ``mission`` (configs written before the rungs were an env feature)."""
    from debris_gym.envs.common import checked_mission

    stages = typed(data if data is not None else [], list, "curriculum", source)
    out: list[dict[str, Any]] = []
    previous = 0
    for k, stage in enumerate(stages):
        where = f"curriculum[{k}]"
        stage = check_keys(stage, ["until", "mission", "env_kwargs"], f"{where}.", source)
        if "until" not in stage:
            raise config_error(source, f"{where}.until", "is missing (required)")
        until = typed(stage["until"], int, f"{where}.until", source)
        if until <= previous:
            raise config_error(
                source, f"{where}.until", f"must be > {previous} (stages in increasing order)"
            )
        previous = until
        if "mission" in stage and "env_kwargs" in stage:
            raise config_error(source, f"{where}", "give mission or env_kwargs, not both")
        key = "env_kwargs" if "env_kwargs" in stage else "mission"
        mission = typed(stage.get(key) or {}, dict, f"{where}.{key}", source)
        try:
            checked_mission(final, mission)
        except ValueError as exc:
            raise config_error(source, f"{where}.{key}", f"is invalid: {exc}") from None
        out.append({"until": until, "mission": mission})
    return out


def validate_policy_kwargs(data: Any, policy_cls: type[Any], source: str) -> dict[str, Any]:
    params = inspect.signature(policy_cls.__init__).parameters
    known = [p for p in params if p not in ("self", "observation_space", "action_space")]
    known = [p for p in known if p != "lr_schedule"]
    kwargs = dict(check_keys({} if data is None else data, known, "policy_kwargs.", source))
    for key, value in kwargs.items():
        default = params[key].default
        kwargs[key] = _typed_like_default(value, default, f"policy_kwargs.{key}", source)
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
            sizes = isinstance(value, list) and all(
                isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_LAYER_WIDTH
                for v in value
            )
            if not sizes or len(value) > MAX_LAYERS:
                raise config_error(
                    source,
                    key,
                    f"must be a list of at most {MAX_LAYERS} layer sizes in [1, "
                    f"{MAX_LAYER_WIDTH}], got {value!r}",
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


@dataclasses.dataclass(frozen=True)
class Range:
    """The allowed values of one numeric keyword argument.

    Attributes:
        kind: ``int`` or ``float``.
        low, high: bounds (None: unbounded on that side).
        low_open: ``low`` itself is excluded (``> low`` rather than ``>= low``).
        also: further allowed values outside the bounds (``-1`` for "as many as collected").
    """

    kind: type
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    also: tuple[Any, ...] = ()

    def describe(self) -> str:
        """The allowed values in words, e.g. ``"an integer >= 1"``, ``"a number in [0, 1]"``."""
        what = "an integer" if self.kind is int else "a number"
        if self.low is not None and self.high is not None:
            text = f"{what} in {'(' if self.low_open else '['}{self.low}, {self.high}]"
        elif self.low is not None:
            text = f"{what} {'>' if self.low_open else '>='} {self.low}"
        else:
            text = what
        return text + "".join(f" or {v!r}" for v in self.also)

    def contains(self, value: float) -> bool:
        if value in self.also:
            return True
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return self.high is None or value <= self.high


ALGO_KWARG_RANGES: dict[str, Range] = {
    "learning_rate": Range(float, 0, low_open=True),
    "n_steps": Range(int, 1),
    "batch_size": Range(int, 1),
    "n_epochs": Range(int, 1),
    "gamma": Range(float, 0, 1),
    "gae_lambda": Range(float, 0, 1),
    "clip_range": Range(float, 0, low_open=True),
    "clip_range_vf": Range(float, 0, low_open=True),
    "ent_coef": Range(float, 0),
    "vf_coef": Range(float, 0),
    "max_grad_norm": Range(float, 0, low_open=True),
    "target_kl": Range(float, 0, low_open=True),
    "sde_sample_freq": Range(int, 1, also=(-1,)),
    "stats_window_size": Range(int, 1),
    "buffer_size": Range(int, 1, MAX_BUFFER_SIZE),
    "learning_starts": Range(int, 0),
    "tau": Range(float, 0, 1, low_open=True),
    "train_freq": Range(int, 1),
    "gradient_steps": Range(int, 1, also=(-1,)),
    "target_update_interval": Range(int, 1),
    "exploration_fraction": Range(float, 0, 1),
    "exploration_initial_eps": Range(float, 0, 1),
    "exploration_final_eps": Range(float, 0, 1),
    "policy_delay": Range(int, 1),
    "target_policy_noise": Range(float, 0),
    "target_noise_clip": Range(float, 0),
}
"""Allowed values of the SB3 keyword arguments a recipe may set (``algo_kwargs.<key>``); every
algorithm takes the subset its signature has. ``learning_rate`` and ``clip_range`` may also be
``lin_<value>`` with the value in the same range; ``clip_range_vf`` and ``target_kl`` may be
null; SAC's ``ent_coef`` may also be ``auto`` or ``auto_<initial value > 0>``."""

ALGO_RANGE_OVERRIDES: dict[str, dict[str, Range]] = {
    "ppo": {"batch_size": Range(int, 2)},  # SB3 normalises advantages per minibatch
    "recurrent_ppo": {"batch_size": Range(int, 2)},
}
"""Per-algorithm ranges that differ from :data:`ALGO_KWARG_RANGES`."""

CLASS_ALGO_KWARGS = ("rollout_buffer_class", "replay_buffer_class")
"""Keyword arguments that take a Python class: not settable from a config file."""


def algo_kwarg_range(algo: str, key: str) -> Range | None:
    """The allowed values of ``algo_kwargs.<key>`` for ``algo`` (None: only its type is checked)."""
    return ALGO_RANGE_OVERRIDES.get(algo, {}).get(key) or ALGO_KWARG_RANGES.get(key)


def _in_range(value: Any, allowed: Range, key: str, source: str) -> Any:
    """``value`` as ``allowed.kind``, or a ConfigError naming the key, value and range."""
    problem = config_error(
        source, f"algo_kwargs.{key}", f"must be {allowed.describe()}, got {value!r}"
    )
    value = number(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise problem
    if not math.isfinite(value) or (allowed.kind is int and value != int(value)):
        raise problem
    value = int(value) if allowed.kind is int else float(value)
    if not allowed.contains(value):
        raise problem
    return value


def _typed_like_default(value: Any, default: Any, where: str, source: str) -> Any:
    """A keyword argument without a range: the type of SB3's default (bool, int or float)."""
    value = number(value)
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise config_error(source, where, f"must be true or false, got {value!r}")
    elif isinstance(default, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise config_error(source, where, f"must be a number, got {value!r}")
        if isinstance(default, int) and (not math.isfinite(value) or value != int(value)):
            raise config_error(source, where, f"must be an integer, got {value!r}")
        value = int(value) if isinstance(default, int) else value
    return value


def validate_algo_kwargs(data: Any, cls: type[Any], algo: str, source: str) -> dict[str, Any]:
    """The SB3 keyword arguments of a recipe, each checked against :data:`ALGO_KWARG_RANGES`
    (or, for keys without a range, against the type of SB3's default).

    Raises:
        ConfigError: an unknown, reserved or class-valued key, or a value out of its range.
    """
    params = inspect.signature(cls.__init__).parameters
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: algo_kwargs must be a mapping, got {type(data).__name__}")
    for key in data:
        if key in RESERVED_ALGO_KWARGS:
            raise config_error(
                source, f"algo_kwargs.{key}", f"is not set here; use {RESERVED_ALGO_KWARGS[key]}"
            )
        if key in CLASS_ALGO_KWARGS:
            raise config_error(source, f"algo_kwargs.{key}", "cannot be set from a config file")
    known = [p for p in params if p != "self" and p not in RESERVED_ALGO_KWARGS]
    kwargs = dict(check_keys(data, known, "algo_kwargs.", source))
    for key, value in list(kwargs.items()):
        allowed = algo_kwarg_range(algo, key)
        value = kwargs[key] = number(value)  # YAML 1.1 reads 3e-4 as a string
        if value is None and key in ("clip_range_vf", "target_kl"):
            continue
        # (learning_rate, clip_range and train_freq always have a range)
        if (
            key in ("learning_rate", "clip_range")
            and isinstance(value, str)
            and allowed is not None
        ):
            if not (value.startswith("lin_") and _FLOAT_RE.match(value[4:].strip())):
                raise config_error(
                    source,
                    f"algo_kwargs.{key}",
                    f"must be {allowed.describe()} or 'lin_<number>' (linear decay), got {value!r}",
                )
            _in_range(value[4:], allowed, key, source)
            continue
        if key == "ent_coef" and algo == "sac" and isinstance(value, str):
            initial = value[5:] if value.startswith("auto_") else None
            if value != "auto" and (initial is None or not _FLOAT_RE.match(initial.strip())):
                raise config_error(
                    source,
                    "algo_kwargs.ent_coef",
                    f"must be a number >= 0, 'auto' or 'auto_<number > 0>', got {value!r}",
                )
            if initial is not None:
                _in_range(initial, Range(float, 0, low_open=True), key, source)
            continue
        if key == "train_freq" and isinstance(value, list) and allowed is not None:
            if len(value) != 2 or value[1] not in ("step", "episode"):
                raise config_error(
                    source,
                    "algo_kwargs.train_freq",
                    f"must be n or [n, step|episode], got {value!r}",
                )
            kwargs[key] = [_in_range(value[0], allowed, key, source), value[1]]
            continue
        if allowed is not None:
            kwargs[key] = _in_range(value, allowed, key, source)
        elif key != "action_noise":
            default = params[key].default
            kwargs[key] = _typed_like_default(value, default, f"algo_kwargs.{key}", source)
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
