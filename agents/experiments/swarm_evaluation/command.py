"""What ``evaluate.py --env SWARM_ID`` does: fly every team on the same seeded fields and write
the tables.

Every team (:mod:`~agents.experiments.swarm_evaluation.teams`) gets its own swarm env (a learned
member needs its own observation options), made with ``assignment="given"``; episode i of every
team is reset with seed ``SEED + i`` (the same field for all: checked by its fingerprint). The
run takes the output directory's lock and flies the teams' episodes in this process, or on
``--workers N`` processes (:mod:`~agents.experiments.swarm_evaluation.flight`; the same records
apart from the timing columns). Every finished episode goes to the journal in
``DIR/unfinished/`` (:mod:`~agents.experiments.swarm_evaluation.journal`), so that Ctrl-C or a
failing team loses at most the episodes in flight and ``evaluate.py --resume DIR`` finishes the
run. At the end it writes ``episodes.csv``, ``assignments.csv``, ``summary.json``,
``summary.md`` and the trajectory plots (``--plots N``,
:mod:`~agents.experiments.swarm_evaluation.recording`) as one set
(:class:`~agents.experiments.run_directory.OutputSet`, each file written atomically) and removes
the journal; ``--video N`` writes videos beside it. With ``--shield`` every team flies behind
the safety shield, one per chaser, that counts the teammates as bodies
(:class:`~agents.policies.shielded.TeamShield`; decision times include it), and the tables count
the commands it replaced. Options of the single-agent evaluation that do not apply (the paper
table, Ray) are refused with :class:`UsageError` before anything runs.
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.experiments.evaluation.command import default_out
from agents.experiments.evaluation.plan import UsageError
from agents.experiments.evaluation.report import to_json
from agents.experiments.evaluation.statistics import CI_METHODS
from agents.experiments.run_directory import (
    OutputDirError,
    OutputSet,
    RunDirectoryBusy,
    RunDirectoryLock,
)
from agents.experiments.swarm_evaluation.flight import (
    BuiltTeam,
    Flight,
    Mission,
    TeamFailed,
    build_teams,
    fly_tasks,
)
from agents.experiments.swarm_evaluation.journal import (
    FinishedEpisode,
    JournalError,
    SwarmJournal,
)
from agents.experiments.swarm_evaluation.recording import (
    DEFAULT_SWARM_PLOTS,
    PLOT_PATTERN,
    check_video_support,
)
from agents.experiments.swarm_evaluation.report import (
    assignment_gaps,
    assignments_csv,
    episodes_csv,
    summarize_teams,
    summary_markdown,
)
from agents.experiments.swarm_evaluation.teams import DEFAULT_TEAMS, parse_teams
from agents.planners.team_assignment import TeamAssignment
from agents.policies.shield import ShieldParams
from debris_gym.files import write_atomic
from debris_gym.suites import list_suites, load_suite
from debris_gym.swarm import SWARM_SPECS

__all__ = [
    "DEFAULT_SWARM_EPISODES",
    "DEFAULT_SWARM_OUT",
    "NOT_FOR_SWARMS",
    "SwarmEvaluateOptions",
    "SwarmRunStopped",
    "is_swarm_id",
    "is_swarm_suite",
    "run_swarm_evaluation",
]

DEFAULT_SWARM_OUT = Path("runs/eval-swarm")
DEFAULT_SWARM_EPISODES = 20
OUTPUTS = ("episodes.csv", "assignments.csv", "summary.json", "summary.md")

NOT_FOR_SWARMS: dict[str, tuple[str, Any]] = {
    "paper": ("--paper", False),
    "address": ("--address", None),
    "backend": ("--backend", "local"),
}
"""``evaluate.py`` options (destination → flag, default) that swarm IDs refuse unless left at
their default."""


def is_swarm_id(env_id: str | None) -> bool:
    """Whether ``env_id`` is a swarm ID (:data:`debris_gym.swarm.SWARM_SPECS`)."""
    return env_id is not None and env_id.rpartition(":")[2] in SWARM_SPECS


def is_swarm_suite(name: str | None) -> bool:
    """Whether ``name`` is a shipped suite of a swarm ID."""
    return name in list_suites() and is_swarm_id(load_suite(name).env_id)


def _suite_plan(options: SwarmEvaluateOptions) -> tuple[str, dict[str, Any], list[Mission]]:
    """The env, options and missions of ``options.suite`` (its first ``episodes``).

    Raises:
        UsageError: an unknown suite, or an option that would change its missions.
    """
    try:
        suite = load_suite(str(options.suite))
    except ValueError as exc:
        raise UsageError("--suite", str(exc)) from exc
    if not is_swarm_id(suite.env_id):
        raise UsageError("--suite", f"{suite.name} is a single-agent suite ({suite.env_id})")
    if options.env not in (None, suite.env_id):
        raise UsageError("--env", f"{suite.name} flies {suite.env_id}, not {options.env}")
    for flag, value in (("--env-kwargs", options.env_kwargs), ("--seed", options.seed)):
        if value is not None:
            raise UsageError(flag, f"a frozen suite fixes it ({suite.name})")
    count = len(suite.missions) if options.episodes is None else options.episodes
    if count > len(suite.missions):
        raise UsageError(
            "--episodes", f"{suite.name} has {len(suite.missions)} missions, not {count}"
        )
    missions = [Mission(m.seed, m.scenario) for m in suite.missions[:count]]
    return suite.env_id, dict(suite.env_kwargs), missions


@dataclass(frozen=True)
class SwarmEvaluateOptions:
    """The options of a swarm evaluation (None: the default).

    Attributes:
        env: the swarm ID.
        agents: comma-separated team names (``team-AGENT@RULE``); None: :data:`DEFAULT_TEAMS`.
        episodes: episodes per team (default :data:`DEFAULT_SWARM_EPISODES`); ``seed`` the
            first reset seed (default 0).
        out: the output directory (default: :data:`DEFAULT_SWARM_OUT`, or ``-2``, ``-3``, …
            when it holds another run).
        env_kwargs: swarm options over the ID's own.
        max_steps: the time limit (steps) over the ID's own.
        reference: the team others are paired with (default: the first).
        progress: draw a progress bar on stderr.
        plots: trajectory plots of each team's first episodes (default
            :data:`~agents.experiments.swarm_evaluation.recording.DEFAULT_SWARM_PLOTS`).
        video: videos of each team's first episodes (0: none).
        suite: a frozen suite of a swarm ID (:mod:`debris_gym.suites`): its env, options,
            seeds and pinned fields (its first ``episodes`` missions); None: seeded fields.
        shield: fly every team behind the safety shield (default parameters,
            :class:`~agents.policies.shield.ShieldParams`), one per chaser.
        resume: a directory holding an unfinished swarm evaluation, to finish: its options
            are read from its journal (every option above but ``progress`` must be left
            unset).
        workers: processes flying the episodes (default 1: this one); the records are the
            same whatever the count, apart from the timing columns.
    """

    env: str | None
    agents: str | None = None
    episodes: int | None = None
    seed: int | None = None
    out: Path | None = None
    env_kwargs: dict[str, Any] | None = None
    max_steps: int | None = None
    reference: str | None = None
    progress: bool = True
    plots: int | None = None
    video: int = 0
    suite: str | None = None
    shield: bool = False
    resume: Path | None = None
    workers: int | None = None

    @classmethod
    def from_arguments(cls, arguments: dict[str, Any]) -> SwarmEvaluateOptions:
        """The options of ``evaluate.py``'s parsed arguments (its destinations by name).

        Raises:
            UsageError: an option that does not apply to swarm IDs was given, or an option
                beside ``--resume`` that the journal fixes.
        """
        env = arguments.get("env")
        for key, (flag, default) in NOT_FOR_SWARMS.items():
            if arguments.get(key, default) != default:
                raise UsageError(flag, f"does not apply to swarm IDs ({env})")
        names = ("agents", "episodes", "seed", "out", "env_kwargs", "max_steps", "reference",
                 "plots", "suite")  # fmt: skip
        kwargs = {k: arguments.get(k) for k in names}
        video = int(arguments.get("video") or 0)
        shield = bool(arguments.get("shield", False))
        resume = arguments.get("resume")
        if resume is not None:
            given = [f"--{k.replace('_', '-')}" for k, v in kwargs.items() if v is not None]
            given += ["--env"] * (env is not None) + ["--video"] * bool(video)
            given += ["--shield"] * shield
            if given:
                raise UsageError(
                    "--resume",
                    f"takes no {', '.join(given)}: the run's options are read from "
                    f"{resume}/unfinished/ (only --no-progress and --workers may be given)",
                )
        check_video_support(video)
        return cls(
            env=env, progress=bool(arguments.get("progress", True)), video=video,
            shield=shield, resume=None if resume is None else Path(resume),
            workers=arguments.get("workers"), **kwargs,
        )  # fmt: skip

    def to_journal(self) -> dict[str, Any]:
        """What a run's journal keeps of its options (all but where and how it runs)."""
        keep = ("env", "agents", "episodes", "seed", "env_kwargs", "max_steps", "reference",
                "plots", "video", "suite", "shield")  # fmt: skip
        return {k: getattr(self, k) for k in keep}

    @property
    def shield_params(self) -> ShieldParams | None:
        """The shield every team flies behind (None: unshielded)."""
        return ShieldParams() if self.shield else None


