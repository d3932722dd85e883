"""Loading learned policies (SB3 models saved by ``train.py``) for an env, and the registry of
the pretrained ones shipped with the package.

``load_agent("ppo:runs/ppo/model.zip", env)`` (also ``ppo=…``, and ``sac``, ``td3``, ``dqn``)
returns a :class:`~agents.policies.learned_agent.LearnedAgent`; ``load_agent("ppo:runs/ppo",
env)`` takes the run directory's ``model.zip``, else its newest checkpoint (a warning names it);
``load_agent("pretrained", env)`` the policy shipped in ``agents/pretrained/`` for that env.
Loading

* checks the run's ``config.yaml`` first (its ``normalize`` and ``env_kwargs`` mappings, and warns
  when its ``env_id`` is not the env's: a policy flown on a task it was not trained for);
* checks the model's observation and action spaces against the env's (a clear error otherwise),
  letting a DQN policy (trained with ``action="discrete"``) fly the default continuous env
  through the env's discrete action table (coast, ±x, ±y, ±z at full thrust): so
  ``evaluate.py --agents apf,dqn=model.zip`` compares it with the baselines on the same env;
* finds the VecNormalize statistics saved next to the model (the
  :func:`agents.policies.model_files.sidecar_path` name: ``vecnormalize.pkl`` beside ``model.zip``,
  ``best_model_vecnormalize.pkl`` beside ``best_model.zip``, ``rl_model_vecnormalize_N_steps.pkl``
  beside a checkpoint), read with an unpickler that only builds their own types, so a
  statistics file cannot run code (the model zip itself is read by Stable-Baselines3, which
  unpickles parts of it: a model is trusted like code).

The agent that flies it is :mod:`agents.policies.learned_agent`'s.
"""

from __future__ import annotations

import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.policies.learned_agent import LearnedAgent, read_vecnormalize
from agents.policies.model_files import (
    LEARNED_ALGOS,
    algo_class,
    find_model_file,
    read_config_mapping,
    sidecar_path,
)

__all__ = [
    "OBSERVATION_KEYS",
    "PRETRAINED",
    "PRETRAINED_DIR",
    "PRETRAINED_POLICIES",
    "load_agent",
    "observation_options",
    "pretrained_path",
    "run_config_path",
    "trained_env_id",
]

OBSERVATION_KEYS = (
    "observation", "obs_targets", "obs_obstacles", "lidar_rays", "lidar_range", "obs_goal",
    "obs_other_targets", "obs_hold", "obs_near", "obs_teammates",
)  # fmt: skip
"""Env options that shape the observation (and nothing else): a learned policy needs the ones
it was trained with."""

RESIDUAL = "residual"
"""The action mode whose actions are corrections to the env's base law: a policy trained in it
is flown in it (:func:`observation_options` adds ``action``), as its thrust alone means
nothing."""

PRETRAINED = "pretrained"

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "pretrained"
"""Package data: the shipped policies (and their VecNormalize statistics)."""

PRETRAINED_POLICIES: dict[str, tuple[str, str]] = {
    "DebrisGym/Rendezvous2D-v0": ("ppo", "rendezvous2d_dagger.zip"),
    "DebrisGym/Rendezvous2D-Easy-v1": ("ppo", "rendezvous2d-easy_ppo.zip"),
    "DebrisGym/Rendezvous2D-v1": ("ppo", "rendezvous2d_finetuned.zip"),
    "DebrisGym/Rendezvous3D-v1": ("ppo", "rendezvous3d_finetuned.zip"),
    "DebrisGym/Rendezvous2D-v2": ("ppo", "rendezvous2d_v2_residual.zip"),
    "DebrisGym/Rendezvous3D-v2": ("ppo", "rendezvous3d_v2_residual.zip"),
}
"""Env ID → (algorithm, file in :data:`PRETRAINED_DIR`). The v2 policies are residual ones
(:data:`RESIDUAL`): they fly in the env made with :func:`observation_options`."""


def _env_spaces(env: Any) -> tuple[spaces.Space, spaces.Space]:
    """Single observation and action spaces of a gym env, SB3 VecEnv or gymnasium VectorEnv."""
    if hasattr(env, "single_observation_space"):  # gymnasium VectorEnv
        return env.single_observation_space, env.single_action_space
    return env.observation_space, env.action_space


