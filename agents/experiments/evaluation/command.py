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
resume); ``evaluate.py --resume DIR`` (:attr:`EvaluateOptions.resume`) continues the journal.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import shlex
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from agents.experiments.evaluation.journal import EvaluationJournal, JournalError
from agents.experiments.evaluation.paper import (
    PAPER_AGENTS,
    PAPER_ENV_ID,
    PAPER_TITLE,
    paper_table,
    paper_table_markdown,
)
from agents.experiments.evaluation.plan import (
    BACKENDS,
    EvaluateOptions,
    EvaluationPlan,
    UsageError,
)
from agents.experiments.evaluation.report import summary_markdown, to_json, write_outputs
from agents.experiments.evaluation.runner import (
    EpisodeBackend,
    evaluate_agents,
    index_finished,
    make_env,
)
from agents.experiments.evaluation.specs import (
    PRETRAINED,
    AgentSpec,
    agent_env_options,
    build_agent,
    check_agent_available,
    known_specs_text,
    parse_agent_specs,
)
from agents.experiments.evaluation.statistics import summarize
from agents.experiments.run_directory import OutputDirError, RunDirectoryLock
from agents.policies.shield import ShieldParams
from debris_gym.suites import Suite, load_suite

__all__ = [
    "DEFAULT_ENV",
    "DEFAULT_EPISODES",
    "DEFAULT_OUT",
    "EvaluateOptions",
    "EvaluationInterrupted",
    "EvaluationPlan",
    "UsageError",
    "run_evaluation",
]

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v1"
"""Env of a plain ``python evaluate.py``."""

DEFAULT_EPISODES = 20
"""Episodes per agent of a plain ``python evaluate.py``."""

DEFAULT_OUT = Path("runs/eval")

VIDEO_DIR = "videos"
"""Where ``--video N`` puts each agent's recordings: ``DIR/videos/<agent>/``."""
"""Output directory of a plain ``python evaluate.py``."""

AGENT_ERRORS = (ImportError, FileNotFoundError, NotImplementedError, TypeError, ValueError)
"""What building an agent raises when the agent, not the code, is at fault."""


class EvaluationInterrupted(Exception):
    """Ctrl-C (or SIGTERM) stopped a run; what finished is journaled in ``out``.

    Attributes:
        out: the output directory.
        finished: episodes (agent × episode) finished, this run and earlier ones.
        total: episodes the evaluation has in all.
    """

    def __init__(self, out: Path, finished: int, total: int) -> None:
        self.out = out
        self.finished = finished
        self.total = total
        super().__init__(self.message())

    @property
    def resume_command(self) -> str:
        """The command line that finishes the run."""
        return f"python evaluate.py --resume {shlex.quote(str(self.out))}"

    def message(self) -> str:
        """What to tell the user (several lines)."""
        if self.finished == self.total:
            done = f"all {self.total} episodes finished but the outputs were not written"
        else:
            done = f"{self.finished} of {self.total} episodes finished"
        return (
            f"interrupted: {done}; they are kept in {self.out / 'unfinished'}/\n"
            f"resume with: {self.resume_command}"
        )


def _note(text: str) -> None:
    print(f"note: {text}", file=sys.stderr)


def _default_agents(
    env_id: str, env_kwargs: dict[str, Any], max_steps: int | None
) -> tuple[list[str], dict[str, str]]:
    """Every baseline, and 'pretrained' if it loads for ``env_id``.

    Returns the agent names and {skipped agent: reason}.
    """
    import agents

    names = list(agents.BASELINES)
    env = make_env(env_id, {**env_kwargs, **agent_env_options(PRETRAINED, env_id)}, max_steps)
    try:
        agents.load_agent(PRETRAINED, env)
    except (FileNotFoundError, NotImplementedError, ValueError, KeyError) as exc:
        reason = str(exc)  # it names the env and why
    else:
        return [*names, PRETRAINED], {}
    finally:
        env.close()
    _note(f"skipped 'pretrained' — {reason}")
    return names, {PRETRAINED: reason}


