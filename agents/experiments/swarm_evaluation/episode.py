"""One team's episode on a swarm env, measured: :func:`fly_episode` → :class:`TeamEpisode`.

The episode starts with :func:`~agents.policies.team.start_episode` (reset with the seed, the
team's assignment chosen on that field, reset again with it) and runs until no chaser is
flying. Each step times the team's ``predict`` and counts the time per chaser that decided.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.experiments.evaluation.records import scenario_fingerprint
from agents.experiments.swarm_evaluation.recording import EpisodeFrames
from agents.planners.team_assignment import ASSIGNMENT_RULES, TeamAssignment, assign, tour_costs
from agents.policies.shielded import ShieldStats
from agents.policies.team import TeamPolicy, start_episode, team_field

__all__ = [
    "CHASER_OUTCOMES",
    "TeamEpisode",
    "chaser_outcome",
    "field_assignments",
    "fly_episode",
]

CHASER_OUTCOMES = (
    "success",
    "debris_collision",
    "teammate_collision",
    "out_of_bounds",
    "delta_v_budget",
    "time_limit",
)
"""How a chaser's mission ends (a contact with a teammate and a body in one step counts as a
teammate collision)."""


def chaser_outcome(missions: Any, row: int) -> str:
    """The outcome (:data:`CHASER_OUTCOMES`) of row ``row`` of a swarm's missions at the end of
    an episode."""
    if missions.teammate_collision[row]:
        return "teammate_collision"
    if missions.collision[row]:
        return "debris_collision"
    if missions.out_of_bounds[row]:
        return "out_of_bounds"
    if missions.budget_spent[row]:
        return "delta_v_budget"
    if missions.success[row]:
        return "success"
    return "time_limit"


@dataclass(frozen=True)
class TeamEpisode:
    """One team's episode (SI units; per-chaser tuples in chaser order).

    Attributes:
        agent: the team's label.
        episode: the episode's index; ``seed`` its reset seed.
        field_hash: fingerprint of the field flown (every team meets the same one).
        team_success: every target captured and every chaser that did not fail home.
        team_captures: targets the team captured, of ``n_targets``.
        outcomes: each chaser's outcome (:data:`CHASER_OUTCOMES`).
        captures: the targets each chaser captured (its own).
        delta_v: Δv each chaser spent (m/s).
        end_time: when each chaser's mission ended (s).
        min_separation: the closest two chasers came (m, centre to centre).
        steps: steps until the last chaser ended; ``time`` the same in s.
        assignment: the team's rule; ``targets`` each chaser's targets.
        cost, longest: its total and longest tour (m, :mod:`~agents.planners.team_assignment`).
        optimal_cost: the least total on this field (the ``optimal`` rule), m.
        minmax_longest: the least longest tour on this field (the ``minmax`` rule), m.
        decision_ms: team decision time per chaser deciding, one per step (ms).
        wall_s: the episode's wall-clock time, both resets included (s).
        exploration: what the team explored before the first step, when it does
            (``team.last_exploration`` as a dict: :class:`~agents.policies.ma_se_scp.
            ExplorationRecord`); None otherwise.
        shield: each chaser's safety-shield counters, when the team flew shielded
            (:class:`~agents.policies.shielded.ShieldStats`: decisions filtered, commands
            replaced, their total and largest size ‖u_safe − u_cmd‖ / max_accel); empty
            otherwise.
    """

    agent: str
    episode: int
    seed: int
    field_hash: str
    n_targets: int
    team_success: bool
    team_captures: int
    outcomes: tuple[str, ...]
    captures: tuple[int, ...]
    delta_v: tuple[float, ...]
    end_time: tuple[float, ...]
    min_separation: float
    steps: int
    time: float
    assignment: str
    targets: tuple[tuple[int, ...], ...]
    cost: float
    longest: float
    optimal_cost: float
    minmax_longest: float
    decision_ms: tuple[float, ...] = field(repr=False, default=())
    wall_s: float = 0.0
    exploration: dict[str, Any] | None = None
    shield: tuple[ShieldStats, ...] = ()

    @property
    def n_chasers(self) -> int:
        """K."""
        return len(self.outcomes)

    def count(self, outcome: str) -> int:
        """Chasers whose mission ended with ``outcome``."""
        return sum(o == outcome for o in self.outcomes)

    @property
    def collisions(self) -> int:
        """Chasers that collided (with debris or a teammate)."""
        return self.count("debris_collision") + self.count("teammate_collision")

    @property
    def clean_success(self) -> bool:
        """Team success with no chaser colliding (the env's team success forgives a chaser
        that collides once every target is captured)."""
        return self.team_success and self.collisions == 0

    @property
    def shield_interventions(self) -> int:
        """Commands the shields replaced, over the chasers (0 unshielded)."""
        return sum(s.interventions for s in self.shield)

    @property
    def shield_decisions(self) -> int:
        """Commands the shields filtered, over the chasers (0 unshielded)."""
        return sum(s.decisions for s in self.shield)

    @property
    def shield_size_mean(self) -> float:
        """Mean size of the replaced commands, over the chasers (0 without any)."""
        count = self.shield_interventions
        return sum(s.size_sum for s in self.shield) / count if count else 0.0

    @property
    def shield_size_max(self) -> float:
        """Largest size of a replaced command (0 without any)."""
        return max((s.size_max for s in self.shield), default=0.0)

    @property
    def gap(self) -> float:
        """Total tour cost above the optimum (m)."""
        return self.cost - self.optimal_cost

    @property
    def gap_pct(self) -> float:
        """:attr:`gap` as a percentage of the optimum (0 when the optimum is 0)."""
        return 100.0 * self.gap / self.optimal_cost if self.optimal_cost > 0 else 0.0


def field_assignments(views: Any) -> dict[str, TeamAssignment]:
    """Every rule's assignment (:data:`~agents.planners.team_assignment.ASSIGNMENT_RULES`) on
    the field the views' swarm holds now."""
    team = team_field(list(views))
    tours = None if team.one_each else tour_costs(team)
    return {rule: assign(rule, team, tours) for rule in ASSIGNMENT_RULES}


