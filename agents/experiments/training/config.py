"""Training recipes: the typed, validated form of a YAML config, one per env × algorithm.

Hyper-parameters live in versioned YAML files shipped in ``agents/configs/`` (rl-zoo style);
:class:`TrainConfig` is their typed form and :meth:`TrainConfig.from_dict` the one place that
checks keys and values (with :mod:`agents.experiments.training.validation`).
"""

from __future__ import annotations

import dataclasses
import inspect
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.experiments.config_files import CONFIG_DIR, ConfigError, apply_overrides, env_stub
from agents.experiments.training.sweep_config import SweepConfig, validate_sweep
from agents.experiments.training.validation import (
    at_least,
    at_most,
    check_keys,
    config_error,
    section,
    typed,
    validate_algo_kwargs,
    validate_curriculum,
    validate_policy_kwargs,
)
from agents.policies.model_files import LEARNED_ALGOS, algo_class

ALGOS = LEARNED_ALGOS
"""Algorithms ``train.py`` trains: every algorithm whose models a learned agent loads."""

ON_POLICY_ALGOS = ("ppo", "recurrent_ppo")
"""Algorithms that learn from rollouts (``n_steps`` × envs samples per update)."""

OFF_POLICY = ("sac", "td3", "dqn")
"""Algorithms with a replay buffer."""

EVAL_SEED = 1_000_000
"""Evaluation sub-env ``i`` is reset with seed ``EVAL_SEED + i``; training seeds stay below it."""

MAX_TIMESTEPS = 10**12
"""Largest training budget (env steps); a larger one is a typo."""

MAX_ENVS = 16_384
"""Most sub-envs of a training or evaluation env."""

MAX_EVAL_EPISODES = 100_000
"""Most episodes of one periodic evaluation."""

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v2"
"""Env of a ``train.py`` run that names neither ``--env`` nor ``--config``."""


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
class EncoderConfig:
    """How the policy reads the observation before its MLP layers.

    Attributes:
        kind: ``"flat"`` (SB3's flatten, the default) or ``"set"``: a permutation-invariant
            encoder of the body slots (:class:`agents.policies.set_encoder.SlotSetExtractor`).
        embed_dim: ``set``: output size of the per-slot network (each slot kind adds twice as
            many features: a mean and a max).
        hidden_dim: ``set``: hidden width of the per-slot network.
    """

    kind: str = "flat"
    embed_dim: int = 64
    hidden_dim: int = 64


ENCODERS = ("flat", "set")
"""``encoder.kind`` values."""


@dataclass(frozen=True)
class InitConfig:
    """RL fine-tuning: start PPO from another run's policy (``train.py --init DIR``).

    Attributes:
        path: run directory of the initial policy (``imitate.py`` or ``train.py`` output:
            ``model.zip``, ``vecnormalize.pkl``, ``config.yaml``); None = learn from scratch.
            Its policy weights and observation statistics are the start (the statistics stay
            frozen), its observation options are taken over.
        critic_warmup: env steps (over all sub-envs) at the start during which only the value
            function learns; the policy, ``log_std`` included, does not change.
        anchor_coef: weight of the imitation anchor ``mean ‖μθ(s) − μ₀(s)‖²`` (μ: deterministic
            action, normalised thrust in [-1, 1] per axis; μ₀: the initial policy's) at the end
            of the warm-up.
        anchor_decay: env steps after the warm-up over which the anchor's weight falls linearly
            to 0.
    """

    path: str | None = None
    critic_warmup: int = 0
    anchor_coef: float = 0.0
    anchor_decay: int = 0


