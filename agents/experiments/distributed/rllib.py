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

The swarm IDs go through RLlib's multi-agent API, RLlib's ``ParallelPettingZooEnv`` around
:func:`debris_gym.swarm.make`, one policy shared by every chaser: :func:`swarm_ppo_config`
(IPPO: actor and critic on the chaser's own observation) and :func:`swarm_mappo_config` (MAPPO:
the critic on the team's state, :mod:`~agents.experiments.distributed.rllib_mappo`). Both log
the team's success per episode (:class:`IterationSummary`).

``examples/rllib_ppo.py`` and ``examples/swarm_mappo.py`` run them; docs/distributed.md and
docs/swarm.md show measured runs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from agents.experiments.distributed import require_ray

__all__ = [
    "IterationSummary",
    "ppo_config",
    "rllib_env_id",
    "swarm_mappo_config",
    "swarm_ppo_config",
    "train_ppo",
]

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
    of sizes ``hidden``) and the seed (None: unseeded) every config of this module shares.

    The value loss is not clipped (``vf_clip_param`` infinite): RLlib clamps each row's squared
    value error at ``vf_clip_param`` (10 by default), which takes the value gradient away from
    every row whose error is above √10 — nearly every row while the critic learns returns of
    tens to hundreds, as here."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    config = config.training(
        train_batch_size_per_learner=train_batch_size,
        minibatch_size=min(minibatch_size, train_batch_size),
        num_epochs=num_epochs,
        lr=lr,
        gamma=gamma,
        vf_clip_param=math.inf,
    ).rl_module(
        model_config=DefaultModelConfig(
            fcnet_hiddens=list(hidden), fcnet_activation="tanh", vf_share_layers=False
        )
    )
    return config if seed is None else config.debugging(seed=seed)


SWARM_PREFIX = "debris_swarm:"
"""Prefix of the RLlib env names :func:`swarm_ppo_config` registers for swarm IDs."""

MAPPO_PREFIX = "debris_swarm_state:"
"""Prefix of the RLlib env names :func:`swarm_mappo_config` registers for swarm IDs (the env
with :class:`~debris_gym.swarm.wrappers.CentralState` observations)."""

TEAM_SUCCESS = "team_success"
"""Metric the swarm configs log per ended episode (1 or 0), under ``env_runners``."""


def _swarm_env(config: Any, central_state: bool = False) -> Any:
    """RLlib's env creator of a swarm: ``config["env_id"]`` with the other keys as options, as
    RLlib's ``ParallelPettingZooEnv`` (imported here: only RLlib's processes need it); with
    ``central_state``, each agent's observation is ``{"obs": own, "state": team}``
    (:class:`~debris_gym.swarm.wrappers.CentralState`, own block first)."""
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    from debris_gym import swarm
    from debris_gym.swarm.wrappers import CentralState

    options = dict(config)
    env = swarm.make(options.pop("env_id"), **options)
    return ParallelPettingZooEnv(CentralState(env) if central_state else env)


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
    config = _swarm_base(env_id, env_kwargs, SWARM_PREFIX, _swarm_env, num_env_runners,
                         train_batch_size, minibatch_size, num_epochs)  # fmt: skip
    return _learning(config, train_batch_size, minibatch_size, num_epochs, lr, gamma, hidden, seed)


