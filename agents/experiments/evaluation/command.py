"""What ``evaluate.py`` does once its arguments are parsed: choose and check the agents, run them,
write the outputs and compose the text it prints.

Problems with the arguments raise :class:`UsageError` naming the flag, which the script turns
into an argparse error (exit status 2) before any episode runs.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

from agents.experiments.evaluation.paper import (
    PAPER_AGENTS,
    PAPER_ENV_ID,
    paper_table,
    paper_table_markdown,
)
from agents.experiments.evaluation.report import summary_markdown, to_json, write_outputs
from agents.experiments.evaluation.runner import evaluate_agents, make_env
from agents.experiments.evaluation.specs import (
    PRETRAINED,
    AgentSpec,
    agent_env_options,
    build_agent,
    check_agent_available,
    parse_agent_specs,
)
from agents.experiments.evaluation.statistics import summarize
from debris_gym.files import write_atomic

__all__ = ["DEFAULT_ENV", "DEFAULT_EPISODES", "EvaluateOptions", "UsageError", "run_evaluation"]

DEFAULT_ENV = "DebrisGym/Rendezvous2D-v0"
"""Env of a plain ``python evaluate.py``."""

DEFAULT_EPISODES = 20
"""Episodes per agent of a plain ``python evaluate.py``."""

AGENT_ERRORS = (ImportError, FileNotFoundError, NotImplementedError, TypeError, ValueError)
"""What building an agent raises when the agent, not the code, is at fault."""


class UsageError(ValueError):
    """A command-line argument is wrong; ``flag`` names it (``"--agents"``)."""

    def __init__(self, flag: str, message: str) -> None:
        super().__init__(message)
        self.flag = flag


@dataclass(frozen=True)
class EvaluateOptions:
    """The arguments of ``evaluate.py`` (see its ``--help``); None means the default."""

    out: Path
    env: str | None = None
    agents: str | None = None
    episodes: int | None = None
    seed: int = 0
    plots: int = 3
    env_kwargs: dict[str, Any] | None = None
    max_steps: int | None = None
    reference: str | None = None
    progress: bool = True
    paper: bool = False


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
        reason = f"no pretrained policy for {env_id} ({exc})"
    else:
        return [*names, PRETRAINED], {}
    finally:
        env.close()
    _note(f"skipped 'pretrained' — {reason}")
    return names, {PRETRAINED: reason}


def _usable(
    specs: list[AgentSpec], explicit: bool, flag: str, env_for: Callable[[AgentSpec], gym.Env]
) -> tuple[list[AgentSpec], dict[str, str]]:
    """Check each agent can be built: a :class:`UsageError` if listed explicitly, else a note.

    Agents other than baselines are built once here (``env_for(spec)`` gives the env), so a wrong
    file, a space mismatch, a missing pretrained policy or an object without ``predict`` fails
    before any episode runs.
    """
    keep, skipped = [], {}
    for spec in specs:
        try:
            check_agent_available(spec)
            if spec.kind != "baseline":
                env = env_for(spec)
                try:
                    build_agent(spec, env)
                finally:
                    env.close()
        except AGENT_ERRORS as exc:
            if explicit:
                raise UsageError(flag, str(exc)) from exc
            _note(f"skipped — {exc}")
            skipped[spec.label] = str(exc)
            continue
        keep.append(spec)
    return keep, skipped


def _resolve_env(options: EvaluateOptions) -> tuple[str, int]:
    if not options.paper:
        return options.env or DEFAULT_ENV, options.episodes or DEFAULT_EPISODES
    for flag, value in (("--env", options.env), ("--agents", options.agents)):
        if value is not None:
            raise UsageError(flag, "not allowed with --paper (it fixes the env/agents)")
    if options.episodes is not None:
        raise UsageError("--episodes", "not allowed with --paper (its world is fixed)")
    return PAPER_ENV_ID, 1


def _choose_agents(
    options: EvaluateOptions, env_id: str, env_kwargs: dict[str, Any]
) -> tuple[list[AgentSpec], dict[str, str]]:
    """The agents to run (checked) and {skipped agent: reason}."""
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
    else:
        agent_text, unregistered = _default_agents(env_id, env_kwargs, options.max_steps)
    try:
        specs = parse_agent_specs(agent_text) if agent_text else []
    except ValueError as exc:
        raise UsageError("--agents", str(exc)) from exc

    def env_for(spec: AgentSpec) -> gym.Env:
        kwargs = {**env_kwargs, **agent_env_options(spec, env_id)}
        return make_env(env_id, kwargs, options.max_steps)

    specs, skipped = _usable(specs, explicit, "--agents", env_for)
    if not specs:
        flag = "--paper" if options.paper else "--agents"
        raise UsageError(flag, "none of its agents can be built (see the notes above)")
    labels = [spec.label for spec in specs]
    if options.reference is not None and options.reference not in labels:
        raise UsageError(
            "--reference",
            f"{options.reference!r} is not an evaluated agent; agents: {', '.join(labels)}",
        )
    return specs, {**unregistered, **skipped}


def run_evaluation(options: EvaluateOptions) -> str:
    """Evaluate, write every output file into ``options.out``, and return the text to print
    (the summary table, with ``paper`` Table I beside ours, and the files written).

    Notes about skipped agents go to stderr as they happen.

    Raises:
        UsageError: a bad argument (before any episode runs).
    """
    env_id, episodes = _resolve_env(options)
    env_kwargs = dict(options.env_kwargs or {})
    try:  # validate the env ID and its keyword arguments before any agent runs
        make_env(env_id, env_kwargs, options.max_steps).close()
    except gym.error.Error as exc:
        raise UsageError("--env", str(exc)) from exc
    except (TypeError, ValueError) as exc:
        raise UsageError("--env-kwargs", str(exc)) from exc
    specs, skipped = _choose_agents(options, env_id, env_kwargs)

    results = evaluate_agents(
        env_id,
        specs,
        episodes=episodes,
        seed=options.seed,
        env_kwargs=env_kwargs,
        progress=options.progress,
        max_episode_steps=options.max_steps,
    )
    summary = summarize(results, reference=options.reference)
    if skipped:
        summary["skipped"] = skipped
    out = Path(options.out)
    written = write_outputs(results, out, plots=options.plots, summary=summary)
    text = summary_markdown(summary)
    if options.paper:
        table = paper_table(results, skipped)
        table_text = paper_table_markdown(table)
        for name, content in (("paper_table.md", table_text), ("paper_table.json", to_json(table))):
            write_atomic(out / name, content)
            written.append(out / name)
        text += "\n[APF-MPC] Table I, paper vs ours:\n\n" + table_text
    text += f"\nwrote {len(written)} files to {out}/ ({results.elapsed:.1f} s):\n"
    text += "".join(f"  {path}\n" for path in written)
    return text