@dataclass(frozen=True)
class StartsConfig:
    """Training missions that start part-way, from a bank of recorded states (``python
    starts.py``), the legs chosen by prioritised level replay
    (:class:`agents.experiments.starts.LegSampler`; docs/training.md, "Starting part-way").

    Attributes:
        bank: path of the start bank (``.npz``); None = every mission starts at the dock.
            Relative paths are read from the working directory.
        usual: share of missions that start as usual, at the dock.
        temperature: β of the legs' rank prioritisation (> 0).
        staleness: ρ, weight of the staleness term.
        smoothing: rate of each leg's moving-average failure rate.
    """

    bank: str | None = None
    usual: float = 0.5
    temperature: float = 0.3
    staleness: float = 0.1
    smoothing: float = 0.05


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
        init: RL fine-tuning from another run's policy (:class:`InitConfig`; ppo only).
        encoder: how the policy reads the observation (:class:`EncoderConfig`).
        starts: training missions that start part-way (:class:`StartsConfig`).
        sweep: the search space of a hyper-parameter sweep over this recipe
            (:class:`~agents.experiments.training.sweep_config.SweepConfig`, ``sweep.py``);
            None: none. A plain ``train.py`` run ignores it.
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
    init: InitConfig = field(default_factory=InitConfig)
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    starts: StartsConfig = field(default_factory=StartsConfig)
    sweep: SweepConfig | None = None
    notes: str = ""

    def stage(self, timesteps: int) -> int:
        """Index of the curriculum stage at ``timesteps`` (``len(curriculum)``: the final task)."""
        for k, stage in enumerate(self.curriculum):
            if timesteps < stage["until"]:
                return k
        return len(self.curriculum)

    def stage_mission(self, stage: int) -> dict[str, Any]:
        """The ``reset(options={"mission": ...})`` of curriculum stage ``stage`` (``{}``: the
        final task, the env's own mission)."""
        if stage >= len(self.curriculum):
            return {}
        return dict(self.curriculum[stage]["mission"])

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
        data = dataclasses.asdict(self)
        data["sweep"] = None if self.sweep is None else self.sweep.to_dict()
        return data

    @property
    def gamma(self) -> float:
        """The algorithm's discount (its SB3 default when the config does not set it)."""
        value = self.algo_kwargs.get("gamma")
        if value is None:
            value = inspect.signature(algo_class(self.algo).__init__).parameters["gamma"].default
        return float(value)


