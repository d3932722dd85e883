"""The "ma-se-scp" team: Multi-Agent SE–SCP ([Bandyopadhyay17] Algorithm 1) on a swarm.

Each chaser is a :class:`SwarmMember`: the single-agent "se-scp" machinery
(:class:`~agents.policies.se_scp.SESCPAgent`: a chain of spheres, the trajectory programme of
:func:`~agents.planners.scp.scp_trajectory`, tracked by the shared MPC) with what the paper's
swarm adds:

* **exploration before the first step** (lines 1–38): on a frozen field (the paper's stationary
  obstacles) the team grows every chaser's graph with node sharing
  (:class:`~agents.planners.swarm_expansion.SwarmGraphs`) from the chasers' positions to every
  chaser's final goal (its own dock slot, which the swarm envs name ``batch.dock[row]``) until
  every graph connects its start to every goal, and records the iterations; the same
  exploration without node sharing, from the same seed, is run beside it for the measurement
  only (:attr:`MASESCPTeam.last_exploration`);
* **teammates as spheres** (lines 8–16): every plan sees the other chasers' current positions
  as spheres of radius r_col + r_max; a chain toward the final goal is the Dijkstra path in the
  chaser's own graph (lines 40–45), which keeps growing by one sample per chaser and decision
  (the paper's expansion step runs every iteration) and keeps sharing;
* **re-plan every** ``replan_every`` **decisions** (lines 45–52; 1 = the paper's every step),
  each time from the chaser's state, with a fresh time allocation;
* targets (the capture missions ``DebrisGym/Swarm2D-v0`` …, where the chasers have targets
  before their slots) and every goal in a moving field are planned as "se-scp" plans them — a
  spherical expansion grown for that plan — with the teammates' spheres added to the bodies:
  the shared graph was grown on the field at t = 0 and holds only while the bodies stand still.

The targets are shared out among the chasers by the ``rule`` of
:mod:`agents.planners.team_assignment`, as a team of single agents
does (:class:`~agents.policies.team.TeamOfSingles`); the default is the envs' balanced rule
(at most ⌈T / K⌉ targets each): the total-cost optimum often sends one chaser to every target.

r_max, "the maximum distance an agent travels in one time instant", is by default the
distance the programme's cruise speed covers between two plans: :data:`CRUISE_SPEED` × the env
step × ``replan_every``, 4 m in the v2 world, so the teammate spheres (r_col + r_max = 6 m) are
half the Reconfigure IDs' 12 m slot pitch and every start and slot keeps a free sphere as wide.
The paper asks every two starts and every two goals to be r_col + r_max apart (its eq. 1–2);
the capture missions' dock lattice is tighter (5 m), so a teammate already closer than
r_col + r_max to the chaser, or to the chaser's goal, is a sphere reaching to ``min_radius``
short of it: the chaser may move away, not closer, and can still reach its goal. The
programme's speed is not capped: r_max is the plan's cruise, not a hard bound, and the MPC
tracker may fly faster for a while. Uniform samples in a large field rarely fall near a start
hemmed in by its neighbours' spheres: a stranded chaser draws half its samples near its start,
its unreached slots or, in flight, its position and slot (``local_bias``,
:class:`~agents.planners.swarm_expansion.SwarmParams`). A chaser that has arrived stands
still: its sphere is r_col and the bodies' keep-out (``parked_radius``), so the slots inside
a formation stay reachable. In flight a graph chain that detours, or none, is weighed against
a spherical expansion grown from the chaser (``detour``, ``stranded_expansion``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.planners.mission import Goal
from agents.planners.scp import SCPParams
from agents.planners.spherical_expansion import ExpansionParams, SphereChain, thin_chain
from agents.planners.swarm_expansion import SwarmGraphs, SwarmParams
from agents.planners.swarm_exploration import Exploration, explore
from agents.planners.team_assignment import TeamAssignment, assign, assign_goals
from agents.policies.chaser_view import ChaserView
from agents.policies.se_scp import SESCPAgent
from agents.policies.shield import ShieldParams
from agents.policies.shielded import ShieldStats, TeamShield
from agents.policies.team import check_team_env, team_field

__all__ = [
    "CRUISE_SPEED",
    "DETOUR",
    "FLIGHT_POOL",
    "ExplorationRecord",
    "MASESCPTeam",
    "SwarmMember",
    "TeammateSpheres",
]

CRUISE_SPEED = 0.4
"""The programme's cruise speed (m/s) in a team: at the v2 world's 10 s step it makes
r_max = 4 m, so the teammate spheres (r_col + r_max = 6 m at r_col = 2 m) are half the
Reconfigure IDs' 12 m slot pitch and every start and goal keeps a free sphere as wide."""


