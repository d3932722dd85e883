"""What ``evaluate.py --env SWARM_ID`` does: fly every team on the same seeded fields and write
the tables.

Every team (:mod:`~agents.experiments.swarm_evaluation.teams`) gets its own swarm env (a learned
member needs its own observation options), made with ``assignment="given"``; episode i of every
team is reset with seed ``SEED + i`` (the same field for all: checked by its fingerprint). The
run takes the output directory's lock, flies the teams one after another in this one process,
and writes ``episodes.csv``, ``assignments.csv``, ``summary.json``, ``summary.md`` and the
trajectory plots (``--plots N``, :mod:`~agents.experiments.swarm_evaluation.recording`) as one
set (:class:`~agents.experiments.run_directory.OutputSet`, each file written atomically);
``--video N`` writes videos beside it. With ``--shield`` every team flies behind the safety shield,
one per chaser, that counts the teammates as bodies
(:class:`~agents.policies.shielded.TeamShield`; decision times include it), and the tables count
the commands it replaced. Options of the single-agent evaluation that do not apply (the paper
table, Ray, several workers, resuming) are refused with :class:`UsageError` before anything runs;
Ctrl-C writes nothing.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

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
from agents.experiments.swarm_evaluation.episode import TeamEpisode, fly_episode
from agents.experiments.swarm_evaluation.recording import (
    DEFAULT_SWARM_PLOTS,
    PLOT_PATTERN,
    EpisodeFrames,
    check_video_support,
    plot_name,
    png_bytes,
    write_video,
)
from agents.experiments.swarm_evaluation.report import (
    assignment_gaps,
    assignments_csv,
    episodes_csv,
    summarize_teams,
    summary_markdown,
)
from agents.experiments.swarm_evaluation.teams import (
    DEFAULT_TEAMS,
    TeamSpec,
    make_team,
    parse_teams,
)
from agents.planners.team_assignment import TeamAssignment
from agents.policies.shield import ShieldParams
from agents.policies.team import TeamPolicy, team_options
from debris_gym.files import write_atomic
from debris_gym.scenario import Scenario
from debris_gym.suites import list_suites, load_suite
from debris_gym.swarm import SWARM_SPECS, checked_options
from debris_gym.swarm import make as make_swarm

__all__ = [
    "DEFAULT_SWARM_EPISODES",
    "DEFAULT_SWARM_OUT",
    "NOT_FOR_SWARMS",
    "SwarmEvaluateOptions",
    "is_swarm_id",
    "is_swarm_suite",
    "run_swarm_evaluation",
]

DEFAULT_SWARM_OUT = Path("runs/eval-swarm")
DEFAULT_SWARM_EPISODES = 20
OUTPUTS = ("episodes.csv", "assignments.csv", "summary.json", "summary.md")

NOT_FOR_SWARMS: dict[str, tuple[str, Any]] = {
    "paper": ("--paper", False),
    "resume": ("--resume", None),
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


class _Episode(NamedTuple):
    """One episode of every team: its reset seed and the field pinned (None: the seed's)."""

    seed: int
    scenario: Scenario | None


def _suite_plan(options: SwarmEvaluateOptions) -> tuple[str, dict[str, Any], list[_Episode]]:
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
    missions = [_Episode(m.seed, m.scenario) for m in suite.missions[:count]]
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

    @classmethod
    def from_arguments(cls, arguments: dict[str, Any]) -> SwarmEvaluateOptions:
        """The options of ``evaluate.py``'s parsed arguments (its destinations by name).

        Raises:
            UsageError: an option that does not apply to swarm IDs was given, or more than one
                worker.
        """
        env = arguments["env"]
        for key, (flag, default) in NOT_FOR_SWARMS.items():
            if arguments.get(key, default) != default:
                raise UsageError(flag, f"does not apply to swarm IDs ({env})")
        if arguments.get("workers") not in (None, 1):
            raise UsageError("--workers", f"swarm IDs ({env}) are flown in one process: use 1")
        names = ("agents", "episodes", "seed", "out", "env_kwargs", "max_steps", "reference",
                 "plots", "suite")  # fmt: skip
        kwargs = {k: arguments.get(k) for k in names}
        video = int(arguments.get("video") or 0)
        check_video_support(video)
        return cls(
            env=env, progress=bool(arguments.get("progress", True)), video=video,
            shield=bool(arguments.get("shield", False)), **kwargs,
        )  # fmt: skip

    @property
    def shield_params(self) -> ShieldParams | None:
        """The shield every team flies behind (None: unshielded)."""
        return ShieldParams() if self.shield else None

    @property
    def recorded(self) -> int:
        """Episodes of each team that are drawn (plots or videos)."""
        plots = DEFAULT_SWARM_PLOTS if self.plots is None else self.plots
        return max(plots, self.video)


@dataclass
class _Team:
    spec: TeamSpec
    env: Any
    team: TeamPolicy


def _options(env_id: str, spec: TeamSpec, dim: int, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    needed = team_options(spec.agent, dim)
    for key, value in needed.items():
        if key in env_kwargs and env_kwargs[key] != value:
            raise UsageError(
                "--env-kwargs",
                f"{key}={env_kwargs[key]!r} conflicts with {spec.label}, which needs "
                f"{key}={value!r}",
            )
    return {**env_kwargs, **needed}


def _build_teams(
    options: SwarmEvaluateOptions, env_id: str, specs: list[TeamSpec], named: bool
) -> tuple[list[_Team], dict[str, str]]:
    """Every team with its env; teams of the default list that cannot be built (no shipped
    policy) are skipped with the reason."""
    env_kwargs = dict(options.env_kwargs or {})
    try:
        config, _ = checked_options(env_id, {**env_kwargs, "assignment": "given"})
    except (TypeError, ValueError) as exc:
        raise UsageError("--env-kwargs", str(exc)) from exc
    teams: list[_Team] = []
    skipped: dict[str, str] = {}
    for spec in specs:
        kwargs = _options(env_id, spec, config.dim, env_kwargs)
        if options.max_steps is not None:
            kwargs["max_episode_steps"] = options.max_steps
        if options.recorded:
            kwargs["render_mode"] = "rgb_array"
        try:
            env = make_swarm(env_id, **kwargs)
        except (TypeError, ValueError) as exc:
            raise UsageError("--env-kwargs", f"{spec.label}: {exc}") from exc
        try:
            team = make_team(spec, env, options.shield_params)
        except (ValueError, FileNotFoundError) as exc:
            env.close()
            if named:
                raise UsageError("--agents", f"{spec.label}: {exc}") from exc
            skipped[spec.label] = str(exc)
            print(f"note: skipping {spec.label}: {exc}", file=sys.stderr)
            continue
        teams.append(_Team(spec, env, team))
    if not teams:
        raise UsageError("--agents", "no team could be built: " + "; ".join(skipped.values()))
    return teams, skipped


def _lock(out: Path | None) -> tuple[Path, RunDirectoryLock]:
    if out is not None:
        lock = RunDirectoryLock(out, "--out")
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


def _fly(
    teams: list[_Team], missions: list[_Episode], options: SwarmEvaluateOptions, out: Path
) -> tuple[
    list[TeamEpisode], dict[int, tuple[int, dict[str, TeamAssignment]]], dict[str, np.ndarray]
]:
    """Fly every team's episodes; returns the records, every field's assignments, and the
    trajectory plots to write (file name → frame). Videos are written as their episodes end.
    A mission without a scenario is the field its seed draws."""
    from tqdm import tqdm

    progress = options.progress
    plots = DEFAULT_SWARM_PLOTS if options.plots is None else options.plots
    pictures: dict[str, np.ndarray] = {}
    records: list[TeamEpisode] = []
    fields: dict[int, tuple[int, dict[str, TeamAssignment]]] = {}
    prints: dict[int, str] = {}
    bar = tqdm(total=len(teams) * len(missions), desc="swarm episodes", unit="ep",
               disable=not progress, file=sys.stderr, dynamic_ncols=True)  # fmt: skip
    try:
        for t in teams:
            for i, (seed, scenario) in enumerate(missions):
                bar.set_postfix_str(f"{t.spec.label} ep {i}")
                frames = (
                    EpisodeFrames(every_step=i < options.video) if i < options.recorded else None
                )
                try:
                    record, rules = fly_episode(
                        t.env, t.team, t.team.views, seed, i, t.spec.label, frames, scenario
                    )
                except (KeyboardInterrupt, UsageError):
                    raise
                except Exception as exc:
                    raise RuntimeError(
                        f"{t.spec.label} failed in episode {i} (seed {seed}): "
                        f"{type(exc).__name__}: {exc}"
                    ) from exc
                if prints.setdefault(i, record.field_hash) != record.field_hash:
                    raise RuntimeError(
                        f"{t.spec.label} flew another field in episode {i} than the first team "
                        "(the seeded fields must be the same for every team)"
                    )
                fields.setdefault(i, (seed, rules))
                records.append(record)
                if frames is not None and i < plots:
                    pictures[plot_name(i, t.spec.label)] = frames.last
                if frames is not None and i < options.video:
                    write_video(out, t.spec.label, i, frames.frames)
                bar.update(1)
    finally:
        bar.close()
    return records, fields, pictures


def run_swarm_evaluation(options: SwarmEvaluateOptions) -> str:
    """Fly every team, write the outputs as one set, and return the text to print (the tables
    and the files written).

    Raises:
        UsageError: a bad option (before anything runs).
        RuntimeError: a team failed mid-run (nothing is written).
    """
    suite_hash = None
    if options.suite is not None:
        env_id, suite_kwargs, missions = _suite_plan(options)
        suite_hash = load_suite(options.suite).content_hash
        options = dataclasses.replace(options, env=env_id, env_kwargs=suite_kwargs)
    else:
        env_id = (options.env or "").rpartition(":")[2]
        if env_id not in SWARM_SPECS:
            raise UsageError(
                "--env", f"unknown swarm ID {env_id!r}; known: {', '.join(SWARM_SPECS)}"
            )
        first = 0 if options.seed is None else options.seed
        count = DEFAULT_SWARM_EPISODES if options.episodes is None else options.episodes
        missions = [_Episode(first + i, None) for i in range(count)]
    try:
        specs = parse_teams(options.agents)
    except ValueError as exc:
        raise UsageError("--agents", str(exc)) from exc
    labels = [s.label for s in specs]
    if options.reference is not None and options.reference not in labels:
        raise UsageError("--reference", f"{options.reference!r} is not one of {labels}")
    episodes, seed = len(missions), missions[0].seed
    teams, skipped = _build_teams(options, env_id, specs, named=options.agents is not None)
    out, lock = _lock(options.out)
    try:
        start = time.perf_counter()
        records, fields, pictures = _fly(teams, missions, options, out)
        elapsed = time.perf_counter() - start
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
        summary.update(
            title=(
                f"{env_id}{' ' + to_json(kwargs).strip() if kwargs else ''}: {episodes} episodes "
                f"per team, {where}{steps}, one process"
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
            for name, frame in pictures.items():
                write_atomic(files.path(name), png_bytes(frame))
            written = files.commit(
                evaluation={"env_id": env_id, "env_kwargs": kwargs, "agents": flown,
                            "episodes": episodes, "seed": seed, "max_steps": options.max_steps,
                            "suite": options.suite, "suite_hash": suite_hash,
                            "shield": options.shield}
            )  # fmt: skip
    finally:
        lock.release()
        for t in teams:
            t.env.close()
    text += f"\nwrote {len(written)} files to {out}/ ({elapsed:.1f} s):\n"
    return text + "".join(f"  {path}\n" for path in written)


DEFAULTS_TEXT = ", ".join(DEFAULT_TEAMS)
"""The default teams, for ``--help``."""
