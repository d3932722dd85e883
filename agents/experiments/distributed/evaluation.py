"""Evaluation episodes fanned out to Ray actors: the engine of ``evaluate.py --backend ray``.

:class:`RayBackend` is an :class:`~agents.experiments.evaluation.runner.EpisodeBackend`: the
runner (:func:`~agents.experiments.evaluation.runner.evaluate_agents`) hands it the episodes
still to fly and gets every record back in this process as it arrives, so the progress bar, the
journal (``DIR/unfinished/``, hence ``--resume``) and the outputs are the local run's.

Each worker is a long-lived Ray actor around an
:class:`~agents.experiments.evaluation.workers.EpisodeWorker` (one env and one agent per agent
label, built once), and the work is shared out as the local process pool shares it
(:func:`~agents.experiments.evaluation.workers.plan_units`, :class:`~agents.experiments.
evaluation.workers.UnitQueue`): independent agents' episodes to whichever worker is free, a
stateful agent's episodes in order on one worker, so the records are the local run's (apart from
decision times).
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable, Mapping
from typing import Any

from agents.experiments.distributed import INSTALL_HINT, require_ray
from agents.experiments.evaluation.command import UsageError
from agents.experiments.evaluation.failures import AgentFailure
from agents.experiments.evaluation.records import EpisodeRecord
from agents.experiments.evaluation.runner import EvaluationJob, check_replay
from agents.experiments.evaluation.workers import (
    IN_FLIGHT,
    EpisodeWorker,
    Unit,
    UnitQueue,
    check_workers,
    plan_units,
)

__all__ = [
    "IN_FLIGHT",
    "EpisodeWorker",
    "RayBackend",
    "RayRemote",
    "Unit",
    "check_workers",
    "plan_units",
]


class RayRemote:
    """``evaluate.py --backend ray``: the option checks and the :class:`RayBackend`, handed to
    :func:`~agents.experiments.evaluation.command.run_evaluation` by the script."""

    def check(self, address: str | None) -> None:
        """Refuse a missing Ray and an empty ``--address`` before anything runs.

        Raises:
            UsageError: naming ``--backend`` or ``--address``.
        """
        if importlib.util.find_spec("ray") is None:
            raise UsageError("--backend", f"ray needs Ray, which is not installed: {INSTALL_HINT}")
        if address is not None and not address.strip():
            raise UsageError("--address", "must name a Ray cluster (e.g. auto, HOST:6379), got ''")

    def make(self, address: str | None, workers: int | None) -> RayBackend:
        """The backend of ``--address`` and ``--workers``."""
        return RayBackend(address, workers)


class RayBackend:
    """Fly an evaluation's episodes on Ray actors (see the module docstring).

    Args:
        address: the Ray cluster to join (``"auto"``, ``"HOST:6379"``, ``"ray://HOST:10001"``,
            as :func:`ray.init` takes it); None starts a local Ray for the run and stops it
            after. Either way, if this process is already connected to Ray, that Ray is used.
        workers: actors (each takes one CPU); None: as many as the cluster has CPUs. Never
            more than there are episodes to fly.
        module_dir: where the workers look for a ``MODULE:ATTR`` policy's module first
            (default: this process's working directory, where ``evaluate.py`` finds them; a
            worker on a machine without that directory looks on its ``sys.path`` only). On a
            cluster, the package (and your policy modules) must be installed on every node.

    Raises:
        ValueError: ``workers`` is not None or an integer >= 1.
    """

    def __init__(
        self,
        address: str | None = None,
        workers: int | None = None,
        module_dir: str | None = None,
    ) -> None:
        self.address = address
        self.workers = check_workers(workers)
        self.module_dir = os.getcwd() if module_dir is None else module_dir

    def fly(
        self,
        job: EvaluationJob,
        done: Mapping[tuple[str, int], EpisodeRecord],
        on_record: Callable[[EpisodeRecord], None],
        on_start: Callable[[], None] | None = None,
    ) -> None:
        """Fly every unfinished episode of ``job``; ``on_record`` gets each record in this
        process as it arrives, ``on_start`` is called once Ray and the actors are up (see
        :class:`~agents.experiments.evaluation.runner.EpisodeBackend`: what Ray prints when it
        starts lands above the progress bar). Interrupted (Ctrl-C) or failing, it stops its
        workers and, if it started it, the local Ray."""
        ray = require_ray("evaluate.py --backend ray")
        todo = len(job.specs) * job.episodes - len(done)
        if todo == 0:
            if on_start is not None:
                on_start()
            return
        started = not ray.is_initialized()
        if started:
            _init_ray(ray, self.address, self.workers)
        actors: list[Any] = []
        try:
            cpus = int(ray.cluster_resources().get("CPU", 1))
            count = max(1, min(self.workers or cpus, todo))
            remote = ray.remote(num_cpus=1, max_restarts=0)(EpisodeWorker)
            actors = [remote.remote(job, self.module_dir) for _ in range(count)]
            flags = ray.get([actor.independence.remote() for actor in actors])
            if on_start is not None:
                on_start()
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
    """Keep every worker busy until all units are flown (:class:`UnitQueue`; Ray runs one
    caller's calls on an actor in submission order, so a stream is flown in order)."""
    queue = UnitQueue(len(actors), shared, streams)
    pending: dict[Any, tuple[int, Unit]] = {}
    load = [0] * len(actors)

    def refill(k: int) -> None:
        while load[k] < IN_FLIGHT:
            unit = queue.next_for(k)
            if unit is None:
                return
            pending[actors[k].fly.remote(unit.label, unit.episode)] = (k, unit)
            load[k] += 1

    for k in range(len(actors)):
        refill(k)
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        k, unit = pending.pop(ready[0])
        load[k] -= 1
        try:
            record = ray.get(ready[0])
        except Exception as exc:  # Ray wraps what the actor raised; an agent's failure is
            cause = getattr(exc, "cause", None)  # reported as in the local run
            if isinstance(cause, AgentFailure):
                raise cause from None
            raise
        if unit.replay:
            check_replay(done[(unit.label, unit.episode)], record)
        else:
            on_record(record)
        refill(k)
