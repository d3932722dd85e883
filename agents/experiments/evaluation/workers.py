"""Episodes apart from where they run: the worker that flies them and the plan that shares them
out, used by every backend that flies an evaluation in other processes (the local process pool,
:mod:`agents.experiments.evaluation.pool`, and the Ray actors of
:mod:`agents.experiments.distributed.evaluation`).

A worker (:class:`EpisodeWorker`) lives for the whole run and holds one env and one agent per
agent label, built on first use: the numba compile (or its on-disk cache load) and a learned
model's load are paid once per worker, never per episode. An episode is flown by the runner's own
:func:`~agents.experiments.evaluation.episode.run_episode`, so a record equals the one the
in-process loop writes apart from the timing columns
(:data:`~agents.experiments.evaluation.records.TIMING_COLUMNS`).

Episodes of an agent whose ``episode_independent`` attribute is true (every classical baseline
but ``random``, learned policies) are flown one by one by whichever worker is free. Any other
agent (``random``, whose generator runs on across episodes, and your own policies unless they
declare the attribute) may carry state from one episode to the next: its episodes are flown in
order by one worker, which first re-flies, unrecorded, the finished episodes before its last
unfinished one — what the in-process loop does on ``--resume`` — so its records are the
in-process loop's too (:func:`plan_units`, :class:`UnitQueue`).

Both backends are a :class:`WorkerBackend`: the run's frame (nothing to fly, start the workers,
share the work out, stop them whatever happens) is written once there, and each backend supplies
its :class:`WorkerPool`.
"""

from __future__ import annotations

import os
import warnings
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from agents.experiments.evaluation.episode import run_episode
from agents.experiments.evaluation.records import EpisodeRecord
from agents.experiments.evaluation.runner import EvaluationJob, build_agent_env

__all__ = [
    "IN_FLIGHT",
    "EpisodeWorker",
    "Finished",
    "RecordSink",
    "Unit",
    "UnitQueue",
    "WorkerBackend",
    "WorkerPool",
    "check_workers",
    "plan_units",
]

IN_FLIGHT = 2
"""Episodes queued on each worker at a time: the next one is already there when one ends."""

Finished = Mapping[tuple[str, int], EpisodeRecord]
"""The records of an evaluation's finished episodes, by (agent label, episode)."""

RecordSink = Callable[[EpisodeRecord], None]
"""What a backend hands each new record to, in the driver's process, as it arrives."""


def check_workers(workers: int | None) -> int | None:
    """``workers`` checked: None (the backend's default) or an integer >= 1.

    Raises:
        ValueError: anything else (the message names ``workers``).
    """
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    return workers


class EpisodeWorker:
    """One worker's state: an env and an agent per agent label of ``job``, built on first use
    and kept, flying the episodes it is sent.

    Args:
        job: the evaluation.
        module_dir: the directory a ``MODULE:ATTR`` agent's module is looked for in first (the
            driver's working directory; see :func:`~agents.experiments.evaluation.specs.
            resolve_python_agent`); None: this process's working directory.
    """

    def __init__(self, job: EvaluationJob, module_dir: str | None = None) -> None:
        self.job = job
        self.module_dir = module_dir
        self.built: dict[str, tuple[Any, Any]] = {}
        self.specs = {spec.label: spec for spec in job.specs}

    def independence(self) -> dict[str, bool]:
        """{agent label: whether its episodes are independent} — every agent is built here."""
        return {
            label: bool(getattr(self._agent(label)[1], "episode_independent", False))
            for label in self.specs
        }

    def fly(self, label: str, episode: int) -> EpisodeRecord:
        """Fly episode ``episode`` of agent ``label``; its record.

        Raises:
            AgentFailure: the agent failed (see :func:`~agents.experiments.evaluation.runner.
                run_episode`).
        """
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
                self.built[label] = build_agent_env(
                    self.job, self.specs[label], module_dir=self.module_dir
                )
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


