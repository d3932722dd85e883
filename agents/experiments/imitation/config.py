"""The settings of an imitation run: :class:`ImitationConfig` (validated on construction), the
checked-in config files and ``--set`` overrides, and the expert they name.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.config_files import (
    CONFIG_DIR,
    MAX_LAYER_WIDTH,
    MAX_LAYERS,
    apply_overrides,
    env_stub,
    load_config_file,
)

__all__ = [
    "ACTIVATION_NAMES",
    "TRAIN_SEED",
    "ImitationConfig",
    "default_config_path",
    "expert_params",
    "load_imitation_config",
]

ACTIVATION_NAMES = ("tanh", "relu")
"""Hidden activations of the policy network."""

MAX_SEED = 2**31 - 1
"""Largest base seed (torch's manual_seed and the field seeds derived from it stay in range)."""

TRAIN_SEED = 5_000_000
"""Fields of imitation runs are reset with seeds ``seed + TRAIN_SEED + k``: apart from the
held-out evaluation seeds of train.py (1 000 000 + i) and of the docs (10 000 000, 20 000 000)."""


@dataclass(frozen=True)
class ImitationConfig:
    """Everything an imitation run depends on (validated on construction).

    Attributes:
        env_id: the DebrisGym ID.
        env_kwargs: env options (the observation options the policy will need, e.g.
            ``obs_goal``); the task itself should be the default one.
        expert: baseline name (:func:`agents.make_agent`).
        expert_kwargs: its constructor arguments (``ordering`` defaults to "nearest").
        bc_episodes: expert-flown episodes first.
        dagger_rounds: DAgger rounds after cloning.
        dagger_episodes: policy-flown, expert-labelled episodes per round.
        dagger_beta: probability per step that the expert's action is executed instead of the
            policy's in the DAgger rollouts (0 = pure DAgger).
        net_arch: hidden layer widths of the MLP.
        activation_fn: hidden activation ("tanh" or "relu").
        epochs: passes over the data set per fit (the first fit; later fits warm-start).
        refit_epochs: passes per fit after a DAgger round.
        batch_size: minibatch size.
        learning_rate: Adam step size.
        weight_decay: Adam weight decay.
        workers: rollout processes.
        max_episode_steps: time limit of the rollouts (None: the ID's).
        seed: base seed (fields, network initialisation, minibatch order).
    """

    env_id: str = "DebrisGym/Rendezvous2D-v2"
    env_kwargs: dict[str, Any] = field(
        default_factory=lambda: {"obs_goal": True, "obs_targets": 1, "obs_other_targets": True}
    )
    expert: str = "apf-mpc"
    expert_kwargs: dict[str, Any] = field(default_factory=lambda: {"ordering": "nearest"})
    bc_episodes: int = 400
    dagger_rounds: int = 4
    dagger_episodes: int = 200
    dagger_beta: float = 0.0
    net_arch: tuple[int, ...] = (256, 256)
    activation_fn: str = "tanh"
    epochs: int = 30
    refit_epochs: int = 10
    batch_size: int = 512
    learning_rate: float = 1e-3
    weight_decay: float = 0.0
    workers: int = 2
    max_episode_steps: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        ints = {
            "bc_episodes": (1, None),
            "dagger_rounds": (0, None),
            "dagger_episodes": (1, None),
            "epochs": (1, None),
            "refit_epochs": (1, None),
            "batch_size": (1, None),
            "workers": (1, 64),
            "seed": (0, MAX_SEED),
        }
        for key, (low, high) in ints.items():
            _check_int(key, getattr(self, key), low, high)
        if self.max_episode_steps is not None:
            _check_int("max_episode_steps", self.max_episode_steps, 1, None)
        floats = {  # key: (low, high, low excluded)
            "dagger_beta": (0.0, 1.0, False),
            "learning_rate": (0.0, None, True),
            "weight_decay": (0.0, None, False),
        }
        for key, (least, most, low_open) in floats.items():
            value = getattr(self, key)
            upper = f"{most:g}]" if most is not None else "inf)"
            allowed = f"{'(' if low_open else '['}{least:g}, {upper}"
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{key} must be a number in {allowed}, got {value!r}")
            above = value > least if low_open else value >= least
            inside = above and (most is None or value <= most)
            if not (np.isfinite(value) and inside):
                raise ValueError(f"{key}={value!r} is out of range; allowed: {allowed}")
        arch = self.net_arch
        if (
            not isinstance(arch, tuple)
            or not arch
            or any(isinstance(w, bool) or not isinstance(w, int) for w in arch)
            or any(not 1 <= w <= MAX_LAYER_WIDTH for w in arch)
            or len(arch) > MAX_LAYERS
        ):
            raise ValueError(
                f"net_arch={list(arch) if isinstance(arch, tuple) else arch!r} is out of range; "
                f"allowed: a non-empty list of at most {MAX_LAYERS} integer widths in "
                f"[1, {MAX_LAYER_WIDTH}]"
            )
        if self.activation_fn not in ACTIVATION_NAMES:
            raise ValueError(
                f"activation_fn={self.activation_fn!r}; allowed: {', '.join(ACTIVATION_NAMES)}"
            )
        for key in ("env_id", "expert"):
            if not isinstance(getattr(self, key), str):
                raise ValueError(f"{key}={getattr(self, key)!r} must be a string")
        for key in ("env_kwargs", "expert_kwargs"):
            if not isinstance(getattr(self, key), dict):
                raise ValueError(f"{key} must be a mapping, got {getattr(self, key)!r}")
        self._refuse_suite_seeds()

    @property
    def field_seeds(self) -> range:
        """Reset seeds of every field the run flies (expert rollouts, then DAgger rounds)."""
        first = TRAIN_SEED + self.seed * 100_000
        return range(first, first + self.bc_episodes + self.dagger_rounds * self.dagger_episodes)

    def _refuse_suite_seeds(self) -> None:
        """Suites are evaluation-only: no imitation field may be a frozen suite's mission."""
        from debris_gym.suites import refuse_suite_seeds

        refuse_suite_seeds(self.field_seeds, "imitation (seed, bc_episodes, dagger_*)")

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["net_arch"] = list(self.net_arch)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "config") -> ImitationConfig:
        """Build from a mapping (a YAML file's), rejecting unknown keys by name.

        Raises:
            ValueError: an unknown key (the closest known one suggested), a bad value.
        """
        known = [f.name for f in dataclasses.fields(cls)]
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key == "version":
                continue
            if key not in known:
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ValueError(f"{source}: unknown key {key!r}{hint}; known: {', '.join(known)}")
            kwargs[key] = value
        if isinstance(kwargs.get("net_arch"), list):
            kwargs["net_arch"] = tuple(kwargs["net_arch"])
        for key in ("env_kwargs", "expert_kwargs"):
            if key in kwargs and not isinstance(kwargs[key], dict):
                raise ValueError(f"{source}: {key} must be a mapping, got {kwargs[key]!r}")
        try:
            config = cls(**kwargs)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source}: {exc}") from None
        config.check_env()
        return config

    def check_env(self) -> None:
        """Validate ``env_id`` and ``env_kwargs`` with the env's own checks.

        Raises:
            ValueError: an unknown ID or a bad env option.
        """
        import gymnasium as gym

        import debris_gym  # noqa: F401

        if self.env_id not in gym.registry:
            raise ValueError(f"unknown env_id {self.env_id!r}")
        kwargs = dict(self.env_kwargs)
        if kwargs.get("action", "continuous") != "continuous":
            raise ValueError("imitation needs env_kwargs.action = 'continuous' (the expert's)")
        from debris_gym.config import EnvConfig

        EnvConfig.from_kwargs(**{**gym.registry[self.env_id].kwargs, **kwargs})
        import agents

        env = gym.make(self.env_id, **kwargs)
        try:  # the expert's own checks (unknown name, bad parameters)
            agents.make_agent(self.expert, env, **expert_params(self.expert_kwargs))
        except TypeError as exc:
            raise ValueError(f"expert_kwargs: {exc}") from None
        finally:
            env.close()