def _env_id(env: Any) -> str | None:
    if getattr(env, "env_id", None):  # NativeVecEnv
        return str(env.env_id)
    spec = getattr(env, "spec", None)
    if spec is None and hasattr(env, "envs") and env.envs:  # SB3 DummyVecEnv
        spec = getattr(env.envs[0], "spec", None)
    return getattr(spec, "id", None)


def _env_config(env: Any) -> Any:
    base = env.envs[0] if hasattr(env, "envs") and env.envs else env
    base = getattr(base, "unwrapped", base)
    return getattr(base, "config", None)


def _env_dim(env: Any) -> int | None:
    return getattr(_env_config(env), "dim", None)


def _describe(space: spaces.Space) -> str:
    if isinstance(space, spaces.Box):
        return f"Box(shape={space.shape}, dtype={space.dtype})"
    return str(space)


def _same_box(a: spaces.Box, b: spaces.Box) -> bool:
    return (
        a.shape == b.shape
        and np.allclose(a.low, b.low, equal_nan=True)
        and np.allclose(a.high, b.high, equal_nan=True)
    )


def _observation_hint(path: Path) -> str:
    """How to make an env that fits the model at ``path`` (for an observation-space mismatch)."""
    try:
        options = _run_observation_options(path)
    except ValueError:
        options = {}  # the damaged config is reported when the statistics are looked up
    if options:
        return (
            f"the run was trained with env options {options}: make the env with them, e.g. "
            "gym.make(env_id, **agents.observation_options(spec, env_id)) "
            "(evaluate.py does this itself)"
        )
    return (
        "was it trained on another env or with other env options (dim, observation, obs_targets, "
        "obs_obstacles, lidar_rays, obs_goal)? Make the env with the options in the run's "
        "config.yaml"
    )


def _check_spaces(model: Any, env: Any, path: Path) -> np.ndarray | None:
    """Raise ValueError on a mismatch; return the discrete→continuous table if one is needed."""
    obs_space, act_space = _env_spaces(env)
    m_obs, m_act = model.observation_space, model.action_space
    if not (isinstance(m_obs, spaces.Box) and isinstance(obs_space, spaces.Box)) or not _same_box(
        m_obs, obs_space
    ):
        raise ValueError(
            f"{path}: the model observes {_describe(m_obs)} but the env gives "
            f"{_describe(obs_space)}; {_observation_hint(path)}"
        )
    if isinstance(m_act, spaces.Box) and isinstance(act_space, spaces.Box):
        if _same_box(m_act, act_space):
            return None
    elif isinstance(m_act, spaces.Discrete) and isinstance(act_space, spaces.Discrete):
        if m_act.n == act_space.n:
            return None
    elif isinstance(m_act, spaces.Discrete) and isinstance(act_space, spaces.Box):
        dim = act_space.shape[0] if len(act_space.shape) == 1 else None
        if dim is not None and _env_dim(env) in (None, dim):
            from debris_gym.envs.common import discrete_action_table

            fine = getattr(_env_config(env), "fine_thrust", 0.0)  # the env's discrete table
            table = discrete_action_table(dim, fine)
            if m_act.n == len(table):
                return table.astype(np.float32)
    raise ValueError(
        f"{path}: the model acts in {_describe(m_act)} but the env expects {_describe(act_space)}"
        + (
            "; make the env with action='discrete' (e.g. --env-kwargs '{\"action\": \"discrete\"}')"
            if isinstance(act_space, spaces.Discrete)
            else ""
        )
    )


def _run_config(path: Path) -> dict[str, Any] | None:
    """The config of the run that wrote model ``path`` (None: no config file found).

    Raises:
        ValueError: the config file is there but unreadable, not YAML or not a mapping (the
            message names it).
    """
    config = run_config_path(path)
    if config is None:
        return None
    try:
        data = read_config_mapping(config)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(
            f"{config}: the run config of {path} is damaged ({exc}); restore it from the "
            "training run, or delete it (then the model's VecNormalize statistics decide)"
        ) from None
    return data


RUN_CONFIG_MAPPINGS = {
    "normalize": "enabled, norm_obs, …",
    "env_kwargs": "the env options the run was trained with",
}
"""Entries of a run's ``config.yaml`` the loader reads, each a mapping (or absent / null)."""


