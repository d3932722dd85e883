"""Expert-labelled rollouts: the expert (or the policy being taught) flies seeded fields while
the expert names the action it would take in every state visited; in worker processes.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import signal
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from agents.experiments.imitation.config import ImitationConfig, expert_params
from agents.experiments.imitation.fitting import MLPActor

__all__ = ["RolloutStats", "collect"]


@dataclass
class RolloutStats:
    """Outcomes of a batch of rollouts (per episode)."""

    seeds: list[int] = field(default_factory=list)
    success: list[bool] = field(default_factory=list)
    collision: list[bool] = field(default_factory=list)
    captured: list[int] = field(default_factory=list)
    delta_v: list[float] = field(default_factory=list)
    steps: list[int] = field(default_factory=list)

    def extend(self, other: RolloutStats) -> None:
        for f in dataclasses.fields(self):
            getattr(self, f.name).extend(getattr(other, f.name))

    def summary(self) -> dict[str, float]:
        n = max(len(self.seeds), 1)
        ok = [dv for dv, s in zip(self.delta_v, self.success, strict=True) if s]
        return {
            "episodes": len(self.seeds),
            "success": sum(self.success) / n,
            "collision": sum(self.collision) / n,
            "captured": float(np.mean(self.captured)) if self.captured else 0.0,
            "delta_v_success": float(np.mean(ok)) if ok else float("nan"),
            "steps": int(sum(self.steps)),
        }


def _rollouts(
    task: tuple[ImitationConfig, Sequence[int], MLPActor | None, float, int],
) -> tuple[np.ndarray, np.ndarray, RolloutStats]:
    """Fly the episodes of ``seeds`` (worker process): observations, expert actions, outcomes."""
    import gymnasium as gym

    import agents
    import debris_gym  # noqa: F401  (registers the IDs)

    config, seeds, actor, beta, rng_seed = task
    kwargs = dict(config.env_kwargs)
    if config.max_episode_steps is not None:
        kwargs["max_episode_steps"] = config.max_episode_steps
    env = gym.make(config.env_id, **kwargs)
    expert = agents.make_agent(config.expert, env, **expert_params(config.expert_kwargs))
    rng = np.random.default_rng(rng_seed)
    observations: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    stats = RolloutStats()
    for seed in seeds:
        obs, info = env.reset(seed=int(seed))
        done, steps = False, 0
        while not done:
            label, _ = expert.predict(obs)
            observations.append(obs)
            labels.append(label)
            if actor is None or rng.random() < beta:
                action = label
            else:
                action = actor(obs)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            steps += 1
        stats.seeds.append(int(seed))
        stats.success.append(bool(info.get("is_success", False)))
        stats.collision.append(bool(info.get("collision", False)))
        stats.captured.append(int(info.get("targets_captured", 0)))
        stats.delta_v.append(float(info.get("delta_v", 0.0)))
        stats.steps.append(steps)
    env.close()
    return np.asarray(observations, np.float32), np.asarray(labels, np.float32), stats


def _ignore_interrupts() -> None:
    """Worker initialiser: Ctrl-C is the parent's to handle; the parent's SIGTERM (how
    ``Pool.terminate`` stops a worker) ends a worker quietly, whatever handler imitate.py set."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def collect(
    config: ImitationConfig,
    seeds: Sequence[int],
    actor: MLPActor | None = None,
    beta: float = 0.0,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, RolloutStats]:
    """Expert-labelled rollouts on the fields of ``seeds``, in ``config.workers`` processes.

    Args:
        config: the run's configuration.
        seeds: reset seeds, one episode each.
        actor: the policy that flies (None: the expert flies).
        beta: probability per step of executing the expert's action instead of the actor's.
        progress: called with the number of episodes finished, after each chunk.

    Returns:
        (observations (M, obs_dim), expert actions (M, act_dim), per-episode outcomes).
    """
    seeds = [int(s) for s in seeds]
    chunk = 5
    tasks = [
        (config, seeds[i : i + chunk], actor, beta, config.seed * 7919 + i)
        for i in range(0, len(seeds), chunk)
    ]
    obs_parts, act_parts, stats = [], [], RolloutStats()
    results: Iterator[tuple[np.ndarray, np.ndarray, RolloutStats]]
    if config.workers == 1:
        results = map(_rollouts, tasks)
        pool = None
    else:
        pool = multiprocessing.get_context("fork").Pool(config.workers, _ignore_interrupts)
        results = pool.imap(_rollouts, tasks)
    try:
        for obs, act, part in results:
            obs_parts.append(obs)
            act_parts.append(act)
            stats.extend(part)
            if progress is not None:
                progress(len(part.seeds))
    except BaseException:  # Ctrl-C or a worker's error: stop the workers now
        if pool is not None:
            pool.terminate()
            pool.join()
            pool = None
        raise
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return np.concatenate(obs_parts), np.concatenate(act_parts), stats
