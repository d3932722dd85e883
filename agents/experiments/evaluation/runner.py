"""Run agents on the same seeded episodes and record what they flew.

Every agent flies the same episodes: episode ``i`` starts with ``env.reset(seed=seed + i)``, and
the field comes from the reset seed, so all agents meet the same debris fields (checked after
every run through a fingerprint of each scenario). A frozen suite
(:mod:`debris_gym.suites`) instead pins episode ``i``'s field: ``env.reset(seed=missions[i].seed,
options={"scenario": missions[i].scenario})``.

An episode is flown by :func:`~agents.experiments.evaluation.episode.run_episode` (decision
times, what the records hold, how a failing agent is named). The episodes run in this process, or
on a backend (:class:`EpisodeBackend`: worker processes on this machine, Ray actors) that hands
the records back as they arrive.

With ``shield`` every agent flies behind the safety shield
(:class:`agents.policies.shielded.ShieldedAgent`): its decision time includes the shield's, and
each record counts the commands the shield replaced.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the DebrisGym IDs)
from agents.experiments.evaluation.episode import run_episode
from agents.experiments.evaluation.failures import AgentFailure, describe
from agents.experiments.evaluation.records import (
    RECORD_FIELDS,
    TIMING_COLUMNS,
    EpisodeRecord,
    EvaluationResults,
)
from agents.experiments.evaluation.specs import (
    AgentSpec,
    agent_env_options,
    build_agent,
    parse_agent_specs,
)
from agents.experiments.evaluation.video import attach_shield, recording_env
from agents.policies.shield import ShieldParams
from agents.policies.shielded import ShieldedAgent
from debris_gym.config import UNCERTAINTY_KEYS
from debris_gym.scenario import Scenario
from debris_gym.suites import Suite

__all__ = [
    "EpisodeBackend",
    "EvaluationJob",
    "build_agent_env",
    "check_replay",
    "episode_resets",
    "evaluate_agents",
    "index_finished",
    "make_env",
    "run_episode",
]


@dataclass(frozen=True)
class EvaluationJob:
    """Everything needed to fly any episode of an evaluation, on this machine or another.

    Attributes:
        env_id: the env every agent flies; ``env_kwargs`` its ``gym.make`` options.
        max_episode_steps: time-limit override (steps), or None for the registered one.
        specs: the agents, in order.
        resets: ``(reset seed, pinned scenario or None)`` of each episode
            (:func:`episode_resets`).
        shield: fly every agent behind the safety shield with these parameters, or None.
    """

    env_id: str
    env_kwargs: dict[str, Any]
    max_episode_steps: int | None
    specs: tuple[AgentSpec, ...]
    resets: tuple[tuple[int, Scenario | None], ...]
    shield: ShieldParams | None = None

    @property
    def episodes(self) -> int:
        """Episodes per agent."""
        return len(self.resets)


class EpisodeBackend(Protocol):
    """Flies an evaluation's unfinished episodes somewhere else: worker processes on this
    machine (:class:`agents.experiments.evaluation.pool.ProcessBackend`) or Ray actors
    (:class:`agents.experiments.distributed.evaluation.RayBackend`)."""

    def fly(
        self,
        job: EvaluationJob,
        done: Mapping[tuple[str, int], EpisodeRecord],
        on_record: Callable[[EpisodeRecord], None],
        on_start: Callable[[], None] | None = None,
    ) -> None:
        """Fly every (agent, episode) of ``job`` not in ``done``, calling ``on_record`` in this
        process with each record as it arrives, and ``on_start`` once its workers are up (the
        progress bar is drawn then, below whatever starting them printed). The records must
        equal those of the local loop apart from :data:`TIMING_COLUMNS` (so an agent whose
        episodes depend on earlier ones must fly them in order, replaying finished ones as the
        local loop does).

        Raises:
            AgentFailure: an agent failed (named with its episode and step).
        """
        ...


def build_agent_env(
    job: EvaluationJob, spec: AgentSpec, module_dir: str | None = None
) -> tuple[gym.Env, Any]:
    """The env ``spec`` flies in (with the observation options it was trained with) and the
    agent built for it, behind the shield if ``job`` asks for one.

    Raises:
        AgentFailure: the agent could not be built (its module, factory or model failed).
    """
    env = _agent_env(job, spec)
    try:
        return env, _job_agent(job, spec, env, module_dir)
    except BaseException:
        env.close()
        raise


def _agent_env(
    job: EvaluationJob, spec: AgentSpec, video: tuple[Path, int] | None = None
) -> gym.Env:
    """The env ``spec`` flies in: the job's options and the agent's observation options; with
    ``video``, rendering and recording (:func:`~agents.experiments.evaluation.video.
    recording_env`)."""
    kwargs = {**job.env_kwargs, **agent_env_options(spec, job.env_id)}
    if video is None:
        return make_env(job.env_id, kwargs, job.max_episode_steps)
    env = make_env(job.env_id, kwargs, job.max_episode_steps, render_mode="rgb_array")
    return recording_env(env, spec.label, *video, shielded=job.shield is not None)


def _job_agent(
    job: EvaluationJob, spec: AgentSpec, env: gym.Env, module_dir: str | None = None
) -> Any:
    """The agent of ``spec`` for ``env``, behind the shield if ``job`` asks for one.

    Raises:
        AgentFailure: building it failed (it was built once before the run started, so this is
            an agent that fails only sometimes, or a file changed since).
    """
    try:
        agent = build_agent(spec, env, module_dir)
        agent = agent if job.shield is None else ShieldedAgent(agent, env, job.shield)
    except (Exception, SystemExit) as exc:
        raise AgentFailure(spec.label, None, None, None, describe(exc)) from exc
    attach_shield(env, agent)
    return agent


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any] | None = None,
    max_episode_steps: int | None = None,
    render_mode: str | None = None,
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, with the time limit overridden if given."""
    kwargs = dict(env_kwargs or {})
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    if max_episode_steps is not None:
        if int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        kwargs["max_episode_steps"] = int(max_episode_steps)
    return gym.make(env_id, **kwargs)