def _usable(
    specs: list[AgentSpec], explicit: bool, flag: str, env_for: Callable[[AgentSpec], gym.Env]
) -> tuple[list[AgentSpec], dict[str, str], dict[str, str]]:
    """Check each agent can be built: a :class:`UsageError` if listed explicitly, else a note.

    Every agent is built once here (``env_for(spec)`` gives the env), so a wrong file, a space
    mismatch (a baseline in a discrete-action env), a missing pretrained policy or an object
    without ``predict`` fails before any episode runs. A ``UserWarning`` while an agent is built
    (a learned model without its VecNormalize statistics and run config, say) becomes a note
    and is kept for the summary.

    Returns:
        The agents to run, {skipped agent: reason} and {agent: warning}.
    """
    keep, skipped, warned = [], {}, {}
    for spec in specs:
        try:
            check_agent_available(spec)
            env = env_for(spec)
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", UserWarning)
                    try:
                        build_agent(spec, env)
                    except ValueError as exc:
                        if spec.kind != "baseline":
                            raise
                        raise ValueError(f"{exc}; {_who_can_act(env)}") from exc
            finally:
                env.close()
        except AGENT_ERRORS as exc:
            if explicit:
                raise UsageError(flag, str(exc)) from exc
            _note(f"skipped — {exc}")
            skipped[spec.label] = str(exc)
            continue
        messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
        if messages:
            warned[spec.label] = "\n".join(dict.fromkeys(messages))
            _note(f"agent {spec.label!r}: {warned[spec.label]}")
        keep.append(spec)
    return keep, skipped, warned


def _who_can_act(env: gym.Env) -> str:
    """Which agents can act in ``env`` (for a baseline that cannot)."""
    import agents

    able = []
    for name in agents.BASELINES:
        try:
            agents.make_agent(name, env)
        except (ImportError, TypeError, ValueError):
            continue
        able.append(name)
    others = (
        "a learned model trained in this action space (e.g. dqn=PATH for action='discrete') or "
        "your own policy (LABEL=MODULE:ATTR)"
    )
    if able:
        return f"agents that can act in this env: {', '.join(able)}, or {others}"
    return f"no baseline can act in this env; {others} can"


def _load_suite(name: str, flag: str = "--suite") -> Suite:
    try:
        return load_suite(name)
    except ValueError as exc:
        raise UsageError(flag, str(exc)) from exc


def _resolve_suite(options: EvaluateOptions) -> tuple[Suite, int]:
    """The suite of ``--suite`` and the missions to fly (``--episodes``: its first N)."""
    assert options.suite is not None
    for flag, value in (
        ("--env", options.env),
        ("--seed", options.seed),
        ("--env-kwargs", options.env_kwargs),
    ):
        if value is not None:
            raise UsageError(
                flag, "not allowed with --suite (the suite fixes the env, its options and seeds)"
            )
    if options.paper:
        raise UsageError("--paper", "not allowed with --suite (--paper flies its own world)")
    suite = _load_suite(options.suite)
    episodes = len(suite) if options.episodes is None else options.episodes
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise UsageError("--episodes", f"must be an integer >= 1, got {episodes!r}")
    if episodes > len(suite):
        raise UsageError(
            "--episodes",
            f"must be <= {len(suite)}: suite {suite.name!r} has {len(suite)} missions, got "
            f"{episodes}",
        )
    return suite, episodes


def _resolve_env(options: EvaluateOptions) -> tuple[str, int]:
    if not options.paper:
        episodes = DEFAULT_EPISODES if options.episodes is None else options.episodes
        if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
            raise UsageError("--episodes", f"must be an integer >= 1, got {episodes!r}")
        return (DEFAULT_ENV if options.env is None else options.env), episodes
    for flag, value in (("--env", options.env), ("--agents", options.agents)):
        if value is not None:
            raise UsageError(flag, "not allowed with --paper (it fixes the env/agents)")
    if options.episodes is not None:
        raise UsageError("--episodes", "not allowed with --paper (its world is fixed)")
    return PAPER_ENV_ID, 1