def _check_action_mode(path: Path, config: dict[str, Any] | None, env: Any) -> None:
    """Refuse to fly a policy trained in the residual mode in an env without it, or the
    reverse: the same Box of actions means a correction in one and the whole thrust in the
    other.

    Raises:
        ValueError: naming both modes and how to make the env.
    """
    trained = ((config or {}).get("env_kwargs") or {}).get("action", "continuous")
    env_config = getattr(getattr(env, "unwrapped", env), "config", None)
    flown = getattr(env_config, "action", None)
    if flown is None or trained == flown or RESIDUAL not in (trained, flown):
        return
    raise ValueError(
        f"{path}: the policy was trained with action={trained!r} but the env has "
        f"action={flown!r}; make the env with action={trained!r} (evaluate.py does this itself)"
    )


def _checked_run_config(path: Path) -> dict[str, Any] | None:
    """The config of the run that wrote model ``path`` (None: none found), with the entries the
    loader reads (:data:`RUN_CONFIG_MAPPINGS`) checked — whether or not the statistics file is
    there, so a damaged entry is never skipped.

    Raises:
        ValueError: a damaged run config, or one of those entries not a mapping (the message
            names the file and the key).
    """
    data = _run_config(path)
    if data is None:
        return None
    for key, what in RUN_CONFIG_MAPPINGS.items():
        value = data.get(key)
        if value is not None and not isinstance(value, dict):
            raise ValueError(
                f"{run_config_path(path)}: {key!r} must be a mapping ({what}), got {value!r}; "
                "restore the file from the training run"
            )
    env_id = data.get("env_id")
    if env_id is not None and not isinstance(env_id, str):
        raise ValueError(
            f"{run_config_path(path)}: 'env_id' must be an env ID string, got {env_id!r}"
        )
    return data


def _trained_with_normalization(path: Path) -> bool | None:
    """Whether the run that wrote ``path`` used VecNormalize observations (None: unknown).

    Raises:
        ValueError: a damaged run config (:func:`_checked_run_config`).
    """
    data = _checked_run_config(path)
    if data is None:
        return None
    norm = data.get("normalize") or {}
    return bool(norm.get("enabled")) and bool(norm.get("norm_obs", True))


def _load_normalizer(path: Path, observation_space: spaces.Space) -> Any:
    """The frozen VecNormalize statistics beside model ``path``, or None when the model reads raw
    observations.

    Raises:
        FileNotFoundError: the run normalised observations but the statistics file is missing.
        ValueError: the statistics file is unreadable, not VecNormalize statistics, or of
            another observation shape.
    """
    stats = sidecar_path(path, "vecnormalize")
    if not stats.is_file():
        trained = _trained_with_normalization(path)
        if trained:
            raise FileNotFoundError(
                f"{path} was trained with VecNormalize observations but its statistics file "
                f"{stats} is missing; copy the run's {stats.name} (train.py writes it beside "
                "every model it saves) next to the model — without it the policy would see raw "
                "observations it was never trained on"
            )
        if trained is None:
            warnings.warn(
                f"{path}: no VecNormalize statistics ({stats}) and no run config.yaml to tell "
                "whether the run normalised observations; the policy gets raw observations. If "
                f"it was trained with VecNormalize, put its statistics file at {stats}",
                UserWarning,
                stacklevel=3,
            )
        return None
    normalizer = read_vecnormalize(stats)
    normalizer.training = False  # never update the statistics at evaluation
    if not normalizer.norm_obs:
        return None
    mean_shape = np.shape(normalizer.obs_rms.mean)
    if mean_shape != observation_space.shape:
        raise ValueError(
            f"{stats}: VecNormalize statistics of shape {mean_shape} do not fit observations of "
            f"shape {observation_space.shape}"
        )
    return normalizer


def _parse(spec: str) -> tuple[str, Path | None]:
    text = str(spec).strip()
    if text == PRETRAINED:
        return PRETRAINED, None
    seps = [i for i in (text.find(":"), text.find("=")) if i >= 0]
    if not seps:
        raise ValueError(
            f"learned agent {text!r}: expected ALGO:PATH or ALGO=PATH (ALGO one of "
            f"{', '.join(LEARNED_ALGOS)}) or {PRETRAINED!r}"
        )
    algo, path = text[: min(seps)].strip().lower(), text[min(seps) + 1 :].strip()
    if algo not in LEARNED_ALGOS:
        raise ValueError(
            f"unknown learning algorithm {algo!r} in {text!r}; use one of "
            f"{', '.join(LEARNED_ALGOS)}"
        )
    if not path:
        raise ValueError(f"learned agent {text!r} needs a model path: {algo}:path/to/model.zip")
    return algo, Path(path)


