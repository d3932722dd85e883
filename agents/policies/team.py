"""Team policies: one decision for every chaser of a swarm, behind an assignment of the targets.

A team policy answers the swarm's PettingZoo protocol::

    actions = team.predict(observations)   # {agent: observation} -> {agent: action}

for the agents still flying (``env.agents``; observations of the others are ignored), and
says, before an episode, which chaser captures which target
(:meth:`TeamOfSingles.choose_assignment`, on the field just drawn): the swarm must be made
with ``assignment="given"`` and reset with that assignment (the reset option ``assignment``;
:func:`start_episode` does both resets).

:class:`TeamOfSingles` flies one single-agent policy per chaser:

* a classical baseline (:data:`agents.BASELINES`) built on each chaser's
  :class:`~agents.policies.chaser_view.ChaserView`, so it sees the field, its own dock slot and
  its own targets (the others' read as captured; they stay bodies to avoid), and, if it reads
  them (the MPC trackers: APF-MPC, A*, SE-SCP), its teammates as spheres on their predicted
  tracks: the members decide in chaser order and share their plans
  (:class:`~agents.policies.chaser_view.TeamPlans`), so each one predicts the teammates that
  decided before it in this step by their new plans and the others by their plans of the
  step before, flown on from where they are now;
* a learned single-agent policy (``"pretrained"``, the v2 policy shipped for a swarm's
  world (:data:`SWARM_PRETRAINED`), or ``"ALGO:PATH"``), given the single-agent part of each
  chaser's swarm observation (its first elements, when the swarm is made with the policy's
  observation options: :func:`team_options`), all chasers in one batch.
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from agents.planners.team_assignment import (
    ASSIGNMENT_RULES,
    TeamAssignment,
    TeamField,
    assign,
)
from agents.policies.base import unwrap
from agents.policies.chaser_view import ChaserView, TeamPlans
from agents.policies.learned import (
    LEARNED_ALGOS,
    OBSERVATION_KEYS,
    PRETRAINED,
    PRETRAINED_DIR,
    observation_options,
    trained_env_id,
)
from agents.policies.registry import BASELINES, load_agent, make_agent
from agents.policies.shield import ShieldParams
from agents.policies.shielded import ShieldStats, TeamShield
from debris_gym.swarm import SWARM_SPECS

__all__ = [
    "SWARM_PRETRAINED",
    "ChaserSpaces",
    "TeamOfSingles",
    "TeamPolicy",
    "check_team_env",
    "member_spec",
    "single_agent_id",
    "start_episode",
    "team_field",
    "team_options",
]


class TeamPolicy(Protocol):
    """What the swarm evaluation flies: a name, the chasers' views, an assignment per episode
    and a joint ``predict``."""

    name: str
    rule: str
    views: list[ChaserView]

    def choose_assignment(self) -> TeamAssignment:
        """The assignment for the field the env holds now (before its missions begin)."""

    def predict(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """One action per agent of ``observations`` (the agents still flying)."""


def single_agent_id(dim: int) -> str:
    """The single-agent ID whose world (v2) the swarm IDs fly, in ``dim`` dimensions: the ID
    a learned single-agent policy for a team is looked up and checked for."""
    return f"DebrisGym/Rendezvous{int(dim)}D-v2"


SWARM_PRETRAINED: dict[int, str] = {2: "rendezvous2d_v2.zip", 3: "rendezvous3d_v2.zip"}
"""Dimension → the shipped file (in :data:`~agents.policies.learned.PRETRAINED_DIR`) a team's
``"pretrained"`` member flies: the v2 policy that commands the thrust itself. The single-agent
v2 IDs' ``pretrained`` is a residual policy; the teams fly the swarm in its default action mode,
commanding the thrust as the classical members do."""


def member_spec(agent: str, dim: int) -> str:
    """The learned-policy spec a team member ``agent`` is loaded from: ``"pretrained"`` names
    the swarm's shipped policy (:data:`SWARM_PRETRAINED`), anything else is kept."""
    if agent.strip() != PRETRAINED:
        return agent
    return f"ppo:{PRETRAINED_DIR / SWARM_PRETRAINED[int(dim)]}"


def _is_learned(agent: str) -> bool:
    text = agent.strip().replace("=", ":")
    head, sep, _ = text.partition(":")
    return text == PRETRAINED or (bool(sep) and head.strip().lower() in LEARNED_ALGOS)


