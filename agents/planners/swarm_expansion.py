"""Multi-agent spherical expansion: N agents' graphs grown together, shared nodes, teammates as
spheres, and the assignment of the goals on the graphs' path costs.

Reference: [Bandyopadhyay17] Algorithm 1 (keys refer to docs/references.md), the steps before
the trajectory programme. Agent i keeps a graph G^i = (V^i, E^i) of body-free spheres:

* initialisation (lines 1–5): V^i holds agent i's start and every goal X^j_goal;
* each iteration (lines 7–27), every agent in turn of the same round: the other agents' new
  nodes of the previous iteration join V^i (``AllAgentCommunicate``; the first iteration has
  none); the other agents' current positions Y^ℓ become spheres of radius r_col + r_max added
  to the bodies, so every node radius of V^i shrinks to its distance to them (lines 8–16; a
  teammate already closer than r_col + r_max — agents that start tighter than the paper's
  eq. 1 allows — is a sphere reaching to ``min_radius`` short of the agent); a
  sample is drawn uniformly in the bounds (or, for a stranded agent and with probability
  ``local_bias``, near its start, its unreached goals or its position: the paper leaves the
  sampler open), the nearest node of V^i found, and the new node is
  the sample if it lies in that node's sphere, else the point of the sphere's surface nearest
  the sample (``Steer``, lines 17–19); it joins V^i with its radius (``MinDistObs``, line 20);
  two nodes are joined by an edge when their spheres overlap (lines 21–27);
* F^i_connected is the number of goals agent i's start reaches in G^i (``MinPath``: Dijkstra,
  :func:`scipy.sparse.csgraph.dijkstra`, lines 32–38); the exploration is over when
  Σ_ℓ F^ℓ_connected = N² (line 29; the loop is :func:`agents.planners.swarm_exploration.explore`);
* in flight (line 45) the chain from the agent's position Y^i to its goal is searched first
  among the nodes that a chain at most half again as long as the straight line may visit (an
  ellipsoid: an edge costs at least its length), then, when none is found there, in the whole
  graph: the same least chain at a fraction of the edges.

The radii, the steering, the edge rule and the edge cost are the single-agent ones of
:mod:`agents.planners.spherical_expansion` (:func:`node_radii`, :func:`joinable`,
:func:`edge_cost`, :func:`shortest_chain` of a :class:`SphereGraph`): an edge needs
``d ≤ κ (r_v + r_w) − min_overlap`` so the trajectory programme's polytopes share a point.

The goals are then shared out (line 30, ``DistributedAssignment``): the paper leaves the method
open (it cites linear programming and auctions); here it is the optimal assignment of the
N × N graph path costs, the Hungarian method of :func:`scipy.optimize.linear_sum_assignment`,
computed centrally (:func:`agents.planners.team_assignment.assign_goals`).

Every body radius is the same for every agent (they share the field), so a node's clearance to
the bodies is computed once, and each agent's radius is that clearance cut by its teammates'
spheres. Nodes live in one pool; ``known[i, v]`` says whether node v is in V^i.

Everything here is a pure function of the field and the generator passed in; nothing prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from agents.planners.spherical_expansion import (
    ExpansionParams,
    SphereChain,
    SphereGraph,
    edge_cost,
    joinable,
    node_radii,
    shortest_chain,
)

__all__ = ["SwarmGraphs", "SwarmParams"]


@dataclass(frozen=True)
class SwarmParams:
    """Tunables of the multi-agent expansion.

    Attributes:
        r_col: centre-to-centre distance (m) two agents must keep (≥ 0).
        r_max: farthest (m) an agent travels between two plans (≥ 0); a teammate is a sphere
            of radius ``r_col + r_max`` around its current position.
        share_nodes: whether agents add each other's new nodes (``AllAgentCommunicate``).
        max_iterations: iterations :func:`explore` runs at most before giving up.
        expansion: the single-agent tunables used here: ``min_radius`` (new nodes with a
            smaller radius are dropped), ``min_overlap``, ``polytope_factor``, ``narrow_cost``
            (edges and their cost), ``goal_bias`` (probability that a sample is a goal drawn
            uniformly; the paper samples the workspace only: 0 by default) and ``max_nodes``
            (the pool's size: no node is added past it).
        local_bias: probability that the sample of an agent not yet connected is local,
            uniform in the ball of radius 3 (r_col + r_max) around one of its
            :meth:`SwarmGraphs.local_anchors` (its start while that reaches no goal, then the
            goals it does not reach; after a failed :meth:`SwarmGraphs.chain_to`, its position
            and its assigned goal); 0: every sample uniform in the bounds (the paper).
        parked_radius: radius (m) of the sphere of an agent that has arrived and stands still
            (:attr:`SwarmGraphs.parked`: r_max is the distance it travels per step, 0);
            None: r_col + r_max like the others.
    """

    r_col: float
    r_max: float
    share_nodes: bool = True
    max_iterations: int = 300
    expansion: ExpansionParams = field(
        default_factory=lambda: ExpansionParams(goal_bias=0.0, max_nodes=20_000)
    )
    local_bias: float = 0.0
    parked_radius: float | None = None

    def __post_init__(self) -> None:
        for name in ("r_col", "r_max"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (
                isinstance(value, (int, float, np.integer, np.floating))
                and math.isfinite(value)
                and value >= 0
            ):
                raise ValueError(f"{name} must be finite and >= 0 m, got {value!r}")
        if not isinstance(self.share_nodes, bool):
            raise ValueError(f"share_nodes must be True or False, got {self.share_nodes!r}")
        if isinstance(self.max_iterations, bool) or not (
            isinstance(self.max_iterations, int) and self.max_iterations >= 1
        ):
            raise ValueError(f"max_iterations must be an integer >= 1, got {self.max_iterations!r}")
        if not isinstance(self.expansion, ExpansionParams):
            raise ValueError(f"expansion must be an ExpansionParams, got {self.expansion!r}")
        if isinstance(self.local_bias, bool) or not (
            isinstance(self.local_bias, (int, float)) and 0.0 <= self.local_bias <= 1.0
        ):
            raise ValueError(f"local_bias must be in [0, 1], got {self.local_bias!r}")
        parked = self.parked_radius
        if parked is not None and (
            isinstance(parked, bool)
            or not (isinstance(parked, (int, float)) and math.isfinite(parked) and parked >= 0)
        ):
            raise ValueError(f"parked_radius must be finite and >= 0 m or None, got {parked!r}")

    @property
    def teammate_radius(self) -> float:
        """r_col + r_max (m): the sphere each teammate's current position is."""
        return float(self.r_col) + float(self.r_max)

    def sphere_radii(self, parked: np.ndarray) -> np.ndarray:
        """(N,) each agent's sphere (m): r_col + r_max, ``parked_radius`` where ``parked``."""
        parked = np.asarray(parked, dtype=bool)
        radii = np.full(parked.shape, self.teammate_radius)
        if self.parked_radius is not None:
            radii[parked] = self.parked_radius
        return radii


def _points(name: str, value: Any, dim: int | None = None) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim != 2 or array.shape[0] < 1 or array.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (N >= 1, 2 or 3), got {array.shape}")
    if dim is not None and array.shape[1] != dim:
        raise ValueError(f"{name} must have {dim} columns (the field's dim), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return array


class SwarmGraphs:
    """The N agents' graphs G^i over one pool of nodes, grown one iteration at a time.

    Args:
        geometry: the field's geometry (``dim``, ``n_bodies``, ``signed_distance``), the same
            for every agent.
        starts: (N, dim) each agent's start X^i_init (m); its current position Y^i too.
        goals: (N, dim) the goals X^j_goal (m).
        margins: (n_bodies,) keep-out (m) of each body surface (see :func:`node_radii`).
        params: the tunables.
        low, high: (dim,) bounds (m) samples are drawn in and spheres stay inside.

    Raises:
        ValueError: naming the parameter (shapes, N mismatch, NaN, inverted bounds).
    """

    def __init__(
        self,
        geometry: Any,
        starts: np.ndarray,
        goals: np.ndarray,
        margins: np.ndarray,
        params: SwarmParams,
        *,
        low: np.ndarray,
        high: np.ndarray,
    ) -> None:
        if not isinstance(params, SwarmParams):
            raise ValueError(f"params must be a SwarmParams, got {params!r}")
        d = int(geometry.dim)
        starts = _points("starts", starts, d)
        goals = _points("goals", goals, d)
        if goals.shape[0] != starts.shape[0]:
            raise ValueError(
                f"goals must have one row per agent: {starts.shape[0]} starts, "
                f"{goals.shape[0]} goals"
            )
        margins = np.asarray(margins, dtype=float)
        if margins.shape != (geometry.n_bodies,) or not np.all(np.isfinite(margins)):
            raise ValueError(f"margins must be {geometry.n_bodies} finite values (one per body)")
        low, high = np.asarray(low, float).reshape(-1), np.asarray(high, float).reshape(-1)
        if low.shape != (d,) or high.shape != (d,) or not np.all(np.isfinite(low - high)):
            raise ValueError(f"low and high must be {d} finite values each")
        if not np.all(low < high):
            raise ValueError(f"low must be below high on every axis, got {low} and {high}")
        self.geometry, self.params, self.margins = geometry, params, margins
        self.low, self.high, self.dim = low, high, d
        self.n_agents = n = starts.shape[0]
        self.positions = starts.copy()
        """(N, dim) the agents' current positions Y^ℓ (m)."""
        self.present = np.ones(n, dtype=bool)
        """(N,) the agents whose positions are spheres to the others."""
        self.parked = np.zeros(n, dtype=bool)
        """(N,) the present agents that have arrived and stand still (``parked_radius``)."""
        self.assigned: np.ndarray | None = None
        """(N,) each agent's goal once assigned (None before)."""
        self.iterations = 0
        self.reached = np.zeros((n, n), dtype=bool)
        """(N, N) whether agent i's start reaches goal j in G^i (kept by :func:`explore`)."""
        self.stranded = np.zeros(n, dtype=bool)
        """(N,) the agents whose last :meth:`chain_to` found no path."""
        cap = 2 * n + 64
        self._centers = np.empty((cap, d))
        self._clearance = np.empty(cap)  # body and wall clearance, the same for every agent
        self._owner = np.empty(cap, dtype=np.int64)  # -1: a goal
        self._known = np.zeros((n, cap), dtype=bool)
        self._size = 0
        self._pairs = np.zeros((2, 0), dtype=np.int64)  # candidate edges v < w
        self._pair_dist = np.zeros(0)
        self._fresh: list[int] = []  # nodes of the last iteration, shared at the next
        self.goal_nodes = self._add(goals, np.full(n, -1), np.ones((n, n), dtype=bool))
        self.start_nodes = self._add(starts, np.arange(n), np.eye(n, dtype=bool))

    # --- the pool ------------------------------------------------------------------------------

    @property
    def n_nodes(self) -> int:
        """Nodes in the pool."""
        return self._size

    @property
    def centers(self) -> np.ndarray:
        """(M, dim) every node of the pool (m), a view."""
        return self._centers[: self._size]

    @property
    def owners(self) -> np.ndarray:
        """(M,) the agent that drew each node (its start: that agent; −1: a goal), a view."""
        return self._owner[: self._size]

    def known(self, agent: int) -> np.ndarray:
        """(M,) bool: the pool's nodes in V^agent (a copy)."""
        return self._known[agent, : self._size].copy()

    def nodes_per_agent(self) -> np.ndarray:
        """(N,) |V^i|."""
        return self._known[:, : self._size].sum(axis=1)

    def _add(self, points: np.ndarray, owners: np.ndarray, known: np.ndarray) -> np.ndarray:
        """Append nodes (their clearance computed here); ``known`` (N, B) their membership.
        Candidate edges are kept for pairs some agent may hold both of, under the bodies alone
        (a teammate sphere only shrinks radii)."""
        count = len(points)
        need = self._size + count
        if need > len(self._clearance):
            cap = max(2 * len(self._clearance), need)
            self._centers = np.resize(self._centers, (cap, self.dim))
            self._clearance = np.resize(self._clearance, cap)
            self._owner = np.resize(self._owner, cap)
            grown = np.zeros((self.n_agents, cap), dtype=bool)
            grown[:, : self._size] = self._known[:, : self._size]
            self._known = grown
        first = self._size
        new = np.arange(first, need)
        self._centers[new] = points
        self._clearance[new] = node_radii(self.geometry, points, self.margins, self.low, self.high)
        self._owner[new] = owners
        self._known[:, new] = known
        self._size = need
        # who may ever hold node v: everyone when shared (or a goal), else its known set
        audience = known.copy()
        if self.params.share_nodes:
            audience[:, owners >= 0] |= True
        audience_all = self._known[:, :need].astype(np.float32)
        audience_all[:, new] = audience
        together = audience.T.astype(np.float32) @ audience_all > 0.5  # (B, need)
        together[:, first:] &= new[:, None] > np.arange(first, need)[None, :]
        dist = np.linalg.norm(points[:, None, :] - self._centers[None, :need], axis=-1)
        r = np.maximum(self._clearance[:need], 0.0)
        keep = together & joinable(dist, r[new][:, None], r[None, :], self.params.expansion)
        rows, cols = np.nonzero(keep)
        pairs = np.stack([cols, new[rows]])  # v < w
        self._pairs = np.concatenate([self._pairs, pairs], axis=1)
        self._pair_dist = np.concatenate([self._pair_dist, dist[rows, cols]])
        return new

    # --- one agent's graph ---------------------------------------------------------------------

    def radii(self, agent: int, nodes: np.ndarray | None = None) -> np.ndarray:
        """``MinDistObs`` of ``nodes`` (default: the whole pool) in G^agent (m): the body
        clearance cut by the spheres of radius r_col + r_max around the other present agents'
        positions (lines 8–16); negative inside one."""
        nodes = np.arange(self._size) if nodes is None else np.asarray(nodes, dtype=np.int64)
        return np.minimum(self._clearance[nodes], self._teammate_gap(agent, self._centers[nodes]))

    def graph(
        self,
        agent: int,
        floor: dict[int, float] | None = None,
        extra: np.ndarray | None = None,
        extra_radius: float | None = None,
        region: np.ndarray | None = None,
    ) -> SphereGraph:
        """G^agent over the whole pool (nodes not in V^agent have no edge), as a
        :class:`SphereGraph` (its ``connected`` is not computed: False).

        Args:
            agent: i.
            floor: node → least radius (m) it is given.
            extra: (dim,) a point (m) added as node M (after the pool), in G^agent alone: the
                agent's current position Y^i (line 52).
            extra_radius: least radius (m) of ``extra``.
            region: (M,) bool: only these nodes of the pool get edges (None: all).
        """
        ex = self.params.expansion
        m = self._size
        v, w = self._pairs
        dist = self._pair_dist
        if region is None:
            radius = self.radii(agent)
        else:
            inside = np.flatnonzero(region)
            radius = np.full(m, -1.0)
            radius[inside] = self.radii(agent, inside)
            keep = region[v] & region[w]
            v, w, dist = v[keep], w[keep], dist[keep]
        for node, least in (floor or {}).items():
            radius[node] = max(radius[node], least)
        known = self._known[agent, :m]
        ok = known[v] & known[w] & (radius[v] > 0) & (radius[w] > 0)
        ok &= joinable(dist, radius[v], radius[w], ex)
        v, w = v[ok], w[ok]
        centers = self.centers
        size = m
        if extra is not None:
            point = np.asarray(extra, dtype=float).reshape(1, self.dim)
            own = float(node_radii(self.geometry, point, self.margins, self.low, self.high)[0])
            own = min(own, float(self._teammate_gap(agent, point)[0]))
            if extra_radius is not None:
                own = max(own, float(extra_radius))
            candidates = np.flatnonzero(known & (radius > 0))
            gap = np.linalg.norm(centers[candidates] - point, axis=1)
            near: np.ndarray = (
                candidates[joinable(gap, radius[candidates], own, ex)]
                if own > 0
                else np.empty(0, dtype=np.int64)
            )
            v = np.concatenate([v, np.asarray(near, dtype=np.int64)])
            w = np.concatenate([w, np.full(len(near), m, dtype=np.int64)])
            centers = np.vstack([centers, point])
            radius = np.append(radius, own)
            size = m + 1
        cost = np.maximum(
            edge_cost(centers[v], radius[v], centers[w], radius[w], ex.narrow_cost), 1e-9
        )
        adjacency = csr_matrix(
            (np.concatenate([cost, cost]), (np.concatenate([v, w]), np.concatenate([w, v]))),
            shape=(size, size),
        )
        return SphereGraph(centers.copy(), radius, adjacency, False, self.iterations)

    def teammate_radii(self, agent: int) -> np.ndarray:
        """(N,) radius (m) of each agent's sphere in G^agent: r_col + r_max (``parked_radius``
        for a :attr:`parked` one), or for a teammate
        already closer than that (starts tighter than the paper's eq. 1) its distance less
        ``min_radius``, so the agent stays outside it and may move away; likewise a teammate
        closer than that to the agent's assigned goal (:attr:`assigned`; goals tighter than
        the paper's eq. 2); 0 for the agent itself and the absent."""
        gaps = np.linalg.norm(self.positions - self.positions[agent], axis=1)
        if self.assigned is not None:  # nor over the agent's own goal (the paper's eq. 2)
            goal = self._centers[self.goal_nodes[self.assigned[agent]]]
            gaps = np.minimum(gaps, np.linalg.norm(self.positions - goal, axis=1))
        least = self.params.expansion.min_radius
        full = self.params.sphere_radii(self.parked)
        radii = np.clip(np.minimum(full, gaps - least), 0.0, None)
        radii[agent] = 0.0
        radii[~self.present] = 0.0
        return radii

    def _teammate_gap(self, agent: int, points: np.ndarray) -> np.ndarray:
        """(P,) distance (m) from ``points`` to the nearest other present agent's sphere
        (:meth:`teammate_radii`; inf when there is none)."""
        others = self.present.copy()
        others[agent] = False
        if not others.any():
            return np.full(len(points), np.inf)
        radii = self.teammate_radii(agent)[others]
        gaps = np.linalg.norm(points[:, None, :] - self.positions[others][None], axis=-1)
        return (gaps - radii[None]).min(axis=1)

    def path_costs(self, agent: int, source: int | None = None) -> np.ndarray:
        """(N,) least path cost (m) in G^agent from ``source`` (default: the agent's start) to
        every goal; inf where there is none (``MinPath``, lines 33–38)."""
        source = int(self.start_nodes[agent] if source is None else source)
        g = self.graph(agent)
        dist = dijkstra(g.adjacency, directed=False, indices=[source])[0]
        return np.asarray(dist)[self.goal_nodes]

    def connected(self) -> np.ndarray:
        """(N,) F^i_connected: the goals each agent's start reaches in its graph."""
        return np.array([int(np.isfinite(self.path_costs(i)).sum()) for i in range(self.n_agents)])

    # --- iterations ------------------------------------------------------------------------------

    def iterate(self, rng: np.random.Generator, agents: np.ndarray | None = None) -> int:
        """One iteration of lines 7–20 for ``agents`` (default: all; in order): shared nodes
        of the previous iteration received, one sample each, steered, kept when its radius in
        the agent's graph is at least ``min_radius``. Returns the nodes added."""
        n, ex = self.n_agents, self.params.expansion
        if self.params.share_nodes and self._fresh:
            fresh = np.array(self._fresh, dtype=np.int64)
            self._known[:, fresh] = True
        self._fresh = []
        self.iterations += 1
        active = np.arange(n) if agents is None else np.asarray(agents, dtype=np.int64)
        if self._size >= ex.max_nodes:
            return 0
        goals = self._centers[self.goal_nodes]
        new_points, owners = [], []
        for i in active.tolist():
            if ex.goal_bias > 0 and rng.random() < ex.goal_bias:
                sample = goals[rng.integers(n)].copy()
            elif (
                self.params.local_bias > 0
                and (self.stranded[i] or not self.reached[i].all())
                and rng.random() < self.params.local_bias
            ):
                sample = self._local_sample(i, rng)
            else:
                sample = self.low + rng.random(self.dim) * (self.high - self.low)
            nodes = np.flatnonzero(self._known[i, : self._size])
            radius = self.radii(i, nodes)
            grow = radius > 0
            if not grow.any():
                continue
            nodes, radius = nodes[grow], radius[grow]
            offsets = self._centers[nodes] - sample
            dist2 = np.einsum("ij,ij->i", offsets, offsets)
            near = int(np.argmin(dist2))
            gap = math.sqrt(float(dist2[near]))
            center = self._centers[nodes[near]]
            new = (
                sample if gap <= radius[near] else center + (sample - center) * (radius[near] / gap)
            )
            if np.min(np.linalg.norm(self._centers[: self._size] - new, axis=1)) < 1e-6:
                continue
            new_points.append(new)
            owners.append(i)
        if not new_points:
            return 0
        points = np.array(new_points)
        owner = np.array(owners, dtype=np.int64)
        clearance = node_radii(self.geometry, points, self.margins, self.low, self.high)
        keep = [
            b
            for b, i in enumerate(owners)
            if min(float(clearance[b]), float(self._teammate_gap(i, points[b : b + 1])[0]))
            >= ex.min_radius
        ]
        keep = keep[: max(ex.max_nodes - self._size, 0)]
        if not keep:
            return 0
        membership = np.zeros((n, len(keep)), dtype=bool)
        membership[owner[keep], np.arange(len(keep))] = True
        added = self._add(points[keep], owner[keep], membership)
        self._fresh = added.tolist()
        return len(added)

    def local_anchors(self, agent: int) -> np.ndarray:
        """(A, dim) the points (m) the agent's local samples are drawn around: a
        :attr:`stranded` agent's position and its assigned goal; else its start while that
        reaches no goal, then every goal its start does not reach yet."""
        if self.stranded[agent] and self.assigned is not None:
            goal = self._centers[self.goal_nodes[self.assigned[agent]]]
            return np.stack([self.positions[agent], goal])
        if not self.reached[agent].any():
            return self._centers[self.start_nodes[agent : agent + 1]]
        return self._centers[self.goal_nodes[~self.reached[agent]]]

    def _local_sample(self, agent: int, rng: np.random.Generator) -> np.ndarray:
        """A sample uniform in the ball of radius 3 (r_col + r_max) around one of the agent's
        :meth:`local_anchors` (drawn uniformly), clipped into the bounds."""
        anchors = self.local_anchors(agent)
        center = anchors[rng.integers(len(anchors))]
        reach = 3.0 * max(self.params.teammate_radius, self.params.expansion.min_radius)
        direction = rng.normal(size=self.dim)
        direction /= max(float(np.linalg.norm(direction)), 1e-12)
        point = center + direction * reach * rng.random() ** (1.0 / self.dim)
        return np.clip(point, self.low, self.high)

    def move(
        self,
        positions: np.ndarray,
        present: np.ndarray | None = None,
        parked: np.ndarray | None = None,
    ) -> None:
        """The agents' current positions Y (m), which of them are spheres to the others and
        which of those have arrived and stand still (:attr:`parked`)."""
        positions = np.asarray(positions, dtype=float)
        if positions.shape != self.positions.shape or not np.all(np.isfinite(positions)):
            raise ValueError(f"positions must be {self.positions.shape}, finite")
        self.positions = positions.copy()
        for name, mask in (("present", present), ("parked", parked)):
            if mask is not None:
                mask = np.array(mask, dtype=bool)
                if mask.shape != (self.n_agents,):
                    raise ValueError(f"{name} must have shape ({self.n_agents},)")
                setattr(self, name, mask)

    def chain_to(
        self, agent: int, goal: int, floor: float | None = None
    ) -> tuple[SphereChain, int]:
        """``MinPath`` in G^agent from the agent's current position Y^agent (line 52: a node
        of its graph for this search) to goal ``goal`` (line 45).

        Args:
            agent: i.
            goal: the goal's index j.
            floor: least radius (m) of the position and goal spheres (an agent already inside
                a teammate's sphere still needs a sphere to leave it by); None: ``min_radius``.

        Returns:
            the chain (``success`` False when the goal is out of reach) and |V^agent|.
        """
        floor = self.params.expansion.min_radius if floor is None else float(floor)
        target = int(self.goal_nodes[goal])
        here = self.positions[agent]
        # an edge costs at least its length, so every node of a chain costing at most
        # ``bound`` lies in the ellipsoid of foci Y^i and the goal whose distances to them sum
        # to ``bound``: the search there finds the least chain whenever it costs that little
        goal_point = self._centers[target]
        bound = _ELLIPSOID_STRETCH * float(np.linalg.norm(goal_point - here)) + 4.0 * max(
            self.params.teammate_radius, self.params.expansion.min_radius
        )
        pool = self.centers
        region = (
            np.linalg.norm(pool - here, axis=1) + np.linalg.norm(pool - goal_point, axis=1) <= bound
        )
        g = self.graph(agent, {target: floor}, here, floor, region=region)
        chain = shortest_chain(g, g.n_nodes - 1, target)
        if not (chain.success and chain.cost <= bound):
            g = self.graph(agent, {target: floor}, here, floor)
            chain = shortest_chain(g, g.n_nodes - 1, target)
        self.stranded[agent] = not chain.success
        return chain, int(self._known[agent, : self._size].sum()) + 1


_ELLIPSOID_STRETCH = 1.5
"""The chain a :meth:`SwarmGraphs.chain_to` search looks for first costs at most this times
the straight distance (plus four teammate radii); a dearer or missing one is searched for in
the whole graph."""