def _choose_agents(
    options: EvaluateOptions, env_id: str, env_kwargs: dict[str, Any]
) -> tuple[list[AgentSpec], dict[str, str], dict[str, str]]:
    """The agents to run (checked), {skipped agent: reason} and {agent: warning}."""
    from agents import BASELINES

    explicit = options.agents is not None
    unregistered: dict[str, str] = {}
    if options.paper:
        agent_text: list[str] | str = [a for a in PAPER_AGENTS if a in BASELINES]
        for name in sorted(set(PAPER_AGENTS) - set(agent_text)):
            unregistered[name] = f"agent {name!r} is not in agents.BASELINES"
            _note(f"skipped — {unregistered[name]}")
    elif explicit:
        agent_text = options.agents or ""
        if not agent_text.strip():
            raise UsageError("--agents", f"empty list of agents; {known_specs_text()}")
    else:
        agent_text, unregistered = _default_agents(env_id, env_kwargs, options.max_steps)
    try:
        specs = parse_agent_specs(agent_text) if agent_text else []
    except ValueError as exc:
        raise UsageError("--agents", str(exc)) from exc

    def env_for(spec: AgentSpec) -> gym.Env:
        kwargs = {**env_kwargs, **agent_env_options(spec, env_id)}
        return make_env(env_id, kwargs, options.max_steps)

    specs, skipped, warned = _usable(specs, explicit, "--agents", env_for)
    if not specs:
        flag = "--paper" if options.paper else "--agents"
        raise UsageError(flag, "none of its agents can be built (see the notes above)")
    labels = [spec.label for spec in specs]
    if options.reference is not None and options.reference not in labels:
        raise UsageError(
            "--reference",
            f"{options.reference!r} is not an evaluated agent; agents: {', '.join(labels)}",
        )
    return specs, {**unregistered, **skipped}, warned


def _debris_env_ids() -> list[str]:
    return sorted(k for k in gym.registry if k.startswith("DebrisGym/"))


def _check_env(
    env_id: str,
    env_kwargs: dict[str, Any],
    max_steps: int | None,
    seed: int,
    suite: Suite | None = None,
) -> None:
    """Make the env and reset it once with the first episode's seed (and, for a suite, its
    first mission's field): a bad ID or option fails here, before any agent is built."""
    from debris_gym.envs import DebrisFieldEnv

    ids = ", ".join(_debris_env_ids())
    if not env_id.strip():
        raise UsageError("--env", f"must name an env, got an empty string; DebrisGym IDs: {ids}")
    try:
        env = make_env(env_id, env_kwargs, max_steps)
    except (gym.error.Error, ImportError) as exc:  # ImportError: a "module:ID" that fails
        raise UsageError("--env", f"{exc}; DebrisGym IDs: {ids}") from exc
    except (TypeError, ValueError, OverflowError) as exc:
        raise UsageError("--env-kwargs", str(exc)) from exc
    try:
        if not isinstance(env.unwrapped, DebrisFieldEnv):
            raise UsageError("--env", f"{env_id!r} is not a DebrisGym env; DebrisGym IDs: {ids}")
        if suite is not None:
            try:
                env.reset(
                    seed=suite.missions[0].seed, options={"scenario": suite.missions[0].scenario}
                )
            except ValueError as exc:
                raise UsageError("--suite", f"{suite.name}: {exc}") from exc
            return
        try:
            env.reset(seed=seed)
        except (TypeError, ValueError, OverflowError) as exc:
            if not env_kwargs:
                raise  # the registered env itself fails: a bug, not a usage error
            raise UsageError("--env-kwargs", str(exc)) from exc
    finally:
        env.close()