def _lock(out: Path | None, flag: str = "--out") -> tuple[Path, RunDirectoryLock]:
    if out is not None:
        lock = RunDirectoryLock(out, flag)
        try:
            lock.acquire()
        except OutputDirError as exc:
            raise UsageError(exc.flag, str(exc)) from exc
        return out, lock
    for candidate in default_out(DEFAULT_SWARM_OUT):
        lock = RunDirectoryLock(candidate, "--out")
        try:
            lock.acquire()
        except RunDirectoryBusy:
            continue
        except OutputDirError as exc:
            raise UsageError("--out", f"{exc}; choose a directory with --out") from exc
        return candidate, lock
    raise UsageError("--out", f"no free directory {DEFAULT_SWARM_OUT}-N left; use --out")


class SwarmRunStopped(Exception):
    """A swarm evaluation stopped before its end (Ctrl-C, or a team that failed): the episodes
    finished are kept in its journal, and ``evaluate.py --resume DIR`` finishes the run.

    Attributes:
        out: the output directory; ``finished`` and ``total`` the episodes journaled and
            planned; ``error`` what failed (None: interrupted).
    """

    def __init__(self, out: Path, finished: int, total: int, error: str | None = None) -> None:
        super().__init__(error or "interrupted")
        self.out, self.finished, self.total, self.error = out, finished, total, error

    @property
    def interrupted(self) -> bool:
        """Stopped by Ctrl-C (or SIGTERM), not by a failure."""
        return self.error is None

    def message(self) -> str:
        """What happened, what is kept and how to go on."""
        kept = f"{self.finished} of {self.total} episodes are kept in {self.out / 'unfinished'}/"
        resume = f"python evaluate.py --resume {shlex.quote(str(self.out))}"
        if self.error is None:
            return f"interrupted: {kept}\nresume with: {resume}"
        return f"error: {self.error}\nstopped: {kept}\nonce it is fixed, resume with: {resume}"