def _validate(data: dict[str, Any], source: str) -> TrainConfig:
    import gymnasium as gym

    import debris_gym  # noqa: F401  (registers the IDs)
    from debris_gym.config import EnvConfig
    from debris_gym.swarm import SWARM_SPECS
    from debris_gym.swarm import checked_options as checked_swarm_options

    top = [f.name for f in dataclasses.fields(TrainConfig)]
    data = check_keys(data, top, "", source)
    for key in ("version", "env_id", "algo", "timesteps", "n_envs"):
        if key not in data:
            raise config_error(source, key, "is missing (required)")
    version = typed(data["version"], int, "version", source)
    at_least(version, 1, "version", source)
    env_id = typed(data["env_id"], str, "env_id", source)
    swarm = env_id in SWARM_SPECS
    if not swarm and (env_id not in gym.registry or gym.registry[env_id].namespace != "DebrisGym"):
        ids = [i for i in gym.registry if i.startswith("DebrisGym/")] + list(SWARM_SPECS)
        what = "is not a DebrisGym env" if env_id in gym.registry else "names an unknown env"
        raise config_error(source, "env_id", f"{what}: {env_id!r}; DebrisGym IDs: {', '.join(ids)}")
    algo = typed(data["algo"], str, "algo", source).lower()
    if algo not in ALGOS:
        raise config_error(source, "algo", f"must be one of {', '.join(ALGOS)}, got {algo!r}")
    timesteps = typed(data["timesteps"], int, "timesteps", source)
    at_least(timesteps, 1, "timesteps", source)
    at_most(timesteps, MAX_TIMESTEPS, "timesteps", source)
    n_envs = typed(data["n_envs"], int, "n_envs", source)
    at_least(n_envs, 1, "n_envs", source)
    at_most(n_envs, MAX_ENVS, "n_envs", source)
    notes = typed(data.get("notes", ""), str, "notes", source, optional=True) or ""

    # env options: the env's own validation names the key
    env_kwargs = typed(data.get("env_kwargs") or {}, dict, "env_kwargs", source)
    options = {k: v for k, v in env_kwargs.items() if k != "max_episode_steps"}
    spec_kwargs = SWARM_SPECS[env_id]["kwargs"] if swarm else gym.registry[env_id].kwargs
    if "max_episode_steps" in env_kwargs:
        steps = typed(env_kwargs["max_episode_steps"], int, "env_kwargs.max_episode_steps", source)
        at_least(steps, 1, "env_kwargs.max_episode_steps", source)
        env_kwargs["max_episode_steps"] = steps
    try:
        if swarm:  # one env per chaser: n_envs counts chasers
            env_config, swarm_config = checked_swarm_options(env_id, options)
            if n_envs % swarm_config.n_chasers:
                raise config_error(
                    source, "n_envs", f"must be a multiple of n_chasers={swarm_config.n_chasers} "
                    f"(one env per chaser), got {n_envs}",
                )  # fmt: skip
        else:
            env_config = EnvConfig.from_kwargs(**{**spec_kwargs, **options})
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise config_error(source, "env_kwargs", f"is invalid: {exc}") from None
    if algo == "dqn" and env_config.action != "discrete":
        raise config_error(
            source,
            "env_kwargs.action",
            "must be 'discrete' for dqn (DQN needs a discrete action space); "
            "set env_kwargs: {action: discrete}",
        )
    if algo in ("sac", "td3") and env_config.action == "discrete":
        raise config_error(
            source, "env_kwargs.action", f"must be 'continuous' or 'residual' for {algo}"
        )

    try:
        cls = algo_class(algo)
    except ValueError as exc:  # an algorithm whose package is not installed
        raise config_error(source, "algo", str(exc)) from None
    policy = typed(data.get("policy", "MlpPolicy"), str, "policy", source)
    if policy not in cls.policy_aliases:
        raise config_error(
            source, "policy", f"must be one of {', '.join(cls.policy_aliases)}, got {policy!r}"
        )
    policy_kwargs = validate_policy_kwargs(
        data.get("policy_kwargs"), cls.policy_aliases[policy], source
    )
    algo_kwargs = validate_algo_kwargs(data.get("algo_kwargs"), cls, algo, source)
    if algo in ON_POLICY_ALGOS:  # SB3 asserts a rollout of at least 2 samples
        n_steps = algo_kwargs.get(
            "n_steps", inspect.signature(cls.__init__).parameters["n_steps"].default
        )
        if n_steps * n_envs < 2:
            raise config_error(
                source,
                "algo_kwargs.n_steps",
                f"must give a rollout of at least 2 samples (n_steps x n_envs >= 2), got "
                f"n_steps={n_steps}, n_envs={n_envs}",
            )

    normalize = section(NormalizeConfig, data.get("normalize"), "normalize.", source)
    for key in ("clip_obs", "clip_reward", "epsilon"):
        if getattr(normalize, key) <= 0:
            raise config_error(source, f"normalize.{key}", "must be > 0")
    if normalize.gamma is not None and not 0.0 <= normalize.gamma <= 1.0:
        raise config_error(source, "normalize.gamma", f"must lie in [0, 1], got {normalize.gamma}")
    evaluation = section(EvalConfig, data.get("eval"), "eval.", source)
    at_least(evaluation.freq, 0, "eval.freq", source)
    at_least(evaluation.n_episodes, 1, "eval.n_episodes", source)
    at_most(evaluation.n_episodes, MAX_EVAL_EPISODES, "eval.n_episodes", source)
    at_least(evaluation.n_envs, 1, "eval.n_envs", source)
    at_most(evaluation.n_envs, MAX_ENVS, "eval.n_envs", source)
    checkpoint = section(CheckpointConfig, data.get("checkpoint"), "checkpoint.", source)
    at_least(checkpoint.freq, 0, "checkpoint.freq", source)
    at_least(checkpoint.keep, 0, "checkpoint.keep", source)
    at_least(checkpoint.replay_buffer_max_mb, 0, "checkpoint.replay_buffer_max_mb", source)
    if checkpoint.replay_buffer not in ("auto", "always", "never"):
        raise config_error(
            source,
            "checkpoint.replay_buffer",
            f"must be 'auto', 'always' or 'never', got {checkpoint.replay_buffer!r}",
        )
    if swarm and data.get("curriculum"):
        raise config_error(source, "curriculum", "is not supported for swarm IDs yet (use [])")
    curriculum = validate_curriculum(
        data.get("curriculum"), env_kwargs, spec_kwargs, env_config, source
    )
    init = _validate_init(data.get("init"), algo, normalize, source)
    encoder = _validate_encoder(data.get("encoder"), init, source)
    starts = _validate_starts(data.get("starts"), swarm, source)
    if starts.bank is not None and curriculum:
        raise config_error(
            source, "starts.bank", "and a curriculum both change where missions start: use one"
        )
    recipe = {key: value for key, value in data.items() if key != "sweep"}

    def check_values(key: str, value: Any) -> None:  # the recipe with one swept value set
        _validate(apply_overrides(recipe, [f"{key}={json.dumps(value)}"]), source)

    sweep = validate_sweep(data.get("sweep"), check_values, source)
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
        init=init,
        encoder=encoder,
        starts=starts,
        sweep=sweep,
        notes=notes,
    )


