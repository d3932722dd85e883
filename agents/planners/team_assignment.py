"""Which chaser of a team captures which target: assignment rules and the cost they are judged by.

The cost of an assignment is the sum over the chasers of each one's shortest tour: from its dock
slot through its targets (in the best order) and back to its slot when the mission returns
(``return_to_dock``). Legs are measured surface to surface, on the field as it is at t = 0:
dock slot → target is the distance from the slot to the target's surface, target → target the
gap between their surfaces (never below 0). It is a stated, static proxy of the work a tour
takes, not a Δv: the bodies move during a mission.

Rules, each returning a :class:`TeamAssignment` (a (K, T) bool table, every target one
chaser's):

* :func:`optimal_assignment` — the least total cost over every partition of the targets among
  the chasers (a chaser may get none), each chaser's tour exact (Held–Karp over subsets):
  brute force over K^T partitions, fine for the swarm IDs (K = 3, T = 6: 729). When the dock
  slots are close together (the swarm IDs: 5 m apart in a 1 km field) splitting one tour among
  several chasers cannot shorten it (the triangle inequality), so this optimum is nearly always
  one chaser flying every target while the others stay home;
* :func:`minmax_assignment` — the least longest tour (the team's makespan, in distance), ties
  by the total: the same enumeration, a team's work shared;
* :func:`greedy_assignment` — the floor: the chasers in turn (0, 1, …, K − 1, 0, …) each take
  the unassigned target nearest the end of their tour so far (their slot at first), until none
  is left;
* :func:`auction_assignment` — a decentralised auction (CBBA, :mod:`agents.planners.auction`):
  at most ⌈T / K⌉ targets each, every chaser bidding on its own route;
* the env's balanced rule, :func:`debris_gym.swarm.assignment.balanced_assignment` (at most
  ⌈T / K⌉ targets each, least total slot-to-surface distance), judged by the same cost
  (:func:`assignment_cost`).

A reconfiguration gives every chaser exactly one target, a formation slot (a
:class:`TeamField` with ``one_each``): the same rule names are then matchings judged by the
legs alone (:func:`slot_assignment`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from agents.planners.auction import cbba
from debris_gym.swarm.assignment import balanced_assignment

__all__ = [
    "ASSIGNMENT_RULES",
    "MAX_PARTITIONS",
    "TeamAssignment",
    "TeamField",
    "assign",
    "assign_goals",
    "assignment_cost",
    "auction_assignment",
    "greedy_assignment",
    "minmax_assignment",
    "optimal_assignment",
    "slot_assignment",
    "tour_costs",
]

ASSIGNMENT_RULES = ("balanced", "greedy", "optimal", "minmax", "auction")
"""The rules :func:`assign` knows."""

MAX_PARTITIONS = 1_000_000
"""Most partitions (K^T) :func:`optimal_assignment` enumerates; more raise ``ValueError``."""

MAX_TOUR_TARGETS = 12
"""Most targets a tour table (2^T subsets per chaser) is built for."""


@dataclass(frozen=True)
class TeamField:
    """What an assignment rule reads of a field (SI units, at t = 0).

    Attributes:
        docks: (K, dim) each chaser's dock slot (m).
        centers: (T, dim) the targets' centres (m).
        radii: (T,) the targets' bounding radii (m).
        return_to_dock: whether each tour ends back at its chaser's slot.
    """

    docks: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    return_to_dock: bool = True
    one_each: bool = False
    """Every chaser takes exactly one target (K = T: a reconfiguration's formation slots, radii
    0); the rules are then matchings (:func:`slot_assignment`)."""

    def __post_init__(self) -> None:
        docks, centers = np.asarray(self.docks, float), np.asarray(self.centers, float)
        radii = np.asarray(self.radii, float)
        if docks.ndim != 2 or docks.shape[0] < 1:
            raise ValueError(f"docks must have shape (K >= 1, dim), got {docks.shape}")
        if centers.ndim != 2 or centers.shape[1] != docks.shape[1]:
            raise ValueError(
                f"centers must have shape (T, {docks.shape[1]}) like docks, got {centers.shape}"
            )
        if radii.shape != (centers.shape[0],):
            raise ValueError(f"radii must have shape ({centers.shape[0]},), got {radii.shape}")
        for name, value in (("docks", docks), ("centers", centers), ("radii", radii)):
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be finite")
        if np.any(radii < 0):
            raise ValueError("radii must be >= 0 m")
        if self.one_each and centers.shape[0] != docks.shape[0]:
            raise ValueError(
                f"one target each needs as many targets as chasers, got {centers.shape[0]} "
                f"for {docks.shape[0]}"
            )
        object.__setattr__(self, "docks", docks)
        object.__setattr__(self, "centers", centers)
        object.__setattr__(self, "radii", radii)

    @property
    def n_chasers(self) -> int:
        """K."""
        return int(self.docks.shape[0])

    @property
    def n_targets(self) -> int:
        """T."""
        return int(self.centers.shape[0])

    def dock_legs(self) -> np.ndarray:
        """(K, T) distance (m) from each chaser's slot to each target's surface (≥ 0)."""
        gaps = np.linalg.norm(self.docks[:, None, :] - self.centers[None, :, :], axis=-1)
        return np.maximum(gaps - self.radii[None, :], 0.0)

    def target_legs(self) -> np.ndarray:
        """(T, T) gap (m) between each two targets' surfaces (≥ 0; 0 on the diagonal)."""
        gaps = np.linalg.norm(self.centers[:, None, :] - self.centers[None, :, :], axis=-1)
        legs = np.maximum(gaps - self.radii[:, None] - self.radii[None, :], 0.0)
        np.fill_diagonal(legs, 0.0)
        return legs