DETOUR = 1.2
"""The graph chain's cost, over the straight distance to the slot, past which a chaser also
grows a chain of its own and flies the cheaper. The shortest chains of a swarm that left its
starts in a crowd share the few exits the exploration found from it (the pool was grown while
every teammate sphere stood at its start), and the chasers queue there; a chain grown from the
chaser among its teammates' current spheres leaves straight between them."""

FLIGHT_POOL = 5000
"""Pool size (nodes) up to which every flying chaser keeps sampling, as the paper's expansion
step does at every iteration; past it only the stranded chasers (no chain to their slot) do.
The samples of the flight make the chains of a small pool shorter (six chasers explore about
200 nodes and fly on about 1 500), but every node costs every later search of every chaser,
and the candidate edges grow with the square of the pool: 48 chasers explore about 3 000 and
would add 48 a step."""


class TeammateSpheres:
    """A field's geometry with extra spheres (the teammates), for
    :func:`~agents.planners.spherical_expansion.node_radii`: the bodies' signed distances, then
    one column per sphere, |p − c| − radius (m).

    Args:
        base: the field's geometry (``dim``, ``n_bodies``, ``signed_distance``).
        centers: (P, dim) sphere centres (m).
        radii: (P,) the spheres' radii (m).
    """

    def __init__(self, base: Any, centers: np.ndarray, radii: np.ndarray) -> None:
        self.base = base
        self.dim = base.dim
        self.centers = np.asarray(centers, dtype=float).reshape(-1, base.dim)
        self.radii = np.asarray(radii, dtype=float).reshape(len(self.centers))
        self.n_bodies = base.n_bodies + len(self.centers)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(M, n_bodies) signed distance (m) of each point to each body, then each sphere."""
        pts = np.asarray(points, dtype=float).reshape(-1, self.dim)
        mates = np.linalg.norm(pts[:, None] - self.centers[None], axis=-1) - self.radii[None]
        return np.hstack([self.base.signed_distance(pts), mates])


@dataclass(frozen=True)
class ExplorationRecord:
    """The exploration before an episode's first step (the paper's Fig. 4 and 7 measurement).

    Attributes:
        agents: N, the chasers.
        iterations_shared: iterations until every graph connected its start to every goal,
            with node sharing (the cap when ``connected_shared`` is False); None when not run.
        connected_shared: whether that happened within the cap.
        iterations_alone, connected_alone: the same without node sharing (same seed); None
            when not run.
        nodes_shared, nodes_alone: (N,) nodes per agent's graph at the end.
        r_col, r_max: the teammate spheres' parts (m).
        wall_s: wall-clock time of both explorations (s).
    """

    agents: int
    iterations_shared: int | None
    connected_shared: bool | None
    iterations_alone: int | None
    connected_alone: bool | None
    nodes_shared: tuple[int, ...] | None
    nodes_alone: tuple[int, ...] | None
    r_col: float
    r_max: float
    wall_s: float


class SwarmMember(SESCPAgent):
    """One chaser of a :class:`MASESCPTeam`: "se-scp" with the teammates as spheres, the
    team's graph toward its final goal, and a re-plan every ``team.replan_every`` decisions.

    Args:
        view: the chaser's :class:`~agents.policies.chaser_view.ChaserView`.
        team: the team (its graphs, the teammates' positions, r_col + r_max).
        **params: :class:`~agents.policies.se_scp.SESCPAgent` parameters.
    """

    name = "ma-se-scp"
    keep_arrival = False
    programme_substeps = 6
    replans_frozen_field = True

    def __init__(self, view: ChaserView, team: MASESCPTeam, **params: Any) -> None:
        super().__init__(view, **params)
        self.team = team
        self.index = view.chaser

    def plan_expired(self, now: float) -> bool:
        """Every ``team.replan_every`` decisions (the paper: every step); in a moving field
        also when "se-scp" would (the plan meets a body)."""
        if self._since_plan >= self.team.replan_every:
            return True
        return self.motion is not None and super().plan_expired(now)

    def sphere_chain(
        self,
        start: np.ndarray,
        goal: Goal,
        geometry: Any,
        margins: np.ndarray,
        low: np.ndarray,
        high: np.ndarray,
        start_radius: float,
        goal_radius: float,
    ) -> tuple[SphereChain, int]:
        """Toward the final goal on a frozen field: the path in the chaser's own graph from its
        position (lines 40–45), or the chain of a spherical expansion for this plan from the
        chaser among the bodies and the teammates' spheres where that is cheaper and the
        graph's detours (``team.detour``); otherwise, or when that graph holds no path and
        ``team.stranded_expansion`` is set, the expansion's chain alone. Still no path: on a
        frozen field a one-sphere chain at the chaser (stop and wait for the teammates to move;
        the next decision re-plans); on a moving field the "se-scp" chain among the bodies
        alone. With ``team.thin_chains`` the chain flown skips the spheres it can."""
        team, floor = self.team, self.expansion_params.min_radius
        mates = team.teammates(self.index)
        rho = team.teammate_radii(self.index)
        # a teammate already closer than r_col + r_max to the chaser or its goal reaches to
        # ``floor`` short of it
        near = np.minimum(
            np.linalg.norm(mates - start, axis=1), np.linalg.norm(mates - goal.point, axis=1)
        )
        radii = np.clip(np.minimum(rho, near - floor), 0.0, None)
        if len(mates):
            gap = float(np.min(np.linalg.norm(mates - start, axis=1) - radii))
            start_radius = max(min(start_radius, gap), floor)
            goal_gap = float(np.min(np.linalg.norm(mates - goal.point, axis=1) - radii))
            goal_radius = max(min(goal_radius, goal_gap), floor)
        spheres = TeammateSpheres(geometry, mates, radii)
        spheres_margins = np.concatenate([margins, np.zeros(len(mates))])
        chain = None
        if goal.kind == "dock" and team.graphs is not None:
            assert team.graphs.assigned is not None
            slot = int(team.graphs.assigned[self.index])
            chain, nodes = team.graphs.chain_to(self.index, slot, floor)
            straight = float(np.linalg.norm(goal.point - start))
            if (
                chain.success
                and team.detour is not None
                and team.params is not None
                and chain.cost > team.detour * straight + 4.0 * team.params.teammate_radius
            ):
                # the graph's shortest chains from a crowd share its few exits: a chain grown
                # from the chaser may go straight out between its neighbours
                own, own_nodes = super().sphere_chain(
                    start, goal, spheres, spheres_margins, low, high, start_radius, goal_radius
                )
                self.stats["detours"] = self.stats.get("detours", 0) + 1
                if own.success and own.cost < chain.cost:
                    self.stats["detours_replaced"] = self.stats.get("detours_replaced", 0) + 1
                    chain, nodes = own, own_nodes
            if not chain.success and team.stranded_expansion:
                # amid a crowd of teammates the graph's nodes are cut by their spheres while
                # free space is left between them: grow a tree from where the chaser is
                self.stats["own_expansions"] = self.stats.get("own_expansions", 0) + 1
                chain = None
        if chain is None:
            chain, nodes = super().sphere_chain(
                start, goal, spheres, spheres_margins, low, high, start_radius, goal_radius
            )
        if not chain.success and self.motion is not None:
            # a moving field: a chain held in the goal's frame would drift with the goal; fly
            # the "se-scp" chain among the bodies alone, the teammates left to the re-plans
            self.stats["teammate_fallbacks"] = self.stats.get("teammate_fallbacks", 0) + 1
            return super().sphere_chain(
                start, goal, geometry, margins, low, high, start_radius, goal_radius
            )
        if not chain.success:
            self.stats["holds"] = self.stats.get("holds", 0) + 1
            d = len(start)
            chain = SphereChain(
                True, np.zeros(1, dtype=np.int64), np.asarray(start, float).reshape(1, d),
                np.array([start_radius]), 0.0,
            )  # fmt: skip
        if team.thin_chains:
            chain = thin_chain(chain, self.expansion_params)
        return chain, nodes


class MASESCPTeam:
    """Multi-Agent SE–SCP on a swarm env made with ``assignment="given"`` (a
    :class:`~agents.policies.team.TeamPolicy`).

    Args:
        env: the swarm env (:class:`~debris_gym.swarm.parallel.SwarmParallelEnv`).
        rule: the target assignment rule (one of
            :data:`~agents.planners.team_assignment.ASSIGNMENT_RULES`).
        replan_every: decisions between two plans of a chaser (≥ 1; 1: the paper).
        r_max: farthest a chaser travels between two plans (m); None: the programme's cruise
            speed times ``replan_every`` env steps.
        share_nodes: share new nodes (the paper); False flies with each chaser's own graph.
        max_iterations: cap on the exploration's iterations.
        local_bias: probability that a stranded chaser's sample is local
            (:class:`~agents.planners.swarm_expansion.SwarmParams`).
        flight_pool: in flight every chaser draws a sample at each decision (the paper: the
            expansion step runs every iteration) while the pool holds fewer nodes than this;
            past it only the chasers whose last chain found no path do (:data:`FLIGHT_POOL`);
            None: every chaser, always.
        stranded_expansion: when a chaser's graph holds no chain from its position to its
            slot, plan with a spherical expansion grown for this plan from its position among
            the bodies and the teammates' spheres (as "se-scp" does); False: hold and wait.
        detour: when the graph's chain costs more than this times the straight distance to
            the slot (plus 4 (r_col + r_max)), a spherical expansion for this plan is grown too
            and the cheaper chain flown (:data:`DETOUR`); None: the graph's chain always.
        thin_chains: fly every chain with the spheres it can skip left out
            (:func:`~agents.planners.spherical_expansion.thin_chain`); False: as found.
        measure_alone: also run the exploration without sharing, for the record.
        seed: seed of every sampler (chaser k's own expansions: ``seed + k``).
        expansion: spherical-expansion tunables (``min_radius`` and the edge rule are used
            by the team's graph too); None: the "se-scp" defaults.
        scp: trajectory-programme tunables; None: the "se-scp" defaults (soft spheres).
        shield: the safety shield's parameters, to filter every chaser's commands through a
            shield of its own on its view that counts the teammates as bodies
            (:class:`~agents.policies.shielded.TeamShield`; the members share no plans, so it
            predicts them coasting); None: no shield.
        **params: further :class:`~agents.policies.se_scp.SESCPAgent` parameters.

    Raises:
        ValueError: a bad parameter, or a swarm not made with ``assignment="given"``.
    """

    name = "ma-se-scp"

    def __init__(
        self,
        env: Any,
        rule: str = "balanced",
        *,
        replan_every: int = 1,
        r_max: float | None = None,
        share_nodes: bool = True,
        max_iterations: int = 300,
        local_bias: float = 0.5,
        flight_pool: int | None = FLIGHT_POOL,
        stranded_expansion: bool = True,
        detour: float | None = DETOUR,
        thin_chains: bool = True,
        measure_alone: bool = True,
        seed: int = 0,
        expansion: ExpansionParams | None = None,
        scp: SCPParams | None = None,
        shield: ShieldParams | None = None,
        **params: Any,
    ) -> None:
        core = check_team_env(env, rule, "ma-se-scp assigns the targets itself")
        if isinstance(replan_every, bool) or not (
            isinstance(replan_every, int) and replan_every >= 1
        ):
            raise ValueError(f"replan_every must be an integer >= 1, got {replan_every!r}")
        if r_max is not None and not (math.isfinite(r_max) and r_max >= 0):
            raise ValueError(f"r_max must be finite and >= 0 m or None, got {r_max!r}")
        if not (isinstance(seed, int) and seed >= 0):
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        if isinstance(local_bias, bool) or not (
            isinstance(local_bias, (int, float)) and 0.0 <= local_bias <= 1.0
        ):
            raise ValueError(f"local_bias must be in [0, 1], got {local_bias!r}")
        if flight_pool is not None and (
            isinstance(flight_pool, bool) or not (isinstance(flight_pool, int) and flight_pool >= 0)
        ):
            raise ValueError(f"flight_pool must be an integer >= 0 or None, got {flight_pool!r}")
        self.flight_pool = flight_pool
        self.stranded_expansion = bool(stranded_expansion)
        if detour is not None and (
            isinstance(detour, bool)
            or not (isinstance(detour, (int, float)) and math.isfinite(detour) and detour >= 1.0)
        ):
            raise ValueError(f"detour must be finite and >= 1 or None, got {detour!r}")
        self.detour = None if detour is None else float(detour)
        self.thin_chains = bool(thin_chains)
        self.env, self.rule = env, rule
        self.replan_every, self.r_max = replan_every, r_max
        self.share_nodes, self.max_iterations = bool(share_nodes), int(max_iterations)
        self.local_bias = local_bias
        self.measure_alone, self.seed = bool(measure_alone), seed
        self.agents: list[str] = list(env.possible_agents)
        self._index = {a: k for k, a in enumerate(self.agents)}
        self.views = [ChaserView(core, k) for k in range(core.chasers)]
        self.scp_base = scp or SCPParams(sphere_penalty=100.0, cruise_speed=CRUISE_SPEED)
        self.members = [
            SwarmMember(view, self, expansion=expansion, scp=self.scp_base, seed=seed + k, **params)
            for k, view in enumerate(self.views)
        ]
        self.shield = None if shield is None else TeamShield(self.views, shield)
        """The chasers' shields (None: unshielded)."""
        self.params: SwarmParams | None = None
        self.graphs: SwarmGraphs | None = None
        self.last_exploration: ExplorationRecord | None = None
        """The exploration before the last episode's first step (None on a moving field)."""
        self._episode: tuple[int, float] | None = None
        self._prepared: (
            tuple[np.ndarray, np.ndarray, SwarmGraphs, ExplorationRecord | None] | None
        ) = None
        self._rng = np.random.default_rng(seed)

    # --- the TeamPolicy protocol -------------------------------------------------------------

    def choose_assignment(self) -> TeamAssignment:
        """The assignment on the field the swarm holds now. A reconfiguration on a frozen
        field under a least-total rule (``balanced``, ``optimal``): the exploration runs here
        and the slots go by the optimal assignment of its graph path costs
        (:func:`~agents.planners.team_assignment.assign_goals`; its cost is still reported on
        the straight legs, as the other teams'); otherwise the rule's own assignment."""
        field = team_field(self.views)
        scenario = self.views[0].scenario
        if scenario is None:
            raise RuntimeError("reset the swarm before choosing an assignment")
        self._prepared = None
        if not field.one_each or self.rule not in ("balanced", "optimal") or scenario.moving:
            return assign(self.rule, field)
        self._setup(scenario)
        graphs, record = self._explore(scenario, field.docks, field.centers)
        if graphs is None:
            return assign(self.rule, field)
        costs = np.array([graphs.path_costs(k) for k in range(field.n_chasers)])
        order, total = assign_goals(costs)
        if not math.isfinite(total):  # some chaser reaches no free slot yet: the straight legs
            return assign(self.rule, field)
        graphs.assigned = order
        self._prepared = (field.docks.copy(), field.centers[order].copy(), graphs, record)
        k = field.n_chasers
        table = np.zeros((k, k), dtype=bool)
        table[np.arange(k), order] = True
        legs = field.dock_legs()[np.arange(k), order]
        return TeamAssignment(self.rule, table, float(legs.sum()), legs)

    def predict(
        self, observations: dict[str, np.ndarray], deterministic: bool = True
    ) -> dict[str, np.ndarray]:
        """One action per agent of ``observations`` still flying; the first call of an
        episode runs the exploration first.

        Raises:
            ValueError: an unknown agent name.
        """
        unknown = sorted(set(observations) - set(self._index))
        if unknown:
            raise ValueError(f"unknown agents {unknown}; the team flies {self.agents}")
        view = self.views[0]
        scenario = view.scenario
        if scenario is None:
            raise RuntimeError("reset the swarm before calling predict()")
        key = (id(scenario), view.elapsed)
        if self._episode is None or (view.elapsed == 0.0 and key != self._episode):
            self._start(scenario)
        self._episode = key
        names = [a for a in observations if self.views[self._index[a]].flying]
        if self.graphs is not None:
            present = self.present()
            self.graphs.move(self.positions(), present, present & ~self.flying())
            flying = np.array([self._index[a] for a in names], dtype=np.int64)
            if self.flight_pool is not None and self.graphs.n_nodes >= self.flight_pool:
                flying = flying[self.graphs.stranded[flying]]
            self.graphs.iterate(self._rng, flying)
        actions = {
            self._index[a]: np.asarray(self.members[self._index[a]].predict(observations[a])[0])
            for a in names
        }
        if self.shield is not None:
            actions = self.shield.filter(actions)
        return {self.agents[k]: np.asarray(action) for k, action in actions.items()}

    @property
    def shield_stats(self) -> list[ShieldStats]:
        """Each chaser's shield counters this episode (empty without a shield)."""
        return [] if self.shield is None else self.shield.stats

    # --- what the members read ----------------------------------------------------------------

    @staticmethod
    def _dock(view: ChaserView) -> tuple[float, ...]:
        """The chaser's dock slot (its goal at the end) of the field the view holds."""
        scenario = view.scenario
        if scenario is None:
            raise RuntimeError("reset the swarm before flying it")
        return scenario.dock

    def positions(self) -> np.ndarray:
        """(N, dim) every chaser's position now (m)."""
        return np.array([v.chaser_state[: v.dim] for v in self.views])

    def present(self) -> np.ndarray:
        """(N,) the chasers still in the field: flying, or ended at their goal."""
        m = self.env.core.shell.batch_in_use.missions
        rows = [v.row for v in self.views]
        return self.flying() | np.asarray(m.success)[rows]

    def flying(self) -> np.ndarray:
        """(N,) the chasers still flying."""
        return np.array([v.flying for v in self.views])

    def teammates(self, k: int) -> np.ndarray:
        """(P, dim) the positions (m) of the chasers other than ``k`` still in the field."""
        mask = self.present()
        mask[k] = False
        return self.positions()[mask]

    def teammate_radii(self, k: int) -> np.ndarray:
        """(P,) the sphere radius (m) of each of :meth:`teammates`: r_col + r_max, or the
        ``parked_radius`` of one that has arrived (none before an episode's setup)."""
        mask = self.present()
        mask[k] = False
        if self.params is None:
            return np.zeros(int(mask.sum()))
        return self.params.sphere_radii(~self.flying())[mask]

    # --- the exploration ----------------------------------------------------------------------

    def _setup(self, scenario: Any) -> None:
        """r_max and the teammate spheres for an episode on ``scenario``."""
        cfg = self.views[0].config
        core = self.env.core
        r_col = float(core.swarm.r_col if core.swarm.r_col is not None else 2 * cfg.chaser_radius)
        # r_max: one env step at the programme's cruise speed (the paper: the farthest an
        # agent travels in one time instant), times the steps between two plans
        r_max = self.r_max
        if r_max is None:
            r_max = self.scp_base.cruise_speed * scenario.dt * self.replan_every
        ex = dataclasses.replace(self.members[0].expansion_params, goal_bias=0.0, max_nodes=20_000)
        # a chaser that has arrived stands still (r_max = 0): kept out of as the debris are,
        # by r_col and the keep-out "se-scp" gives its spheres (0.2 % of the field by default)
        member0 = self.members[0]
        margin = member0.margin if member0.margin is not None else 0.002 * scenario.size
        self.params = SwarmParams(
            r_col, r_max, self.share_nodes, self.max_iterations, ex, local_bias=self.local_bias,
            parked_radius=r_col + margin,
        )  # fmt: skip

    def _explore(
        self, scenario: Any, starts: np.ndarray, goals: np.ndarray
    ) -> tuple[SwarmGraphs | None, ExplorationRecord | None]:
        """The exploration from ``starts`` to ``goals`` (with sharing and, for the record,
        without), or nothing where the shared graph would not hold (a moving field) or a
        chaser's goal is its start (the capture missions' dock slots)."""
        assert self.params is not None
        away = np.linalg.norm(goals[: len(starts)] - starts, axis=1).min()
        if scenario.moving or away <= self.params.teammate_radius:
            return None, None
        began = time.perf_counter()
        cfg, member0 = self.views[0].config, self.members[0]
        # the keep-out "se-scp" gives its spheres: the MPC tracker's default, 0.2 % of the field
        margin = member0.margin if member0.margin is not None else 0.002 * scenario.size
        geometry = self.views[0].geometry
        margins = np.full(geometry.n_bodies, cfg.chaser_radius + margin)
        low, high = np.array(scenario.low, float), np.array(scenario.high, float)
        runs: dict[bool, Exploration] = {}
        for share in (True, False) if self.measure_alone else (self.share_nodes,):
            p = dataclasses.replace(self.params, share_nodes=share)
            rng = np.random.default_rng(self.seed)
            runs[share] = explore(geometry, starts, goals, margins, rng, p, low=low, high=high)
        shared, alone = runs.get(True), runs.get(False)
        record = ExplorationRecord(
            agents=len(starts),
            iterations_shared=None if shared is None else shared.iterations,
            connected_shared=None if shared is None else shared.connected,
            iterations_alone=None if alone is None else alone.iterations,
            connected_alone=None if alone is None else alone.connected,
            nodes_shared=None if shared is None else tuple(map(int, shared.nodes_per_agent)),
            nodes_alone=None if alone is None else tuple(map(int, alone.nodes_per_agent)),
            r_col=self.params.r_col,
            r_max=float(self.params.r_max),
            wall_s=time.perf_counter() - began,
        )
        return runs[self.share_nodes].graphs, record

    def _start(self, scenario: Any) -> None:
        """A new episode: r_max, the teammate spheres and (frozen field) the graphs, reused
        from :meth:`choose_assignment` when it explored this field."""
        self._rng = np.random.default_rng(self.seed)
        starts = self.positions()
        goals = np.array([self._dock(v) for v in self.views], dtype=float)
        prepared, self._prepared = self._prepared, None
        if (
            prepared is not None
            and np.allclose(prepared[0], starts)
            and np.allclose(prepared[1], goals)
        ):
            self.graphs, self.last_exploration = prepared[2], prepared[3]
            return
        self._setup(scenario)
        self.graphs, self.last_exploration = self._explore(scenario, starts, goals)
        if self.graphs is not None:
            self.graphs.assigned = np.arange(len(starts))  # each chaser's goal: its own slot

    def __repr__(self) -> str:
        return f"MASESCPTeam(rule={self.rule!r}, replan_every={self.replan_every})"
