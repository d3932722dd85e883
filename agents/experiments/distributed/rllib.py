"""DebrisGym under RLlib's new API stack (RLModule / Learner / EnvRunner): a PPO config on a
registered ID, and a short training loop that reports returns.

RLlib's env runners are separate Ray processes: an ID registered only in the driver does not
exist there (``gym.make`` fails with ``NamespaceNotFound``, which RLlib reports as ``IndexError:
list index out of range``). The env is therefore named ``"debris_gym:DebrisGym/…"`` — gymnasium
imports ``debris_gym`` (which registers every ID) in whichever process makes it. Each env runner
makes its ``num_envs_per_env_runner`` sub-envs with ``gym.make_vec``; by default through the
package's native vector env (``vectorization_mode="vector_entry_point"``: every sub-env stepped
in one compiled call, Gymnasium's ``NEXT_STEP`` autoreset, as RLlib's ``sync`` mode), or with
``vectorize="sync"`` through gymnasium's ``SyncVectorEnv`` of single envs.

The swarm IDs go through RLlib's multi-agent API (:func:`swarm_ppo_config`: RLlib's
``ParallelPettingZooEnv`` around :func:`debris_gym.swarm.make`, one policy shared by every
chaser).

``examples/rllib_ppo.py`` runs it; docs/distributed.md shows a measured run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from agents.experiments.distributed import require_ray

__all__ = ["IterationSummary", "ppo_config", "rllib_env_id", "train_ppo"]

VECTORIZE_MODES = ("vector_entry_point", "sync", "async")
"""How an env runner vectorises its sub-envs (``gymnasium.VectorizeMode`` values)."""


def rllib_env_id(env_id: str) -> str:
    """``env_id`` in the ``module:ID`` form that makes it on any Ray worker
    (``"DebrisGym/X"`` → ``"debris_gym:DebrisGym/X"``; a ``module:ID`` is kept)."""
    if ":" in env_id:
        return env_id
    if not env_id.startswith("DebrisGym/"):
        raise ValueError(f"env_id must be a DebrisGym ID (DebrisGym/…), got {env_id!r}")
    return f"debris_gym:{env_id}"


def ppo_config(
    env_id: str = "DebrisGym/Rendezvous2D-Easy-v2",
    env_kwargs: dict[str, Any] | None = None,
    *,
    num_env_runners: int = 1,
    num_envs_per_env_runner: int = 8,
    vectorize: str = "vector_entry_point",
    train_batch_size: int = 4000,
    minibatch_size: int = 500,
    num_epochs: int = 5,
    lr: float = 3e-4,
    gamma: float = 0.995,
    hidden: tuple[int, ...] = (128, 128),
    seed: int | None = 0,
) -> Any:
    """A PPO ``AlgorithmConfig`` (new API stack, torch) for a DebrisGym ID.

    Args:
        env_id: a DebrisGym ID (made on each env runner by :func:`rllib_env_id`'s name).
        env_kwargs: ``gym.make`` options (any env key of docs/environments.md).
        num_env_runners: sampling processes (0: sample in the driver's process).
        num_envs_per_env_runner: sub-envs per env runner.
        vectorize: one of :data:`VECTORIZE_MODES`.
        train_batch_size: env steps per training iteration (per learner).
        minibatch_size: SGD minibatch (env steps).
        num_epochs: passes over each batch.
        lr: learning rate.
        gamma: discount.
        hidden: hidden layer sizes of the policy and value networks.
        seed: seed of the env runners and the model (None: unseeded).

    Raises:
        ImportError: Ray RLlib is not installed.
        ValueError: a bad ID, vectorisation mode or count.
    """
    require_ray("RLlib training", "ray.rllib")
    from ray.rllib.algorithms.ppo import PPOConfig

    if vectorize not in VECTORIZE_MODES:
        raise ValueError(
            f"vectorize must be one of {', '.join(VECTORIZE_MODES)}, got {vectorize!r}"
        )
    _check_counts(num_env_runners=(num_env_runners, 0),
                  num_envs_per_env_runner=(num_envs_per_env_runner, 1),
                  train_batch_size=(train_batch_size, 1), minibatch_size=(minibatch_size, 1),
                  num_epochs=(num_epochs, 1))  # fmt: skip
    config = (
        PPOConfig()
        .environment(rllib_env_id(env_id), env_config=dict(env_kwargs or {}))
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=num_envs_per_env_runner,
            gym_env_vectorize_mode=vectorize,
            num_cpus_per_env_runner=1,
        )
    )
    return _learning(config, train_batch_size, minibatch_size, num_epochs, lr, gamma, hidden, seed)


def _check_counts(**counts: tuple[Any, int]) -> None:
    """Raise ``ValueError`` for a count (name → (value, least allowed)) that is not an integer
    at least its least value."""
    for name, (value, low) in counts.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")


def _learning(
    config: Any, train_batch_size: int, minibatch_size: int, num_epochs: int, lr: float,
    gamma: float, hidden: tuple[int, ...], seed: int | None,
) -> Any:  # fmt: skip
    """``config`` with the PPO training settings, the policy and value networks (tanh MLPs
    of sizes ``hidden``) and the seed (None: unseeded) every config of this module shares."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    config = config.training(
        train_batch_size_per_learner=train_batch_size,
        minibatch_size=min(minibatch_size, train_batch_size),
        num_epochs=num_epochs,
        lr=lr,
        gamma=gamma,
    ).rl_module(
        model_config=DefaultModelConfig(
            fcnet_hiddens=list(hidden), fcnet_activation="tanh", vf_share_layers=False
        )
    )
    return config if seed is None else config.debugging(seed=seed)


SWARM_PREFIX = "debris_swarm:"
"""Prefix of the RLlib env names :func:`swarm_ppo_config` registers for swarm IDs."""


def _swarm_env(config: Any) -> Any:
    """RLlib's env creator of a swarm: ``config["env_id"]`` with the other keys as options, as
    RLlib's ``ParallelPettingZooEnv`` (imported here: only RLlib's processes need it)."""
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    from debris_gym import swarm

    options = dict(config)
    return ParallelPettingZooEnv(swarm.make(options.pop("env_id"), **options))


def swarm_ppo_config(
    env_id: str = "DebrisGym/Swarm2D-Easy-v0",
    env_kwargs: dict[str, Any] | None = None,
    *,
    num_env_runners: int = 0,
    train_batch_size: int = 4000,
    minibatch_size: int = 500,
    num_epochs: int = 5,
    lr: float = 3e-4,
    gamma: float = 0.995,
    hidden: tuple[int, ...] = (128, 128),
    seed: int | None = 0,
) -> Any:
    """A multi-agent PPO ``AlgorithmConfig`` (new API stack, torch) for a swarm ID: one policy
    shared by every chaser (IPPO), through RLlib's PettingZoo wrapper; the env is registered
    as ``debris_swarm:<ID>``.

    Args: as :func:`ppo_config` (``num_env_runners`` 0: sample in the driver's process).

    Raises:
        ImportError: Ray RLlib or PettingZoo is not installed.
        ValueError: not a swarm ID, or a bad count.
    """
    require_ray("RLlib training", "ray.rllib")
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.tune.registry import register_env

    from debris_gym.swarm import SWARM_SPECS

    if env_id not in SWARM_SPECS:
        raise ValueError(f"env_id must be a swarm ID ({', '.join(SWARM_SPECS)}), got {env_id!r}")
    _check_counts(num_env_runners=(num_env_runners, 0), train_batch_size=(train_batch_size, 1),
                  minibatch_size=(minibatch_size, 1), num_epochs=(num_epochs, 1))  # fmt: skip
    name = SWARM_PREFIX + env_id
    register_env(name, _swarm_env)
    config = (
        PPOConfig()
        .environment(name, env_config={"env_id": env_id, **dict(env_kwargs or {})})
        .multi_agent(policies={"shared"}, policy_mapping_fn=_shared_policy)
        .env_runners(num_env_runners=num_env_runners)
    )
    return _learning(config, train_batch_size, minibatch_size, num_epochs, lr, gamma, hidden, seed)


def _shared_policy(agent_id: Any, *args: Any, **kwargs: Any) -> str:
    """Every chaser flies the one shared policy."""
    return "shared"


@dataclass(frozen=True)
class IterationSummary:
    """One ``algo.train()`` call: cumulative env steps, the mean return of the episodes that
    ended in it (NaN when none did), episodes ended, and its wall time (s)."""

    iteration: int
    env_steps: int
    episode_return_mean: float
    episodes: int
    wall_time_s: float


def train_ppo(config: Any, iterations: int) -> list[IterationSummary]:
    """Build the algorithm from ``config``, train ``iterations`` iterations, stop it; the
    summary of each iteration.

    A local Ray is started if none is running (and stopped after).
    """
    ray = require_ray("RLlib training")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")
    started = not ray.is_initialized()
    if started:
        ray.init(include_dashboard=False, logging_level="WARNING")
    try:
        algo = config.build_algo()
        try:
            return [_summary(k, algo) for k in range(1, iterations + 1)]
        finally:
            algo.stop()
    finally:
        if started:
            ray.shutdown()


def _summary(k: int, algo: Any) -> IterationSummary:
    """Train one iteration and summarise it."""
    start = time.perf_counter()
    result = algo.train()
    runners = result.get("env_runners", {})
    lifetime = result.get("num_env_steps_sampled_lifetime", runners.get(
        "num_env_steps_sampled_lifetime", 0))  # fmt: skip
    return IterationSummary(
        iteration=k,
        env_steps=int(lifetime),
        episode_return_mean=float(runners.get("episode_return_mean", float("nan"))),
        episodes=int(runners.get("num_episodes", 0)),
        wall_time_s=time.perf_counter() - start,
    )
