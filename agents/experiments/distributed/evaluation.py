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
from typing import Any

from agents.experiments.distributed import INSTALL_HINT, require_ray
from agents.experiments.evaluation.command import UsageError
from agents.experiments.evaluation.failures import AgentFailure
from agents.experiments.evaluation.runner import EvaluationJob, check_replay
from agents.experiments.evaluation.workers import (
    IN_FLIGHT,
    EpisodeWorker,
    Finished,
    RecordSink,
    Unit,
    UnitQueue,
    WorkerBackend,
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


class RayBackend(WorkerBackend):
    """Fly an evaluation's episodes on Ray actors (see the module docstring); its
    :meth:`~agents.experiments.evaluation.workers.WorkerBackend.fly` stops its workers and, if
    it started it, the local Ray, when interrupted (Ctrl-C) or failing.

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
        super().__init__(workers, module_dir)
        self.address = address

    def before_flying(self) -> None:
        """Refuse to fly without Ray, episodes left or not.

        Raises:
            ImportError: Ray is not installed (naming the extra that installs it).
        """
        require_ray("evaluate.py --backend ray")

    def pool(self, job: EvaluationJob, todo: int) -> _RayPool:
        """The actors (not started) for ``todo`` episodes of ``job``."""
        return _RayPool(require_ray("evaluate.py --backend ray"), self, job, todo)


class _RayPool:
    """The Ray actors of one :meth:`RayBackend.fly` call, and the local Ray if it starts one
    (what Ray prints when it starts lands above the progress bar: ``fly`` calls ``on_start``
    after :meth:`start`)."""

    def __init__(self, ray: Any, backend: RayBackend, job: EvaluationJob, todo: int) -> None:
        self.ray = ray
        self.backend = backend
        self.job = job
        self.todo = todo
        self.count = 0
        self.actors: list[Any] = []
        self.started = False  # whether this pool started the local Ray (and stops it)

    def start(self) -> dict[str, bool]:
        """Join Ray (or start a local one), start the actors and wait until each has built
        its agents; {agent label: episode-independent}."""
        ray, backend = self.ray, self.backend
        if not ray.is_initialized():
            _init_ray(ray, backend.address, backend.workers)
            self.started = True
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.count = max(1, min(backend.workers or cpus, self.todo))
        remote = ray.remote(num_cpus=1, max_restarts=0)(EpisodeWorker)
        self.actors = [remote.remote(self.job, backend.module_dir) for _ in range(self.count)]
        flags = ray.get([actor.independence.remote() for actor in self.actors])
        return flags[0]

    def run(self, queue: UnitQueue, done: Finished, on_record: RecordSink) -> None:
        """Keep every actor busy until all units are flown (Ray runs one caller's calls on an
        actor in submission order, so a stream is flown in order)."""
        ray, actors = self.ray, self.actors
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

    def stop(self) -> None:
        """Kill the actors; stop the local Ray if this pool started it."""
        for actor in self.actors:
            self.ray.kill(actor)
        if self.started:
            self.ray.shutdown()


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
