"""Flying a swarm evaluation's episodes: in this process, or on ``--workers N`` processes.

Every team is built with its own swarm env (:func:`build_teams`; a learned member needs its
own observation options). A *task* is one team's episode; :func:`fly_tasks` flies the tasks not
yet finished and hands each :class:`~agents.experiments.swarm_evaluation.journal.
FinishedEpisode` (with its plot's PNG bytes) to a callback as it ends, in this process
(``workers=1``) or on a pool of ``spawn``-started worker processes, each of which builds the
teams once. An episode's record does not depend on where or after what it flew: every team
draws its random numbers afresh at each reset, so the results are the same whatever the count
(apart from the timing columns). Videos are written by whichever process flew the episode.

The workers ignore SIGINT: a Ctrl-C reaches this process, which stops the pool (the episodes in
flight are lost; the finished ones have been handed over).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from agents.experiments.evaluation.plan import UsageError
from agents.experiments.swarm_evaluation.episode import fly_episode
from agents.experiments.swarm_evaluation.journal import FinishedEpisode
from agents.experiments.swarm_evaluation.recording import (
    EpisodeFrames,
    plot_name,
    png_bytes,
    write_video,
)
from agents.experiments.swarm_evaluation.teams import TeamSpec, make_team
from agents.policies.shield import ShieldParams
from agents.policies.team import TeamPolicy, team_options
from debris_gym.scenario import Scenario
from debris_gym.swarm import checked_options
from debris_gym.swarm import make as make_swarm

__all__ = ["BuiltTeam", "Flight", "Mission", "TeamFailed", "build_teams", "fly_one", "fly_tasks"]


class Mission(NamedTuple):
    """One episode of every team: its reset seed and the field pinned (None: the seed's)."""

    seed: int
    scenario: Scenario | None


@dataclass
class BuiltTeam:
    """A team ready to fly: its spec, its own swarm env and its policy."""

    spec: TeamSpec
    env: Any
    team: TeamPolicy


@dataclass(frozen=True)
class Flight:
    """What every process needs to build the teams and fly their episodes.

    Attributes:
        env_id: the swarm ID; ``env_kwargs`` its options over the ID's own.
        specs: the teams, in order (task ``(t, i)`` is team ``specs[t]``'s episode i).
        missions: the episodes.
        max_steps: the time limit (steps) over the ID's own.
        plots: draw a trajectory plot of each team's first ``plots`` episodes.
        video: record each team's first ``video`` episodes (mp4 in ``out/videos/``).
        shield: the safety shield every team flies behind (None: unshielded).
        out: the output directory (videos); None until the run has taken its lock.
    """

    env_id: str
    env_kwargs: dict[str, Any]
    specs: tuple[TeamSpec, ...]
    missions: tuple[Mission, ...]
    max_steps: int | None
    plots: int
    video: int
    shield: ShieldParams | None
    out: Path | None = None

    @property
    def recorded(self) -> int:
        """Episodes of each team that are drawn (plots or videos)."""
        return max(self.plots, self.video)


def _env_options(spec: TeamSpec, dim: int, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    needed = team_options(spec.agent, dim)
    for key, value in needed.items():
        if key in env_kwargs and env_kwargs[key] != value:
            raise UsageError(
                "--env-kwargs",
                f"{key}={env_kwargs[key]!r} conflicts with {spec.label}, which needs "
                f"{key}={value!r}",
            )
    return {**env_kwargs, **needed}


def build_teams(
    flight: Flight, named: bool, note: Callable[[str], None] = lambda _: None
) -> tuple[list[BuiltTeam], dict[str, str]]:
    """Every team of ``flight`` with its env. A team that cannot be built (no shipped policy)
    is refused when ``named``, else skipped with its reason (passed to ``note`` too).

    Raises:
        UsageError: bad swarm options, or a named team that cannot be built.
    """
    env_kwargs = dict(flight.env_kwargs)
    try:
        config, _ = checked_options(flight.env_id, {**env_kwargs, "assignment": "given"})
    except (TypeError, ValueError) as exc:
        raise UsageError("--env-kwargs", str(exc)) from exc
    teams: list[BuiltTeam] = []
    skipped: dict[str, str] = {}
    for spec in flight.specs:
        kwargs = _env_options(spec, config.dim, env_kwargs)
        if flight.max_steps is not None:
            kwargs["max_episode_steps"] = flight.max_steps
        if flight.recorded:
            kwargs["render_mode"] = "rgb_array"
        try:
            env = make_swarm(flight.env_id, **kwargs)
        except (TypeError, ValueError) as exc:
            raise UsageError("--env-kwargs", f"{spec.label}: {exc}") from exc
        try:
            team = make_team(spec, env, flight.shield)
        except (ValueError, FileNotFoundError) as exc:
            env.close()
            if named:
                raise UsageError("--agents", f"{spec.label}: {exc}") from exc
            skipped[spec.label] = str(exc)
            note(f"note: skipping {spec.label}: {exc}")
            continue
        teams.append(BuiltTeam(spec, env, team))
    if not teams:
        raise UsageError("--agents", "no team could be built: " + "; ".join(skipped.values()))
    return teams, skipped


class TeamFailed(RuntimeError):
    """A team raised during an episode; the message names the team, episode and seed."""


def fly_one(built: BuiltTeam, flight: Flight, i: int) -> tuple[FinishedEpisode, bytes | None]:
    """Fly ``built``'s episode ``i``: the finished episode and its plot's PNG bytes (None when
    it is not drawn); its video is written now.

    Raises:
        TeamFailed: the team raised (the message says where).
    """
    seed, scenario = flight.missions[i]
    label = built.spec.label
    frames = EpisodeFrames(every_step=i < flight.video) if i < flight.recorded else None
    try:
        record, rules = fly_episode(
            built.env, built.team, built.team.views, seed, i, label, frames, scenario
        )
    except (KeyboardInterrupt, UsageError):
        raise
    except Exception as exc:
        raise TeamFailed(
            f"{label} failed in episode {i} (seed {seed}): {type(exc).__name__}: {exc}"
        ) from exc
    picture = None
    if frames is not None and i < flight.plots:
        picture = png_bytes(frames.last)
    if frames is not None and i < flight.video:
        if flight.out is None:
            raise ValueError("a flight that records videos needs its output directory (out)")
        write_video(flight.out, label, i, frames.frames)
    plot = plot_name(i, label) if picture is not None else None
    return FinishedEpisode(record, rules, plot), picture


Sink = Callable[[FinishedEpisode, bytes | None], None]
"""What receives each finished episode (and its plot's PNG bytes), in this process."""


def fly_tasks(
    flight: Flight,
    teams: Sequence[BuiltTeam],
    tasks: Sequence[tuple[int, int]],
    sink: Sink,
    workers: int = 1,
) -> None:
    """Fly every ``(team index, episode index)`` of ``tasks`` and hand each finished episode
    to ``sink`` as it ends: in this process with ``teams`` (``workers=1``, in task order), or
    on ``workers`` processes (in the order they finish).

    Raises:
        TeamFailed: a team raised (the episodes already handed over stay handed over).
    """
    if workers <= 1 or len(tasks) <= 1:
        for t, i in tasks:
            sink(*fly_one(teams[t], flight, i))
        return
    context = multiprocessing.get_context("spawn")
    count = min(workers, len(tasks))
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:  # SIGINT blocked while the workers start: it never lands before they ignore it
        pool = context.Pool(count, initializer=_start_worker, initargs=(flight,))
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
    try:
        for outcome in pool.imap_unordered(_fly_task, tasks):
            if isinstance(outcome, str):
                raise TeamFailed(outcome)
            sink(*outcome)
        pool.close()
    finally:
        pool.terminate()
        pool.join()


_WORKER: dict[str, Any] = {}
"""A worker process's flight and teams (built once, in :func:`_start_worker`)."""


def _start_worker(flight: Flight) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    os.environ["OMP_NUM_THREADS"] = "1"  # before torch is imported (a learned member's build)
    teams, _ = build_teams(flight, named=True)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    _WORKER.update(flight=flight, teams=teams)


def _fly_task(task: tuple[int, int]) -> tuple[FinishedEpisode, bytes | None] | str:
    """A worker's task; a failure comes back as its message (an exception's traceback would
    not pickle whole)."""
    t, i = task
    try:
        return fly_one(_WORKER["teams"][t], _WORKER["flight"], i)
    except TeamFailed as exc:
        return f"{exc}\n{traceback.format_exc()}"
