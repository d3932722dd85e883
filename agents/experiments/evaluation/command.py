"""What ``evaluate.py`` does once its arguments are parsed: choose and check the agents, run them,
write the outputs and compose the text it prints.

Problems with the arguments raise :class:`UsageError` naming the flag, which the script turns
into an argparse error (exit status 2) before any episode runs and before the output directory
changes. A run then

1. takes the output directory's lock (a second run on it is refused, naming the first);
2. journals its resolved options and every finished episode in ``DIR/unfinished/``
   (:mod:`agents.experiments.evaluation.journal`);
3. writes its outputs as one set (:func:`~agents.experiments.evaluation.report.write_outputs`)
   and removes the journal.

Ctrl-C at any point after 1 raises :class:`EvaluationInterrupted` (what finished, how to
resume); an agent that fails mid-run or a file that cannot be written (a full disk) raises
:class:`EvaluationStopped` (what happened, what finished, how to resume once it is fixed);
``evaluate.py --resume DIR`` (:attr:`EvaluateOptions.resume`) continues the journal.

Without ``--out`` a run writes into ``runs/eval``, or, when that holds another run's files, the
first free ``runs/eval-2``, ``runs/eval-3``, … (:func:`default_out`): a run never replaces
another run's results unasked.
"""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Protocol

from agents.experiments.evaluation.failures import AgentFailure, OutputWriteError
from agents.experiments.evaluation.journal import EvaluationJournal, JournalError
from agents.experiments.evaluation.paper import PAPER_TITLE, paper_table, paper_table_markdown
from agents.experiments.evaluation.plan import (
    BACKENDS,
    EvaluateOptions,
    EvaluationPlan,
    UsageError,
)
from agents.experiments.evaluation.pool import ProcessBackend, WorkerCrash, available_cores
from agents.experiments.evaluation.records import EpisodeRecord
from agents.experiments.evaluation.report import summary_markdown, to_json, write_outputs
from agents.experiments.evaluation.resolve import (
    DEFAULT_ENV,
    DEFAULT_EPISODES,
    DEFAULT_OUT,
    fresh_plan,
    note,
    plan_seeds,
    plan_suite,
    resume_plan,
)
from agents.experiments.evaluation.runner import EpisodeBackend, evaluate_agents, index_finished
from agents.experiments.evaluation.statistics import summarize
from agents.experiments.evaluation.video import VIDEO_DIR, video_files
from agents.experiments.evaluation.workers import check_workers
from agents.experiments.run_directory import (
    LOCK_FILE,
    MANIFEST,
    OutputDirError,
    RunDirectoryBusy,
    RunDirectoryLock,
    check_output_dir,
)
from agents.policies.shield import ShieldParams

__all__ = [
    "DEFAULT_ENV",
    "DEFAULT_EPISODES",
    "DEFAULT_OUT",
    "EvaluateOptions",
    "EvaluationInterrupted",
    "EvaluationPlan",
    "EvaluationStopped",
    "RemoteBackend",
    "UsageError",
    "default_out",
    "run_evaluation",
]


class _RunStop(Exception):
    """A run that stopped before its end, what finished journaled in ``out``."""

    def __init__(self, out: Path, finished: int, total: int) -> None:
        self.out = out
        self.finished = finished
        self.total = total
        super().__init__(self.message())

    @property
    def resume_command(self) -> str:
        """The command line that finishes the run."""
        return f"python evaluate.py --resume {shlex.quote(str(self.out))}"

    def kept(self) -> str:
        """How much finished, and where it is kept."""
        if self.finished == self.total:
            done = f"all {self.total} episodes finished but the outputs were not written"
        else:
            done = f"{self.finished} of {self.total} episodes finished"
        return f"{done}; they are kept in {self.out / 'unfinished'}/"

    def message(self) -> str:
        """What to tell the user (several lines)."""
        raise NotImplementedError


