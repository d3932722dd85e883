"""Train SB3 agents (PPO, SAC, TD3, DQN) on the DebrisGym envs: configs, callbacks, runs, resume.

The library behind ``train.py``. Hyper-parameters live in versioned YAML files, one per env × algo,
shipped in ``agents/configs/`` (rl-zoo style); :class:`TrainConfig` is their typed, validated form
(:meth:`TrainConfig.from_dict` is the one place that checks keys and values). A run directory
holds::

    DIR/model.zip                 final model (written atomically)
    DIR/vecnormalize.pkl          its VecNormalize statistics (when normalisation is on)
    DIR/replay_buffer.pkl         off-policy replay buffer (when small, or on request)
    DIR/config.yaml               the resolved config plus how the run was made (``run:``)
    DIR/train_log.json            wall time and env-steps/s of every segment (fresh run, resumes)
    DIR/learning_curve.png        evaluation return and success rate vs timesteps, training return
    DIR/evaluations.npz           EvalCallback's log (held-out seeds >= EVAL_SEED)
    DIR/best_model.zip            best evaluation so far (+ best_model_vecnormalize.pkl)
    DIR/train_episodes.csv        every finished training episode (VecMonitor), with its timestep
    DIR/checkpoints/              rl_model_<N>_steps.zip (+ _vecnormalize_, _replay_buffer_ .pkl),
                                  interrupted.zip (+ interrupted_vecnormalize.pkl …) after Ctrl-C
    DIR/tb/                       TensorBoard logs (if the ``tensorboard`` package is installed)

Training envs are :class:`~debris_gym.integrations.sb3.NativeVecEnv` (the native vector env) in
SB3's ``VecMonitor`` and, optionally, ``VecNormalize``. Sub-env ``i`` of a fresh run is seeded with
``seed + i``; evaluation uses seeds ``EVAL_SEED + i`` so it never flies a training field first.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import difflib
import importlib.util
import inspect
import json
import math
import platform
import re
import shlex
import signal
import sys
import threading
import time
import zipfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.policies.model_files import (
    ALGOS,
    CHECKPOINT_RE,
    FINAL_MODEL,
    ConfigError,
    algo_class,
    load_config_file,
    sidecar_path,
)
from debris_gym.files import save_atomic, write_atomic

__all__ = [
    "ALGOS",
    "CONFIG_DIR",
    "EVAL_SEED",
    "CheckpointConfig",
    "EvalConfig",
    "NormalizeConfig",
    "TrainConfig",
    "TrainOptions",
    "TrainResult",
    "apply_overrides",
    "available_configs",
    "default_config_path",
    "find_latest_checkpoint",
    "load_config_file",
    "plot_learning_curve",
    "sidecar_path",
    "train",
]

OFF_POLICY = ("sac", "td3", "dqn")

CONFIG_DIR = Path(__file__).resolve().parent / "configs"
"""The checked-in configs, ``<env>_<algo>.yaml`` (e.g. ``rendezvous2d_ppo.yaml``)."""

EVAL_SEED = 1_000_000
"""Evaluation sub-env ``i`` is reset with seed ``EVAL_SEED + i``; training seeds stay below it."""

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v0"

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

CHECKPOINT_PREFIX = "rl_model"
INTERRUPTED = "interrupted"


# --------------------------------------------------------------------------------------------------
# configuration
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class NormalizeConfig:
    """SB3 ``VecNormalize`` around the training env.

    Attributes:
        enabled: wrap the env in VecNormalize at all.
        norm_obs: normalise observations by running mean / std (saved as ``vecnormalize.pkl`` and
            re-applied by :func:`agents.load_agent`).
        norm_reward: scale rewards by the running std of the discounted return (training only).
        clip_obs: clip normalised observations to ±clip_obs.
        clip_reward: clip scaled rewards to ±clip_reward.
        gamma: discount of the return whose std scales rewards; None = the algorithm's gamma.
        epsilon: added to the running variance before dividing (VecNormalize's ``epsilon``).
            A larger value (e.g. 0.01, a floor of 0.1 on the std) keeps an element that was
            constant so far — an empty target slot in a curriculum stage with fewer targets —
            from being blown up to ±clip_obs when it starts to vary.
    """

    enabled: bool = False
    norm_obs: bool = True
    norm_reward: bool = False
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    gamma: float | None = None
    epsilon: float = 1e-8


@dataclass(frozen=True)
class EvalConfig:
    """Periodic evaluation on held-out seeds (SB3 ``EvalCallback``).

    Attributes:
        freq: env steps (summed over sub-envs) between evaluations; 0 = no evaluation.
        n_episodes: episodes per evaluation (the same held-out fields every time).
        n_envs: sub-envs of the evaluation env.
        deterministic: evaluate the deterministic policy.
    """

    freq: int = 100_000
    n_episodes: int = 20
    n_envs: int = 10
    deterministic: bool = True


@dataclass(frozen=True)
class CheckpointConfig:
    """Periodic checkpoints (SB3 ``CheckpointCallback``) in ``DIR/checkpoints``.

    Attributes:
        freq: env steps between checkpoints; 0 = none (Ctrl-C still writes one).
        keep: most recent periodic checkpoints kept; 0 = keep all.
        replay_buffer: off-policy algos: save the replay buffer with checkpoints and the final
            model — ``"auto"`` (only if it is at most ``replay_buffer_max_mb``), ``"always"``,
            ``"never"``. Only the latest replay buffer is kept.
        replay_buffer_max_mb: the ``"auto"`` size limit (MB, the buffer's allocated arrays).
    """

    freq: int = 250_000
    keep: int = 3
    replay_buffer: str = "auto"
    replay_buffer_max_mb: float = 256.0


@dataclass(frozen=True)
class TrainConfig:
    """One training recipe: env × algorithm × hyper-parameters (a YAML file's typed form).

    Attributes:
        version: version of this recipe (bump it when hyper-parameters change).
        env_id: a DebrisGym ID.
        algo: one of :data:`ALGOS`.
        timesteps: default training budget (env steps over all sub-envs); ``--timesteps``
            overrides it.
        n_envs: training sub-envs (``--n-envs`` overrides it).
        env_kwargs: env options (any key of ``docs/environments.md``) and ``max_episode_steps``.
        policy: SB3 policy alias (``MlpPolicy``).
        policy_kwargs: keyword arguments of the policy; ``activation_fn`` by name (``tanh``).
        algo_kwargs: keyword arguments of the SB3 algorithm. ``learning_rate`` / ``clip_range``
            may be ``lin_<value>`` (linear decay to 0); ``action_noise`` (TD3/SAC) is
            ``{type: normal | ornstein_uhlenbeck, sigma: float}``; ``train_freq`` may be
            ``[n, "step" | "episode"]``.
        normalize: VecNormalize options.
        eval: evaluation options.
        checkpoint: checkpoint options.
        curriculum: training stages before the final task, each ``{until: N, env_kwargs:
            {...}}``: while fewer than N env steps are done, the training env uses
            ``env_kwargs`` merged over the top-level ones (e.g. fewer targets); afterwards the
            top-level ones. Observation and action spaces must not change; evaluation always
            flies the final task.
        notes: free text (what the recipe is for, what it was tuned on).
    """

    version: int
    env_id: str
    algo: str
    timesteps: int
    n_envs: int
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    policy: str = "MlpPolicy"
    policy_kwargs: dict[str, Any] = field(default_factory=dict)
    algo_kwargs: dict[str, Any] = field(default_factory=dict)
    normalize: NormalizeConfig = field(default_factory=NormalizeConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)
    curriculum: list[dict[str, Any]] = field(default_factory=list)
    notes: str = ""

    def stage(self, timesteps: int) -> int:
        """Index of the curriculum stage at ``timesteps`` (``len(curriculum)``: the final task)."""
        for k, stage in enumerate(self.curriculum):
            if timesteps < stage["until"]:
                return k
        return len(self.curriculum)

    def stage_env_kwargs(self, stage: int) -> dict[str, Any]:
        """The training env's options in curriculum stage ``stage``."""
        if stage >= len(self.curriculum):
            return dict(self.env_kwargs)
        return {**self.env_kwargs, **self.curriculum[stage]["env_kwargs"]}

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "config") -> TrainConfig:
        """Validate a config mapping (e.g. parsed YAML) and build the config.

        Every check lives here: unknown keys (with a close match suggested), missing required
        keys, types, ranges, env options (via the env's own validation), algorithm and policy
        keyword arguments (against the SB3 signatures), and algorithm vs action space.

        Raises:
            ValueError: the first problem found, naming the key and the source.
        """
        return _validate(data, source)

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (what ``config.yaml`` holds, without the ``run`` section)."""
        return dataclasses.asdict(self)

    @property
    def gamma(self) -> float:
        """The algorithm's discount (its SB3 default when the config does not set it)."""
        value = self.algo_kwargs.get("gamma")
        if value is None:
            value = inspect.signature(algo_class(self.algo).__init__).parameters["gamma"].default
        return float(value)


def _fail(source: str, key: str, problem: str) -> ConfigError:
    return ConfigError(f"{source}: config key {key!r} {problem}")


def _suggest(key: str, known: Iterable[str]) -> str:
    match = difflib.get_close_matches(key, list(known), n=1)
    return f" (did you mean {match[0]!r}?)" if match else ""


def _check_keys(data: Any, known: Sequence[str], prefix: str, source: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        where = prefix.rstrip(".") or "the top level"
        raise ConfigError(f"{source}: {where} must be a mapping, got {type(data).__name__}")
    for key in data:
        if key not in known:
            raise _fail(
                source,
                f"{prefix}{key}",
                f"is unknown{_suggest(str(key), known)}; known keys here: {', '.join(known)}",
            )
    return data


_FLOAT_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _number(value: Any) -> Any:
    """YAML 1.1 reads ``3e-4`` as a string; turn numeric strings into floats."""
    if isinstance(value, str) and _FLOAT_RE.match(value.strip()):
        return float(value)
    return value


def _typed(value: Any, kind: type, key: str, source: str, optional: bool = False) -> Any:
    value = _number(value)
    if value is None:
        if optional:
            return None
        raise _fail(source, key, "must not be null")
    if kind is bool:
        if not isinstance(value, bool):
            raise _fail(source, key, f"must be true or false, got {value!r}")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
            raise _fail(source, key, f"must be an integer, got {value!r}")
        return int(value)
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(source, key, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise _fail(source, key, f"must be finite, got {value!r}")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise _fail(source, key, f"must be a string, got {value!r}")
        return value
    if kind is dict:
        if not isinstance(value, dict):
            raise _fail(source, key, f"must be a mapping, got {value!r}")
        return dict(value)
    if kind is list:
        if not isinstance(value, list):
            raise _fail(source, key, f"must be a list, got {value!r}")
        return list(value)
    raise TypeError(kind)  # pragma: no cover


def _at_least(value: float | None, low: float, key: str, source: str) -> None:
    if value is not None and value < low:
        raise _fail(source, key, f"must be >= {low}, got {value!r}")


def _section(cls: type, data: Any, prefix: str, source: str, rules: dict[str, tuple]) -> Any:
    """Build a flat dataclass section; ``rules[name] = (type, optional)``."""
    names = [f.name for f in dataclasses.fields(cls)]
    data = _check_keys({} if data is None else data, names, prefix, source)
    values = {}
    for name in names:
        if name in data:
            kind, optional = rules[name]
            values[name] = _typed(data[name], kind, f"{prefix}{name}", source, optional)
    return cls(**values)


def _validate(data: dict[str, Any], source: str) -> TrainConfig:
    import gymnasium as gym

    import debris_gym  # noqa: F401  (registers the IDs)
    from debris_gym.config import EnvConfig

    top = [f.name for f in dataclasses.fields(TrainConfig)]
    data = _check_keys(data, top, "", source)
    for key in ("version", "env_id", "algo", "timesteps", "n_envs"):
        if key not in data:
            raise _fail(source, key, "is missing (required)")
    version = _typed(data["version"], int, "version", source)
    _at_least(version, 1, "version", source)
    env_id = _typed(data["env_id"], str, "env_id", source)
    if env_id not in gym.registry:
        ids = [i for i in gym.registry if i.startswith("DebrisGym/")]
        raise _fail(source, "env_id", f"names an unknown env {env_id!r}; known: {', '.join(ids)}")
    algo = _typed(data["algo"], str, "algo", source).lower()
    if algo not in ALGOS:
        raise _fail(source, "algo", f"must be one of {', '.join(ALGOS)}, got {algo!r}")
    timesteps = _typed(data["timesteps"], int, "timesteps", source)
    _at_least(timesteps, 1, "timesteps", source)
    n_envs = _typed(data["n_envs"], int, "n_envs", source)
    _at_least(n_envs, 1, "n_envs", source)
    notes = _typed(data.get("notes", ""), str, "notes", source, optional=True) or ""

    # env options: the env's own validation names the key
    env_kwargs = _typed(data.get("env_kwargs") or {}, dict, "env_kwargs", source)
    spec = gym.registry[env_id]
    options = {k: v for k, v in env_kwargs.items() if k != "max_episode_steps"}
    if "max_episode_steps" in env_kwargs:
        steps = _typed(env_kwargs["max_episode_steps"], int, "env_kwargs.max_episode_steps", source)
        _at_least(steps, 1, "env_kwargs.max_episode_steps", source)
        env_kwargs["max_episode_steps"] = steps
    try:
        env_config = EnvConfig.from_kwargs(**{**spec.kwargs, **options})
    except (TypeError, ValueError) as exc:
        raise _fail(source, "env_kwargs", f"is invalid: {exc}") from None
    if algo == "dqn" and env_config.action != "discrete":
        raise _fail(
            source,
            "env_kwargs.action",
            "must be 'discrete' for dqn (DQN needs a discrete action space); "
            "set env_kwargs: {action: discrete}",
        )
    if algo in ("sac", "td3") and env_config.action != "continuous":
        raise _fail(source, "env_kwargs.action", f"must be 'continuous' for {algo}")

    cls = algo_class(algo)
    policy = _typed(data.get("policy", "MlpPolicy"), str, "policy", source)
    if policy not in cls.policy_aliases:
        raise _fail(
            source, "policy", f"must be one of {', '.join(cls.policy_aliases)}, got {policy!r}"
        )
    policy_kwargs = _validate_policy_kwargs(
        data.get("policy_kwargs"), cls.policy_aliases[policy], source
    )
    algo_kwargs = _validate_algo_kwargs(data.get("algo_kwargs"), cls, algo, source)

    normalize = _section(
        NormalizeConfig,
        data.get("normalize"),
        "normalize.",
        source,
        {
            "enabled": (bool, False),
            "norm_obs": (bool, False),
            "norm_reward": (bool, False),
            "clip_obs": (float, False),
            "clip_reward": (float, False),
            "gamma": (float, True),
            "epsilon": (float, False),
        },
    )
    for key in ("clip_obs", "clip_reward", "epsilon"):
        if getattr(normalize, key) <= 0:
            raise _fail(source, f"normalize.{key}", "must be > 0")
    if normalize.gamma is not None and not 0.0 <= normalize.gamma <= 1.0:
        raise _fail(source, "normalize.gamma", f"must lie in [0, 1], got {normalize.gamma}")
    evaluation = _section(
        EvalConfig,
        data.get("eval"),
        "eval.",
        source,
        {
            "freq": (int, False),
            "n_episodes": (int, False),
            "n_envs": (int, False),
            "deterministic": (bool, False),
        },
    )
    _at_least(evaluation.freq, 0, "eval.freq", source)
    _at_least(evaluation.n_episodes, 1, "eval.n_episodes", source)
    _at_least(evaluation.n_envs, 1, "eval.n_envs", source)
    checkpoint = _section(
        CheckpointConfig,
        data.get("checkpoint"),
        "checkpoint.",
        source,
        {
            "freq": (int, False),
            "keep": (int, False),
            "replay_buffer": (str, False),
            "replay_buffer_max_mb": (float, False),
        },
    )
    _at_least(checkpoint.freq, 0, "checkpoint.freq", source)
    _at_least(checkpoint.keep, 0, "checkpoint.keep", source)
    _at_least(checkpoint.replay_buffer_max_mb, 0, "checkpoint.replay_buffer_max_mb", source)
    if checkpoint.replay_buffer not in ("auto", "always", "never"):
        raise _fail(
            source,
            "checkpoint.replay_buffer",
            f"must be 'auto', 'always' or 'never', got {checkpoint.replay_buffer!r}",
        )
    curriculum = _validate_curriculum(
        data.get("curriculum"), env_kwargs, spec.kwargs, env_config, source
    )
    return TrainConfig(
        version=version,
        env_id=env_id,
        algo=algo,
        timesteps=timesteps,
        n_envs=n_envs,
        env_kwargs=env_kwargs,
        policy=policy,
        policy_kwargs=policy_kwargs,
        algo_kwargs=algo_kwargs,
        normalize=normalize,
        eval=evaluation,
        checkpoint=checkpoint,
        curriculum=curriculum,
        notes=notes,
    )


def _validate_curriculum(
    data: Any, env_kwargs: dict[str, Any], spec_kwargs: dict[str, Any], final: Any, source: str
) -> list[dict[str, Any]]:
    """Curriculum stages: ``until`` strictly increasing, env options valid, same spaces."""
    from debris_gym.config import EnvConfig
    from debris_gym.envs.common import observation_names

    stages = _typed(data if data is not None else [], list, "curriculum", source)
    out: list[dict[str, Any]] = []
    previous = 0
    for k, stage in enumerate(stages):
        where = f"curriculum[{k}]"
        stage = _check_keys(stage, ["until", "env_kwargs"], f"{where}.", source)
        if "until" not in stage:
            raise _fail(source, f"{where}.until", "is missing (required)")
        until = _typed(stage["until"], int, f"{where}.until", source)
        if until <= previous:
            raise _fail(
                source, f"{where}.until", f"must be > {previous} (stages in increasing order)"
            )
        previous = until
        kwargs = _typed(stage.get("env_kwargs") or {}, dict, f"{where}.env_kwargs", source)
        options = {k2: v for k2, v in {**env_kwargs, **kwargs}.items() if k2 != "max_episode_steps"}
        try:
            cfg = EnvConfig.from_kwargs(**{**spec_kwargs, **options})
        except (TypeError, ValueError) as exc:
            raise _fail(source, f"{where}.env_kwargs", f"is invalid: {exc}") from None
        if len(observation_names(cfg)) != len(observation_names(final)) or (
            cfg.action,
            cfg.dim,
        ) != (final.action, final.dim):
            raise _fail(
                source,
                f"{where}.env_kwargs",
                "changes the observation or action space (keep obs_targets, obs_obstacles, "
                "observation, lidar_rays, obs_goal, action and dim as in env_kwargs)",
            )
        out.append({"until": until, "env_kwargs": kwargs})
    return out


def _validate_policy_kwargs(data: Any, policy_cls: type, source: str) -> dict[str, Any]:
    params = inspect.signature(policy_cls.__init__).parameters
    known = [p for p in params if p not in ("self", "observation_space", "action_space")]
    known = [p for p in known if p != "lr_schedule"]
    kwargs = dict(_check_keys({} if data is None else data, known, "policy_kwargs.", source))
    for key, value in kwargs.items():
        kwargs[key] = _number(value)
    if "activation_fn" in kwargs:
        name = kwargs["activation_fn"]
        if name not in ACTIVATIONS:
            raise _fail(
                source,
                "policy_kwargs.activation_fn",
                f"must be one of {', '.join(ACTIVATIONS)}, got {name!r}",
            )
    for key in ("features_extractor_class", "optimizer_class"):
        if key in kwargs:
            raise _fail(source, f"policy_kwargs.{key}", "cannot be set from a config file")
    if "net_arch" in kwargs:
        arch = kwargs["net_arch"]

        def layers(value: Any, key: str) -> list[int]:
            if not isinstance(value, list) or not all(
                isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in value
            ):
                raise _fail(source, key, f"must be a list of layer sizes >= 1, got {value!r}")
            return list(value)

        if isinstance(arch, dict):
            heads = ("pi", "vf", "qf")
            _check_keys(arch, heads, "policy_kwargs.net_arch.", source)
            kwargs["net_arch"] = {
                k: layers(v, f"policy_kwargs.net_arch.{k}") for k, v in arch.items()
            }
        else:
            kwargs["net_arch"] = layers(arch, "policy_kwargs.net_arch")
    return kwargs


def _validate_algo_kwargs(data: Any, cls: type, algo: str, source: str) -> dict[str, Any]:
    params = inspect.signature(cls.__init__).parameters
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: algo_kwargs must be a mapping, got {type(data).__name__}")
    for key in data:
        if key in RESERVED_ALGO_KWARGS:
            raise _fail(
                source, f"algo_kwargs.{key}", f"is not set here; use {RESERVED_ALGO_KWARGS[key]}"
            )
    known = [p for p in params if p != "self" and p not in RESERVED_ALGO_KWARGS]
    kwargs = dict(_check_keys(data, known, "algo_kwargs.", source))
    for key, value in list(kwargs.items()):
        value = _number(value)
        default = params[key].default
        if isinstance(default, int) and not isinstance(default, bool) and isinstance(value, float):
            if value != int(value):
                raise _fail(source, f"algo_kwargs.{key}", f"must be an integer, got {value!r}")
            value = int(value)
        kwargs[key] = value
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str):
            if not (value.startswith("lin_") and _FLOAT_RE.match(value[4:])):
                raise _fail(
                    source,
                    f"algo_kwargs.{key}",
                    f"must be a number or 'lin_<number>' (linear decay), got {value!r}",
                )
        elif value is not None:
            _typed(value, float, f"algo_kwargs.{key}", source)
    if "gamma" in kwargs:
        gamma = _typed(kwargs["gamma"], float, "algo_kwargs.gamma", source)
        if not 0.0 <= gamma <= 1.0:
            raise _fail(source, "algo_kwargs.gamma", f"must lie in [0, 1], got {gamma}")
    if "train_freq" in kwargs and isinstance(kwargs["train_freq"], list):
        freq = kwargs["train_freq"]
        if len(freq) != 2 or freq[1] not in ("step", "episode"):
            raise _fail(
                source, "algo_kwargs.train_freq", f"must be n or [n, step|episode], got {freq!r}"
            )
    if "action_noise" in kwargs and kwargs["action_noise"] is not None:
        noise = _check_keys(
            kwargs["action_noise"], ("type", "sigma"), "algo_kwargs.action_noise.", source
        )
        if noise.get("type") not in ("normal", "ornstein_uhlenbeck"):
            raise _fail(
                source,
                "algo_kwargs.action_noise.type",
                f"must be 'normal' or 'ornstein_uhlenbeck', got {noise.get('type')!r}",
            )
        sigma = _typed(noise.get("sigma"), float, "algo_kwargs.action_noise.sigma", source)
        _at_least(sigma, 0.0, "algo_kwargs.action_noise.sigma", source)
        kwargs["action_noise"] = {"type": noise["type"], "sigma": sigma}
    return kwargs


def env_stub(env_id: str) -> str:
    """``"DebrisGym/Rendezvous2D-v0"`` → ``"rendezvous2d"`` (the config file name prefix)."""
    name = env_id.split("/")[-1].split(":")[-1]
    return re.sub(r"-v\d+$", "", name).lower()


def default_config_path(env_id: str, algo: str) -> Path:
    """The checked-in config for ``env_id`` × ``algo`` (it may not exist)."""
    return CONFIG_DIR / f"{env_stub(env_id)}_{algo.lower()}.yaml"


def available_configs() -> list[str]:
    """Names of the checked-in training configs (``rendezvous2d_ppo``, …; one per algorithm,
    so not imitate.py's ``*_imitation.yaml``)."""
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml") if p.stem.rsplit("_", 1)[-1] in ALGOS)


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


# --------------------------------------------------------------------------------------------------
# envs and models
# --------------------------------------------------------------------------------------------------


def _vec_env(config: TrainConfig, n_envs: int) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor

    from debris_gym.integrations.sb3 import NativeVecEnv

    venv = NativeVecEnv(config.env_id, n_envs, **config.env_kwargs)
    return VecMonitor(venv, info_keywords=("is_success", "targets_captured"))


def make_train_env(config: TrainConfig, seed: int, stats: Path | None = None) -> Any:
    """Training VecEnv: NativeVecEnv → VecMonitor → VecNormalize (if enabled; stats restored from
    ``stats`` when given). Sub-env ``i`` is seeded with ``seed + i`` on the next reset."""
    from stable_baselines3.common.vec_env import VecNormalize

    venv = _vec_env(config, config.n_envs)
    norm = config.normalize
    if norm.enabled:
        if stats is not None:
            venv = VecNormalize.load(str(stats), venv)
            venv.training = True
            venv.norm_obs, venv.norm_reward = norm.norm_obs, norm.norm_reward
        else:
            venv = VecNormalize(
                venv,
                training=True,
                norm_obs=norm.norm_obs,
                norm_reward=norm.norm_reward,
                clip_obs=norm.clip_obs,
                clip_reward=norm.clip_reward,
                gamma=norm.gamma if norm.gamma is not None else config.gamma,
                epsilon=norm.epsilon,
            )
    venv.seed(seed)
    return venv


def make_eval_env(config: TrainConfig) -> Any:
    """Evaluation VecEnv (seeds ``EVAL_SEED + i``; VecNormalize frozen, synced from training)."""
    from stable_baselines3.common.vec_env import VecNormalize

    venv = _vec_env(config, config.eval.n_envs)
    if config.normalize.enabled:
        norm = config.normalize
        venv = VecNormalize(
            venv,
            training=False,
            norm_obs=norm.norm_obs,
            norm_reward=False,
            clip_obs=norm.clip_obs,
            clip_reward=norm.clip_reward,
            gamma=norm.gamma if norm.gamma is not None else config.gamma,
            epsilon=norm.epsilon,
        )
    venv.seed(EVAL_SEED)
    return venv


def _policy_kwargs(config: TrainConfig) -> dict[str, Any]:
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
    return kwargs


def _algo_kwargs(config: TrainConfig, action_dim: int) -> dict[str, Any]:
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


def _tensorboard_dir(out: Path) -> str | None:
    if importlib.util.find_spec("tensorboard") is None:
        print(
            "note: TensorBoard logging off (the 'tensorboard' package is not installed; "
            "pip install tensorboard)",
            file=sys.stderr,
        )
        return None
    return str(out / "tb")


# --------------------------------------------------------------------------------------------------
# file naming
# --------------------------------------------------------------------------------------------------


def model_timesteps(model_path: str | Path) -> int:
    """``num_timesteps`` stored in an SB3 model zip (read without building the model)."""
    with zipfile.ZipFile(model_path) as archive:
        data = json.loads(archive.read("data"))
    return int(data["num_timesteps"])


def find_latest_checkpoint(run_dir: str | Path) -> Path:
    """The model with the most timesteps among ``DIR/checkpoints/*.zip`` and ``DIR/model.zip``.

    Raises:
        FileNotFoundError: no readable model in the run directory.
    """
    run_dir = Path(run_dir)
    candidates = sorted((run_dir / "checkpoints").glob("*.zip"))
    if (run_dir / FINAL_MODEL).is_file():
        candidates.append(run_dir / FINAL_MODEL)
    best: tuple[int, float, Path] | None = None
    for path in candidates:
        try:
            key = (model_timesteps(path), path.stat().st_mtime, path)
        except (OSError, KeyError, ValueError, zipfile.BadZipFile):
            continue  # a half-written file from a hard kill
        if best is None or key[:2] > best[:2]:
            best = key
    if best is None:
        raise FileNotFoundError(
            f"no checkpoint in {run_dir} (looked for checkpoints/*.zip and {FINAL_MODEL})"
        )
    return best[2]


@contextlib.contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) that arrives inside the block, and raise it as a
    ``KeyboardInterrupt`` when the block ends.

    For saves during learning: a ``KeyboardInterrupt`` inside torch's zip writer comes out as a
    ``RuntimeError`` ("unexpected pos …"), which is not an interrupt and ended the run with an
    error instead of the interrupt checkpoint (seen in the Ctrl-C test). Only Python's default
    handler is replaced; off the main thread, or under any other handler (e.g. SIG_IGN while the
    final files are written), the block runs as it is.
    """
    main = threading.current_thread() is threading.main_thread()
    if not main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def _replay_buffer_bytes(model: Any) -> int:
    buffer = getattr(model, "replay_buffer", None)
    if buffer is None:
        return 0
    return sum(v.nbytes for v in vars(buffer).values() if isinstance(v, np.ndarray))


def _save_replay_buffer(config: TrainConfig, model: Any) -> bool:
    if config.algo not in OFF_POLICY or config.checkpoint.replay_buffer == "never":
        return False
    if config.checkpoint.replay_buffer == "always":
        return True
    return _replay_buffer_bytes(model) <= config.checkpoint.replay_buffer_max_mb * 1e6


def save_model_files(model: Any, config: TrainConfig, path: Path) -> list[Path]:
    """Save ``model`` at ``path`` with its VecNormalize stats and (per config) replay buffer,
    each atomically, under the :func:`sidecar_path` names. Returns the files written."""
    written = [save_atomic(path, model.save)]
    venv = model.get_vec_normalize_env()
    if venv is not None:
        written.append(save_atomic(sidecar_path(path, "vecnormalize"), venv.save))
    if _save_replay_buffer(config, model):
        written.append(save_atomic(sidecar_path(path, "replay_buffer"), model.save_replay_buffer))
    return written


# --------------------------------------------------------------------------------------------------
# callbacks
# --------------------------------------------------------------------------------------------------


def _callbacks_module() -> Any:
    from stable_baselines3.common import callbacks

    return callbacks


def _make_callbacks(
    config: TrainConfig, out: Path, eval_env: Any, resume_at: int | None, seed: int = 0
) -> tuple[list[Any], Any, Any, Any]:
    """(callbacks, eval callback or None, checkpoint callback or None, episode logger)."""
    cb = _callbacks_module()

    class CurriculumCallback(cb.BaseCallback):
        """Before each rollout, give the training env the options of the current stage."""

        def __init__(self) -> None:
            super().__init__()
            self.current: int | None = None

        def _on_rollout_start(self) -> None:
            from debris_gym.integrations.sb3 import NativeVecEnv

            stage = config.stage(self.num_timesteps)
            if stage == self.current:
                return
            kwargs = config.stage_env_kwargs(stage)
            holder = self.training_env  # VecNormalize → VecMonitor → NativeVecEnv
            while not isinstance(holder.venv, NativeVecEnv):
                holder = holder.venv
            holder.venv.close()
            holder.venv = NativeVecEnv(config.env_id, config.n_envs, **kwargs)
            self.training_env.seed(seed + stage)
            self.model._last_obs = self.training_env.reset()
            self.model._last_episode_starts = np.ones(config.n_envs, dtype=bool)
            self.current = stage
            final = stage == len(config.curriculum)
            what = "the final task" if final else f"until {config.curriculum[stage]['until']:,}"
            print(
                f"curriculum: stage {stage} ({what}) from step {self.num_timesteps:,}: "
                f"{config.curriculum[stage]['env_kwargs'] if not final else config.env_kwargs}",
                flush=True,
            )

        def _on_step(self) -> bool:
            return True

    class EpisodeLogCallback(cb.BaseCallback):
        """Append every finished training episode (VecMonitor's ``info["episode"]``) to a CSV."""

        columns = ("timesteps", "return", "length", "is_success", "targets_captured", "wall_s")

        def __init__(self, path: Path) -> None:
            super().__init__()
            self.path = path
            self.rows: list[tuple] = []
            self.start = time.perf_counter()

        def _on_training_start(self) -> None:
            if not self.path.exists():
                with open(self.path, "w", newline="") as fh:
                    csv.writer(fh).writerow(self.columns)

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", ()):
                ep = info.get("episode")
                if ep is not None:
                    self.rows.append(
                        (
                            self.num_timesteps,
                            round(float(ep["r"]), 6),
                            int(ep["l"]),
                            int(bool(ep.get("is_success", False))),
                            int(ep.get("targets_captured", 0)),
                            round(time.perf_counter() - self.start, 3),
                        )
                    )
            if len(self.rows) >= 256:
                self.flush()
            return True

        def flush(self) -> None:
            if self.rows:
                with open(self.path, "a", newline="") as fh:
                    csv.writer(fh).writerows(self.rows)
                self.rows = []

        def _on_training_end(self) -> None:
            self.flush()

    class SaveBest(cb.BaseCallback):
        """Called by EvalCallback on a new best model: save it and its VecNormalize stats,
        atomically and with a Ctrl-C held until both are written (EvalCallback's own save
        writes in place)."""

        def _on_step(self) -> bool:
            with _interrupts_deferred():
                save_atomic(out / "best_model.zip", self.model.save)
                venv = self.model.get_vec_normalize_env()
                if venv is not None:
                    save_atomic(sidecar_path(out / "best_model.zip", "vecnormalize"), venv.save)
            return True

    class HeldOutEvalCallback(cb.EvalCallback):
        """EvalCallback on the same held-out fields every time (seeds EVAL_SEED + i), timed."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.seconds = 0.0
            self._targets_buffer: list[int] = []
            self.evaluations_targets: list[list[int]] = []

        def _log_success_callback(self, locals_: dict, globals_: dict) -> None:
            super()._log_success_callback(locals_, globals_)
            if locals_["done"]:
                self._targets_buffer.append(int(locals_["info"].get("targets_captured", 0)))

        def _on_step(self) -> bool:
            if not (self.eval_freq > 0 and self.n_calls % self.eval_freq == 0):
                return True
            self.eval_env.seed(EVAL_SEED)
            self._targets_buffer = []
            start = time.perf_counter()
            # EvalCallback writes its log in place (a Ctrl-C mid-write would leave it cut): let
            # it write to a scratch name, and write the real file below, atomically
            log_path = self.log_path
            if log_path is not None:
                self.log_path = str(Path(log_path).with_name(".evaluations_scratch"))
            try:
                result = super()._on_step()
            finally:
                if log_path is not None:
                    with contextlib.suppress(FileNotFoundError):
                        Path(self.log_path + ".npz").unlink()
                self.log_path = log_path
            self.evaluations_targets.append(self._targets_buffer)
            if len(self.evaluations_successes) < len(self.evaluations_timesteps):
                self.evaluations_successes.append([np.nan])  # no episode reported is_success
            if self.log_path is not None:  # EvalCallback's file, plus targets captured
                arrays = dict(
                    timesteps=self.evaluations_timesteps,
                    results=self.evaluations_results,
                    ep_lengths=self.evaluations_length,
                    successes=self.evaluations_successes,
                    targets_captured=self.evaluations_targets,
                )
                save_atomic(Path(self.log_path + ".npz"), lambda tmp: np.savez(tmp, **arrays))
            self.seconds += time.perf_counter() - start
            returns = self.evaluations_results[-1] if self.evaluations_results else [np.nan]
            success = self.evaluations_successes[-1] if self.evaluations_successes else [np.nan]
            print(
                f"eval @ {self.num_timesteps:,} steps: return {np.mean(returns):.2f} "
                f"± {np.std(returns):.2f}, success {100 * np.mean(success):.0f}% "
                f"({len(returns)} held-out episodes, {time.perf_counter() - start:.1f} s)",
                flush=True,
            )
            return result

        def evaluate_now(self) -> None:
            """One evaluation now (at the end of training, if the last one is older)."""
            freq, calls = self.eval_freq, self.n_calls
            self.eval_freq, self.n_calls = 1, 0
            try:
                self._on_step()
            finally:
                self.eval_freq, self.n_calls = freq, calls

        def preload(self, path: Path, until: int) -> None:
            """Continue an earlier run's ``evaluations.npz`` (entries after ``until`` dropped)."""
            if not path.is_file():
                return
            try:
                self._preload(path, until)
            except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:  # cut by a kill
                print(f"note: ignoring unreadable {path.name} ({exc})", file=sys.stderr)

        def _preload(self, path: Path, until: int) -> None:
            with np.load(path, allow_pickle=True) as data:
                # every evaluation has an entry in each array; a run cut mid-write can leave
                # some arrays shorter, so keep only the evaluations that every array holds
                names = ("timesteps", "results", "ep_lengths", "successes", "targets_captured")
                present = [data[k] for k in names if k in data]
                n = min(len(a) for a in present)
                keep = [i for i in range(n) if data["timesteps"][i] <= until]
                self.evaluations_timesteps = [int(data["timesteps"][i]) for i in keep]
                self.evaluations_results = [list(data["results"][i]) for i in keep]
                self.evaluations_length = [list(data["ep_lengths"][i]) for i in keep]
                if "successes" in data:
                    self.evaluations_successes = [list(data["successes"][i]) for i in keep]
                if "targets_captured" in data:
                    self.evaluations_targets = [list(data["targets_captured"][i]) for i in keep]
            if self.evaluations_results:
                self.best_mean_reward = max(float(np.mean(r)) for r in self.evaluations_results)

    class PruningCheckpointCallback(cb.CheckpointCallback):
        """CheckpointCallback that keeps the last ``keep`` checkpoints and the latest buffer."""

        def __init__(self, *args: Any, keep: int = 0, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.keep = keep
            self.seconds = 0.0

        def _on_step(self) -> bool:
            if self.n_calls % self.save_freq != 0:
                return True
            start = time.perf_counter()
            with _interrupts_deferred():  # atomic and whole, unlike CheckpointCallback's
                save_model_files(self.model, config, Path(self._checkpoint_path(extension="zip")))
                self._prune()
            self.seconds += time.perf_counter() - start
            return True

        def _prune(self) -> None:
            folder = Path(self.save_path)
            models = sorted(
                folder.glob(f"{self.name_prefix}_*_steps.zip"), key=lambda p: model_steps(p)
            )
            if self.keep > 0:
                for old in models[: -self.keep]:
                    for path in (old, *(sidecar_path(old, k) for k in SIDECARS)):
                        path.unlink(missing_ok=True)
            buffers = sorted(
                folder.glob(f"{self.name_prefix}_replay_buffer_*_steps.pkl"),
                key=lambda p: int(p.stem.split("_")[-2]),
            )
            for old in buffers[:-1]:
                old.unlink(missing_ok=True)

    def model_steps(path: Path) -> int:
        match = CHECKPOINT_RE.match(path.stem)
        return int(match["steps"]) if match else -1

    episodes = EpisodeLogCallback(out / "train_episodes.csv")
    callbacks: list[Any] = [episodes]
    if config.curriculum:
        callbacks.insert(0, CurriculumCallback())
    n = config.n_envs
    checkpoint = None
    if config.checkpoint.freq > 0:
        checkpoint = PruningCheckpointCallback(
            save_freq=max(config.checkpoint.freq // n, 1),
            save_path=str(out / "checkpoints"),
            name_prefix=CHECKPOINT_PREFIX,
            save_replay_buffer=False,  # unused: _on_step saves through save_model_files
            save_vecnormalize=False,
            keep=config.checkpoint.keep,
        )
        callbacks.append(checkpoint)
    evaluation = None
    if config.eval.freq > 0:
        evaluation = HeldOutEvalCallback(
            eval_env,
            callback_on_new_best=SaveBest(),
            n_eval_episodes=config.eval.n_episodes,
            eval_freq=max(config.eval.freq // n, 1),
            log_path=str(out),
            best_model_save_path=None,  # SaveBest writes best_model.zip
            deterministic=config.eval.deterministic,
            verbose=0,
        )
        if resume_at is not None:
            evaluation.preload(out / "evaluations.npz", resume_at)
        callbacks.append(evaluation)
    return callbacks, evaluation, checkpoint, episodes


SIDECARS = ("vecnormalize", "replay_buffer")


# --------------------------------------------------------------------------------------------------
# the run
# --------------------------------------------------------------------------------------------------


@dataclass
class TrainOptions:
    """What ``train.py`` was asked for (see its ``--help``).

    Attributes:
        out: run directory (created; must not already hold a run unless resuming).
        env_id, algo: pick the checked-in config when ``config`` is None (defaults:
            Rendezvous2D, ppo); must agree with ``config`` when both are given.
        config: a config YAML file.
        overrides: ``key.sub=value`` strings applied to the config.
        timesteps: training budget (env steps); None = the config's. With ``resume``: steps to
            add (None = finish the run's budget).
        n_envs: overrides the config's ``n_envs``.
        seed: base seed (sub-env i: seed + i), 0 <= seed, seed + n_envs <= EVAL_SEED.
        resume: a run directory to continue from its latest checkpoint.
        progress: show SB3's progress bar.
        threads: torch CPU threads.
        device: torch device.
        argv: the command line (recorded in config.yaml).
    """

    out: Path | None = None
    env_id: str | None = None
    algo: str | None = None
    config: Path | None = None
    overrides: list[str] = field(default_factory=list)
    timesteps: int | None = None
    n_envs: int | None = None
    seed: int | None = None
    resume: Path | None = None
    progress: bool = True
    threads: int = 1
    device: str = "cpu"
    argv: list[str] | None = None


@dataclass
class TrainResult:
    """How a run (or one resumed segment) ended.

    Attributes:
        out: the run directory.
        status: ``"completed"`` or ``"interrupted"``.
        num_timesteps: the model's ``num_timesteps`` at the end.
        model_path: ``DIR/model.zip`` (completed) or the interrupt checkpoint.
        wall_time_s: wall time of this segment (s).
        env_steps_per_s: env steps of this segment / its wall time.
    """

    out: Path
    status: str
    num_timesteps: int
    model_path: Path
    wall_time_s: float
    env_steps_per_s: float


def resolve_config(options: TrainOptions) -> tuple[TrainConfig, str]:
    """The validated config of a fresh run and where it came from.

    Raises:
        FileNotFoundError: no checked-in config for env × algo (the message lists them).
        ValueError: an invalid config or override, or ``--env``/``--algo`` disagreeing with it.
    """
    if options.config is not None:
        path = Path(options.config)
    else:
        env_id = options.env_id or DEFAULT_ENV
        algo = (options.algo or "ppo").lower()
        if algo not in ALGOS:
            raise ConfigError(f"unknown algo {algo!r}; use one of {', '.join(ALGOS)}")
        path = default_config_path(env_id, algo)
        if not path.is_file():
            raise FileNotFoundError(
                f"no checked-in config for {env_id} × {algo} (expected {path.name} in "
                f"{CONFIG_DIR}); available: {', '.join(available_configs())}. Write one and pass "
                "--config FILE"
            )
    data, _ = load_config_file(path)
    for key, flag, value in (("env_id", "--env", options.env_id), ("algo", "--algo", options.algo)):
        given = data.get(key)
        if value is not None and given is not None and str(given).lower() != value.lower():
            raise ConfigError(f"{flag} {value!r} disagrees with {key}: {given!r} in {path}")
    data = apply_overrides(data, options.overrides)
    if options.n_envs is not None:
        data["n_envs"] = options.n_envs
    if options.timesteps is not None:
        data["timesteps"] = options.timesteps
    config = TrainConfig.from_dict(data, source=str(path))
    rollout = config.algo_kwargs.get("n_steps", 2048) * config.n_envs
    batch = config.algo_kwargs.get("batch_size", 64)
    if config.algo == "ppo" and batch > rollout:  # e.g. the 128-env recipe run with --n-envs 2
        print(
            f"note: batch_size {batch} > rollout size {rollout} (n_steps x n_envs); using "
            f"batch_size {rollout}",
            file=sys.stderr,
        )
        kwargs = {**config.algo_kwargs, "batch_size": rollout}
        config = dataclasses.replace(config, algo_kwargs=kwargs)
    return config, str(path)


def _check_seed(seed: int, n_envs: int) -> None:
    if seed < 0 or seed + n_envs > EVAL_SEED:
        raise ValueError(
            f"seed must satisfy 0 <= seed and seed + n_envs <= {EVAL_SEED} (evaluation uses "
            f"seeds from {EVAL_SEED}); got seed={seed}, n_envs={n_envs}"
        )


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import debris_gym

    versions = {
        "debris_gym": debris_gym.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gymnasium.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
    return {k: str(v) for k, v in versions.items()}  # torch's version is a str subclass


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _write_config(out: Path, config: TrainConfig, run: dict[str, Any]) -> None:
    header = (
        "# Resolved training config of this run (train.py writes it; --resume reads it).\n"
        "# The 'run' section records how the run was made.\n"
    )
    body = yaml.safe_dump(
        {**config.to_dict(), "run": run}, sort_keys=False, width=100, default_flow_style=None
    )
    write_atomic(out / "config.yaml", header + body)


def _read_log(out: Path) -> dict[str, Any]:
    path = out / "train_log.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def _write_log(out: Path, log: dict[str, Any]) -> None:
    segments = log.get("segments", [])
    wall = sum(s["wall_time_s"] for s in segments)
    steps = sum(s["end_timesteps"] - s["start_timesteps"] for s in segments)
    log["wall_time_s"] = round(wall, 3)
    log["env_steps"] = steps
    log["env_steps_per_s"] = round(steps / wall, 1) if wall > 0 else None
    ordered = {k: v for k, v in log.items() if k != "segments"} | {"segments": segments}
    write_atomic(out / "train_log.json", json.dumps(ordered, indent=2) + "\n")


def _row_ok(row: list[str], width: int) -> bool:
    """A complete numeric CSV row (a hard kill can leave a half-written last line)."""
    if len(row) != width:
        return False
    try:
        [float(v) for v in row]
    except ValueError:
        return False
    return True


def _truncate_episodes(path: Path, until: int) -> None:
    if not path.is_file():
        return
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    width = len(rows[0]) if rows else 0
    kept = [rows[0], *(r for r in rows[1:] if _row_ok(r, width) and int(r[0]) <= until)]
    if len(kept) != len(rows):
        buffer = "".join(",".join(r) + "\n" for r in kept)
        write_atomic(path, buffer)


def _close_progress_bar(callbacks: Sequence[Any]) -> None:
    cb = _callbacks_module()
    for c in callbacks:
        if isinstance(c, cb.ProgressBarCallback) and getattr(c, "pbar", None) is not None:
            with contextlib.suppress(Exception):
                c.pbar.close()


def train(options: TrainOptions) -> TrainResult:
    """Train (or resume) one run; see the module docstring for what lands in the directory.

    A ``KeyboardInterrupt`` during learning saves ``DIR/checkpoints/interrupted.zip`` (with its
    VecNormalize stats and, per config, replay buffer), updates the logs and the learning curve,
    and returns with ``status="interrupted"``; ``train(TrainOptions(resume=DIR))`` continues it.

    Raises:
        FileNotFoundError, ValueError: bad options or config (messages name the problem).
    """
    import torch
    from stable_baselines3.common.utils import set_random_seed

    torch.set_num_threads(max(int(options.threads), 1))
    argv = options.argv if options.argv is not None else sys.argv
    command = shlex.join(["python", *argv]) if argv else ""

    if options.resume is not None:
        out = Path(options.resume)
        for name, value in (
            ("--config", options.config),
            ("--env", options.env_id),
            ("--algo", options.algo),
            ("--n-envs", options.n_envs),
            ("--seed", options.seed),
            ("--set", options.overrides or None),
        ):
            if value is not None:
                raise ValueError(
                    f"{name} cannot be combined with --resume (a resumed run keeps its own config "
                    f"in {out / 'config.yaml'})"
                )
        if options.out is not None and Path(options.out).resolve() != out.resolve():
            raise ValueError("--out and --resume name different directories; give only --resume")
        data, run = load_config_file(out / "config.yaml")
        config = TrainConfig.from_dict(data, source=str(out / "config.yaml"))
        seed = int(run.get("seed", 0))
        checkpoint = find_latest_checkpoint(out)
        start_steps = model_timesteps(checkpoint)
        if options.timesteps is not None:
            add = int(options.timesteps)
        else:
            add = int(config.timesteps) - start_steps
            if add <= 0:
                raise ValueError(
                    f"the run in {out} already reached its budget ({start_steps:,} >= "
                    f"{config.timesteps:,} steps); pass --timesteps N to train N more"
                )
        if add < 1:
            raise ValueError(f"--timesteps must be >= 1, got {add}")
        config = dataclasses.replace(config, timesteps=max(config.timesteps, start_steps + add))
        source = run.get("config_source", str(out / "config.yaml"))
    else:
        if options.out is None:
            raise ValueError("--out DIR is required (or --resume DIR)")
        out = Path(options.out)
        if (out / "config.yaml").exists() or (out / FINAL_MODEL).exists():
            raise FileExistsError(
                f"{out} already holds a run; continue it with --resume {out} or pick another --out"
            )
        config, source = resolve_config(options)
        seed = 0 if options.seed is None else int(options.seed)
        checkpoint, start_steps, add = None, 0, config.timesteps
        run = {}

    log = _read_log(out)
    segments = log.setdefault("segments", [])
    segment = len(segments)
    segment_seed = seed + segment * config.n_envs
    _check_seed(segment_seed, config.n_envs)
    out.mkdir(parents=True, exist_ok=True)
    run = {
        **run,
        "command": run.get("command", command),
        "seed": seed,
        "config_source": source,
        "config_version": config.version,
        "started_at": run.get("started_at", _now()),
        "versions": _versions(),
        "device": options.device,
        "torch_threads": torch.get_num_threads(),
    }
    if options.resume is not None:
        run.setdefault("resumes", []).append(
            {"command": command, "from": str(checkpoint), "at": _now(), "add_timesteps": add}
        )
    else:
        run["overrides"] = list(options.overrides)

    set_random_seed(segment_seed)
    cls = algo_class(config.algo)
    stats = sidecar_path(checkpoint, "vecnormalize") if checkpoint is not None else None
    if stats is not None and config.normalize.enabled and not stats.is_file():
        raise FileNotFoundError(
            f"checkpoint {checkpoint} has no VecNormalize statistics ({stats.name}); cannot resume"
        )
    train_env = make_train_env(config, segment_seed, stats if config.normalize.enabled else None)
    eval_env = make_eval_env(config) if config.eval.freq > 0 else None
    tb = _tensorboard_dir(out)
    if checkpoint is None:
        model = cls(
            config.policy,
            train_env,
            policy_kwargs=_policy_kwargs(config),
            seed=segment_seed,
            device=options.device,
            tensorboard_log=tb,
            verbose=0,
            **_algo_kwargs(config, int(np.prod(train_env.action_space.shape or (1,)))),
        )
    else:
        model = cls.load(str(checkpoint), env=train_env, device=options.device)
        model.tensorboard_log = tb
        model.set_random_seed(segment_seed)
        buffer = sidecar_path(checkpoint, "replay_buffer")
        if config.algo in OFF_POLICY:
            if buffer.is_file():
                model.load_replay_buffer(str(buffer))
            else:
                print(
                    f"note: no replay buffer saved with {checkpoint.name}; resuming with an "
                    "empty buffer (random actions until it refills)",
                    file=sys.stderr,
                )
                model.learning_starts = model.num_timesteps + int(
                    config.algo_kwargs.get("learning_starts", model.learning_starts)
                )
        _truncate_episodes(out / "train_episodes.csv", start_steps)

    _write_config(out, config, run)  # before learning, so an interrupted run can be resumed
    callbacks, evaluation, checkpointer, episodes = _make_callbacks(
        config, out, eval_env, start_steps if checkpoint is not None else None, segment_seed
    )
    if options.progress:
        callbacks.append(_callbacks_module().ProgressBarCallback())

    what = f"resuming {out} at {start_steps:,} steps" if checkpoint else f"training into {out}"
    print(
        f"{what}: {config.algo} on {config.env_id}, {add:,} steps, {config.n_envs} envs, "
        f"seed {seed}, config {Path(source).name} v{config.version}",
        flush=True,
    )
    status = "completed"
    start = time.perf_counter()
    try:
        model.learn(
            total_timesteps=add,
            callback=callbacks,
            reset_num_timesteps=checkpoint is None,
            tb_log_name=config.algo.upper(),
            progress_bar=False,
        )
    except KeyboardInterrupt:
        status = "interrupted"
        _close_progress_bar(callbacks)
    wall = time.perf_counter() - start
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:  # a second Ctrl-C must not cut the saving short
        episodes.flush()
        if status == "completed":
            if evaluation is not None and (
                not evaluation.evaluations_timesteps
                or evaluation.evaluations_timesteps[-1] < model.num_timesteps
            ):
                evaluation.evaluate_now()
            model_path = out / FINAL_MODEL
        else:
            model_path = out / "checkpoints" / f"{INTERRUPTED}.zip"
        save_model_files(model, config, model_path)
        eval_s = evaluation.seconds if evaluation is not None else 0.0
        ckpt_s = checkpointer.seconds if checkpointer is not None else 0.0
        steps = model.num_timesteps - start_steps
        segments.append(
            {
                "status": status,
                "started_at": run["resumes"][-1]["at"] if checkpoint else run["started_at"],
                "resumed_from": str(checkpoint) if checkpoint else None,
                "n_envs": config.n_envs,
                "env_seed": segment_seed,
                "torch_threads": torch.get_num_threads(),
                "start_timesteps": start_steps,
                "end_timesteps": int(model.num_timesteps),
                "wall_time_s": round(wall, 3),
                "eval_time_s": round(eval_s, 3),
                "checkpoint_time_s": round(ckpt_s, 3),
                "env_steps_per_s": round(steps / wall, 1) if wall > 0 else None,
                "env_steps_per_s_excluding_eval": (
                    round(steps / (wall - eval_s - ckpt_s), 1)
                    if wall - eval_s - ckpt_s > 0
                    else None
                ),
            }
        )
        log.update(
            {
                "env_id": config.env_id,
                "algo": config.algo,
                "status": status,
                "num_timesteps": int(model.num_timesteps),
                "target_timesteps": int(config.timesteps),
                "model": str(model_path),
            }
        )
        _write_log(out, log)
        run["finished_at" if status == "completed" else "interrupted_at"] = _now()
        _write_config(out, config, run)
        plot_learning_curve(out)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous)
        train_env.close()
        if eval_env is not None:
            eval_env.close()
    return TrainResult(
        out=out,
        status=status,
        num_timesteps=int(model.num_timesteps),
        model_path=model_path,
        wall_time_s=wall,
        env_steps_per_s=(model.num_timesteps - start_steps) / wall if wall > 0 else 0.0,
    )


# --------------------------------------------------------------------------------------------------
# learning curve
# --------------------------------------------------------------------------------------------------


def _rolling(values: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over ``window`` values (over all values so far for the first ones)."""
    if values.size == 0:
        return values
    csum = np.concatenate([[0.0], np.cumsum(values, dtype=float)])
    idx = np.arange(1, values.size + 1)
    start = np.maximum(idx - window, 0)
    return (csum[idx] - csum[start]) / (idx - start)


def plot_learning_curve(run_dir: str | Path) -> Path:
    """Draw ``DIR/learning_curve.png`` vs timesteps: held-out evaluation mean return (± std),
    targets captured and success rate (``evaluations.npz``), with the training episodes'
    (``train_episodes.csv``, trailing mean over 100 episodes). Returns the PNG path.

    The return includes the potential-based progress term, whose undiscounted sum grows with
    episode length (each step pays (1 − γ)·|Φ|): survival alone raises it. Targets captured and
    success rate are the task's own measures.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    fig, axes = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True)
    ax_r, ax_t, ax_s = axes
    title = run_dir.name
    config_path = run_dir / "config.yaml"
    if config_path.is_file():
        with contextlib.suppress(Exception):
            data, _ = load_config_file(config_path)
            title = f"{data.get('algo', '?')} on {data.get('env_id', '?')} ({run_dir.name})"
    train_label = "training episodes (mean of last 100)"
    path = run_dir / "train_episodes.csv"
    if path.is_file():
        with open(path, newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, [])
            rows = [dict(zip(header, r)) for r in reader if _row_ok(r, len(header))]
        if rows:
            t = np.array([float(r["timesteps"]) for r in rows])
            columns = {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "wall_s"}
            ax_r.scatter(t, columns["return"], s=3, color="tab:gray", alpha=0.2)
            for ax, key in ((ax_r, "return"), (ax_t, "targets_captured"), (ax_s, "is_success")):
                ax.plot(t, _rolling(columns[key], 100), color="tab:gray", label=train_label)
    path = run_dir / "evaluations.npz"
    if path.is_file():
        with np.load(path, allow_pickle=True) as data:
            t = np.asarray(data["timesteps"], dtype=float)
            series = {
                key: [np.asarray(v, dtype=float) for v in data[key]]
                for key in ("results", "targets_captured", "successes")
                if key in data and len(data[key]) == t.size
            }
        if t.size:
            label = "held-out evaluation (mean)"
            mean = np.array([r.mean() for r in series["results"]])
            std = np.array([r.std() for r in series["results"]])
            ax_r.plot(t, mean, "o-", color="tab:blue", label=label + " ± std")
            ax_r.fill_between(t, mean - std, mean + std, color="tab:blue", alpha=0.2)
            for ax, key in ((ax_t, "targets_captured"), (ax_s, "successes")):
                if key in series:
                    ax.plot(t, [v.mean() for v in series[key]], "o-", color="tab:blue", label=label)
    ax_r.set_ylabel("episode return")
    ax_t.set_ylabel("targets captured")
    ax_s.set_ylabel("success rate")
    ax_s.set_ylim(-0.05, 1.05)
    ax_s.set_xlabel("timesteps (env steps)")
    for ax in axes:
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
        else:
            ax.text(0.5, 0.5, "no finished episodes yet", ha="center", transform=ax.transAxes)
    ax_r.set_title(title, fontsize=10)
    fig.tight_layout()
    out = run_dir / "learning_curve.png"
    save_atomic(out, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return out