def _fresh_plan(options: EvaluateOptions) -> EvaluationPlan:
    """Check every argument and choose the agents (nothing runs, nothing is written)."""
    suite = None
    if options.suite is not None:
        suite, episodes = _resolve_suite(options)
        env_id, env_kwargs, seed = suite.env_id, dict(suite.env_kwargs), suite.missions[0].seed
    else:
        env_id, episodes = _resolve_env(options)
        seed = 0 if options.seed is None else options.seed
        env_kwargs = dict(options.env_kwargs or {})
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UsageError("--seed", f"must be an integer >= 0 (a reset seed), got {seed!r}")
    plots = 3 if options.plots is None else options.plots
    if isinstance(plots, bool) or not isinstance(plots, int) or plots < 0:
        raise UsageError("--plots", f"must be an integer >= 0, got {plots!r}")
    _check_env(env_id, env_kwargs, options.max_steps, seed, suite)
    specs, skipped, warned = _choose_agents(options, env_id, env_kwargs)
    video = options.video
    if isinstance(video, bool) or not isinstance(video, int) or video < 0:
        raise UsageError("--video", f"must be an integer >= 0, got {video!r}")
    if video and importlib.util.find_spec("moviepy") is None:
        raise UsageError(
            "--video", "needs moviepy (gymnasium's RecordVideo writes mp4 with it): "
            "pip install 'debris-gym[video]'"
        )  # fmt: skip
    return EvaluationPlan(
        shield=bool(options.shield),
        video=video,
        out=Path(options.out if options.out is not None else DEFAULT_OUT),
        env_id=env_id,
        env_kwargs=env_kwargs,
        agents=tuple((spec.text, spec.label) for spec in specs),
        episodes=episodes,
        seed=seed,
        max_steps=options.max_steps,
        plots=plots,
        reference=options.reference,
        paper=options.paper,
        skipped=skipped,
        warnings=warned,
        suite=None if suite is None else suite.name,
        suite_hash=None if suite is None else suite.content_hash,
    )


def _resume_plan(options: EvaluateOptions) -> EvaluationPlan:
    """The plan journaled in ``options.resume``, its env and agents checked again (a model file
    may have moved since)."""
    assert options.resume is not None
    defaults = EvaluateOptions(progress=options.progress, resume=options.resume)
    for name in ("out", "env", "agents", "episodes", "seed", "plots", "env_kwargs", "max_steps",
                 "reference", "paper", "suite", "shield", "video"):  # fmt: skip
        if getattr(options, name) != getattr(defaults, name):
            flag = "--" + name.replace("_", "-")
            raise UsageError(
                flag, "not allowed with --resume (the run's options are read from its directory)"
            )
    out = Path(options.resume)
    journal = EvaluationJournal(out)
    try:
        plan = EvaluationPlan.from_json(journal.read_options(), out)
    except JournalError as exc:
        raise UsageError("--resume", str(exc)) from exc
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(
            "--resume", f"{journal.options_path}: not an evaluation's options ({exc!r})"
        ) from exc
    suite = _plan_suite(plan)
    _check_env(plan.env_id, plan.env_kwargs, plan.max_steps, plan.seed, suite)

    def env_for(spec: AgentSpec) -> gym.Env:
        kwargs = {**plan.env_kwargs, **agent_env_options(spec, plan.env_id)}
        return make_env(plan.env_id, kwargs, plan.max_steps)

    _, _, warned = _usable(plan.specs, True, "--resume", env_for)
    return dataclasses.replace(plan, warnings=warned)


def _plan_suite(plan: EvaluationPlan) -> Suite | None:
    """The suite of a journaled plan, checked to be the one the run started with."""
    if plan.suite is None:
        return None
    suite = _load_suite(plan.suite, "--resume")
    if suite.content_hash != plan.suite_hash:
        raise UsageError(
            "--resume",
            f"suite {plan.suite!r} has changed since the run started (content hash "
            f"{plan.suite_hash}, now {suite.content_hash}); start a new evaluation",
        )
    return suite


def _lock(plan: EvaluationPlan, flag: str) -> RunDirectoryLock:
    lock = RunDirectoryLock(plan.out, flag)
    try:
        lock.acquire()
    except OutputDirError as exc:
        raise UsageError(exc.flag, str(exc)) from exc
    except OSError as exc:
        raise UsageError(flag, f"cannot use {plan.out} ({exc})") from exc
    return lock


