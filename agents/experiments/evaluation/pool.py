"""A local process pool for evaluations: the engine of ``evaluate.py --workers N`` (default: one
worker per core this process may run on).

:class:`ProcessBackend` is an :class:`~agents.experiments.evaluation.runner.EpisodeBackend`, like
the Ray backend: the runner hands it the episodes still to fly and gets every record back in this
process as it arrives, so the progress bar, the journal (``DIR/unfinished/``, hence ``--resume``)
and the outputs are those of the in-process loop, and the records equal its records apart from
the timing columns.

Each worker is a process started once for the run (``spawn``: a fresh interpreter, never a copy
of this one's threads) around an :class:`~agents.experiments.evaluation.workers.EpisodeWorker`:
its envs and agents are built once, so the numba kernels are loaded from their on-disk cache and
a learned model is read once per worker, not per episode. The work is shared out by
:func:`~agents.experiments.evaluation.workers.plan_units` / :class:`~agents.experiments.
evaluation.workers.UnitQueue`: episodes of independent agents to whichever worker is free, a
stateful agent's episodes in order on one worker.

Signals: the workers ignore SIGINT, so a Ctrl-C at the terminal (sent to the whole process group)
reaches only this process, which stops the workers (SIGKILL: the episodes in flight are lost,
the finished ones are journaled) and reports the interruption. SIGINT is blocked while a worker
starts, so it never lands in a worker before the worker ignores it. Workers use one torch thread
each.

From Python, a script that flies on a :class:`ProcessBackend` must keep its main code under
``if __name__ == "__main__":``, as with any ``spawn``-started multiprocessing: each worker
imports the main module again (``evaluate.py`` does so).

Under CPU contention the operating system shares the CPU between sessions (Linux's autogroups),
not between processes: a pool on a machine busy with other sessions gets no more CPU than one
process, and pays its workers' start-up on top (a few seconds: imports, the numba cache, every
agent built once per worker).
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import sys
import traceback
from collections import deque
from multiprocessing.connection import Connection, wait
from typing import Any

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
)

__all__ = ["ProcessBackend", "WorkerCrash", "available_cores"]


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells it, else the machine's
    count); at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


class WorkerCrash(RuntimeError):
    """A worker process failed in the evaluation's own code (a bug), or died; the message holds
    its traceback or exit status."""


def _serve(conn: Connection, job: EvaluationJob, module_dir: str | None) -> None:
    """A worker's life: build the agents, say which are episode-independent, then fly the
    episodes it is sent until told to stop (``None``) or its parent is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    os.environ["OMP_NUM_THREADS"] = "1"  # before torch is imported (a learned agent's build)
    worker = EpisodeWorker(job, module_dir)
    try:
        try:
            flags = worker.independence()
            if "torch" in sys.modules:
                sys.modules["torch"].set_num_threads(1)
            conn.send(("ready", flags))
            while (message := conn.recv()) is not None:
                label, episode = message
                conn.send(("record", worker.fly(label, episode)))
        except AgentFailure as exc:
            conn.send(("failed", exc))
        except (EOFError, BrokenPipeError):
            return  # the parent is gone or stopped the run
        except BaseException:
            conn.send(("crashed", traceback.format_exc()))
    except (EOFError, BrokenPipeError, OSError):
        pass
    finally:
        worker.close()
        conn.close()


class ProcessBackend(WorkerBackend):
    """Fly an evaluation's episodes in worker processes on this machine (see the module
    docstring). Its :meth:`~agents.experiments.evaluation.workers.WorkerBackend.fly` raises
    :class:`AgentFailure` when an agent fails in a worker (or its worker dies while flying
    it), :class:`WorkerCrash` when a worker fails outside any agent's code, and ``ValueError``
    when the job cannot be sent to another process (:meth:`pool`).

    Args:
        workers: worker processes; None: one per available core (:func:`available_cores`).
            Never more than there are episodes to fly.
        module_dir: where the workers look for a ``MODULE:ATTR`` policy's module first (default:
            this process's working directory).

    Raises:
        ValueError: ``workers`` is not None or an integer >= 1.
    """

    def pool(self, job: EvaluationJob, todo: int) -> _Pool:
        """The worker processes (not started) for ``todo`` episodes of ``job``.

        Raises:
            ValueError: ``job`` cannot be sent to another process (an agent handed in from
                Python that cannot be pickled, such as a lambda).
        """
        try:
            pickle.dumps(job)
        except Exception as exc:
            raise ValueError(
                f"the evaluation cannot be sent to worker processes ({type(exc).__name__}: "
                f"{exc}); an agent handed in from Python must be picklable (a class or function "
                "defined at a module's top level), or fly in this process (one worker)"
            ) from exc
        return _Pool(job, min(self.workers or available_cores(), todo), self.module_dir)