class EvaluationStopped(_RunStop):
    """The run stopped before its end: an agent failed, or a file could not be written. What
    finished is journaled in ``out``; the run resumes once the cause is fixed.

    Attributes:
        out: the output directory.
        reason: what happened (one line: the agent, episode and step; or the file).
        finished: episodes (agent × episode) finished, this run and earlier ones.
        total: episodes the evaluation has in all.
        fix: what to do before resuming.
    """

    def __init__(self, out: Path, reason: str, finished: int, total: int, fix: str) -> None:
        self.reason = reason
        self.fix = fix
        super().__init__(out, finished, total)

    def message(self) -> str:
        """What to tell the user (several lines)."""
        return (
            f"error: {self.reason}\n"
            f"stopped: {self.kept()}\n"
            f"{self.fix}, then resume with: {self.resume_command}"
        )


class EvaluationInterrupted(_RunStop):
    """Ctrl-C (or SIGTERM) stopped a run; what finished is journaled in ``out``.

    Attributes:
        out: the output directory.
        finished: episodes (agent × episode) finished, this run and earlier ones.
        total: episodes the evaluation has in all.
    """

    def message(self) -> str:
        """What to tell the user (several lines)."""
        return f"interrupted: {self.kept()}\nresume with: {self.resume_command}"


def _lock(plan: EvaluationPlan, flag: str) -> RunDirectoryLock:
    lock = RunDirectoryLock(plan.out, flag)
    try:
        lock.acquire()
    except OutputDirError as exc:
        raise UsageError(exc.flag, str(exc)) from exc
    except OSError as exc:
        raise UsageError(flag, f"cannot use {plan.out} ({exc})") from exc
    return lock


def _holds_a_run(out: Path) -> bool:
    """Whether ``out`` holds anything but a lock file (another run's results, its unfinished
    journal, the user's files)."""
    try:
        return any(entry.name != LOCK_FILE for entry in out.iterdir())
    except FileNotFoundError:
        return False
    except NotADirectoryError:
        return True


def default_out(base: Path = DEFAULT_OUT, limit: int = 10_000) -> Iterator[Path]:
    """The directories a run without ``--out`` may write into, in order: ``base`` and then
    ``base-2``, ``base-3``, … — each only if it holds no other run's files (nor anything else)."""
    for n in range(1, limit + 1):
        candidate = base if n == 1 else base.with_name(f"{base.name}-{n}")
        if not _holds_a_run(candidate):
            yield candidate


def _lock_default(plan: EvaluationPlan) -> tuple[EvaluationPlan, RunDirectoryLock]:
    """The plan moved to the first free default directory (:func:`default_out`), locked; a
    note says where the results go when it is not ``runs/eval``."""
    try:
        check_output_dir(DEFAULT_OUT)
    except OutputDirError as exc:
        raise UsageError("--out", f"the default {exc}; choose a directory with --out") from exc
    for out in default_out():
        lock = RunDirectoryLock(out, "--out")
        try:
            lock.acquire()
        except RunDirectoryBusy:
            continue  # another run without --out took it a moment ago
        except OutputDirError as exc:
            raise UsageError("--out", f"{exc}; choose a directory with --out") from exc
        if _holds_a_run(out):  # filled between the look and the lock
            lock.release()
            continue
        if out != DEFAULT_OUT:
            unfinished = EvaluationJournal(DEFAULT_OUT).exists()
            hint = f"; python evaluate.py --resume {DEFAULT_OUT} finishes it" if unfinished else ""
            note(
                f"{DEFAULT_OUT} holds an earlier evaluation, kept{hint}; this one writes to {out} "
                "(--out DIR to choose)"
            )
        return dataclasses.replace(plan, out=out), lock
    raise UsageError("--out", f"no free directory {DEFAULT_OUT}-N left; choose one with --out")


def _note_replaced(out: Path) -> None:
    """Say so when a run given ``--out DIR`` is about to replace the results already there."""
    manifest = out / MANIFEST
    try:
        earlier = json.loads(manifest.read_text())
    except (OSError, ValueError):
        return
    if isinstance(earlier, dict) and "evaluation" in earlier:
        note(f"{out} holds an earlier evaluation's results; they are replaced when this one ends")


