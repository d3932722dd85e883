"""Evaluation on the swarm IDs: teams of single-agent policies behind assignment rules, flown on
the same seeded fields (``evaluate.py --env DebrisGym/Swarm2D-v0``; docs/swarm.md, "Baselines").

:func:`run_swarm_evaluation` is the command, :func:`fly_episode` one team's episode,
:mod:`~agents.experiments.swarm_evaluation.report` the tables.
"""

from agents.experiments.swarm_evaluation.command import (
    DEFAULT_SWARM_EPISODES,
    DEFAULT_SWARM_OUT,
    SwarmEvaluateOptions,
    SwarmRunStopped,
    is_swarm_id,
    is_swarm_suite,
    run_swarm_evaluation,
)
from agents.experiments.swarm_evaluation.episode import TeamEpisode, fly_episode
from agents.experiments.swarm_evaluation.teams import DEFAULT_TEAMS, TeamSpec, parse_teams

__all__ = [
    "DEFAULT_SWARM_EPISODES",
    "DEFAULT_SWARM_OUT",
    "DEFAULT_TEAMS",
    "SwarmEvaluateOptions",
    "SwarmRunStopped",
    "TeamEpisode",
    "TeamSpec",
    "fly_episode",
    "is_swarm_id",
    "is_swarm_suite",
    "parse_teams",
    "run_swarm_evaluation",
]