def evaluate_agents(
    env_id: str,
    agent_specs: str | Iterable[str | AgentSpec] | Mapping[str, Any],
    episodes: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
    max_episode_steps: int | None = None,
    finished: Sequence[EpisodeRecord] = (),
    on_episode: Callable[[EpisodeRecord], None] | None = None,
    suite: Suite | None = None,
    shield: ShieldParams | None = None,
    video: tuple[Path, int] | None = None,
    backend: EpisodeBackend | None = None,
) -> EvaluationResults:
    """Fly every agent on the same ``episodes`` seeded scenarios.

    Episode ``i`` of every agent starts with ``env.reset(seed=seed + i)`` — or, with ``suite``,
    with the suite's mission ``i`` (its seed, its field pinned). Each agent gets its own
    env (``gym.make(env_id, **env_kwargs)``), built once and reset per episode; a learned agent's
    env also gets the observation options it was trained with (:func:`agent_env_options`).

    Args:
        env_id: a registered ID, e.g. ``"DebrisGym/Rendezvous2D-v2"``.
        agent_specs: what to evaluate (see :mod:`agents.experiments.evaluation.specs`): a
            comma-separated string (``"apf,ppo=runs/ppo/model.zip"``), a list of specs, or a
            mapping ``{label: spec}`` whose values may also be your own policy objects (anything
            with SB3's ``predict``) or factories ``f(env) -> policy``, e.g.
            ``{"apf": "apf", "mine": MyPolicy()}``.
        episodes: episodes per agent, >= 1.
        seed: seed of episode 0.
        env_kwargs: keyword arguments for ``gym.make``.
        progress: show a tqdm bar over agent × episode on stderr.
        max_episode_steps: override the registration's time limit (steps).
        finished: records of (agent label, episode) pairs already flown by an interrupted run
            of the same evaluation; they are taken as they are. An agent may keep state from one
            episode to the next (the ``random`` baseline's generator does), so an agent with
            episodes still to fly first re-flies, unrecorded, its finished episodes before the
            last unfinished one: the resumed run then equals an uninterrupted one.
        on_episode: called with each newly flown episode's record as soon as it finishes (to
            journal it; see :mod:`agents.experiments.evaluation.journal`).
        suite: a frozen suite whose first ``episodes`` missions are flown; ``env_id`` and
            ``env_kwargs`` must be the suite's, and ``seed`` is ignored.
        shield: fly every agent behind the safety shield with these parameters
            (:mod:`agents.policies.shield`); None: unshielded.
        video: ``(folder, n)``: record the first ``n`` episodes this call flies for each agent
            (replays of a resumed run count) as mp4 files in ``folder/<agent label>/``, with
            gymnasium's ``RecordVideo`` on a ``render_mode="rgb_array"`` env (needs moviepy).
        backend: fly the episodes elsewhere (:class:`EpisodeBackend`, e.g. on Ray) instead of
            in this process; the records are the same. Not combinable with ``video``.

    Raises:
        ValueError: bad arguments (also: ``episodes`` beyond the suite's size, an env other
            than the suite's).
        RuntimeError: two agents met different scenarios in the same episode (a bug).
    """
    if isinstance(episodes, bool) or int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    specs = parse_agent_specs(agent_specs)
    env_kwargs = dict(env_kwargs or {})
    resets = episode_resets(episodes, seed, suite, env_id, env_kwargs)
    seeds = [s for s, _ in resets]
    done = index_finished(finished, specs, episodes, seeds)
    if backend is not None and video is not None:
        raise ValueError("video recording needs the local backend (backend=None)")
    job = EvaluationJob(
        env_id=env_id,
        env_kwargs=env_kwargs,
        max_episode_steps=max_episode_steps,
        specs=tuple(specs),
        resets=tuple(resets),
        shield=shield,
    )
    start = time.perf_counter()
    bar = _Progress(
        total=len(specs) * episodes,
        initial=len(done),
        desc="evaluate",
        unit="ep",
        file=sys.stderr,
        disable=not progress,
        dynamic_ncols=True,
    )
    try:
        if backend is None:
            bar.start()
            records, time_limit = _fly_local(job, done, on_episode, bar, video)
        else:
            records, time_limit = _fly_backend(job, done, on_episode, bar, backend)
    finally:
        bar.close()
    scenarios = _check_same_scenarios(records, episodes)
    return EvaluationResults(
        env_id=env_id,
        env_kwargs=env_kwargs,
        episodes=int(episodes),
        seed=int(seeds[0]),
        max_episode_steps=time_limit,
        agents=specs,
        records=records,
        scenarios=scenarios,
        elapsed=time.perf_counter() - start,
        suite=None if suite is None else suite.name,
        suite_hash=None if suite is None else suite.content_hash,
        suite_size=None if suite is None else len(suite),
        seeds=None if suite is None else seeds,
        shield=None if shield is None else shield.to_dict(),
    )