class RemoteBackend(Protocol):
    """A backend another layer provides (Ray's: :class:`agents.experiments.distributed.
    evaluation.RayRemote`): the script that runs the evaluation passes it in, so this layer
    imports nothing above it."""

    def check(self, address: str | None) -> None:
        """Refuse (:class:`UsageError`) what cannot work, before anything runs."""

    def make(self, address: str | None, workers: int | None) -> EpisodeBackend:
        """The backend for ``--address`` and ``--workers``."""


def run_evaluation(
    options: EvaluateOptions, remote: Mapping[str, RemoteBackend] | None = None
) -> str:
    """Evaluate, write every output file into the output directory as one set, and return the
    text to print (the summary table, with ``paper`` Table I beside ours, and the files written).

    Notes about skipped agents go to stderr as they happen.

    Raises:
        UsageError: a bad argument, or the output directory is in use by another run (before
            any episode runs and before the directory changes).
        EvaluationInterrupted: Ctrl-C or SIGTERM after the run started; the finished episodes
            are journaled in the output directory for ``--resume``.
        EvaluationStopped: an agent failed mid-run, or a file could not be written; the
            finished episodes are journaled for ``--resume``.
    """
    resuming = options.resume is not None
    remote = {} if remote is None else remote
    _check_backend_options(options, remote)
    plan = resume_plan(options) if resuming else fresh_plan(options)
    backend = _backend(options, plan.video, remote)
    if resuming or options.out is not None:
        lock = _lock(plan, "--resume" if resuming else "--out")
        if not resuming:
            _note_replaced(plan.out)
    else:
        plan, lock = _lock_default(plan)
    try:
        return _run_locked(plan, resuming, options.progress, backend)
    finally:
        lock.release()


def _check_backend_options(options: EvaluateOptions, remote: Mapping[str, RemoteBackend]) -> None:
    """``--backend``, ``--address`` and ``--workers`` checked before anything runs.

    Raises:
        UsageError: an unknown backend, ``--address`` without ``--backend ray``, a bad worker
            count, or a remote backend that cannot run here (Ray not installed).
    """
    if options.backend not in BACKENDS:
        choices = ", ".join(BACKENDS)
        raise UsageError("--backend", f"must be one of {choices}, got {options.backend!r}")
    try:
        check_workers(options.workers)
    except ValueError as exc:
        raise UsageError("--workers", str(exc)) from exc
    if options.backend == "local":
        if options.address is not None:
            raise UsageError("--address", "needs --backend ray (the local backend runs here)")
        return
    if options.backend not in remote:
        raise UsageError("--backend", f"{options.backend} is not available to this command")
    remote[options.backend].check(options.address)


def _backend(
    options: EvaluateOptions, video: int, remote: Mapping[str, RemoteBackend]
) -> EpisodeBackend | None:
    """Where the episodes run: None (this process: ``--workers 1``, or ``--video``), a local
    process pool (``--workers N``, default one per core) or Ray.

    Raises:
        UsageError: ``--video`` with ``--backend ray`` or with more than one worker.
    """
    if options.backend != "local":
        if video:
            raise UsageError(
                "--video", f"records on the local backend only; drop --backend {options.backend}"
            )
        return remote[options.backend].make(options.address, options.workers)
    if video:
        if options.workers not in (None, 1):
            raise UsageError(
                "--workers", "--video records in this process: use --workers 1 or drop --workers"
            )
        return None
    workers = available_cores() if options.workers is None else options.workers
    return None if workers == 1 else ProcessBackend(workers)