@dataclass(frozen=True)
class TeamAssignment:
    """An assignment and its cost.

    Attributes:
        rule: the rule that chose it (:data:`ASSIGNMENT_RULES`).
        table: (K, T) bool, ``table[k, j]``: target j is chaser k's; every column has one True.
        cost: :func:`assignment_cost` of ``table`` (m).
        tours: each chaser's cost (m), (K,).
    """

    rule: str
    table: np.ndarray
    cost: float
    tours: np.ndarray

    @property
    def longest(self) -> float:
        """The longest chaser's tour (m): the team's makespan in distance."""
        return float(self.tours.max()) if self.tours.size else 0.0

    def targets(self) -> list[list[int]]:
        """One list of target indices per chaser: the swarm's reset option ``assignment``."""
        return [np.flatnonzero(row).tolist() for row in self.table]


def tour_costs(field: TeamField) -> np.ndarray:
    """(K, 2^T) shortest tour cost (m) of each chaser over each subset of targets (bit j of the
    subset index = target j): slot → the subset's targets in the best order (→ slot when the
    field returns); 0 for the empty subset. Exact (Held–Karp).

    Raises:
        ValueError: more than :data:`MAX_TOUR_TARGETS` targets.
    """
    k, t = field.n_chasers, field.n_targets
    if t > MAX_TOUR_TARGETS:
        raise ValueError(f"tour tables take at most {MAX_TOUR_TARGETS} targets, got {t}")
    out = np.zeros((k, 1 << t))
    if t == 0:
        return out
    start, legs = field.dock_legs(), field.target_legs()
    for c in range(k):
        # best[s, j]: shortest path from the slot through the targets of s, ending at j ∈ s
        best = np.full((1 << t, t), np.inf)
        for j in range(t):
            best[1 << j, j] = start[c, j]
        for s in range(1, 1 << t):
            for j in range(t):
                here = best[s, j]
                if not math.isfinite(here):
                    continue
                for n in range(t):
                    if s >> n & 1:
                        continue
                    nxt = s | 1 << n
                    via = here + legs[j, n]
                    if via < best[nxt, n]:
                        best[nxt, n] = via
        back = start[c] if field.return_to_dock else np.zeros(t)
        out[c, 1:] = np.min(best[1:] + back[None, :], axis=1)
    return out


def _masks(table: np.ndarray) -> np.ndarray:
    """(K,) subset index of each chaser's targets."""
    weights = 1 << np.arange(table.shape[1], dtype=np.int64)
    return (table.astype(np.int64) * weights[None, :]).sum(axis=1)


def _checked_table(table: np.ndarray, field: TeamField) -> np.ndarray:
    table = np.asarray(table)
    if table.shape != (field.n_chasers, field.n_targets) or table.dtype != bool:
        raise ValueError(
            f"an assignment is a ({field.n_chasers}, {field.n_targets}) bool table, got "
            f"{table.dtype} {table.shape}"
        )
    if np.any(table.sum(axis=0) != 1):
        raise ValueError("an assignment gives every target to exactly one chaser")
    return table


def assignment_cost(
    table: np.ndarray, field: TeamField, tours: np.ndarray | None = None
) -> tuple[float, np.ndarray]:
    """The cost (m) of the (K, T) bool ``table`` on ``field`` and each chaser's share (K,)
    (``tours``: :func:`tour_costs` of the field, computed if not given).

    Raises:
        ValueError: ``table`` is not an assignment of the field's targets to its chasers.
    """
    table = _checked_table(table, field)
    tours = tour_costs(field) if tours is None else tours
    per = tours[np.arange(field.n_chasers), _masks(table)]
    return float(per.sum()), per