class _Pool:
    """The worker processes of one :meth:`ProcessBackend.fly` call."""

    def __init__(self, job: EvaluationJob, count: int, module_dir: str) -> None:
        self.job = job
        self.count = count
        self.module_dir = module_dir
        self.procs: list[Any] = []
        self.conns: list[Connection] = []
        self.in_flight: list[deque[Unit]] = [deque() for _ in range(count)]

    def start(self) -> dict[str, bool]:
        """Start the workers; wait until each has built its agents. Returns {agent label:
        episode-independent}."""
        ctx = multiprocessing.get_context("spawn")
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            for _ in range(self.count):
                parent, child = ctx.Pipe()
                proc = ctx.Process(
                    target=_serve, args=(child, self.job, self.module_dir), daemon=True
                )
                proc.start()
                child.close()
                self.procs.append(proc)
                self.conns.append(parent)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        flags: dict[str, bool] = {}
        waiting = set(range(self.count))
        while waiting:
            for k, message in self._receive(waiting):
                if message[0] != "ready":
                    self._raise(k, message)
                flags = message[1]
                waiting.discard(k)
        return flags

    def run(self, queue: UnitQueue, done: Finished, on_record: RecordSink) -> None:
        """Send every unit of ``queue`` and hand each record on as it comes back."""
        for k in range(self.count):
            self._refill(k, queue)
        while any(self.in_flight):
            busy = {k for k in range(self.count) if self.in_flight[k]}
            for k, message in self._receive(busy):
                if message[0] != "record":
                    self._raise(k, message)
                unit = self.in_flight[k].popleft()
                record = message[1]
                if (record.agent, record.episode) != (unit.label, unit.episode):
                    raise WorkerCrash(
                        f"worker {k} answered agent {record.agent!r} episode {record.episode} "
                        f"for agent {unit.label!r} episode {unit.episode}"
                    )
                if unit.replay:
                    check_replay(done[(unit.label, unit.episode)], record)
                else:
                    on_record(record)
                self._refill(k, queue)

    def stop(self) -> None:
        """Stop every worker (at once: what is in flight is dropped) and reap it."""
        for conn in self.conns:
            conn.close()
        for proc in self.procs:
            if proc.is_alive():
                proc.kill()
        for proc in self.procs:
            proc.join()
            proc.close()
        self.procs, self.conns = [], []

    def _refill(self, k: int, queue: UnitQueue) -> None:
        while len(self.in_flight[k]) < IN_FLIGHT:
            unit = queue.next_for(k)
            if unit is None:
                return
            try:
                self.conns[k].send((unit.label, unit.episode))
            except OSError:  # the worker stopped (its failure or death is waiting in its pipe)
                return
            self.in_flight[k].append(unit)

    def _receive(self, workers: set[int]) -> list[tuple[int, tuple[Any, ...]]]:
        """Wait for messages from ``workers``; the ones that arrived, as (worker, message). A
        worker that died is reported as a ``("died", exit code)`` message once its pipe is
        empty."""
        by_conn = {self.conns[k]: k for k in workers}
        by_sentinel = {self.procs[k].sentinel: k for k in workers}
        arrived = []
        for ready in wait([*by_conn, *by_sentinel]):
            if ready in by_conn:
                k = by_conn[ready]
                try:
                    arrived.append((k, ready.recv()))
                except (EOFError, OSError):
                    self.procs[k].join()
                    arrived.append((k, ("died", self.procs[k].exitcode)))
            elif not self.conns[by_sentinel[ready]].poll():
                k = by_sentinel[ready]
                self.procs[k].join()
                arrived.append((k, ("died", self.procs[k].exitcode)))
        seen: set[int] = set()
        unique = []
        for k, message in arrived:  # a dead worker may show up by its pipe and its sentinel
            if message[0] == "died" and k in seen:
                continue
            seen.add(k)
            unique.append((k, message))
        return unique

    def _raise(self, k: int, message: tuple[Any, ...]) -> None:
        kind = message[0]
        if kind == "failed":
            raise message[1]
        if kind == "crashed":
            raise WorkerCrash(f"worker process {k} failed:\n{message[1]}")
        if kind == "died":
            code = message[1]
            how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit {code}"
            unit = self.in_flight[k][0] if self.in_flight[k] else None
            if unit is None:
                raise WorkerCrash(f"worker process {k} died ({how}) while it built the agents")
            raise AgentFailure(
                unit.label,
                unit.episode,
                self.job.resets[unit.episode][0],
                None,
                f"the worker process flying it died ({how}: out of memory, or a crash in "
                "native code?)",
            )
        raise WorkerCrash(f"worker process {k} sent {kind!r}")
