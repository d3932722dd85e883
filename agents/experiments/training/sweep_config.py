"""The ``sweep:`` section of a training recipe: the search space of a hyper-parameter sweep
(``sweep.py``, :mod:`agents.experiments.distributed.sweep`), typed and validated with the rest
of the config.

.. code-block:: yaml

    sweep:
      num_samples: 4            # trials
      metric: success_rate      # success_rate or mean_reward, of the final evaluation
      mode: max                 # max or min
      seed: 0                   # seed of the search (which values are drawn)
      params:                   # dotted config key: one distribution
        algo_kwargs.learning_rate: {loguniform: [1.0e-4, 1.0e-3]}
        algo_kwargs.n_epochs: {choice: [3, 5, 10]}
        algo_kwargs.ent_coef: {uniform: [0.0, 0.01]}
        algo_kwargs.n_steps: {randint: [32, 129]}   # integers low <= k < high

Each trial is the recipe with its drawn values set (as ``--set KEY=VALUE`` would), so every
value a distribution can draw must give a valid config: the checks try the ends of each range
and every choice against the recipe's own validation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from agents.experiments.training.validation import (
    at_least,
    at_most,
    check_keys,
    config_error,
    number,
    section,
    typed,
)

__all__ = ["DISTRIBUTIONS", "MAX_SAMPLES", "METRICS", "SweepConfig", "SweepParam", "validate_sweep"]

DISTRIBUTIONS = ("choice", "uniform", "loguniform", "randint")
"""Distributions a swept key may draw from (Ray Tune's of the same names)."""

MAX_SAMPLES = 10_000
"""Most trials a sweep runs."""

METRICS = ("success_rate", "mean_reward")
"""What a trial reports and the sweep ranks by: the final periodic evaluation's success rate or
mean return (held-out seeds, ``eval.n_episodes`` episodes)."""

FIXED_KEYS = ("version", "env_id", "algo", "sweep", "notes")
"""Top-level keys a sweep may not vary (they name the recipe, not its hyper-parameters)."""


@dataclass(frozen=True)
class SweepParam:
    """One swept key.

    Attributes:
        kind: one of :data:`DISTRIBUTIONS`.
        values: the choices (``choice``) or ``[low, high]`` (``uniform``, ``loguniform``:
            floats, low < high, low > 0 for loguniform; ``randint``: integers, low <= k < high).
    """

    kind: str
    values: list[Any]

    def extremes(self) -> list[Any]:
        """Values that bound what the distribution draws (every choice, or both ends)."""
        if self.kind == "randint":
            return [self.values[0], self.values[1] - 1]
        return list(self.values)

    def to_dict(self) -> dict[str, Any]:
        """The YAML form, ``{kind: values}``."""
        return {self.kind: list(self.values)}


@dataclass(frozen=True)
class SweepConfig:
    """A recipe's search space (see the module docstring).

    Attributes:
        num_samples: trials (>= 1).
        metric: one of :data:`METRICS`.
        mode: ``"max"`` or ``"min"``.
        seed: seed of the search (>= 0): the same seed draws the same trials.
        params: {dotted config key: distribution}, at least one.
    """

    num_samples: int = 4
    metric: str = "success_rate"
    mode: str = "max"
    seed: int = 0
    params: dict[str, SweepParam] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The YAML form (what :func:`validate_sweep` reads)."""
        return {
            "num_samples": self.num_samples,
            "metric": self.metric,
            "mode": self.mode,
            "seed": self.seed,
            "params": {key: p.to_dict() for key, p in self.params.items()},
        }


@dataclass(frozen=True)
class _Flat:
    """The scalar keys of the section (checked by :func:`~agents.experiments.training.
    validation.section`)."""

    num_samples: int = 4
    metric: str = "success_rate"
    mode: str = "max"
    seed: int = 0


def validate_sweep(
    data: Any, check_values: Callable[[str, Any], None], source: str
) -> SweepConfig | None:
    """The ``sweep`` section (None when absent).

    Args:
        data: the section as parsed from YAML.
        check_values: ``check_values(key, value)`` raises ConfigError when setting config key
            ``key`` (dotted) to ``value`` makes the recipe invalid.
        source: the config's file name, for messages.

    Raises:
        ConfigError: the first problem, naming ``sweep.<key>``.
    """
    if data is None:
        return None
    data = dict(check_keys(data, [*_Flat.__dataclass_fields__, "params"], "sweep.", source))
    params_data = data.pop("params", None)
    flat = section(_Flat, data, "sweep.", source)
    at_least(flat.num_samples, 1, "sweep.num_samples", source)
    at_most(flat.num_samples, MAX_SAMPLES, "sweep.num_samples", source)
    at_least(flat.seed, 0, "sweep.seed", source)
    if flat.metric not in METRICS:
        raise config_error(
            source, "sweep.metric", f"must be one of {', '.join(METRICS)}, got {flat.metric!r}"
        )
    if flat.mode not in ("max", "min"):
        raise config_error(source, "sweep.mode", f"must be 'max' or 'min', got {flat.mode!r}")
    params_data = typed(params_data, dict, "sweep.params", source)
    if not params_data:
        raise config_error(source, "sweep.params", "must name at least one config key to sweep")
    params = {}
    for key, spec in params_data.items():
        where = f"sweep.params.{key}"
        if not isinstance(key, str) or not key.strip():
            raise config_error(source, "sweep.params", f"has a bad key {key!r}")
        if key.split(".")[0] in FIXED_KEYS:
            raise config_error(
                source, where, f"cannot be swept (the recipe's {key.split('.')[0]} is fixed)"
            )
        param = _param(spec, where, source)
        for value in param.extremes():
            try:
                check_values(key, value)
            except ValueError as exc:
                reason = str(exc).removeprefix(f"{source}: ")
                raise config_error(
                    source, where, f"can draw {value!r}, which the recipe refuses: {reason}"
                ) from None
        params[key] = param
    return SweepConfig(flat.num_samples, flat.metric, flat.mode, flat.seed, params)


def _param(spec: Any, where: str, source: str) -> SweepParam:
    """One ``{kind: values}`` entry, checked."""
    kinds = ", ".join(DISTRIBUTIONS)
    if not isinstance(spec, dict) or len(spec) != 1:
        raise config_error(
            source, where, f"must be one {{distribution: values}} mapping ({kinds}), got {spec!r}"
        )
    ((kind, values),) = spec.items()
    if kind not in DISTRIBUTIONS:
        raise config_error(source, where, f"has unknown distribution {kind!r}; known: {kinds}")
    if not isinstance(values, list) or not values:
        raise config_error(source, f"{where}.{kind}", f"must be a non-empty list, got {values!r}")
    if kind == "choice":
        return SweepParam(kind, list(values))
    values = [number(v) for v in values]
    if len(values) != 2 or any(
        isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
        for v in values
    ):
        raise config_error(source, f"{where}.{kind}", f"must be [low, high], got {values!r}")
    low, high = values
    if not low < high:
        raise config_error(source, f"{where}.{kind}", f"needs low < high, got {values!r}")
    if kind == "loguniform" and low <= 0:
        raise config_error(source, f"{where}.{kind}", f"needs low > 0, got {values!r}")
    if kind == "randint":
        if low != int(low) or high != int(high):
            raise config_error(source, f"{where}.{kind}", f"must be integers, got {values!r}")
        return SweepParam(kind, [int(low), int(high)])
    return SweepParam(kind, [float(low), float(high)])
