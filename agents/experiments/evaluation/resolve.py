"""``evaluate.py``'s arguments resolved into a checked plan (:class:`~agents.experiments.
evaluation.plan.EvaluationPlan`): the env made and reset once, the suite loaded, every agent
built once on the env it will fly, before anything runs or is written.

A wrong argument raises :class:`~agents.experiments.evaluation.plan.UsageError` naming its flag.
A ``UserWarning`` while an agent is built (a learned model without its statistics, flown on
another env than it was trained on, picked from a run directory without ``model.zip``) is noted
on stderr and kept in the plan, so the summary keeps it too.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from agents.experiments.evaluation.journal import EvaluationJournal, JournalError
from agents.experiments.evaluation.paper import PAPER_AGENTS, PAPER_ENV_ID
from agents.experiments.evaluation.plan import (
    EvaluateOptions,
    EvaluationPlan,
    NoAgentFits,
    UsageError,
)
from agents.experiments.evaluation.runner import make_env
from agents.experiments.evaluation.specs import (
    PRETRAINED,
    AgentSpec,
    agent_env_options,
    build_agent,
    check_agent_available,
    known_specs_text,
    parse_agent_specs,
)
from debris_gym.config import UNCERTAINTY_KEYS
from debris_gym.suites import Suite, load_suite

__all__ = [
    "AGENT_ERRORS",
    "DEFAULT_ENV",
    "DEFAULT_EPISODES",
    "DEFAULT_OUT",
    "fresh_plan",
    "note",
    "plan_seeds",
    "plan_suite",
    "resume_plan",
]

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v2"
"""Env of a plain ``python evaluate.py``."""

DEFAULT_EPISODES = 20
"""Episodes per agent of a plain ``python evaluate.py``."""

DEFAULT_OUT = Path("runs/eval")
"""Output directory of a plain ``python evaluate.py`` (if it is free; :func:`~agents.experiments.
evaluation.command.default_out`)."""

AGENT_ERRORS = (ImportError, FileNotFoundError, NotImplementedError, TypeError, ValueError)
"""What building an agent raises when the agent, not the code, is at fault."""


def note(text: str) -> None:
    print(f"note: {text}", file=sys.stderr)


def _default_agents(
    env_id: str, env_kwargs: dict[str, Any], max_steps: int | None
) -> tuple[list[str], dict[str, str]]:
    """Every baseline, and 'pretrained' if it loads for ``env_id``.

    Returns the agent names and {skipped agent: reason}.
    """
    import agents

    names = list(agents.BASELINES)
    env = None
    try:
        # a residual policy's env may refuse the run's options (navigation errors, say)
        env = make_env(env_id, {**env_kwargs, **agent_env_options(PRETRAINED, env_id)}, max_steps)
        agents.load_agent(PRETRAINED, env)
    except (FileNotFoundError, NotImplementedError, ValueError, KeyError) as exc:
        reason = str(exc)  # it names the env and why
    else:
        return [*names, PRETRAINED], {}
    finally:
        if env is not None:
            env.close()
    note(f"skipped 'pretrained' — {reason}")
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
            note(f"skipped — {exc}")
            skipped[spec.label] = str(exc)
            continue
        messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
        if messages:
            warned[spec.label] = "\n".join(dict.fromkeys(messages))
            note(f"agent {spec.label!r}: {warned[spec.label]}")
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
    for flag, value in (("--env", options.env), ("--seed", options.seed)):
        if value is not None:
            raise UsageError(
                flag, "not allowed with --suite (the suite fixes the env, its options and seeds)"
            )
    other = sorted(set(options.env_kwargs or {}) - set(UNCERTAINTY_KEYS))
    if other:
        raise UsageError(
            "--env-kwargs",
            f"{', '.join(other)} not allowed with --suite (the suite fixes the env and its "
            "options; only the uncertain world's may be added: "
            f"{', '.join(UNCERTAINTY_KEYS)})",
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
            note(f"skipped — {unregistered[name]}")
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

    strict = explicit and not options.skip_unfit
    specs, skipped, warned = _usable(specs, strict, "--agents", env_for)
    if not specs:
        flag = "--paper" if options.paper else "--agents"
        message = "none of its agents can be built (see the notes above)"
        raise NoAgentFits(flag, message, {**unregistered, **skipped})
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


def fresh_plan(options: EvaluateOptions) -> EvaluationPlan:
    """Check every argument and choose the agents (nothing runs, nothing is written)."""
    suite = None
    if options.suite is not None:
        suite, episodes = _resolve_suite(options)
        env_id, seed = suite.env_id, suite.missions[0].seed
        env_kwargs = {**suite.env_kwargs, **(options.env_kwargs or {})}
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


def resume_plan(options: EvaluateOptions) -> EvaluationPlan:
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
    suite = plan_suite(plan)
    _check_env(plan.env_id, plan.env_kwargs, plan.max_steps, plan.seed, suite)

    def env_for(spec: AgentSpec) -> gym.Env:
        kwargs = {**plan.env_kwargs, **agent_env_options(spec, plan.env_id)}
        return make_env(plan.env_id, kwargs, plan.max_steps)

    _, _, warned = _usable(plan.specs, True, "--resume", env_for)
    return dataclasses.replace(plan, warnings=warned)


def plan_suite(plan: EvaluationPlan) -> Suite | None:
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


def plan_seeds(plan: EvaluationPlan) -> list[int]:
    """The reset seed of each episode of ``plan``."""
    suite = plan_suite(plan)
    if suite is None:
        return [plan.seed + i for i in range(plan.episodes)]
    return list(suite.seeds[: plan.episodes])
