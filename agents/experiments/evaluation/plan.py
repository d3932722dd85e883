"""The options of ``evaluate.py`` as given (:class:`EvaluateOptions`) and as resolved into a run
(:class:`EvaluationPlan`, what ``DIR/unfinished/options.json`` holds), and the error that names
a wrong argument (:class:`UsageError`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.experiments.evaluation.specs import AgentSpec, parse_agent_spec

__all__ = ["BACKENDS", "EvaluateOptions", "EvaluationPlan", "UsageError"]


class UsageError(ValueError):
    """A command-line argument is wrong; ``flag`` names it (``"--agents"``)."""

    def __init__(self, flag: str, message: str) -> None:
        super().__init__(message)
        self.flag = flag


class NoAgentFits(UsageError):
    """None of the agents listed can fly the env; ``skipped`` holds each one's reason."""

    def __init__(self, flag: str, message: str, skipped: dict[str, str]) -> None:
        super().__init__(flag, message)
        self.skipped = skipped


@dataclass(frozen=True)
class EvaluateOptions:
    """The arguments of ``evaluate.py`` (see its ``--help``); None means the default.

    With ``resume`` (a directory holding an unfinished evaluation) every other option but
    ``progress`` and the backend options must keep its default: the run's own options are read
    from the directory.

    ``backend`` is ``"local"`` (this process) or ``"ray"`` (episodes fanned out to Ray actors,
    :mod:`agents.experiments.distributed.evaluation`; the same records); ``address`` the Ray
    cluster to join (None: a local Ray) and ``workers`` the number of Ray workers (None: one
    per CPU of the cluster), both for ``"ray"`` only. They say where episodes run, not what the
    evaluation is, so they are not part of the :class:`EvaluationPlan`.

    ``skip_unfit``: an agent listed in ``agents`` that cannot fly the env is left out with its
    reason (in the summary's ``skipped``) instead of refused; the robustness table sets it, as
    not every agent flies every error (the base law reads the true state, so neither it nor a
    residual policy flies with navigation errors).
    """

    out: Path | None = None
    env: str | None = None
    agents: str | None = None
    episodes: int | None = None
    seed: int | None = None
    plots: int | None = None
    env_kwargs: dict[str, Any] | None = None
    max_steps: int | None = None
    reference: str | None = None
    progress: bool = True
    paper: bool = False
    resume: Path | None = None
    suite: str | None = None
    shield: bool = False
    video: int = 0
    backend: str = "local"
    address: str | None = None
    workers: int | None = None
    skip_unfit: bool = False


BACKENDS = ("local", "ray")
"""Where ``evaluate.py`` flies its episodes (``--backend``)."""


@dataclass(frozen=True)
class EvaluationPlan:
    """The resolved options of one evaluation: what ``DIR/unfinished/options.json`` holds and
    ``--resume`` runs again.

    Attributes:
        out: output directory.
        env_id: the env every agent flies; ``env_kwargs`` its ``gym.make`` options.
        agents: ``(spec text, label)`` of every agent to run, in order.
        episodes: episodes per agent; episode i is reset with seed ``seed + i`` — or, with
            ``suite``, is the suite's mission i.
        max_steps: time-limit override (steps), or None for the registered one.
        plots: trajectory plots of the first ``plots`` episodes.
        reference: the agent others' Δv is paired with, or None for the default.
        paper: write ``paper_table.*`` ([APF-MPC] Table I beside ours).
        skipped: agents left out of a default list, {label: reason}.
        warnings: what building an agent warned about, {label: message} (shown in the
            summary).
        suite: the frozen suite flown (:mod:`debris_gym.suites`), else None.
        suite_hash: its content hash when the run started (a resumed run refuses a suite
            whose content has changed since).
        shield: every agent flies behind the safety shield (default parameters,
            :class:`agents.policies.shield.ShieldParams`).
        video: record the first ``video`` episodes of every agent as mp4 in
            ``out/videos/<agent>/`` (gymnasium's ``RecordVideo``).
    """

    out: Path
    env_id: str
    env_kwargs: dict[str, Any]
    agents: tuple[tuple[str, str], ...]
    episodes: int
    seed: int
    max_steps: int | None = None
    plots: int = 3
    reference: str | None = None
    paper: bool = False
    skipped: dict[str, str] = field(default_factory=dict)
    warnings: dict[str, str] = field(default_factory=dict)
    suite: str | None = None
    suite_hash: str | None = None
    shield: bool = False
    video: int = 0

    @property
    def specs(self) -> list[AgentSpec]:
        """The agents, parsed, with their labels."""
        return [dataclasses.replace(parse_agent_spec(t), label=label) for t, label in self.agents]

    def to_json(self) -> dict[str, Any]:
        """Plain-JSON form (``out`` left out: the journal lives in it)."""
        data = dataclasses.asdict(self)
        del data["out"]
        data["agents"] = [list(pair) for pair in self.agents]
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any], out: Path) -> EvaluationPlan:
        """The plan :meth:`to_json` wrote, for output directory ``out``.

        Raises:
            KeyError, TypeError, ValueError: ``data`` is not such a plan.
        """
        agents = tuple((str(text), str(label)) for text, label in data.pop("agents"))
        return cls(out=out, agents=agents, **data)