def _resumed(options: SwarmEvaluateOptions) -> SwarmEvaluateOptions:
    """``options`` with the run's own options read from the journal in ``options.resume``."""
    out = options.resume
    assert out is not None
    try:
        stored = SwarmJournal(out).read_options()
    except JournalError as exc:
        raise UsageError("--resume", str(exc)) from exc
    suite_hash = stored.pop("suite_hash", None)
    try:
        resumed = dataclasses.replace(options, **stored, out=out)
    except TypeError as exc:
        raise UsageError("--resume", f"{out}/unfinished/options.json: {exc}") from exc
    if resumed.suite is not None and load_suite(resumed.suite).content_hash != suite_hash:
        raise UsageError(
            "--resume",
            f"suite {resumed.suite} has changed since the run began (its content hash is not "
            f"{suite_hash}): its missions would differ; start the run again",
        )
    return resumed


def _plan(options: SwarmEvaluateOptions) -> tuple[SwarmEvaluateOptions, str, list[Mission]]:
    """The options with the suite's env filled in, the swarm ID and the missions."""
    if options.suite is not None:
        env_id, suite_kwargs, missions = _suite_plan(options)
        options = dataclasses.replace(options, env=env_id, env_kwargs=suite_kwargs)
        return options, env_id, missions
    env_id = (options.env or "").rpartition(":")[2]
    if env_id not in SWARM_SPECS:
        raise UsageError("--env", f"unknown swarm ID {env_id!r}; known: {', '.join(SWARM_SPECS)}")
    first = 0 if options.seed is None else options.seed
    count = DEFAULT_SWARM_EPISODES if options.episodes is None else options.episodes
    return options, env_id, [Mission(first + i, None) for i in range(count)]


