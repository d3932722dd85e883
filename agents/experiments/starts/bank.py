"""Build a start bank from planner rollouts: fly a baseline on seeded missions and keep where
each mission stood right after every capture (the start of each leg after the first).

The library side of ``python starts.py``; the bank is :class:`debris_gym.start_bank.StartBank`.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the IDs)
from agents.policies.registry import BASELINES, make_agent
from debris_gym.start_bank import StartBank, world_options
from debris_gym.suites import refuse_suite_seeds

__all__ = ["BankEntry", "build_start_bank", "fly_and_record"]


@dataclass(frozen=True)
class BankEntry:
    """One recorded start (see :class:`~debris_gym.start_bank.StartBank`)."""

    episode: int
    word: int
    step: int
    state: np.ndarray
    order: tuple[int, ...]
    delta_v: float


def fly_and_record(env: gym.Env, agent: Any, seed: int, episode: int) -> list[BankEntry]:
    """Fly ``agent`` on the mission of reset seed ``seed``; the entries recorded after each step
    that captured a target and did not end the mission failed (a collision, the bounds or the
    budget: no start is taken from a failure)."""
    obs, info = env.reset(seed=seed)
    if hasattr(agent, "reset"):
        agent.reset()
    unwrapped: Any = env.unwrapped
    word = unwrapped.field_word
    if word is None:
        raise ValueError(
            f"{env.spec.id if env.spec else env}: its fields are not moving random ones, which "
            "a start bank needs (their 64-bit words)"
        )
    entries: list[BankEntry] = []
    order: list[int] = []
    for step in range(1, 1_000_000):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        new = [int(j) for j in np.flatnonzero(info["captured"]) if int(j) not in order]
        failed = info["collision"] or info["out_of_bounds"] or info["budget_spent"]
        if new and not failed and not info["is_success"]:
            order += sorted(new)
            entries.append(
                BankEntry(episode, word, step, np.array(info["chaser_state"], dtype=float),
                          tuple(order), float(info["delta_v"]))
            )  # fmt: skip
        else:
            order += sorted(new)
        if terminated or truncated:
            break
    return entries


_WORKER: dict[str, Any] = {}


def _start_worker(env_id: str, env_kwargs: Mapping[str, Any], source: str) -> None:
    import torch

    torch.set_num_threads(1)
    env = gym.make(env_id, **env_kwargs)
    _WORKER.update(env=env, agent=make_agent(source, env))


def _fly(job: tuple[int, int]) -> list[BankEntry]:
    episode, seed = job
    return fly_and_record(_WORKER["env"], _WORKER["agent"], seed, episode)


def _entries(
    env_id: str,
    env_kwargs: Mapping[str, Any],
    source: str,
    seeds: list[int],
    workers: int,
) -> Iterator[list[BankEntry]]:
    jobs = list(enumerate(seeds))
    if workers <= 1:
        _start_worker(env_id, env_kwargs, source)
        try:
            yield from map(_fly, jobs)
        finally:
            _WORKER["env"].close()
            _WORKER.clear()
        return
    context = multiprocessing.get_context("spawn")
    with context.Pool(workers, _start_worker, (env_id, dict(env_kwargs), source)) as pool:
        yield from pool.imap(_fly, jobs)


def build_start_bank(
    env_id: str,
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    source: str = "apf-mpc",
    missions: int = 100,
    seed: int = 0,
    workers: int = 1,
    progress: bool = True,
) -> StartBank:
    """Fly ``source`` (a baseline's name) on ``missions`` missions of ``env_id`` (reset seeds
    ``seed`` …) and bank every capture it makes (``workers`` processes).

    Raises:
        ValueError: an unknown baseline, a bad count, seeds of an evaluation suite (training
            on its fields would leak them into its evaluation), or an env without moving random
            fields.
    """
    env_kwargs = dict(env_kwargs or {})
    if source not in BASELINES:
        raise ValueError(f"unknown source {source!r}; known baselines: {', '.join(BASELINES)}")
    if not 1 <= missions <= 1_000_000:
        raise ValueError(f"missions={missions} is out of range; allowed: [1, 1000000]")
    if not 1 <= workers <= (os.cpu_count() or 1) * 4:
        raise ValueError(f"workers={workers} is out of range; allowed: [1, 4 × cores]")
    refuse_suite_seeds(range(seed, seed + missions), "a start bank (training starts)")
    seeds = list(range(seed, seed + missions))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=missions, desc=f"{source} on {env_id}", unit="mission")
    entries: list[BankEntry] = []
    for found in _entries(env_id, env_kwargs, source, seeds, workers):
        entries += found
        if bar is not None:
            bar.update(1)
            bar.set_postfix(starts=len(entries))
    if bar is not None:
        bar.close()
    n_targets = max([len(e.order) for e in entries], default=0)
    captured = np.full((len(entries), max(n_targets, 1)), -1, dtype=np.int64)
    for k, e in enumerate(entries):
        captured[k, : len(e.order)] = e.order
    probe = gym.make(env_id, **env_kwargs)
    config = probe.unwrapped.config  # type: ignore[attr-defined]
    probe.close()
    dim = config.dim
    return StartBank(
        env_id=env_id,
        env_kwargs=env_kwargs,
        world=world_options(config),
        source=source,
        words=np.array([e.word for e in entries], dtype=np.uint64),
        steps=np.array([e.step for e in entries], dtype=np.int64),
        states=np.array([e.state for e in entries], dtype=float).reshape(len(entries), 2 * dim),
        captured=captured,
        delta_v=np.array([e.delta_v for e in entries], dtype=float),
        episodes=np.array([e.episode for e in entries], dtype=np.int64),
        meta={"missions": missions, "seed": seed},
    )