def run_config_path(model_path: Path) -> Path | None:
    """The ``config.yaml`` of the run that wrote ``model_path`` (``DIR/model.zip``,
    ``DIR/best_model.zip``, ``DIR/checkpoints/…``), or the ``.yaml`` beside a shipped policy."""
    for candidate in (
        model_path.with_suffix(".yaml"),
        model_path.parent / "config.yaml",
        model_path.parent.parent / "config.yaml",
    ):
        if candidate.is_file():
            return candidate
    return None


def observation_options(spec: str, env_id: str) -> dict[str, Any]:
    """The observation options (:data:`OBSERVATION_KEYS`) the policy behind ``spec`` was
    trained with, to fly it on env ``env_id``: those its run's config set, those the
    registration of the run's env set, and, for an option ``env_id``'s registration sets that
    neither did, the run's env's value (so a policy of a v1 ID, trained without the hold's
    progress, flies a v2 ID with ``obs_hold: False``); and ``action: "residual"`` for a policy
    trained in that mode (:data:`RESIDUAL`). Empty if none is found.

    ``evaluate.py`` makes a learned agent's env with them: same fields, dynamics and rules as
    every other agent's, observed the way the policy was trained to see them.
    """
    algo, path = _parse(spec)
    if algo == PRETRAINED:
        algo, path = pretrained_path(env_id)
    assert path is not None
    if path.is_dir():
        path, _ = find_model_file(path)
    return _run_observation_options(path, env_id)


def trained_env_id(spec: str) -> str | None:
    """The env ID the run behind ``spec`` (``"ALGO:PATH"``) trained on, from its run config
    (None: no config found).

    Raises:
        ValueError: a bad spec or a damaged run config.
    """
    _, path = _parse(spec)
    if path is None:
        return None
    if path.is_dir():
        path, _ = find_model_file(path)
    data = _checked_run_config(path)
    return None if data is None else data.get("env_id")


def _registered_observation_options(env_id: Any) -> dict[str, Any]:
    """The :data:`OBSERVATION_KEYS` the registration of ``env_id`` (gymnasium's, or a swarm ID's)
    sets (none: unregistered)."""
    import gymnasium as gym

    import debris_gym  # noqa: F401  (registers the IDs)
    from debris_gym.swarm import SWARM_SPECS

    env_id = str(env_id).rpartition(":")[2]
    if env_id in gym.registry:
        kwargs = gym.registry[env_id].kwargs
    else:  # a swarm ID (PettingZoo's registry, not gymnasium's), or unregistered
        kwargs = SWARM_SPECS.get(env_id, {}).get("kwargs", {})
    return {k: kwargs[k] for k in OBSERVATION_KEYS if k in kwargs}


def _run_observation_options(path: Path, env_id: str | None = None) -> dict[str, Any]:
    """The :data:`OBSERVATION_KEYS` of the run that wrote model ``path``, flown on ``env_id``
    (:func:`observation_options`; without ``env_id``, those its config and env's registration
    set).

    Raises:
        ValueError: a damaged run config (the message names it).
    """
    from debris_gym.config import EnvConfig

    data = _checked_run_config(path)
    if data is None:
        return {}
    env_kwargs = data.get("env_kwargs") or {}
    run_env = _registered_observation_options(data.get("env_id"))
    options = {**run_env, **{k: env_kwargs[k] for k in OBSERVATION_KEYS if k in env_kwargs}}
    if env_kwargs.get("action") == RESIDUAL:  # its actions are corrections to the base law
        options["action"] = RESIDUAL
    if env_id is not None:
        for key in _registered_observation_options(env_id):
            if key not in options:  # the run's env left it at the default
                options[key] = EnvConfig.__dataclass_fields__[key].default
    return options


