"""RL fine-tuning of another run's policy (``train.py --init DIR``; the ``init`` config section).

The init run (``imitate.py`` or ``train.py`` output) gives the fine-tune run

* its **observation options** (:data:`~agents.policies.learned.OBSERVATION_KEYS` of its
  ``config.yaml``): copied into the run's ``env_kwargs`` when the config leaves them out; a
  different value is refused (:func:`adopt_init_options`) unless it only *adds* observation
  elements (``obs_hold: true`` where the init run had none, say): then the init policy is
  **widened** (:mod:`~agents.experiments.training.widen`) — zero weights and statistics of
  mean 0, variance 1 for the new elements, so it starts acting exactly as the init run did;
* its **policy weights** (actor, ``log_std`` and value head; the value head of a DAgger run is
  untrained, hence the critic warm-up) and network shape (:func:`build_finetune_model`);
* its **observation statistics**, kept frozen for the whole run (:class:`FrozenObsVecNormalize`):
  the policy's input means what it meant to the initial policy, so neither the policy nor the
  anchor's reference μ₀ sees its inputs shift. The reward is normalised by the running std of
  the return as in any run (``normalize.norm_reward``);
* the **frozen reference** of the anchor: a copy of the init model is written into the run
  directory (``init_model.zip`` with ``init_model_vecnormalize.pkl`` and ``init_model.yaml``,
  itself a model ``evaluate.py`` can fly) so that ``--resume`` restores μ₀ from the run alone
  (:func:`restore_reference`).
"""

from __future__ import annotations

import copy
import functools
import shutil
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecNormalize

from agents.experiments.config_files import ConfigError, load_config_file
from agents.experiments.training.anchored import AnchoredPPO
from agents.experiments.training.config import TrainConfig
from agents.experiments.training.sb3_kwargs import construct_model, policy_kwargs
from agents.experiments.training.widen import (
    observation_columns,
    widen_running_stats,
    widen_state_dict,
)
from agents.policies.learned import OBSERVATION_KEYS
from agents.policies.learned_agent import read_vecnormalize
from agents.policies.model_files import FINAL_MODEL, sidecar_path
from debris_gym.files import save_atomic

__all__ = [
    "REFERENCE_MODEL",
    "FrozenObsVecNormalize",
    "adopt_init_options",
    "build_finetune_model",
    "check_init_run",
    "finetune_train_env",
    "init_columns",
    "reference_path",
    "restore_reference",
    "save_reference",
]

REFERENCE_MODEL = "init_model.zip"
"""The init model's copy in the fine-tune run directory (the anchor's reference)."""

_LOAD_OBJECTS = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
"""SB3 ``custom_objects``: the init run's schedules are not needed (and may not unpickle)."""


def _init_error(source: str, problem: str) -> ConfigError:
    return ConfigError(f"{source}: config key 'init.path' {problem}")


def _init_files(path: Path, source: str) -> tuple[Path, Path, Path]:
    """``model.zip``, ``vecnormalize.pkl``, ``config.yaml`` of init run ``path``, all present."""
    what = "(a run directory of imitate.py or train.py: model.zip, vecnormalize.pkl, config.yaml)"
    if not path.is_dir():
        raise _init_error(source, f"names {str(path)!r}, which is not a directory {what}")
    model = path / FINAL_MODEL
    files = (model, sidecar_path(model, "vecnormalize"), path / "config.yaml")
    for file in files:
        if not file.is_file():
            raise _init_error(source, f"names {str(path)!r}, which has no {file.name} {what}")
    if not zipfile.is_zipfile(model):
        raise _init_error(source, f"names {str(path)!r}, whose {model.name} is not an SB3 model")
    return files