def team_options(agent: str, dim: int) -> dict[str, Any]:
    """The swarm options a team of ``agent`` needs: ``assignment="given"``, and for a learned
    policy the observation options it was trained with (so each chaser's observation starts
    with the single-agent layout it knows)."""
    options: dict[str, Any] = {"assignment": "given"}
    if _is_learned(agent):
        options.update(observation_options(member_spec(agent, dim), single_agent_id(dim)))
    return options


def check_team_env(env: Any, rule: str, why: str) -> Any:
    """The swarm core of ``env`` for a team flying behind the assignment ``rule`` (``why``
    begins the message when the swarm does not take given assignments).

    Raises:
        ValueError: an unknown rule, or a swarm not made with ``assignment="given"``.
    """
    if rule not in ASSIGNMENT_RULES:
        raise ValueError(f"unknown assignment rule {rule!r}; known: {', '.join(ASSIGNMENT_RULES)}")
    core = env.core
    if core.swarm.assignment != "given":
        raise ValueError(
            f"{why}: make the swarm with assignment='given' (it has "
            f"assignment={core.swarm.assignment!r})"
        )
    return core


def team_field(views: list[ChaserView]) -> TeamField:
    """What an assignment rule reads of the views' field, at t = 0: each chaser's dock slot,
    the targets' centres and radii, and whether the tours return (a reconfiguration: each
    chaser's start and the formation's slots, one each).

    Raises:
        RuntimeError: the swarm has not been reset.
    """
    scenarios = [v.scenario for v in views]
    if any(s is None for s in scenarios):
        raise RuntimeError("reset the swarm before choosing an assignment")
    core = views[0].core
    if core.formation is not None:  # a reconfiguration: from the starts to the formation slots
        batch = core.shell.batch_in_use
        starts = np.array([v.chaser_state[: v.dim] for v in views])
        slots = batch.field.centers[views[0].field, 0] + core.formation
        return TeamField(starts, slots, np.zeros(len(slots)), False, one_each=True)
    first = scenarios[0]
    assert first is not None
    docks = np.array([s.dock for s in scenarios if s is not None], dtype=float)
    centers = np.array([t.position for t in first.targets], dtype=float).reshape(-1, first.dim)
    radii = np.array([t.radius for t in first.targets], dtype=float)
    return TeamField(docks, centers, radii, bool(views[0].config.return_to_dock))


class ChaserSpaces:
    """One chaser's spaces and the swarm's config, as :func:`~agents.policies.learned.
    load_agent` reads an env: what a policy trained on the swarm itself is checked against."""

    def __init__(self, env: Any) -> None:
        agent = env.possible_agents[0]
        self.observation_space = env.observation_space(agent)
        self.action_space = env.action_space(agent)
        self.config = env.core.config
        self.spec = None