def _journal(
    options: SwarmEvaluateOptions, out: Path, stored: dict[str, Any]
) -> tuple[SwarmJournal, list[FinishedEpisode]]:
    """The journal of a resumed run and its finished episodes, or a fresh journal."""
    journal = SwarmJournal(out)
    if options.resume is not None:
        try:
            finished = journal.read_episodes()
            journal.drop_partial_line()
        except (JournalError, OSError) as exc:
            raise UsageError("--resume", str(exc)) from exc
        return journal, finished
    if journal.exists():
        print(
            f"note: replacing the unfinished evaluation in {journal.dir} (--resume would "
            "finish it)",
            file=sys.stderr,
        )
    journal.start(stored)
    return journal, []


def run_swarm_evaluation(options: SwarmEvaluateOptions) -> str:
    """Fly every team, write the outputs as one set, and return the text to print (the tables
    and the files written).

    Raises:
        UsageError: a bad option (before anything runs).
        SwarmRunStopped: Ctrl-C, or a team failed mid-run: the finished episodes are kept in
            the journal, nothing else is written.
    """
    if options.resume is not None:
        options = _resumed(options)
    stored = options.to_journal()
    options, env_id, missions = _plan(options)
    suite_hash = None if options.suite is None else load_suite(options.suite).content_hash
    stored["suite_hash"] = suite_hash
    try:
        specs = parse_teams(options.agents)
    except ValueError as exc:
        raise UsageError("--agents", str(exc)) from exc
    labels = [s.label for s in specs]
    if options.reference is not None and options.reference not in labels:
        raise UsageError("--reference", f"{options.reference!r} is not one of {labels}")
    episodes, seed = len(missions), missions[0].seed
    plots = DEFAULT_SWARM_PLOTS if options.plots is None else options.plots
    flight = Flight(
        env_id=env_id, env_kwargs=dict(options.env_kwargs or {}), specs=tuple(specs),
        missions=tuple(missions), max_steps=options.max_steps, plots=plots,
        video=options.video, shield=options.shield_params,
    )  # fmt: skip
    named = options.agents is not None
    teams, skipped = build_teams(flight, named, lambda line: print(line, file=sys.stderr))
    workers = options.workers or 1
    out, lock = _lock(options.out if options.resume is None else options.resume,
                      "--out" if options.resume is None else "--resume")  # fmt: skip
    flight = dataclasses.replace(flight, specs=tuple(t.spec for t in teams), out=out)
    if not named:  # the journal names the teams flown, so a resumed run builds these
        stored["agents"] = ",".join(t.spec.label for t in teams)
    try:
        journal, finished = _journal(options, out, stored)
        start = time.perf_counter()
        done = {(f.record.agent, f.record.episode) for f in finished}
        tasks = [(t, i) for t, team in enumerate(teams) for i in range(episodes)
                 if (team.spec.label, i) not in done]  # fmt: skip
        total = len(teams) * episodes
        try:
            _fly(flight, teams, tasks, journal, finished, options.progress, workers)
        except KeyboardInterrupt:
            raise SwarmRunStopped(out, len(finished), total) from None
        except TeamFailed as exc:
            raise SwarmRunStopped(out, len(finished), total, str(exc)) from exc
        elapsed = time.perf_counter() - start
        order = {t.spec.label: k for k, t in enumerate(teams)}
        finished.sort(key=lambda f: (order[f.record.agent], f.record.episode))
        records = [f.record for f in finished]
        fields: dict[int, tuple[int, dict[str, TeamAssignment]]] = {}
        for f in finished:
            fields.setdefault(f.record.episode, (f.record.seed, f.rules))
        flown = [t.spec.label for t in teams]
        summary = summarize_teams(records, flown, options.reference)
        kwargs = dict(options.env_kwargs or {})
        steps = "" if options.max_steps is None else f", max_steps {options.max_steps}"
        shield = options.shield_params
        where = (
            f"suite {options.suite} ({suite_hash}), its first {episodes} missions"
            if options.suite is not None
            else f"seeds {seed}…{seed + episodes - 1}"
        )
        processes = "one process" if workers == 1 else f"{workers} worker processes"
        summary.update(
            title=(
                f"{env_id}{' ' + to_json(kwargs).strip() if kwargs else ''}: {episodes} episodes "
                f"per team, {where}{steps}, {processes}"
            ),
            suite=options.suite,
            suite_hash=suite_hash,
            env_id=env_id,
            env_kwargs=kwargs,
            episodes=episodes,
            seed=seed,
            max_steps=options.max_steps,
            assignment_gaps=assignment_gaps(fields),
            skipped=skipped,
            ci_methods=CI_METHODS,
            elapsed_s=elapsed,
            resumed_episodes=total - len(tasks),
            workers=workers,
            shield=None if shield is None else shield.to_dict(),
        )
        text = summary_markdown(summary)
        contents = {
            "episodes.csv": episodes_csv(records),
            "assignments.csv": assignments_csv(fields),
            "summary.json": to_json(summary),
            "summary.md": text,
        }
        with OutputSet(out, owned=(*OUTPUTS, PLOT_PATTERN)) as files:
            for name, content in contents.items():
                write_atomic(files.path(name), content)
            for f in finished:
                if f.plot is not None:
                    write_atomic(files.path(f.plot), journal.plot(f.plot))
            written = files.commit(
                evaluation={"env_id": env_id, "env_kwargs": kwargs, "agents": flown,
                            "episodes": episodes, "seed": seed, "max_steps": options.max_steps,
                            "suite": options.suite, "suite_hash": suite_hash,
                            "shield": options.shield}
            )  # fmt: skip
        journal.remove()
    finally:
        lock.release()
        for t in teams:
            t.env.close()
    text += f"\nwrote {len(written)} files to {out}/ ({elapsed:.1f} s):\n"
    return text + "".join(f"  {path}\n" for path in written)