class UnitQueue:
    """Which unit each of ``workers`` workers flies next.

    The stateful streams go to the workers round-robin, longest first, and each is flown in
    order by its worker (a backend sends a worker's units in the order it gets them, and a
    worker flies them in that order); the shared units go to whichever worker asks first, after
    its own stream.
    """

    def __init__(self, workers: int, shared: Sequence[Unit], streams: Sequence[list[Unit]]) -> None:
        self.own: list[deque[Unit]] = [deque() for _ in range(workers)]
        for k, stream in enumerate(sorted(streams, key=len, reverse=True)):
            self.own[k % workers].extend(stream)
        self.shared = deque(shared)

    def next_for(self, worker: int) -> Unit | None:
        """The next unit for ``worker``, or None when nothing is left for it."""
        if self.own[worker]:
            return self.own[worker].popleft()
        if self.shared:
            return self.shared.popleft()
        return None

    def __len__(self) -> int:
        return len(self.shared) + sum(len(own) for own in self.own)


class WorkerPool(Protocol):
    """The workers of one :meth:`WorkerBackend.fly` call: started, sent the units, stopped."""

    count: int
    """How many workers there are (known once :meth:`start` has returned)."""

    def start(self) -> dict[str, bool]:
        """Start the workers and wait until each has built its agents; {agent label: whether
        its episodes are independent} (:meth:`EpisodeWorker.independence`)."""
        ...

    def run(self, queue: UnitQueue, done: Finished, on_record: RecordSink) -> None:
        """Fly every unit of ``queue`` (worker k's from :meth:`UnitQueue.next_for`), handing
        each new record to ``on_record`` as it arrives and checking each replayed one against
        its record in ``done``.

        Raises:
            AgentFailure: an agent failed in a worker.
        """
        ...

    def stop(self) -> None:
        """Stop every worker at once (what is in flight is dropped); also after a failed or
        interrupted :meth:`start`."""
        ...


class WorkerBackend:
    """An :class:`~agents.experiments.evaluation.runner.EpisodeBackend` whose episodes are flown
    by long-lived workers, each around an :class:`EpisodeWorker`, with the work shared out by
    :func:`plan_units` and :class:`UnitQueue`; a subclass supplies the workers
    (:meth:`pool`).

    Args:
        workers: how many workers; None: the subclass's default. Never more than there are
            episodes to fly.
        module_dir: where the workers look for a ``MODULE:ATTR`` policy's module first (default:
            this process's working directory, where ``evaluate.py`` finds them).

    Raises:
        ValueError: ``workers`` is not None or an integer >= 1.
    """

    def __init__(self, workers: int | None = None, module_dir: str | None = None) -> None:
        self.workers = check_workers(workers)
        self.module_dir = os.getcwd() if module_dir is None else module_dir

    def fly(
        self,
        job: EvaluationJob,
        done: Finished,
        on_record: RecordSink,
        on_start: Callable[[], None] | None = None,
    ) -> None:
        """Fly every unfinished episode of ``job``; ``on_record`` gets each record in this
        process as it arrives, ``on_start`` is called once the workers are up (at once when
        nothing is left to fly). Interrupted (Ctrl-C) or failing, it stops its workers before
        it returns.

        Raises:
            AgentFailure: an agent failed in a worker.
        """
        self.before_flying()
        todo = len(job.specs) * job.episodes - len(done)
        if todo == 0:
            if on_start is not None:
                on_start()
            return
        pool = self.pool(job, todo)
        try:
            independent = pool.start()
            if on_start is not None:
                on_start()
            shared, streams = plan_units(job, done, independent)
            pool.run(UnitQueue(pool.count, shared, streams), done, on_record)
        finally:
            pool.stop()

    def before_flying(self) -> None:
        """What a backend checks first in every :meth:`fly`, episodes left or not (nothing by
        default)."""

    def pool(self, job: EvaluationJob, todo: int) -> WorkerPool:
        """The workers, not started yet, that fly the ``todo`` (>= 1) unfinished episodes of
        ``job`` (every subclass supplies its own)."""
        raise NotImplementedError