def run_evaluation(options: EvaluateOptions) -> str:
    """Evaluate, write every output file into the output directory as one set, and return the
    text to print (the summary table, with ``paper`` Table I beside ours, and the files written).

    Notes about skipped agents go to stderr as they happen.

    Raises:
        UsageError: a bad argument, or the output directory is in use by another run (before
            any episode runs and before the directory changes).
        EvaluationInterrupted: Ctrl-C or SIGTERM after the run started; the finished episodes
            are journaled in the output directory for ``--resume``.
    """
    resuming = options.resume is not None
    backend = _backend(options)
    plan = _resume_plan(options) if resuming else _fresh_plan(options)
    if backend is not None and plan.video:
        raise UsageError("--video", "records on the local backend only; drop --backend ray")
    flag = "--resume" if resuming else "--out"
    lock = _lock(plan, flag)
    try:
        return _run_locked(plan, resuming, options.progress, backend)
    finally:
        lock.release()


def _backend(options: EvaluateOptions) -> EpisodeBackend | None:
    """The backend ``options`` ask for (None: the local loop), checked before anything runs.

    Raises:
        UsageError: an unknown backend, ``--address`` / ``--workers`` without ``--backend ray``,
            a bad worker count, or Ray not installed.
    """
    if options.backend not in BACKENDS:
        choices = ", ".join(BACKENDS)
        raise UsageError("--backend", f"must be one of {choices}, got {options.backend!r}")
    if options.backend == "local":
        for flag, value in (("--address", options.address), ("--workers", options.workers)):
            if value is not None:
                raise UsageError(flag, "needs --backend ray (the local backend runs here)")
        return None
    from agents.experiments.distributed import INSTALL_HINT
    from agents.experiments.distributed.evaluation import RayBackend

    if importlib.util.find_spec("ray") is None:
        raise UsageError("--backend", f"ray needs Ray, which is not installed: {INSTALL_HINT}")
    if options.address is not None and not options.address.strip():
        raise UsageError("--address", "must name a Ray cluster (e.g. auto, HOST:6379), got ''")
    try:
        return RayBackend(options.address, options.workers)
    except ValueError as exc:
        raise UsageError("--workers", str(exc)) from exc


def _plan_seeds(plan: EvaluationPlan) -> list[int]:
    """The reset seed of each episode of ``plan``."""
    suite = _plan_suite(plan)
    if suite is None:
        return [plan.seed + i for i in range(plan.episodes)]
    return list(suite.seeds[: plan.episodes])


def _run_locked(
    plan: EvaluationPlan, resuming: bool, progress: bool, backend: EpisodeBackend | None
) -> str:
    """Run ``plan`` in its directory (whose lock the caller holds), on ``backend`` (None: in
    this process)."""
    journal = EvaluationJournal(plan.out)
    total = len(plan.agents) * plan.episodes
    if resuming:
        try:
            finished = journal.read_records()
        except JournalError as exc:
            raise UsageError("--resume", str(exc)) from exc
        try:
            index_finished(finished, plan.specs, plan.episodes, _plan_seeds(plan))
        except ValueError as exc:
            raise UsageError("--resume", f"{journal.episodes_path}: {exc}") from exc
        journal.drop_partial_line()
    else:
        if journal.exists():
            _note(
                f"replacing the unfinished evaluation in {journal.dir} (--resume would finish it)"
            )
        journal.start(plan.to_json())
        finished = []
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
                on_episode=journal.append,
                suite=_plan_suite(plan),
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
        written = write_outputs(
            results,
            plan.out,
            plots=plan.plots,
            summary=summary,
            extra=extra,
            manifest={"evaluation": plan.to_json()},
        )
    except KeyboardInterrupt:
        raise EvaluationInterrupted(plan.out, journal.count, total) from None
    journal.remove()
    text += f"\nwrote {len(written)} files to {plan.out}/ ({results.elapsed:.1f} s):\n"
    text += "".join(f"  {path}\n" for path in written)
    return text
