"""The team names ``evaluate.py`` takes on swarm IDs, and the teams it flies by default.

A team is named ``team-AGENT@RULE``: AGENT a single-agent baseline (:data:`agents.BASELINES`),
``pretrained`` (the single-agent policy shipped for the swarm's world) or ``ALGO:PATH`` (a
policy trained by train.py: a single-agent one, or one trained on a swarm ID, which reads the
chaser's whole observation), flown on every chaser; RULE the assignment rule
(:data:`~agents.planners.team_assignment.ASSIGNMENT_RULES`), ``balanced`` (the env's own rule)
when left out. A multi-agent method (:data:`TEAM_POLICIES`) is named by its own name,
``ma-se-scp[@RULE]`` (``balanced`` when left out).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from agents.planners.team_assignment import ASSIGNMENT_RULES
from agents.policies.learned import LEARNED_ALGOS, PRETRAINED
from agents.policies.registry import BASELINES
from agents.policies.shield import ShieldParams
from agents.policies.team import TeamOfSingles

__all__ = [
    "DEFAULT_RULE",
    "DEFAULT_TEAMS",
    "TEAM_POLICIES",
    "TEAM_PREFIX",
    "TeamSpec",
    "make_team",
    "parse_teams",
]

TEAM_PREFIX = "team-"
DEFAULT_RULE = "balanced"
"""The rule of a team named without ``@RULE``: the swarm env's own."""

TEAM_POLICIES: dict[str, tuple[str, str]] = {
    "ma-se-scp": ("agents.policies.ma_se_scp:MASESCPTeam", "balanced"),
}
"""Multi-agent team policies by name → (``module:Class`` built as ``Class(env, rule,
shield=...)``, the rule of a name given without ``@RULE``); imported on first use."""

DEFAULT_TEAMS = (
    *(f"team-apf-mpc@{rule}" for rule in ASSIGNMENT_RULES),
    *(f"team-pretrained@{rule}" for rule in ASSIGNMENT_RULES),
    "team-zero@balanced",
)
"""What ``evaluate.py --env SWARM_ID`` flies without ``--agents``: APF-MPC and the shipped
single-agent policy on every chaser under each assignment rule, and the coasting floor."""


@dataclass(frozen=True)
class TeamSpec:
    """A team to evaluate: its ``label`` (``team-AGENT@RULE``), the single-agent ``agent``
    on every chaser and the assignment ``rule``."""

    label: str
    agent: str
    rule: str


def _checked_agent(agent: str, text: str) -> str:
    if agent in BASELINES or agent == PRETRAINED:
        return agent
    head, sep, path = agent.replace("=", ":").partition(":")
    if sep and head.strip().lower() in LEARNED_ALGOS and path.strip():
        return agent
    raise ValueError(
        f"{text!r}: unknown team member {agent!r}; use team-AGENT@RULE with AGENT one of "
        f"{', '.join(BASELINES)}, {PRETRAINED!r} or ALGO:PATH (ALGO one of "
        f"{', '.join(LEARNED_ALGOS)})"
    )


def parse_teams(text: str | None) -> list[TeamSpec]:
    """The teams of a comma-separated ``--agents`` list (None: :data:`DEFAULT_TEAMS`), in
    order, each named ``team-AGENT[@RULE]``.

    Raises:
        ValueError: a name that is not a team, an unknown member or rule, an empty list or a
            team named twice (the message names it and what is allowed).
    """
    names = list(DEFAULT_TEAMS) if text is None else [t.strip() for t in text.split(",")]
    if not names or any(not n for n in names):
        raise ValueError(f"empty team name in {text!r}; e.g. team-apf-mpc@optimal,team-zero")
    specs: list[TeamSpec] = []
    for name in names:
        head, sep, tail = name.partition("@")
        if head in TEAM_POLICIES:
            rule = tail if sep else TEAM_POLICIES[head][1]
            if rule not in ASSIGNMENT_RULES:
                raise ValueError(
                    f"{name!r}: unknown assignment rule {rule!r}; known: "
                    f"{', '.join(ASSIGNMENT_RULES)}"
                )
            label = f"{head}@{rule}"
            if any(s.label == label for s in specs):
                raise ValueError(f"{label!r} is named twice")
            specs.append(TeamSpec(label, head, rule))
            continue
        if not name.startswith(TEAM_PREFIX):
            raise ValueError(
                f"{name!r}: swarm IDs fly teams, named team-AGENT@RULE (e.g. team-apf-mpc@"
                f"optimal, team-pretrained@minmax, team-zero) or {', '.join(TEAM_POLICIES)}; "
                f"rules: {', '.join(ASSIGNMENT_RULES)}"
            )
        body = name[len(TEAM_PREFIX) :]
        agent, sep, rule = body.rpartition("@")
        if not sep:
            agent, rule = body, DEFAULT_RULE
        if rule not in ASSIGNMENT_RULES:
            raise ValueError(
                f"{name!r}: unknown assignment rule {rule!r}; known: {', '.join(ASSIGNMENT_RULES)}"
            )
        agent = _checked_agent(agent.strip(), name)
        label = f"{TEAM_PREFIX}{agent}@{rule}"
        if any(s.label == label for s in specs):
            raise ValueError(f"{label!r} is named twice")
        specs.append(TeamSpec(label, agent, rule))
    return specs


def make_team(spec: TeamSpec, env: Any, shield: ShieldParams | None = None) -> Any:
    """The team policy of ``spec`` on ``env``: a :data:`TEAM_POLICIES` class, else a
    :class:`~agents.policies.team.TeamOfSingles`; with ``shield``, every chaser's commands
    pass a safety shield of its own that counts the teammates as bodies
    (:class:`~agents.policies.shielded.TeamShield`)."""
    if spec.agent in TEAM_POLICIES:
        module_name, class_name = TEAM_POLICIES[spec.agent][0].split(":")
        team_class = getattr(importlib.import_module(module_name), class_name)
        return team_class(env, spec.rule, shield=shield)
    return TeamOfSingles(env, spec.agent, spec.rule, shield=shield)