def _start_journal(journal: EvaluationJournal, plan: EvaluationPlan, resuming: bool) -> list[Any]:
    """The finished episodes of a resumed run (checked), or a fresh journal for a new one."""
    if resuming:
        try:
            finished = journal.read_records()
        except JournalError as exc:
            raise UsageError("--resume", str(exc)) from exc
        try:
            index_finished(finished, plan.specs, plan.episodes, plan_seeds(plan))
        except ValueError as exc:
            raise UsageError("--resume", f"{journal.episodes_path}: {exc}") from exc
        try:
            journal.drop_partial_line()
        except OSError as exc:
            raise UsageError("--resume", f"cannot write {journal.episodes_path} ({exc})") from exc
        return finished
    if journal.exists():
        note(f"replacing the unfinished evaluation in {journal.dir} (--resume would finish it)")
    try:
        journal.start(plan.to_json())
    except OSError as exc:
        raise UsageError("--out", f"cannot write {journal.dir} ({exc.strerror or exc})") from exc
    return []


def _run_locked(
    plan: EvaluationPlan, resuming: bool, progress: bool, backend: EpisodeBackend | None
) -> str:
    """Run ``plan`` in its directory (whose lock the caller holds), on ``backend`` (None: in
    this process)."""
    journal = EvaluationJournal(plan.out)
    total = len(plan.agents) * plan.episodes
    finished = _start_journal(journal, plan, resuming)

    def journal_episode(record: EpisodeRecord) -> None:
        try:
            journal.append(record)
        except OSError as exc:
            raise OutputWriteError(journal.episodes_path, exc) from exc

    try:
        with warnings.catch_warnings():
            for text in plan.warnings.values():  # already noted when the agents were checked
                for message in text.split("\n"):
                    warnings.filterwarnings("ignore", re.escape(message), UserWarning)
            results = evaluate_agents(
                plan.env_id,
                plan.specs,
                episodes=plan.episodes,
                seed=plan.seed,
                env_kwargs=plan.env_kwargs,
                progress=progress,
                max_episode_steps=plan.max_steps,
                finished=finished,
                on_episode=journal_episode,
                suite=plan_suite(plan),
                shield=ShieldParams() if plan.shield else None,
                video=(plan.out / VIDEO_DIR, plan.video) if plan.video else None,
                backend=backend,
            )
        summary = summarize(results, reference=plan.reference)
        if plan.skipped:
            summary["skipped"] = plan.skipped
        if plan.warnings:
            summary["warnings"] = plan.warnings
        text = summary_markdown(summary)
        extra: dict[str, str] = {}
        if plan.paper:
            table = paper_table(results, plan.skipped)
            table_text = paper_table_markdown(table)
            extra = {"paper_table.md": table_text, "paper_table.json": to_json(table)}
            text += f"\n{PAPER_TITLE}:\n\n" + table_text
        videos = video_files(plan.out) if plan.video else []
        manifest: dict[str, Any] = {"evaluation": plan.to_json()}
        if videos:
            manifest["videos"] = [str(v.relative_to(plan.out)) for v in videos]
        try:
            written = write_outputs(
                results, plan.out, plots=plan.plots, summary=summary, extra=extra,
                manifest=manifest,
            )  # fmt: skip
        except OSError as exc:
            raise OutputWriteError(getattr(exc, "filename", None) or plan.out, exc) from exc
    except KeyboardInterrupt:
        raise EvaluationInterrupted(plan.out, journal.count, total) from None
    except AgentFailure as exc:
        fix = "fix the agent"
        raise EvaluationStopped(plan.out, exc.message(), journal.count, total, fix) from exc
    except OutputWriteError as exc:
        fix = f"make room or restore write access in {plan.out}"
        raise EvaluationStopped(plan.out, exc.message(), journal.count, total, fix) from exc
    except WorkerCrash as exc:
        fix = "this is a fault of the evaluation itself (please report it with the traceback)"
        raise EvaluationStopped(plan.out, str(exc), journal.count, total, fix) from exc
    journal.remove()
    written += videos
    text += f"\nwrote {len(written)} files to {plan.out}/ ({results.elapsed:.1f} s):\n"
    text += "".join(f"  {path}\n" for path in written)
    return text