def pretrained_path(env: Any) -> tuple[str, Path]:
    """(algorithm, file) of the shipped policy for ``env``'s ID (an env or the ID itself).

    Raises:
        ValueError: no pretrained policy is planned for this env.
        FileNotFoundError: it is planned but not shipped yet.
    """
    env_id = env if isinstance(env, str) else _env_id(env)
    if env_id not in PRETRAINED_POLICIES:
        known = ", ".join(PRETRAINED_POLICIES)
        why = ""
        version = (env_id or "").rpartition("-")[2]
        if version in ("v1", "v2"):
            why = f": no policy trained for this {version} ID ships yet"
        raise ValueError(
            f"no pretrained policy for {env_id or 'this env'}{why} (there is one for {known})"
        )
    algo, name = PRETRAINED_POLICIES[env_id]
    path = PRETRAINED_DIR / name
    if not path.is_file():
        raise FileNotFoundError(
            f"no pretrained policy for {env_id} yet: agents/pretrained/{name} is not shipped "
            "(train one with train.py, see docs/training.md)"
        )
    return algo, path


def _warn_if_other_env(path: Path, config: dict[str, Any] | None, env: Any) -> None:
    """A ``UserWarning`` when the run config says model ``path`` was trained on another env ID
    than ``env``'s: the policy is flown on a task it was not trained for (an Easy-rung model on
    the full task, say), which is allowed but must not pass unnoticed."""
    trained_on = None if config is None else config.get("env_id")
    flown_on = _env_id(env)
    if trained_on is None or flown_on is None:
        return
    if trained_on.rpartition(":")[2] == flown_on.rpartition(":")[2]:  # "debris_gym:ID" is ID
        return
    warnings.warn(
        f"{path} was trained on {trained_on} but is flown on {flown_on}: its results measure "
        f"how it transfers, not the task it learned (evaluate it with --env {trained_on})",
        UserWarning,
        stacklevel=3,
    )


def load_agent(spec: str, env: Any, device: str = "cpu") -> LearnedAgent:
    """Load a learned policy for ``env``.

    Args:
        spec: ``"ALGO:PATH"`` or ``"ALGO=PATH"`` (ALGO in :data:`LEARNED_ALGOS`; PATH an SB3 zip
            written by ``train.py``, e.g. ``runs/ppo/model.zip``, or a run directory: its
            ``model.zip``, else its newest checkpoint, with a ``UserWarning`` saying which), or
            ``"pretrained"``.
        env: the env it will fly (gymnasium env, SB3 VecEnv or gymnasium VectorEnv); only its
            spaces (and, for ``pretrained``, its ID) are used.
        device: torch device for the model.

    Warns:
        UserWarning: the model was picked from a run directory without ``model.zip``; its run
            config names another env ID than ``env``'s; neither statistics nor a run config
            tell whether it reads normalised observations.

    Raises:
        ValueError: a bad spec, an unknown algorithm, a model of another algorithm, spaces that
            do not match the env's, a damaged statistics file or run config, or no pretrained
            policy for this env.
        FileNotFoundError: the model (or statistics it needs) is missing; the message lists what
            the run directory holds.
    """

    algo, path = _parse(spec)
    if algo == PRETRAINED:
        algo, path = pretrained_path(env)
    assert path is not None
    try:
        path, chosen = find_model_file(path)
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{algo} {exc}") from None
    if chosen is not None:
        warnings.warn(chosen, UserWarning, stacklevel=2)
    if not zipfile.is_zipfile(path):
        raise ValueError(
            f"{path}: not a model file (an SB3 model is a zip archive; this one is empty, "
            "truncated or something else); copy it again from the training run"
        )
    config = _checked_run_config(path)  # a damaged run config is named before the model loads
    cls = algo_class(algo)
    # schedules are only needed to train; constants avoid unpickling closures at inference
    custom = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
    try:
        model = cls.load(str(path), device=device, custom_objects=custom)
    except Exception as exc:  # SB3 raises many kinds on a foreign file
        raise ValueError(
            f"cannot load {path} as a {algo.upper()} model ({type(exc).__name__}: {exc}); was it "
            "trained with another algorithm?"
        ) from exc
    table = _check_spaces(model, env, path)
    _check_action_mode(path, config, env)
    _warn_if_other_env(path, config, env)  # only for a model that can fly the env at all
    normalizer = _load_normalizer(path, model.observation_space)
    return LearnedAgent(model, algo, path, normalizer, model.observation_space, table)