def _exploration(team: Any) -> dict[str, Any] | None:
    record = getattr(team, "last_exploration", None)
    return None if record is None else dataclasses.asdict(record)


def _shield_stats(team: Any) -> tuple[ShieldStats, ...]:
    """Copies of the team's per-chaser shield counters (none unshielded)."""
    return tuple(dataclasses.replace(s) for s in getattr(team, "shield_stats", ()))


def fly_episode(
    env: Any,
    team: TeamPolicy,
    views: Any,
    seed: int,
    episode: int,
    label: str,
    frames: EpisodeFrames | None = None,
    scenario: Any = None,
) -> tuple[TeamEpisode, dict[str, TeamAssignment]]:
    """Fly one episode of ``team`` on ``env`` from ``seed``.

    Args:
        env: the swarm env the team was built for.
        team: the team policy.
        views: the team's chaser views (:class:`~agents.policies.chaser_view.ChaserView`), to
            read the field.
        seed: the reset seed; ``episode`` the episode's index; ``label`` the team's label.
        frames: records the episode's frames (an env made with ``render_mode="rgb_array"``);
            None: nothing drawn.
        scenario: the field to pin (a frozen suite's mission); None: the one ``seed`` draws.

    Returns:
        the record, and every rule's assignment on the episode's field.
    """
    began = time.perf_counter()
    observations, _, chosen = start_episode(env, team, seed, scenario)
    rules = field_assignments(views)
    scenario = views[0].scenario
    if scenario is None:
        raise RuntimeError(f"the swarm has no field after reset(seed={seed})")
    core = env.core
    decision_ms: list[float] = []
    steps = 0
    clock = time.perf_counter
    if frames is not None:
        frames.after(env)
    while env.agents:
        flying = {a: observations[a] for a in env.agents}
        start = clock()
        actions = team.predict(flying)
        decision_ms.append(1000.0 * (clock() - start) / len(flying))
        observations, _, _, _, _ = env.step(actions)
        steps += 1
        if frames is not None:
            frames.after(env)
    if frames is not None:
        frames.finish(env)
    m = core.shell.batch_in_use.missions
    rows = range(core.chasers)
    own = m.captured & m.assigned
    record = TeamEpisode(
        agent=label,
        episode=episode,
        seed=seed,
        # the swarm's field, not a view's: a view's dock is its chaser's slot, which the
        # assignment chooses in a reconfiguration
        field_hash=scenario_fingerprint(core.shell.scenario(0)),
        n_targets=int(m.captured.shape[1]),
        team_success=bool(core.team_success()[0]),
        team_captures=int(core.team_captures()[0]),
        outcomes=tuple(chaser_outcome(m, r) for r in rows),
        captures=tuple(int(np.count_nonzero(own[r])) for r in rows),
        delta_v=tuple(float(m.delta_v[r]) for r in rows),
        end_time=tuple(float(m.time[r]) for r in rows),
        min_separation=float(core.min_separation()[0]),
        steps=steps,
        time=float(np.max(m.time[: core.chasers])),
        assignment=chosen.rule,
        targets=tuple(tuple(t) for t in chosen.targets()),
        cost=chosen.cost,
        longest=chosen.longest,
        optimal_cost=rules["optimal"].cost,
        minmax_longest=rules["minmax"].longest,
        decision_ms=tuple(decision_ms),
        wall_s=time.perf_counter() - began,
        exploration=_exploration(team),
        shield=_shield_stats(team),
    )
    return record, rules
