"""Evaluation episodes fanned out to Ray actors: the engine of ``evaluate.py --backend ray``.

:class:`RayBackend` is an :class:`~agents.experiments.evaluation.runner.EpisodeBackend`: the
runner (:func:`~agents.experiments.evaluation.runner.evaluate_agents`) hands it the episodes
still to fly and gets every record back in this process as it arrives, so the progress bar, the
journal (``DIR/unfinished/``, hence ``--resume``) and the outputs are the local run's.

Each worker is a long-lived Ray actor holding one env and one agent per agent label, built
once: the numba compile (or the on-disk cache load) and a learned model's load are paid once per
worker, not per episode. An episode is flown by the runner's own
:func:`~agents.experiments.evaluation.runner.run_episode`, so a record equals the local one
apart from the timing columns (:data:`~agents.experiments.evaluation.records.TIMING_COLUMNS`).

Episodes of an agent whose ``episode_independent`` attribute is true (every classical baseline
but ``random``, learned policies) are flown one by one by whichever worker is free. Any other
agent (``random``, whose generator runs on across episodes, and your own policies unless they
declare the attribute) may carry state from one episode to the next: its episodes are flown in
order by one worker, which first re-flies, unrecorded, the finished episodes before its last
unfinished one — exactly what the local run does on ``--resume`` — so the records are the
local run's there too.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from agents.experiments.distributed import require_ray
from agents.experiments.evaluation.records import EpisodeRecord
from agents.experiments.evaluation.runner import (
    EvaluationJob,
    build_agent_env,
    check_replay,
    run_episode,
)

__all__ = ["IN_FLIGHT", "EpisodeWorker", "RayBackend", "check_workers", "plan_units"]

IN_FLIGHT = 2
"""Episodes queued on each worker at a time: the next one is already there when one ends."""


def check_workers(workers: int | None) -> int | None:
    """``workers`` checked: None (as many as the Ray cluster has CPUs) or an integer >= 1.

    Raises:
        ValueError: anything else (the message names ``workers``).
    """
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    return workers


class EpisodeWorker:
    """The body of one Ray actor: an env and an agent per agent label of ``job``, built on first
    use and kept, flying the episodes it is sent.

    Args:
        job: the evaluation.
        paths: entries put in front of ``sys.path`` (the driver's working directory, where
            ``MODULE:ATTR`` policies are imported from); those that do not exist on this
            machine are left out.
    """

    def __init__(self, job: EvaluationJob, paths: tuple[str, ...] = ()) -> None:
        for path in reversed(paths):
            if path not in sys.path and os.path.isdir(path):
                sys.path.insert(0, path)
        self.job = job
        self.built: dict[str, tuple[Any, Any]] = {}
        self.specs = {spec.label: spec for spec in job.specs}

    def independence(self) -> dict[str, bool]:
        """{agent label: whether its episodes are independent} — every agent is built here."""
        return {
            label: bool(getattr(self._agent(label)[1], "episode_independent", False))
            for label in self.specs
        }

    def fly(self, label: str, episode: int) -> EpisodeRecord:
        """Fly episode ``episode`` of agent ``label``; its record."""
        env, agent = self._agent(label)
        return run_episode(env, agent, label, episode, *self.job.resets[episode])

    def close(self) -> None:
        """Close the envs."""
        for env, _ in self.built.values():
            env.close()
        self.built.clear()

    def _agent(self, label: str) -> tuple[Any, Any]:
        if label not in self.built:
            with warnings.catch_warnings():  # already reported by the driver's checks
                warnings.simplefilter("ignore", UserWarning)
                self.built[label] = build_agent_env(self.job, self.specs[label])
        return self.built[label]


@dataclass(frozen=True)
class Unit:
    """One call to a worker: fly episode ``episode`` of agent ``label``; ``replay``: it is
    finished already and re-flown only to bring a stateful agent to the state it had."""

    label: str
    episode: int
    replay: bool = False


def plan_units(
    job: EvaluationJob,
    done: Mapping[tuple[str, int], EpisodeRecord],
    independent: Mapping[str, bool],
) -> tuple[list[Unit], list[list[Unit]]]:
    """The work of ``job`` given the finished episodes ``done``: the units any worker may fly
    (independent agents' unfinished episodes), and one ordered stream per stateful agent with
    unfinished episodes (its episodes up to the last unfinished one, the finished ones as
    replays), to be flown in order by one worker."""
    shared: list[Unit] = []
    streams: list[list[Unit]] = []
    for spec in job.specs:
        todo = [i for i in range(job.episodes) if (spec.label, i) not in done]
        if not todo:
            continue
        if independent[spec.label]:
            shared.extend(Unit(spec.label, i) for i in todo)
        else:
            streams.append(
                [Unit(spec.label, i, (spec.label, i) in done) for i in range(todo[-1] + 1)]
            )
    return shared, streams


class RayBackend:
    """Fly an evaluation's episodes on Ray actors (see the module docstring).

    Args:
        address: the Ray cluster to join (``"auto"``, ``"HOST:6379"``, ``"ray://HOST:10001"``,
            as :func:`ray.init` takes it); None starts a local Ray for the run and stops it
            after. Either way, if this process is already connected to Ray, that Ray is used.
        workers: actors (each takes one CPU); None: as many as the cluster has CPUs. Never
            more than there are episodes to fly.
        paths: ``sys.path`` entries for the workers (default: the current directory, where
            ``evaluate.py`` imports ``MODULE:ATTR`` policies from). On a cluster, the package
            (and your policy modules) must be installed on every node.

    Raises:
        ValueError: ``workers`` is not None or an integer >= 1.
    """

    def __init__(
        self,
        address: str | None = None,
        workers: int | None = None,
        paths: tuple[str, ...] | None = None,
    ) -> None:
        self.address = address
        self.workers = check_workers(workers)
        self.paths = (os.getcwd(),) if paths is None else tuple(paths)

    def fly(
        self,
        job: EvaluationJob,
        done: Mapping[tuple[str, int], EpisodeRecord],
        on_record: Callable[[EpisodeRecord], None],
    ) -> None:
        """Fly every unfinished episode of ``job``; ``on_record`` gets each record in this
        process as it arrives (see :class:`~agents.experiments.evaluation.runner.
        EpisodeBackend`). Interrupted (Ctrl-C) or failing, it stops its workers and, if it
        started it, the local Ray."""
        ray = require_ray("evaluate.py --backend ray")
        todo = len(job.specs) * job.episodes - len(done)
        if todo == 0:
            return
        started = not ray.is_initialized()
        if started:
            _init_ray(ray, self.address, self.workers)
        actors: list[Any] = []
        try:
            cpus = int(ray.cluster_resources().get("CPU", 1))
            count = max(1, min(self.workers or cpus, todo))
            remote = ray.remote(num_cpus=1, max_restarts=0)(EpisodeWorker)
            actors = [remote.remote(job, self.paths) for _ in range(count)]
            flags = ray.get([actor.independence.remote() for actor in actors])
            shared, streams = plan_units(job, done, flags[0])
            _dispatch(ray, actors, shared, streams, done, on_record)
        finally:
            for actor in actors:
                ray.kill(actor)
            if started:
                ray.shutdown()


def _init_ray(ray: Any, address: str | None, workers: int | None) -> None:
    """Start a local Ray (``address`` None; ``workers`` CPUs if given) or join a cluster."""
    kwargs: dict[str, Any] = {
        "include_dashboard": False,
        "logging_level": "WARNING",
        "configure_logging": True,
    }
    if address is None:
        if workers is not None:
            kwargs["num_cpus"] = workers
    else:
        kwargs["address"] = address
    ray.init(**kwargs)


def _dispatch(
    ray: Any,
    actors: list[Any],
    shared: list[Unit],
    streams: list[list[Unit]],
    done: Mapping[tuple[str, int], EpisodeRecord],
    on_record: Callable[[EpisodeRecord], None],
) -> None:
    """Keep every worker busy until all units are flown: stateful streams go to the workers
    round-robin, longest first, and are flown in order by their worker (Ray runs one caller's
    calls on an actor in submission order); the shared units go to whichever worker is free."""
    own: list[deque[Unit]] = [deque() for _ in actors]
    for k, stream in enumerate(sorted(streams, key=len, reverse=True)):
        own[k % len(actors)].extend(stream)
    queue = deque(shared)
    pending: dict[Any, tuple[int, Unit]] = {}
    load = [0] * len(actors)

    def refill(k: int) -> None:
        while load[k] < IN_FLIGHT and (own[k] or queue):
            unit = own[k].popleft() if own[k] else queue.popleft()
            pending[actors[k].fly.remote(unit.label, unit.episode)] = (k, unit)
            load[k] += 1

    for k in range(len(actors)):
        refill(k)
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        k, unit = pending.pop(ready[0])
        load[k] -= 1
        record = ray.get(ready[0])
        if unit.replay:
            check_replay(done[(unit.label, unit.episode)], record)
        else:
            on_record(record)
        refill(k)