class _Progress:
    """A tqdm bar over agent × episode, drawn at :meth:`start` (a backend starts its workers
    first, so what starting them prints lands above the bar, not inside it)."""

    def __init__(self, **kwargs: Any) -> None:
        self.kwargs = kwargs
        self.bar: Any = None

    def start(self) -> None:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(**self.kwargs)

    def note(self, text: str) -> None:
        self.start()
        self.bar.set_postfix_str(text, refresh=False)

    def update(self) -> None:
        self.start()
        self.bar.update()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _fly_local(
    job: EvaluationJob,
    done: Mapping[tuple[str, int], EpisodeRecord],
    on_episode: Callable[[EpisodeRecord], None] | None,
    bar: _Progress,
    video: tuple[Path, int] | None,
) -> tuple[list[EpisodeRecord], int | None]:
    """Fly ``job`` in this process, agent after agent; return every record (agent-major, in
    episode order) and the time limit the envs had."""
    records: list[EpisodeRecord] = []
    time_limit = job.max_episode_steps
    for spec in job.specs:
        todo = [i for i in range(job.episodes) if (spec.label, i) not in done]
        env = _agent_env(job, spec, video)
        try:
            agent = _job_agent(job, spec, env) if todo else None
            if env.spec is not None:
                time_limit = env.spec.max_episode_steps
            for i in range(job.episodes):
                saved = done.get((spec.label, i))
                if saved is not None:
                    if todo and i < todo[-1]:  # bring the agent to the state it had
                        bar.note(f"{spec.label} ep {i} (replay)")
                        replay = run_episode(env, agent, spec.label, i, *job.resets[i])
                        check_replay(saved, replay)
                    records.append(saved)
                    continue
                bar.note(f"{spec.label} ep {i}")
                record = run_episode(env, agent, spec.label, i, *job.resets[i])
                records.append(record)
                if on_episode is not None:
                    on_episode(record)
                bar.update()
        finally:
            env.close()
    return records, time_limit


def _fly_backend(
    job: EvaluationJob,
    done: Mapping[tuple[str, int], EpisodeRecord],
    on_episode: Callable[[EpisodeRecord], None] | None,
    bar: _Progress,
    backend: EpisodeBackend,
) -> tuple[list[EpisodeRecord], int | None]:
    """Fly ``job`` with ``backend``; return every record in the local loop's order (agent-major,
    episode order) and the time limit the envs have."""
    flown: dict[tuple[str, int], EpisodeRecord] = {}

    def arrived(record: EpisodeRecord) -> None:
        key = (record.agent, record.episode)
        if key in flown or key in done:
            raise RuntimeError(f"the backend returned agent {key[0]!r}, episode {key[1]} twice")
        flown[key] = record
        if on_episode is not None:
            on_episode(record)
        bar.note(f"{record.agent} ep {record.episode}")
        bar.update()

    backend.fly(job, done, arrived, on_start=bar.start)
    records = []
    for spec in job.specs:
        for i in range(job.episodes):
            key = (spec.label, i)
            record = done.get(key) or flown.get(key)
            if record is None:
                raise RuntimeError(f"the backend did not fly agent {key[0]!r}, episode {i}")
            records.append(record)
    env = make_env(job.env_id, job.env_kwargs, job.max_episode_steps)
    try:
        time_limit = env.spec.max_episode_steps if env.spec is not None else None
    finally:
        env.close()
    return records, time_limit