def swarm_mappo_config(
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
    """A MAPPO ``AlgorithmConfig`` (new API stack, torch) for a swarm ID: one actor shared by
    every chaser on its own observation, one critic on the team's state (every chaser's
    observation, the chaser's own first: :class:`~debris_gym.swarm.wrappers.CentralState`),
    the network :class:`~agents.experiments.distributed.rllib_mappo.MAPPOTorchModule`; the env
    is registered as ``debris_swarm_state:<ID>``.

    Args: as :func:`swarm_ppo_config` (``hidden``: the actor's and the critic's layers).

    Raises:
        ImportError: Ray RLlib or PettingZoo is not installed.
        ValueError: not a swarm ID, or a bad count.
    """
    creator = partial(_swarm_env, central_state=True)
    config = _swarm_base(env_id, env_kwargs, MAPPO_PREFIX, creator, num_env_runners,
                         train_batch_size, minibatch_size, num_epochs)  # fmt: skip
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    from agents.experiments.distributed.rllib_mappo import MAPPOTorchModule

    spec = MultiRLModuleSpec(rl_module_specs={"shared": RLModuleSpec(MAPPOTorchModule)})
    config = config.rl_module(rl_module_spec=spec)
    return _learning(config, train_batch_size, minibatch_size, num_epochs, lr, gamma, hidden, seed)


def _swarm_base(
    env_id: str, env_kwargs: dict[str, Any] | None, prefix: str, creator: Callable[[Any], Any],
    num_env_runners: int, train_batch_size: int, minibatch_size: int, num_epochs: int,
) -> Any:  # fmt: skip
    """The PPO config both swarm configs start from: ``env_id`` checked and registered as
    ``prefix + env_id`` with ``creator``, every chaser on the one policy ``"shared"``, the
    team's success logged per episode, the counts checked."""
    require_ray("RLlib training", "ray.rllib")
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.tune.registry import register_env

    from debris_gym.swarm import SWARM_SPECS

    if env_id not in SWARM_SPECS:
        raise ValueError(f"env_id must be a swarm ID ({', '.join(SWARM_SPECS)}), got {env_id!r}")
    _check_counts(num_env_runners=(num_env_runners, 0), train_batch_size=(train_batch_size, 1),
                  minibatch_size=(minibatch_size, 1), num_epochs=(num_epochs, 1))  # fmt: skip
    name = prefix + env_id
    register_env(name, creator)
    return (
        PPOConfig()
        .environment(name, env_config={"env_id": env_id, **dict(env_kwargs or {})})
        .multi_agent(policies={"shared"}, policy_mapping_fn=_shared_policy)
        .env_runners(num_env_runners=num_env_runners)
        .callbacks(on_episode_end=_log_team_success)
    )


def _shared_policy(agent_id: Any, *args: Any, **kwargs: Any) -> str:
    """Every chaser flies the one shared policy."""
    return "shared"


def _log_team_success(*, episode: Any, metrics_logger: Any, **kwargs: Any) -> None:
    """RLlib's episode-end callback: log :data:`TEAM_SUCCESS` from the ``team_success`` of the
    infos of the episode's last step (the agents that ended in it; the team's outcome is
    final once the last chaser has ended), averaged as RLlib averages the episode return."""
    infos = episode.get_infos(-1)
    success = any(bool(info.get("team_success")) for info in infos.values() if info)
    config = kwargs["env_runner"].config
    window = math.ceil(config.metrics_num_episodes_for_smoothing / (config.num_env_runners or 1))
    metrics_logger.log_value(TEAM_SUCCESS, float(success), reduce="mean", window=max(1, window))


@dataclass(frozen=True)
class IterationSummary:
    """One ``algo.train()`` call: cumulative env steps, the mean return of the episodes that
    ended in it (a swarm's: the sum over its chasers; NaN when none did), episodes ended, its
    wall time (s), the fraction of those episodes the team succeeded in (the swarm configs;
    NaN otherwise or when none ended), and the PPO policy and value losses RLlib reports for
    it (of the one RLModule trained; NaN when there are several)."""

    iteration: int
    env_steps: int
    episode_return_mean: float
    episodes: int
    wall_time_s: float
    team_success: float = math.nan
    policy_loss: float = math.nan
    vf_loss: float = math.nan


def train_ppo(
    config: Any, iterations: int, on_iteration: Callable[[IterationSummary], None] | None = None
) -> list[IterationSummary]:
    """Build the algorithm from ``config``, train ``iterations`` iterations, stop it; the
    summary of each iteration (``on_iteration``, if given, is called with each as it ends).

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
            summaries = []
            for k in range(1, iterations + 1):
                summaries.append(_summary(k, algo))
                if on_iteration is not None:
                    on_iteration(summaries[-1])
            return summaries
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
    modules = [v for m, v in result.get("learners", {}).items() if m != "__all_modules__"]
    losses = modules[0] if len(modules) == 1 else {}
    return IterationSummary(
        iteration=k,
        env_steps=int(lifetime),
        episode_return_mean=float(runners.get("episode_return_mean", math.nan)),
        episodes=int(runners.get("num_episodes", 0)),
        wall_time_s=time.perf_counter() - start,
        team_success=float(runners.get(TEAM_SUCCESS, math.nan)),
        policy_loss=float(losses.get("policy_loss", math.nan)),
        vf_loss=float(losses.get("vf_loss", math.nan)),
    )