def _env_config(env_id: str, env_kwargs: dict[str, Any]) -> Any:
    """The :class:`~debris_gym.config.EnvConfig` of env ``env_id`` made with ``env_kwargs``."""
    import gymnasium as gym

    import debris_gym  # noqa: F401  (registers the IDs)
    from debris_gym.config import EnvConfig
    from debris_gym.swarm import SWARM_SPECS, checked_options

    options = {k: v for k, v in env_kwargs.items() if k != "max_episode_steps"}
    if env_id in SWARM_SPECS:
        return checked_options(env_id, options)[0]
    spec_kwargs = gym.registry[env_id].kwargs if env_id in gym.registry else {}
    return EnvConfig.from_kwargs(**{**spec_kwargs, **options})


def _observation_names(cfg: Any) -> list[str]:
    from debris_gym.observation import observation_names

    return observation_names(cfg)


def _init_observation(init_data: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    """The init run's env config and its observation options (every key, effective values)."""
    init_env = init_data.get("env_kwargs") or {}
    cfg = _env_config(str(init_data.get("env_id", "")), init_env)
    return cfg, {key: getattr(cfg, key) for key in OBSERVATION_KEYS}


def _adds_elements(init_cfg: Any, key: str, value: Any) -> bool:
    """Whether setting observation option ``key`` to ``value`` on the init's env config only
    adds observation elements (the init's stay, in order, under the same names)."""
    from debris_gym.config import EnvConfig

    widened = EnvConfig.from_kwargs(**{**init_cfg.to_dict(), key: value})
    names, init_names = _observation_names(widened), _observation_names(init_cfg)
    if len(names) <= len(init_names):
        return False
    try:
        observation_columns(init_names, names)
    except ValueError:
        return False
    return True


def adopt_init_options(
    data: dict[str, Any], init: str | Path | None, source: str
) -> dict[str, Any]:
    """A config mapping with ``--init`` applied and the init run's observation options.

    ``init`` (``--init DIR``, may be None) becomes ``init.path`` (absolute, so a resume from
    elsewhere finds it). With an ``init.path``, every observation option the init run set is
    copied into ``env_kwargs`` unless the config sets it, and so is one the config leaves out
    whose default differs in the run's env (the init trained on another version's ID). A value
    that differs from the init run's (its value or, if it left the key out, its env's) is
    allowed only if it adds observation elements (the init policy is widened to them); any
    other is refused.

    Raises:
        ConfigError: ``init.path`` is not an init run directory, an observation option differs
            without only adding elements (the message names the key and both values), or the
            init's elements are not all in the run's observation, in their order (named).
    """
    section = data.get("init")
    if init is not None:
        text = str(init).strip()
        if not text:
            raise ConfigError("--init must name a run directory, got an empty string")
        section = {
            **(section if isinstance(section, dict) else {}),
            "path": str(Path(text).resolve()),
        }
        data = {**data, "init": section}
    if not isinstance(section, dict) or not isinstance(section.get("path"), str):
        return data  # no init, or a malformed section that TrainConfig.from_dict names
    if not section["path"].strip():
        return data  # from_dict names it
    path = Path(section["path"]).resolve()  # a resume from elsewhere finds it
    data = {**data, "init": {**section, "path": str(path)}}
    _, _, config_file = _init_files(path, source)
    try:
        init_data, _ = load_config_file(config_file)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise _init_error(source, f"names a run whose config.yaml is unreadable ({exc})") from None
    init_env = init_data.get("env_kwargs") or {}
    env_kwargs = data.get("env_kwargs") or {}
    if not isinstance(init_env, dict) or not isinstance(env_kwargs, dict):
        return data  # from_dict (or load_agent on the init run) names the problem
    env_kwargs = dict(env_kwargs)
    copied = {key: init_env[key] for key in OBSERVATION_KEYS if key in init_env}
    copied = {key: value for key, value in copied.items() if key not in env_kwargs}
    env_kwargs.update(copied)
    try:
        init_cfg, theirs = _init_observation(init_data)
        cfg = _env_config(str(data.get("env_id", "")), env_kwargs)
    except (TypeError, ValueError):
        return {**data, "env_kwargs": env_kwargs}  # an invalid option: from_dict names it
    added = {}
    for key in OBSERVATION_KEYS:
        ours = getattr(cfg, key)
        if ours == theirs[key]:
            continue
        if _adds_elements(init_cfg, key, ours):
            added[key] = ours
        elif key not in env_kwargs:  # the env's default differs (another version's ID)
            env_kwargs[key] = copied[key] = theirs[key]
        else:
            raise ConfigError(
                f"{source}: config key 'env_kwargs.{key}' is {ours!r} but the initial policy "
                f"({config_file}) was trained with {key}={theirs[key]!r}; a policy needs the "
                "observation it was trained on (a fine-tune may only add elements to it): "
                "drop the key to take the init run's value"
            )
    cfg = _env_config(str(data.get("env_id", "")), env_kwargs)
    try:
        observation_columns(_observation_names(init_cfg), _observation_names(cfg))
    except ValueError as exc:
        raise ConfigError(f"{source}: with the initial policy of {config_file}, {exc}") from None
    if copied:
        print(f"note: observation options {copied} taken from {config_file}", file=sys.stderr)
    if added:
        print(
            f"note: the initial policy is widened to the observation elements that {added} "
            "adds (zero weights: it starts acting as it did)",
            file=sys.stderr,
        )
    return {**data, "env_kwargs": env_kwargs}


def _read_init_config(init_config: Path) -> dict[str, Any]:
    try:
        data, _ = load_config_file(init_config)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(
            f"{init_config}: the initial policy's config is unreadable ({exc})"
        ) from None
    return data


def init_columns(config: TrainConfig, init_config: Path) -> np.ndarray | None:
    """Where the init policy's observation elements sit in the run's observation (None: the
    observations are the same), the init run described by its config file ``init_config``.

    Only observation options may add elements: the run's env observed with the init's options
    must give the init's elements.

    Raises:
        ValueError: ``init_config`` is unreadable, the run's env observed with the init's
            options is not the init's observation (another dimension or world), or the init's
            elements are not all in the run's observation in their order
            (:func:`~agents.experiments.training.widen.observation_columns`).
    """
    init_data = _read_init_config(init_config)
    init_cfg, init_options = _init_observation(init_data)
    init_names = _observation_names(init_cfg)
    names = _observation_names(_env_config(config.env_id, config.env_kwargs))
    if init_names == names:
        return None
    seen = _observation_names(_env_config(config.env_id, {**config.env_kwargs, **init_options}))
    if seen != init_names:
        raise ValueError(
            f"the initial policy's observation space ({len(init_names)} elements, "
            f"{init_data.get('env_id')}) differs from this env's observed with the same "
            f"options ({len(seen)} elements, {config.env_id}): only observation options may "
            "add elements"
        )
    return observation_columns(init_names, names)


def _load_init_model(path: Path, source: str) -> Any:
    from stable_baselines3 import PPO

    try:
        return PPO.load(str(path), device="cpu", custom_objects=_LOAD_OBJECTS)
    except Exception as exc:  # SB3 raises many kinds on a foreign or damaged file
        raise _init_error(
            source, f"names a run whose {path.name} is not a PPO model ({type(exc).__name__})"
        ) from None


def check_init_run(config: TrainConfig, source: str) -> None:
    """Check the init run of ``config`` (nothing to do without ``init.path``) against it.

    Raises:
        ConfigError: missing or damaged files, a model that is not PPO or whose spaces differ
            from the env's, statistics that do not normalise observations, or ``normalize``
            options that differ from the statistics' (``clip_obs``, ``epsilon``).
    """
    if config.init.path is None:
        return
    from debris_gym.integrations.sb3 import envs_per_mission, make_vec_env

    model_file, stats_file, config_file = _init_files(Path(config.init.path), source)
    try:
        stats = read_vecnormalize(stats_file)
    except ValueError as exc:
        raise _init_error(source, f"names a run with unusable statistics: {exc}") from None
    if not stats.norm_obs:
        raise _init_error(
            source, f"names a run whose {stats_file.name} does not normalise observations"
        )
    for key in ("clip_obs", "epsilon"):
        ours, theirs = getattr(config.normalize, key), float(vars(stats)[key])
        if ours != theirs:
            raise ConfigError(
                f"{source}: config key 'normalize.{key}' is {ours} but the initial policy's "
                f"statistics ({stats_file}) use {theirs}; set normalize.{key}: {theirs}"
            )
    model = _load_init_model(model_file, source)
    try:
        columns = init_columns(config, config_file)
    except ValueError as exc:
        raise _init_error(source, f"names a run that does not fit this one: {exc}") from None
    env = make_vec_env(
        config.env_id, envs_per_mission(config.env_id, **config.env_kwargs), **config.env_kwargs
    )
    try:
        for what in ("observation_space", "action_space"):
            ours, theirs = getattr(env, what), getattr(model, what)
            shape = ours.shape if columns is None or what == "action_space" else (len(columns),)
            if shape != theirs.shape or type(ours) is not type(theirs):
                raise _init_error(
                    source,
                    f"names a model whose {what.replace('_', ' ')} {theirs} differs from the "
                    f"env's {ours} ({config.env_id} with env_kwargs {config.env_kwargs})",
                )
    finally:
        env.close()
    if stats.obs_rms.mean.shape != model.observation_space.shape:
        raise _init_error(
            source,
            f"names a run whose {stats_file.name} (shape {stats.obs_rms.mean.shape}) does not "
            f"fit its model's observation {model.observation_space.shape}",
        )
    if columns is not None:
        _check_widened_values(config, config_file, columns, source)
    _policy_kwargs(config, model, source)  # the network shapes agree


_VALUE_CHECK_STEPS = 20
"""Steps (random thrust, two missions) over which a widened observation is compared with the
init's."""


def _check_widened_values(
    config: TrainConfig, init_config: Path, columns: np.ndarray, source: str
) -> None:
    """Refuse a widening whose shared element names do not carry the same values: the run's
    env and the same env observed with the init's options fly the same seeded missions, and
    the init's elements must be equal, bit for bit, in both (a name alone does not say, e.g.,
    which direction a lidar ray points in)."""
    from debris_gym.integrations.sb3 import envs_per_mission, make_vec_env

    _, init_options = _init_observation(_read_init_config(init_config))
    n = 2 * envs_per_mission(config.env_id, **config.env_kwargs)
    wide = make_vec_env(config.env_id, n, **config.env_kwargs)
    narrow = make_vec_env(config.env_id, n, **{**config.env_kwargs, **init_options})
    try:
        for env in (wide, narrow):
            env.seed(0)
        obs_wide, obs_narrow = np.asarray(wide.reset()), np.asarray(narrow.reset())
        wide.action_space.seed(0)
        for step in range(_VALUE_CHECK_STEPS + 1):
            differ = np.flatnonzero(np.any(obs_wide[:, columns] != obs_narrow, axis=0))
            if len(differ):
                cfg = _env_config(config.env_id, config.env_kwargs)
                names = [_observation_names(cfg)[columns[i]] for i in differ]
                raise _init_error(
                    source,
                    f"names a policy whose observation elements {', '.join(names)} take other "
                    f"values in this env (step {step} of a test mission): the same names, not "
                    "the same meaning; keep the init run's observation options",
                )
            action = np.stack([wide.action_space.sample() for _ in range(wide.num_envs)])
            obs_wide, obs_narrow = (
                np.asarray(wide.step(action)[0]),
                np.asarray(narrow.step(action)[0]),
            )
    finally:
        wide.close()
        narrow.close()


class FrozenObsVecNormalize(VecNormalize):
    """VecNormalize that normalises observations with fixed statistics (never updated) and
    rewards by the running std of the discounted return (updated while ``training``).

    It pickles as a plain :class:`VecNormalize` (training off), so its saved statistics are what
    :func:`agents.load_agent` applies, without importing training code.
    """

    @classmethod
    def from_stats(
        cls, stats: VecNormalize, venv: Any, config: TrainConfig
    ) -> FrozenObsVecNormalize:
        """Wrap ``venv`` with the observation statistics of ``stats`` and the reward options of
        ``config`` (its running return statistics come along too: a resume keeps its scale)."""
        norm = config.normalize
        wrapper = cls(
            venv,
            training=True,
            norm_obs=True,
            norm_reward=norm.norm_reward,
            clip_obs=float(stats.clip_obs),
            clip_reward=norm.clip_reward,
            gamma=norm.gamma if norm.gamma is not None else config.gamma,
            epsilon=float(stats.epsilon),
        )
        wrapper.obs_rms = stats.obs_rms.copy()
        wrapper.ret_rms = stats.ret_rms.copy()
        return wrapper

    def reset(self) -> Any:
        obs = _array_observations(self.venv.reset())
        self.old_obs = obs
        self.returns = np.zeros(self.num_envs)
        return self.normalize_obs(obs)

    def step_wait(self) -> Any:
        observations, rewards, dones, infos = self.venv.step_wait()
        obs = _array_observations(observations)
        self.old_obs, self.old_reward = obs, rewards
        if self.training:  # the return's scale is learned; the observation's is not
            self._update_reward(rewards)
        for info, done in zip(infos, dones, strict=True):
            if done and "terminal_observation" in info:
                info["terminal_observation"] = self.normalize_obs(info["terminal_observation"])
        self.returns[dones] = 0.0
        return self.normalize_obs(obs), self.normalize_reward(rewards), dones, infos

    def __reduce_ex__(self, protocol: Any) -> Any:
        import copyreg

        state = self.__getstate__()
        state["training"] = False
        # rebuilt as VecNormalize.__new__ + __setstate__, the way a plain one unpickles
        # (a private name of copyreg: typeshed leaves it out)
        return copyreg._reconstructor, (VecNormalize, object, None), state  # type: ignore[attr-defined]


def _array_observations(obs: Any) -> np.ndarray | dict[str, np.ndarray]:
    """``obs`` as VecNormalize takes it: an array or a dict of arrays (not a tuple)."""
    if not isinstance(obs, (np.ndarray, dict)):
        raise TypeError(f"observations must be an array or a dict of arrays, got {type(obs)}")
    return obs


def finetune_train_env(venv: Any, config: TrainConfig, stats: Path | None) -> FrozenObsVecNormalize:
    """``venv`` normalised for fine-tuning: observation statistics from ``stats`` (a resumed
    checkpoint's) or, for a fresh run, from the init run's ``vecnormalize.pkl`` (widened to
    the run's observation: mean 0, variance 1 for the elements the init run did not see)."""
    assert config.init.path is not None
    if stats is not None:
        return FrozenObsVecNormalize.from_stats(read_vecnormalize(stats), venv, config)
    init = Path(config.init.path)
    normalizer = read_vecnormalize(sidecar_path(init / FINAL_MODEL, "vecnormalize"))
    columns = init_columns(config, init / "config.yaml")
    if columns is not None:
        size = int(np.prod(venv.observation_space.shape))
        normalizer.obs_rms = widen_running_stats(normalizer.obs_rms, columns, size)
    return FrozenObsVecNormalize.from_stats(normalizer, venv, config)


def _policy_kwargs(config: TrainConfig, init_model: Any, source: str) -> dict[str, Any]:
    """The fine-tune policy's keyword arguments: the init policy's network (a config's
    ``net_arch`` / ``activation_fn`` must equal it), the config's other entries over it."""
    theirs = dict(init_model.policy_kwargs)
    ours = policy_kwargs(config)
    for key in ("net_arch", "activation_fn"):
        if key in ours and ours[key] != theirs.get(key):
            raise ConfigError(
                f"{source}: config key 'policy_kwargs.{key}' is {ours[key]!r} but the initial "
                f"policy has {theirs.get(key)!r}; drop the key to take the initial policy's"
            )
    return {**theirs, **ours}


def build_finetune_model(
    config: TrainConfig,
    train_env: Any,
    *,
    seed: int,
    device: str,
    tensorboard_log: str | None,
    source: str,
) -> AnchoredPPO:
    """An :class:`AnchoredPPO` of the recipe with the init policy's weights, anchored to it.

    ``policy_kwargs.log_std_init``, when the config sets it, replaces the init's ``log_std``
    (the exploration noise of the fine-tune; the anchor acts on mean actions only).
    """
    assert config.init.path is not None
    init_model = _load_init_model(Path(config.init.path) / FINAL_MODEL, source)
    kwargs = _policy_kwargs(config, init_model, source)
    model = construct_model(
        AnchoredPPO,
        config,
        train_env,
        source,
        kwargs,
        "PPO",
        critic_warmup=config.init.critic_warmup,
        anchor_coef=config.init.anchor_coef,
        anchor_decay=config.init.anchor_decay,
        seed=seed,
        device=device,
        tensorboard_log=tensorboard_log,
    )
    init_config = Path(config.init.path) / "config.yaml"
    reference = _widened(init_model.policy, model.policy, init_columns(config, init_config))
    model.policy.load_state_dict(reference.state_dict())
    if "log_std_init" in config.policy_kwargs:
        model.policy.log_std.data.fill_(float(config.policy_kwargs["log_std_init"]))
    model.set_reference(reference)
    return model


def _widened(init_policy: Any, policy: Any, columns: np.ndarray | None) -> Any:
    """``init_policy`` as a network of ``policy``'s shape reading the run's observation (itself
    when the observations are the same; :func:`~agents.experiments.training.widen.
    widen_state_dict` otherwise)."""
    if columns is None:
        return init_policy
    widened = copy.deepcopy(policy)
    state = widen_state_dict(init_policy.state_dict(), policy.state_dict(), columns)
    widened.load_state_dict(state)
    return widened


def configure_resumed(model: AnchoredPPO, config: TrainConfig, out: Path) -> None:
    """Give a resumed model its run's anchor settings and frozen reference."""
    model.critic_warmup = config.init.critic_warmup
    model.anchor_coef = config.init.anchor_coef
    model.anchor_decay = config.init.anchor_decay
    restore_reference(model, config, out)


def save_reference(out: Path, config: TrainConfig) -> None:
    """Copy the init model (with its statistics and config) into run directory ``out``."""
    assert config.init.path is not None
    source = Path(config.init.path) / FINAL_MODEL
    target = out / REFERENCE_MODEL
    pairs = [
        (source, target),
        (sidecar_path(source, "vecnormalize"), sidecar_path(target, "vecnormalize")),
        (source.parent / "config.yaml", target.with_suffix(".yaml")),
    ]
    for src, dst in pairs:
        save_atomic(dst, functools.partial(shutil.copyfile, src))


def reference_path(config: TrainConfig, out: Path) -> Path:
    """The model a resumed run anchors to: the run's copy of the init model
    (``DIR/init_model.zip``) or, if that is gone, ``init.path``'s model.

    Raises:
        FileNotFoundError: neither is there.
    """
    assert config.init.path is not None
    for candidate in (out / REFERENCE_MODEL, Path(config.init.path) / FINAL_MODEL):
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(
        f"--resume {out}: the anchor's reference is gone (neither {out / REFERENCE_MODEL} nor "
        f"{Path(config.init.path) / FINAL_MODEL} exists); copy the initial run's model.zip to "
        f"{out / REFERENCE_MODEL}"
    )


def restore_reference(model: AnchoredPPO, config: TrainConfig, out: Path) -> None:
    """Anchor a resumed ``model`` to :func:`reference_path`'s policy."""
    path = reference_path(config, out)
    # the run's copy keeps the init's config beside it (save_reference), an init run in it
    init_config = path.with_suffix(".yaml") if path.name == REFERENCE_MODEL else None
    init_config = init_config or path.parent / "config.yaml"
    if not init_config.is_file():
        raise FileNotFoundError(
            f"--resume {out}: the config of the anchor's reference {path} is gone; copy the "
            f"initial run's config.yaml to {init_config}"
        )
    init_policy = _load_init_model(path, str(out / "config.yaml")).policy
    model.set_reference(_widened(init_policy, model.policy, init_columns(config, init_config)))