def _partition_costs(
    field: TeamField, tours: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every partition of the targets among the chasers as owners (P, T), with its total and
    longest tour (P,) each (m), partitions in lexicographic order of the owners.

    Raises:
        ValueError: K^T above :data:`MAX_PARTITIONS`.
    """
    k, t = field.n_chasers, field.n_targets
    if k**t > MAX_PARTITIONS:
        raise ValueError(
            f"an exact rule enumerates K^T = {k}^{t} partitions, above {MAX_PARTITIONS}; "
            "use fewer targets or chasers, or another rule"
        )
    tours = tour_costs(field) if tours is None else tours
    owners = np.array(list(itertools.product(range(k), repeat=t)), dtype=np.int64).reshape(k**t, t)
    bits = 1 << np.arange(t, dtype=np.int64)
    per = np.stack([tours[c, ((owners == c) * bits[None, :]).sum(axis=1)] for c in range(k)])
    return owners, per.sum(axis=0), per.max(axis=0)


def _from_owners(
    rule: str, owners: np.ndarray, field: TeamField, tours: np.ndarray | None
) -> TeamAssignment:
    table = np.zeros((field.n_chasers, field.n_targets), dtype=bool)
    table[owners, np.arange(field.n_targets)] = True
    cost, per = assignment_cost(table, field, tours)
    return TeamAssignment(rule, table, cost, per)


def optimal_assignment(field: TeamField, tours: np.ndarray | None = None) -> TeamAssignment:
    """The assignment of least :func:`assignment_cost` (the total of the chasers' tours) over
    every partition of the targets among the chasers (K^T of them), ties to the first in
    lexicographic order of the owners.

    Raises:
        ValueError: K^T above :data:`MAX_PARTITIONS`.
    """
    tours = tour_costs(field) if tours is None else tours
    owners, total, _ = _partition_costs(field, tours)
    return _from_owners("optimal", owners[int(np.argmin(total))], field, tours)


def minmax_assignment(field: TeamField, tours: np.ndarray | None = None) -> TeamAssignment:
    """The assignment of least longest tour (m), ties by the least total, then the first in
    lexicographic order of the owners, over every partition (K^T).

    Raises:
        ValueError: K^T above :data:`MAX_PARTITIONS`.
    """
    tours = tour_costs(field) if tours is None else tours
    owners, total, longest = _partition_costs(field, tours)
    best = int(np.lexsort((total, longest))[0])
    return _from_owners("minmax", owners[best], field, tours)


def greedy_assignment(field: TeamField, tours: np.ndarray | None = None) -> TeamAssignment:
    """The floor: the chasers in turn each take the unassigned target whose surface is nearest
    the end of their tour so far (their slot first, then their last target), ties to the lower
    index, until every target is taken."""
    k, t = field.n_chasers, field.n_targets
    start, legs = field.dock_legs(), field.target_legs()
    table = np.zeros((k, t), dtype=bool)
    last: list[int | None] = [None] * k
    free = np.ones(t, dtype=bool)
    turn = 0
    while free.any():
        c = turn % k
        here = last[c]
        gaps = start[c] if here is None else legs[here]
        j = int(np.flatnonzero(free)[np.argmin(gaps[free])])
        table[c, j], free[j], last[c] = True, False, j
        turn += 1
    cost, per = assignment_cost(table, field, tours)
    return TeamAssignment("greedy", table, cost, per)


def auction_assignment(field: TeamField, tours: np.ndarray | None = None) -> TeamAssignment:
    """The targets auctioned among the chasers by CBBA (:func:`~agents.planners.auction.cbba`,
    at most ⌈T / K⌉ each; one each on a ``one_each`` field), judged by the stated cost."""
    if field.one_each:
        won = cbba(field.dock_legs(), field.target_legs(), False, max_bundle=1).table
        legs = field.dock_legs()[won]
        return TeamAssignment("auction", won, float(legs.sum()), legs)
    table = cbba(field.dock_legs(), field.target_legs(), field.return_to_dock).table
    cost, per = assignment_cost(table, field, tours)
    return TeamAssignment("auction", table, cost, per)


def _matching(cost: np.ndarray) -> np.ndarray:
    """(K,) the column of each row in the least-total perfect matching of ``cost`` (K, K)."""
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(cost.shape[0], dtype=np.int64)
    out[rows] = cols
    return out


def assign_goals(costs: np.ndarray) -> tuple[np.ndarray, float]:
    """The optimal assignment of goals to agents on the graph path costs: least total cost,
    one goal each (the Hungarian method, :func:`scipy.optimize.linear_sum_assignment`; the
    paper's ``DistributedAssignment`` leaves the method open).

    Args:
        costs: (N, N) path cost (m) of agent i to goal j, ≥ 0; inf where there is no path.

    Returns:
        (N,) the goal of each agent, and the total cost (inf when no assignment avoids an inf).

    Raises:
        ValueError: not square, NaN or negative costs.
    """
    costs = np.asarray(costs, dtype=float)
    if costs.ndim != 2 or costs.shape[0] != costs.shape[1] or costs.shape[0] < 1:
        raise ValueError(f"costs must be a square (N, N) array, got shape {costs.shape}")
    if np.any(np.isnan(costs)) or np.any(costs < 0):
        raise ValueError("costs must be >= 0 (inf for no path), without NaN")
    finite = np.isfinite(costs)
    # an inf cost becomes more than any assignment of finite costs could total
    big = (costs[finite].sum() + 1.0) * (costs.shape[0] + 1) if finite.any() else 1.0
    goal = _matching(np.where(finite, costs, big))
    return goal, float(costs[np.arange(len(goal)), goal].sum())


def _bottleneck(legs: np.ndarray) -> np.ndarray:
    """The matching with the least longest leg, ties by the least total: the smallest
    threshold that leaves a perfect matching (bisection over the sorted legs), then the
    least-total matching with every longer leg forbidden."""
    values = np.unique(legs)
    lo, hi = 0, len(values) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        allowed = csr_matrix(legs <= values[mid])
        if (maximum_bipartite_matching(allowed, perm_type="column") >= 0).all():
            hi = mid
        else:
            lo = mid + 1
    limit = values[lo]
    penalty = (legs.sum() + 1.0) * (legs > limit)
    return _matching(legs + penalty)


def slot_assignment(rule: str, field: TeamField) -> TeamAssignment:
    """``rule`` on a field where every chaser takes exactly one target (``one_each``), judged
    by the chasers' legs (slot → target's surface; no tours):

    * ``balanced`` and ``optimal`` — the least total (Hungarian: ``linear_sum_assignment``);
    * ``minmax`` — the least longest leg, ties by the least total (:func:`_bottleneck`);
    * ``greedy`` — the chasers in turn each take the free target nearest them.

    Raises:
        ValueError: an unknown rule, or a field that is not ``one_each``.
    """
    if not field.one_each:
        raise ValueError("slot_assignment needs a field with one target each (one_each=True)")
    legs = field.dock_legs()
    k = field.n_chasers
    if rule == "auction":
        return auction_assignment(field)
    if rule in ("balanced", "optimal"):
        order = _matching(legs)
    elif rule == "minmax":
        order = _bottleneck(legs)
    elif rule == "greedy":
        order = np.empty(k, dtype=np.int64)
        free = np.ones(k, dtype=bool)
        for c in range(k):
            order[c] = int(np.argmin(np.where(free, legs[c], np.inf)))
            free[order[c]] = False
    else:
        raise ValueError(f"unknown assignment rule {rule!r}; known: {', '.join(ASSIGNMENT_RULES)}")
    table = np.zeros((k, k), dtype=bool)
    table[np.arange(k), order] = True
    per = legs[np.arange(k), order]
    return TeamAssignment(rule, table, float(per.sum()), per)


def assign(rule: str, field: TeamField, tours: np.ndarray | None = None) -> TeamAssignment:
    """The assignment of ``rule`` (:data:`ASSIGNMENT_RULES`) on ``field`` (a ``one_each``
    field: :func:`slot_assignment`, ``tours`` unused).

    Raises:
        ValueError: an unknown rule (the message lists the known ones).
    """
    if field.one_each:
        return slot_assignment(rule, field)
    tours = tour_costs(field) if tours is None else tours
    if rule == "optimal":
        return optimal_assignment(field, tours)
    if rule == "minmax":
        return minmax_assignment(field, tours)
    if rule == "greedy":
        return greedy_assignment(field, tours)
    if rule == "auction":
        return auction_assignment(field, tours)
    if rule == "balanced":
        table = balanced_assignment(field.docks, field.centers, field.radii)
        cost, per = assignment_cost(table, field, tours)
        return TeamAssignment("balanced", table, cost, per)
    raise ValueError(f"unknown assignment rule {rule!r}; known: {', '.join(ASSIGNMENT_RULES)}")