def episode_resets(
    episodes: int,
    seed: int,
    suite: Suite | None = None,
    env_id: str | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> list[tuple[int, Scenario | None]]:
    """``(reset seed, pinned scenario or None)`` of each episode: ``(seed + i, None)``, or a
    suite's first ``episodes`` missions.

    Raises:
        ValueError: ``episodes`` beyond the suite's size; ``env_id`` / ``env_kwargs`` (when
            given) other than the suite's.
    """
    if suite is None:
        return [(int(seed) + i, None) for i in range(episodes)]
    if episodes > len(suite):
        raise ValueError(
            f"episodes must be <= {len(suite)} (suite {suite.name!r} has {len(suite)} missions), "
            f"got {episodes}"
        )
    if env_id is not None and env_id != suite.env_id:
        raise ValueError(f"suite {suite.name!r} is flown in {suite.env_id}, not {env_id}")
    if env_kwargs is not None:  # the uncertain world's options leave the fields as they are
        kept = {k: v for k, v in dict(env_kwargs).items() if k not in UNCERTAINTY_KEYS}
        if kept != dict(suite.env_kwargs):
            raise ValueError(
                f"suite {suite.name!r} is flown with env_kwargs {dict(suite.env_kwargs)} (and "
                f"any of {', '.join(UNCERTAINTY_KEYS)}), not {dict(env_kwargs)}"
            )
    return [(m.seed, m.scenario) for m in suite.missions[:episodes]]


def index_finished(
    finished: Sequence[EpisodeRecord],
    specs: list[AgentSpec],
    episodes: int,
    seed: int | Sequence[int],
) -> dict[tuple[str, int], EpisodeRecord]:
    """``finished`` by (agent label, episode), checked to belong to the evaluation of ``specs``
    over ``episodes`` episodes from reset seed ``seed`` (episode i: ``seed + i``), or with the
    reset seeds listed in ``seed`` (a suite's).

    Raises:
        ValueError: a record of another agent, episode or seed, or one pair twice.
    """
    labels = {spec.label for spec in specs}
    seeds = (
        [int(seed) + i for i in range(episodes)] if isinstance(seed, (int, np.integer)) else seed
    )
    done: dict[tuple[str, int], EpisodeRecord] = {}
    for record in finished:
        key = (record.agent, record.episode)
        if (
            record.agent not in labels
            or not 0 <= record.episode < episodes
            or record.seed != seeds[record.episode]
        ):
            raise ValueError(
                f"finished record of agent {record.agent!r}, episode {record.episode} (reset "
                f"seed {record.seed}) is not part of this evaluation (agents {sorted(labels)}, "
                f"episodes 0..{episodes - 1} with reset seeds {seeds[0]}…{seeds[-1]})"
            )
        if key in done:
            raise ValueError(f"agent {record.agent!r}, episode {record.episode} finished twice")
        done[key] = record
    return done


def check_replay(saved: EpisodeRecord, replayed: EpisodeRecord) -> None:
    """Warn (``RuntimeWarning``) if a re-flown episode differs from its saved record beyond
    timing: the agent is not deterministic, so a resumed run may differ."""
    fields = [f for f in RECORD_FIELDS if f not in TIMING_COLUMNS]
    if any(getattr(saved, f) != getattr(replayed, f) for f in fields):
        warnings.warn(
            f"agent {saved.agent!r} flew episode {saved.episode} differently when resumed; it "
            "is not deterministic, so the resumed results may differ from an uninterrupted run",
            RuntimeWarning,
            stacklevel=3,
        )


def _check_same_scenarios(records: list[EpisodeRecord], episodes: int) -> list[Scenario]:
    scenarios: list[Scenario] = []
    for i in range(episodes):
        group = [r for r in records if r.episode == i]
        ids = {r.scenario_id for r in group}
        if len(ids) != 1:
            raise RuntimeError(f"agents met different scenarios in episode {i}: {sorted(ids)}")
        scenario = group[0].scenario
        if scenario is None:
            raise RuntimeError(f"the records of episode {i} hold no field")
        scenarios.append(scenario)
    return scenarios