class TeamOfSingles:
    """One single-agent policy per chaser, behind an assignment rule.

    Args:
        env: the swarm env (a :class:`~debris_gym.swarm.parallel.SwarmParallelEnv` made with
            ``assignment="given"`` and :func:`team_options`).
        agent: a baseline name (:data:`agents.BASELINES`), ``"pretrained"`` or ``"ALGO:PATH"``.
        rule: the assignment rule (:data:`~agents.planners.team_assignment.ASSIGNMENT_RULES`).
        shield: the safety shield's parameters, to filter every member's commands (classical
            or learned) through a shield of its own on its chaser's view that counts the
            teammates as bodies (:class:`~agents.policies.shielded.TeamShield`), once every
            member has decided; None: no shield.
        **params: the baseline's constructor parameters (classical agents only).

    Raises:
        ValueError: an unknown agent or rule, a swarm not made with ``assignment="given"``, or
            (learned) a swarm observation that does not start with the policy's layout.
    """

    def __init__(
        self,
        env: Any,
        agent: str,
        rule: str = "balanced",
        shield: ShieldParams | None = None,
        **params: Any,
    ) -> None:
        core = check_team_env(env, rule, "a team of single agents flies behind an assignment")
        self.env, self.agent, self.rule = env, agent, rule
        self.name = f"team-{agent}@{rule}"
        self.agents: list[str] = list(env.possible_agents)
        self.plans = TeamPlans(core.chasers)
        """The plans the members share (posted after each decision)."""
        self.views = [ChaserView(core, k, plans=self.plans) for k in range(core.chasers)]
        self._index = {a: k for k, a in enumerate(self.agents)}
        self._members: list[Any] = []
        self._learned: Any = None
        self._size = 0
        if _is_learned(agent):
            if params:
                raise ValueError(f"a learned team member takes no parameters, got {sorted(params)}")
            self._learned, self._size = self._load(agent, env)
        elif agent in BASELINES:
            self._members = [make_agent(agent, view, **params) for view in self.views]
        else:
            raise ValueError(
                f"unknown team member {agent!r}; known: {', '.join(BASELINES)}, {PRETRAINED!r} "
                "or ALGO:PATH"
            )
        self.shield = None if shield is None else TeamShield(self.views, shield)
        """The members' shields (None: unshielded)."""

    @staticmethod
    def _load(agent: str, env: Any) -> tuple[Any, int]:
        """The learned policy and the size of the observation it reads: a single-agent policy,
        loaded for the single-agent ID of the swarm's world with the swarm's observation
        options and action mode, reads the first elements of each chaser's observation; a
        policy trained on the swarm itself (IPPO, ``train.py`` on a swarm ID) reads all of
        them."""
        config = env.core.config
        options = {k: getattr(config, k) for k in OBSERVATION_KEYS if k != "obs_teammates"}
        single = gym.make(single_agent_id(config.dim), **options, action=config.action)
        spec = member_spec(agent, config.dim)
        try:
            names = unwrap(single).observation_names()
            if env.observation_names()[: len(names)] != names:
                raise ValueError(
                    f"the swarm's observation does not start with the single-agent layout "
                    f"{agent!r} reads; make the swarm with team_options({agent!r}, "
                    f"{config.dim})"
                )
            if trained_env_id(spec) in SWARM_SPECS:
                chaser = ChaserSpaces(env)  # trained on a swarm: the whole chaser observation
                return load_agent(spec, chaser), int(chaser.observation_space.shape[0])
            return load_agent(spec, single), len(names)
        finally:
            single.close()

    @property
    def shield_stats(self) -> list[ShieldStats]:
        """Each chaser's shield counters this episode (empty without a shield)."""
        return [] if self.shield is None else self.shield.stats

    def choose_assignment(self) -> TeamAssignment:
        """The rule's assignment on the field the swarm holds now (after a reset, before the
        missions begin), with its cost (:func:`~agents.planners.team_assignment.assign`)."""
        return assign(self.rule, team_field(self.views))

    def predict(
        self, observations: dict[str, np.ndarray], deterministic: bool = True
    ) -> dict[str, np.ndarray]:
        """One action per agent of ``observations`` still flying (the observations ``step``
        returns for the agents it has just ended are ignored).

        Raises:
            ValueError: an unknown agent name.
        """
        unknown = sorted(set(observations) - set(self._index))
        if unknown:
            raise ValueError(f"unknown agents {unknown}; the team flies {self.agents}")
        names = [a for a in observations if self.views[self._index[a]].flying]
        actions: dict[int, Any] = {}
        if self._learned is not None:
            if names:
                batch = np.stack([np.asarray(observations[a])[: self._size] for a in names])
                chosen, _ = self._learned.predict(batch, deterministic=deterministic)
                actions = {self._index[a]: np.asarray(chosen[i]) for i, a in enumerate(names)}
        else:
            if names and self.views[self._index[names[0]]].elapsed == 0.0:
                self.plans.clear()  # an episode's first decisions: no plans of the last one
            for a in names:
                k = self._index[a]
                member = self._members[k]
                actions[k] = np.asarray(member.predict(observations[a])[0])
                planned = getattr(member, "planned_states", None)
                self.plans.post(k, planned() if callable(planned) else None)
        if self.shield is not None:
            # after every member has decided, so each shield predicts the teammates by their
            # plans of this step
            actions = self.shield.filter(actions)
        return {self.agents[k]: np.asarray(action) for k, action in actions.items()}

    def __repr__(self) -> str:
        return f"TeamOfSingles({self.agent!r}, rule={self.rule!r})"


def start_episode(
    env: Any, team: TeamPolicy, seed: int, scenario: Any = None
) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]], TeamAssignment]:
    """Reset ``env`` with ``seed``, let ``team`` choose its assignment on the field drawn, and
    reset again with the same seed and that assignment (the same field, the missions begun
    with it). ``scenario``: a field to pin in both resets (a frozen suite's mission) instead
    of the one the seed draws.

    Returns:
        the observations and infos of the second reset, and the assignment.

    Raises:
        ValueError: ``seed`` is not an integer (an unseeded reset would draw another field).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer (both resets draw the same field), got {seed!r}")
    pin = {} if scenario is None else {"scenario": scenario}
    env.reset(seed=seed, options=pin or None)
    chosen = team.choose_assignment()
    observations, infos = env.reset(seed=seed, options={**pin, "assignment": chosen.targets()})
    return observations, infos, chosen
