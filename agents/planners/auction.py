"""A decentralised auction of the targets among the chasers: the consensus-based bundle
algorithm (CBBA, [Choi09]), simulated in synchronous rounds.

Each chaser plans alone and talks only through bids. Every round has two phases:

1. **Bundle building.** A chaser keeps adding to its bundle the target it can still win with
   the highest bid — ``C`` minus the least increase of its own route (dock slot → its bundle's
   targets in the order they were added → slot, when the mission returns) from inserting the
   target anywhere in it — while its bundle holds fewer than ``max_bundle`` targets. A bid is
   never above the bid of the target added before it: the insertion costs of a route do not
   always grow as it gets longer, and CBBA's convergence rests on marginal bids that never
   rise along a bundle ([Choi09], "diminishing marginal gain").
2. **Consensus.** The chasers exchange their winning-bid and winner tables (every chaser hears
   every other: one hop on a full communication graph); each keeps, per target, the highest
   bid heard (ties to the lower chaser index). A chaser outbid on a target of its bundle
   releases it and every target it added after it (their bids were made on a route holding
   it).

The rounds stop when no table changes; the result is conflict-free (each target one
chaser's). It is a decentralised heuristic, not an optimum: the swarm evaluation reports its
gap to the optimal total tour (:mod:`~agents.planners.team_assignment`). Legs are the team
assignment's: surface to surface on the field at t = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AuctionResult", "cbba"]

MAX_ROUNDS = 1000
"""Rounds before the auction gives up (CBBA converges within T · K rounds on a full graph)."""


@dataclass(frozen=True)
class AuctionResult:
    """The auction's outcome.

    Attributes:
        table: (K, T) bool, ``table[k, j]``: target j is chaser k's.
        bundles: each chaser's targets in the order it added them.
        rounds: bundle-and-consensus rounds until no table changed.
    """

    table: np.ndarray
    bundles: list[list[int]]
    rounds: int


def _route_cost(route: list[int], k: int, start: np.ndarray, legs: np.ndarray, back: bool) -> float:
    if not route:
        return 0.0
    cost = start[k, route[0]] + sum(legs[a, b] for a, b in zip(route, route[1:]))
    return cost + (start[k, route[-1]] if back else 0.0)


def _insertion(
    route: list[int], j: int, k: int, start: np.ndarray, legs: np.ndarray, back: bool
) -> tuple[float, int]:
    """The least increase (m) of chaser ``k``'s route from inserting target ``j``, and where."""
    base = _route_cost(route, k, start, legs, back)
    best, where = math.inf, 0
    for n in range(len(route) + 1):
        cost = _route_cost([*route[:n], j, *route[n:]], k, start, legs, back) - base
        if cost < best - 1e-12:
            best, where = cost, n
    return best, where


def cbba(
    start: np.ndarray, legs: np.ndarray, back: bool, max_bundle: int | None = None
) -> AuctionResult:
    """Auction T targets among K chasers by CBBA on a full communication graph.

    Args:
        start: (K, T) leg (m) from each chaser's dock slot to each target.
        legs: (T, T) leg (m) between targets.
        back: whether each route ends back at its chaser's slot.
        max_bundle: most targets per chaser (default ⌈T / K⌉); K · ``max_bundle`` ≥ T.

    Raises:
        ValueError: bad shapes, negative or non-finite legs, or too small a bundle.
    """
    start, legs = np.asarray(start, float), np.asarray(legs, float)
    if start.ndim != 2 or legs.shape != (start.shape[1], start.shape[1]):
        raise ValueError(f"start must be (K, T) and legs (T, T); got {start.shape}, {legs.shape}")
    if not (np.all(np.isfinite(start)) and np.all(np.isfinite(legs))):
        raise ValueError("legs must be finite")
    if np.any(start < 0) or np.any(legs < 0):
        raise ValueError("legs must be >= 0 m")
    k, t = start.shape
    if t == 0:
        return AuctionResult(np.zeros((k, 0), dtype=bool), [[] for _ in range(k)], 0)
    size = -(-t // k) if max_bundle is None else int(max_bundle)
    if size < 1 or k * size < t:
        raise ValueError(f"max_bundle={max_bundle} cannot hold {t} targets among {k} chasers")
    # every bid is positive: C exceeds any insertion cost
    ceiling = 2.0 * (float(start.max(initial=0.0)) + float(legs.sum())) + 1.0
    bid = np.zeros((k, t))  # what chaser i believes is the winning bid on each target
    winner = np.full((k, t), -1, dtype=np.int64)  # ... and who holds it
    bundles: list[list[int]] = [[] for _ in range(k)]
    routes: list[list[int]] = [[] for _ in range(k)]
    for rounds in range(1, MAX_ROUNDS + 1):
        for i in range(k):  # phase 1: each chaser adds what it can win
            while len(bundles[i]) < size:
                best_j, best_bid, best_at = -1, 0.0, 0
                cap = math.inf
                if bundles[i]:
                    cap = bid[i, bundles[i][-1]]
                for j in range(t):
                    if j in bundles[i]:
                        continue
                    cost, at = _insertion(routes[i], j, i, start, legs, back)
                    value = min(ceiling - cost, cap)
                    beats = value > bid[i, j] + 1e-12 or (
                        abs(value - bid[i, j]) <= 1e-12 and 0 <= i < winner[i, j]
                    )
                    if beats and value > best_bid + 1e-12:
                        best_j, best_bid, best_at = j, value, at
                if best_j < 0:
                    break
                bundles[i].append(best_j)
                routes[i].insert(best_at, best_j)
                bid[i, best_j], winner[i, best_j] = best_bid, i
        # phase 2: everyone hears everyone; the highest bid wins (ties: the lower index)
        top_bid, top_winner = bid[0].copy(), winner[0].copy()
        for i in range(1, k):
            better = (bid[i] > top_bid + 1e-12) | (
                (np.abs(bid[i] - top_bid) <= 1e-12) & (winner[i] >= 0)
                & ((top_winner < 0) | (winner[i] < top_winner))
            )  # fmt: skip
            top_bid = np.where(better, bid[i], top_bid)
            top_winner = np.where(better, winner[i], top_winner)
        changed = bool(np.any(bid != top_bid[None, :]) or np.any(winner != top_winner[None, :]))
        bid[:], winner[:] = top_bid, top_winner
        for i in range(k):  # an outbid target goes, and every target added after it
            lost = next((n for n, j in enumerate(bundles[i]) if winner[i, j] != i), None)
            if lost is None:
                continue
            changed = True
            for j in bundles[i][lost:]:
                routes[i].remove(j)
                if winner[i, j] == i:  # released, not outbid: nobody holds it now
                    bid[:, j], winner[:, j] = 0.0, -1
            bundles[i] = bundles[i][:lost]
        if not changed:
            table = np.zeros((k, t), dtype=bool)
            for i, bundle in enumerate(bundles):
                table[i, bundle] = True
            return AuctionResult(table, [list(b) for b in bundles], rounds)
    raise RuntimeError(f"the auction did not converge in {MAX_ROUNDS} rounds")
