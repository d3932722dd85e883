"""What a ``train.py`` run was asked for (:class:`TrainOptions`) and the recipe it resolves to:
the checked-in or given config, ``--env``/``--algo``/``--set`` overrides and fine-tuning's init
options applied, validated once (:func:`resolve_config`), and the seed checks of a run."""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass, field
from pathlib import Path

from agents.experiments.config_files import (
    CONFIG_DIR,
    ConfigError,
    apply_overrides,
    env_stub,
    load_config_file,
)
from agents.experiments.training import finetune
from agents.experiments.training.config import (
    ALGOS,
    DEFAULT_ENV,
    EVAL_SEED,
    ON_POLICY_ALGOS,
    TrainConfig,
    available_configs,
    default_config_path,
)

__all__ = ["MAX_THREADS", "TrainOptions", "check_seed", "refuse_suite_seeds_of", "resolve_config"]


MAX_THREADS = 256
"""Most torch CPU threads a run asks for (thousands hang or abort torch's thread pool)."""


@dataclass
class TrainOptions:
    """What ``train.py`` was asked for (see its ``--help``).

    Attributes:
        out: run directory (created; checked by
            :func:`~agents.experiments.run_directory.check_output_dir`; must not already hold a
            model: a directory whose run never saved one is taken over).
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
        device: torch device (see :func:`~agents.experiments.training.models.resolve_device`).
        init: a run directory whose policy the run starts from (config key ``init.path``).
        argv: the command line (recorded in config.yaml).
    """

    out: str | Path | None = None
    env_id: str | None = None
    algo: str | None = None
    config: Path | None = None
    overrides: list[str] = field(default_factory=list)
    timesteps: int | None = None
    n_envs: int | None = None
    seed: int | None = None
    resume: str | Path | None = None
    progress: bool = True
    threads: int = 1
    device: str = "cpu"
    init: str | Path | None = None
    argv: list[str] | None = None


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
    given_env = data.get("env_id")
    if options.env_id is not None and given_env is not None:
        # the versions of one env share its recipe: --env picks the version
        if env_stub(str(given_env)) != env_stub(options.env_id):
            raise ConfigError(
                f"--env {options.env_id!r} disagrees with env_id: {given_env!r} in {path}"
            )
        data["env_id"] = options.env_id
    given_algo = data.get("algo")
    if options.algo is not None and given_algo is not None:
        if str(given_algo).lower() != options.algo.lower():
            raise ConfigError(
                f"--algo {options.algo!r} disagrees with algo: {given_algo!r} in {path}"
            )
    data = finetune.adopt_init_options(
        apply_overrides(data, options.overrides), options.init, str(path)
    )
    if options.n_envs is not None:
        data["n_envs"] = options.n_envs
    if options.timesteps is not None:
        data["timesteps"] = options.timesteps
    # a problem a --set brought in is named with the file it was applied to
    where = f"{path} with --set overrides" if options.overrides else str(path)
    config = TrainConfig.from_dict(data, source=where)
    finetune.check_init_run(config, where)
    rollout = config.algo_kwargs.get("n_steps", 2048) * config.n_envs
    batch = config.algo_kwargs.get("batch_size", 64)
    # e.g. the 128-env recipe run with --n-envs 2
    if config.algo in ON_POLICY_ALGOS and batch > rollout:
        print(
            f"note: batch_size {batch} > rollout size {rollout} (n_steps x n_envs); using "
            f"batch_size {rollout}",
            file=sys.stderr,
        )
        kwargs = {**config.algo_kwargs, "batch_size": rollout}
        config = dataclasses.replace(config, algo_kwargs=kwargs)
    return config, str(path)


def check_seed(seed: int, n_envs: int) -> None:
    if seed < 0 or seed + n_envs > EVAL_SEED:
        raise ValueError(
            f"seed must satisfy 0 <= seed and seed + n_envs <= {EVAL_SEED} (evaluation uses "
            f"seeds from {EVAL_SEED}); got seed={seed}, n_envs={n_envs}"
        )


def refuse_suite_seeds_of(seed: int, config: TrainConfig) -> None:
    """Refuse a run whose training or periodic-evaluation envs would be reset with a frozen
    suite's seeds: suites are evaluation-only (:mod:`debris_gym.suites`).

    Training sub-env ``i`` is seeded with ``seed + i`` (curriculum stages continue its
    generator); periodic evaluation (model selection: ``best_model.zip``) with ``EVAL_SEED + i``.
    """
    from debris_gym.suites import refuse_suite_seeds

    refuse_suite_seeds(range(seed, seed + config.n_envs), "training (--seed)")
    if config.eval.freq > 0:
        refuse_suite_seeds(
            range(EVAL_SEED, EVAL_SEED + config.eval.n_envs),
            "periodic evaluation (model selection; eval.n_envs)",
        )