def _validate_starts(data: Any, swarm: bool, source: str) -> StartsConfig:
    starts = section(StartsConfig, data, "starts.", source)
    if starts.bank is not None:
        typed(starts.bank, str, "starts.bank", source)
        if swarm:
            raise config_error(source, "starts.bank", "is for single-chaser envs (use null)")
    try:
        from agents.experiments.starts.sampler import SamplerParams

        SamplerParams(starts.usual, starts.temperature, starts.staleness, starts.smoothing)
    except ValueError as exc:
        raise config_error(source, "starts", str(exc)) from None
    return starts


def _validate_encoder(data: Any, init: InitConfig, source: str) -> EncoderConfig:
    encoder = section(EncoderConfig, data, "encoder.", source)
    if encoder.kind not in ENCODERS:
        raise config_error(
            source, "encoder.kind", f"must be one of {', '.join(ENCODERS)}, got {encoder.kind!r}"
        )
    at_least(encoder.embed_dim, 1, "encoder.embed_dim", source)
    at_least(encoder.hidden_dim, 1, "encoder.hidden_dim", source)
    if encoder.kind != "flat" and init.path is not None:
        raise config_error(
            source, "encoder.kind", "must be 'flat' with init (fine-tuning keeps the init's net)"
        )
    return encoder


def _validate_init(data: Any, algo: str, normalize: NormalizeConfig, source: str) -> InitConfig:
    """The ``init`` section: ranges, and what fine-tuning needs of the rest of the config (the
    init run directory itself is checked by :func:`~agents.experiments.training.finetune.
    check_init_run`)."""
    init = section(InitConfig, data, "init.", source)
    at_least(init.critic_warmup, 0, "init.critic_warmup", source)
    at_least(init.anchor_coef, 0.0, "init.anchor_coef", source)
    at_least(init.anchor_decay, 0, "init.anchor_decay", source)
    if init.path is None:
        if init.critic_warmup > 0 or init.anchor_coef > 0:
            raise config_error(
                source,
                "init.path",
                "is required with init.critic_warmup or init.anchor_coef > 0 (the run to "
                "fine-tune: train.py --init DIR)",
            )
        return init
    if not init.path.strip():
        raise config_error(source, "init.path", "must name a run directory, got an empty string")
    if algo != "ppo":
        raise config_error(
            source, "init.path", f"fine-tuning from an initial policy needs algo ppo, got {algo!r}"
        )
    if init.anchor_coef > 0 and init.anchor_decay < 1:
        raise config_error(
            source,
            "init.anchor_decay",
            f"must be >= 1 env step when init.anchor_coef > 0 (the anchor decays to 0 over it), "
            f"got {init.anchor_decay}",
        )
    if not (normalize.enabled and normalize.norm_obs):
        raise config_error(
            source,
            "normalize.enabled",
            "and normalize.norm_obs must be true with init.path (the initial policy reads "
            "observations normalised by its run's statistics)",
        )
    return init


def default_config_path(env_id: str, algo: str) -> Path:
    """The checked-in config for ``env_id`` × ``algo`` (it may not exist)."""
    return CONFIG_DIR / f"{env_stub(env_id)}_{algo.lower()}.yaml"


def available_configs() -> list[str]:
    """Names of the checked-in training configs (``rendezvous2d_ppo``, …; one per algorithm,
    so not imitate.py's ``*_imitation.yaml``)."""
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml") if p.stem.rsplit("_", 1)[-1] in ALGOS)