def _check_int(key: str, value: Any, low: int, high: int | None) -> None:
    """``value`` is an integer in ``[low, high]`` (``high`` None: no upper bound)."""
    allowed = f"[{low}, {high}]" if high is not None else f">= {low}"
    if isinstance(value, bool) or not isinstance(value, int):
        words = f"in {allowed}" if high is not None else allowed
        raise ValueError(f"{key} must be an integer {words}, got {value!r}")
    if value < low or (high is not None and value > high):
        raise ValueError(f"{key}={value} is out of range; allowed: {allowed}")


def expert_params(kwargs: dict[str, Any]) -> dict[str, Any]:
    """The expert's constructor arguments, with the parameter mappings of a YAML file
    (``apf``, ``mpc``, ``reference``) turned into their dataclasses."""
    from agents.control.mpc import MPCParams
    from agents.control.reference import ReferenceParams
    from agents.planners.apf import APFParams

    classes = {"apf": APFParams, "mpc": MPCParams, "reference": ReferenceParams}
    out = dict(kwargs)
    for key, cls in classes.items():
        if isinstance(out.get(key), dict):
            out[key] = cls(**out[key])
    return out


def default_config_path(env_id: str) -> Path:
    """The checked-in imitation config of ``env_id`` (``agents/configs/<env>_imitation.yaml``)."""
    return CONFIG_DIR / f"{env_stub(env_id)}_imitation.yaml"


def load_imitation_config(
    env_id: str,
    path: str | Path | None = None,
    overrides: Sequence[str] = (),
    seed: int | None = None,
) -> ImitationConfig:
    """The run's configuration: a YAML file (default: :func:`default_config_path`), ``--set``
    overrides, then ``seed``.

    Raises:
        FileNotFoundError: no such file (or no checked-in config for ``env_id``).
        ValueError: bad YAML, keys or values; an ``env_id`` in the file other than ``env_id``.
    """
    source = Path(path) if path is not None else default_config_path(env_id)
    if path is None and not source.is_file():
        raise FileNotFoundError(
            f"no imitation config for {env_id} ({source.name}); give --config FILE"
        )
    data, _ = load_config_file(source)
    data = apply_overrides(data, overrides)
    file_env = data.setdefault("env_id", env_id)
    if env_stub(str(file_env)) != env_stub(env_id):  # versions of one env share a config
        raise ValueError(f"{source}: env_id {file_env!r} differs from --env {env_id!r}")
    data["env_id"] = env_id
    if seed is not None:
        data["seed"] = seed
    return ImitationConfig.from_dict(data, str(source))