def _fly(
    flight: Flight,
    teams: list[BuiltTeam],
    tasks: list[tuple[int, int]],
    journal: SwarmJournal,
    finished: list[FinishedEpisode],
    progress: bool,
    workers: int,
) -> None:
    """Fly ``tasks``, journal every episode as it ends and add it to ``finished`` (which holds
    the episodes a resumed run read back); every team must meet the same field in episode i."""
    from tqdm import tqdm

    prints = {f.record.episode: f.record.field_hash for f in finished}
    total = len(teams) * len(flight.missions)
    bar = tqdm(total=total, initial=len(finished), desc="swarm episodes", unit="ep",
               disable=not progress, file=sys.stderr, dynamic_ncols=True)  # fmt: skip

    def sink(episode: FinishedEpisode, picture: bytes | None) -> None:
        record = episode.record
        if prints.setdefault(record.episode, record.field_hash) != record.field_hash:
            raise TeamFailed(
                f"{record.agent} flew another field in episode {record.episode} than the "
                "first team (the seeded fields must be the same for every team)"
            )
        journal.append_episode(episode, picture)
        finished.append(episode)
        bar.set_postfix_str(f"{record.agent} ep {record.episode} done")
        bar.update(1)

    try:
        fly_tasks(flight, teams, tasks, sink, workers)
    finally:
        bar.close()


DEFAULTS_TEXT = ", ".join(DEFAULT_TEAMS)
"""The default teams, for ``--help``."""
