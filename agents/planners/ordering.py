"""Visiting order of debris targets: the polygon queue and the shortest closed tour.

References (keys refer to docs/references.md):
    * :func:`polygon_order` — [APF-MPC] Alg. 1 "Multi-Target Debris Queue Ordering": split the
      targets by the line through the min-x and max-x targets, walk the upper set by ascending x
      and the lower set by descending x, which gives a closed polygon whose edges never cross.
    * :func:`shortest_order` — the travelling-salesman tour through a fixed start (the dock).
      Exact by Held–Karp dynamic programming ([Held62]); for larger sets a local search: nearest
      neighbour construction, 2-opt ([Croes58]) and Or-opt ([Or76]), seeded also with the polygon
      tour.
    * :func:`moving_order` — the same question when the targets move (the v1 world): the tour of
      least estimated mission time, each target met where it will be when the chaser gets there
      (an intercept time found by fixed-point iteration at a planning speed), by enumeration of
      every order for a few targets.

All functions are pure: they take coordinates (any length unit, e.g. m) and return Python lists of
indices into ``points``. Tours are closed; the returned orders do not repeat their first element.
"""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "EXACT_MAX_N",
    "MOVING_EXACT_MAX_N",
    "intercept_time",
    "moving_order",
    "moving_tour_time",
    "polygon_order",
    "shortest_order",
    "tour_length",
]

#: Largest number of points solved exactly (Held–Karp, O(2^N N^2) time) by default.
EXACT_MAX_N = 12

_MAX_LOCAL_SEARCH_ROUNDS = 1000

#: Largest number of moving targets whose orders are all enumerated by :func:`moving_order`.
MOVING_EXACT_MAX_N = 5


# --------------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------------


def _as_points(points: ArrayLike, name: str = "points") -> np.ndarray:
    """Checks and converts a point set to a float array of shape (N, 2) or (N, 3)."""
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of shape (N, 2) or (N, 3)") from exc
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (N, 2) or (N, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} must not be empty")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def _as_start(start: ArrayLike, dim: int) -> np.ndarray:
    """Checks and converts the start point to a float array of shape (dim,)."""
    try:
        arr = np.asarray(start, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"start must be a numeric array of shape ({dim},)") from exc
    if arr.shape != (dim,):
        raise ValueError(f"start must have shape ({dim},) like a row of points, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("start must be finite (no NaN or inf)")
    return arr


def _as_order(order: Sequence[int], n: int) -> list[int]:
    """Checks that ``order`` is a permutation of ``range(n)``."""
    try:
        idx = [operator.index(i) for i in order]
    except TypeError as exc:
        raise ValueError("order must be a sequence of integer indices") from exc
    if sorted(idx) != list(range(n)):
        raise ValueError(f"order must be a permutation of range({n})")
    return idx


# --------------------------------------------------------------------------------------------------
# polygon queue ([APF-MPC] Alg. 1)
# --------------------------------------------------------------------------------------------------


def polygon_order(points: ArrayLike) -> list[int]:
    """Polygon queue ordering of targets ([APF-MPC] Alg. 1).

    The first point is the one with the smallest x and the "max-x" point the one with the largest
    x; ties in x are broken by y, i.e. points are compared lexicographically by (x, y) (then by
    index, for duplicate points). The other points are split by the line through these two: points
    above the line or on it form the upper chain, sorted by ascending (x, y); points strictly below
    form the lower chain, sorted by descending (x, y). The tour is
    ``[min-x, upper..., max-x, lower...]`` and closes back to its first element (which is not
    repeated). Both chains are monotone in x and lie on opposite sides of the line, so no two edges
    of the closed tour properly cross, whatever the point set (exactly so when the orientation
    products are exact in floating point, e.g. for integer coordinates below 2**25).

    Args:
        points: target positions, shape (N, 2) or (N, 3), any length unit (m). 3D points are
            projected on their first two coordinates (x, y) for the ordering.

    Returns:
        Indices into ``points``, a permutation of ``range(N)`` starting with the min-x point.

    Raises:
        ValueError: if ``points`` is empty, not of shape (N, 2) or (N, 3), or not finite.
    """
    pts = _as_points(points)[:, :2]
    lex = np.lexsort((pts[:, 1], pts[:, 0]))  # by x, then y; stable, so then by index
    first, last = int(lex[0]), int(lex[-1])
    if first == last:
        return [first]
    rest = lex[1:-1]  # ascending (x, y)
    direction = pts[last] - pts[first]
    rel = pts[rest] - pts[first]
    # z-component of direction × rel: > 0 left of (above) the line first → last, < 0 below.
    cross = direction[0] * rel[:, 1] - direction[1] * rel[:, 0]
    above = rest[cross >= 0.0]
    below = rest[cross < 0.0][::-1]
    return [first, *(int(i) for i in above), last, *(int(i) for i in below)]


# --------------------------------------------------------------------------------------------------
# shortest closed tour
# --------------------------------------------------------------------------------------------------


def tour_length(points: ArrayLike, start: ArrayLike, order: Sequence[int]) -> float:
    """Euclidean length of the closed tour start → points[order] → start.

    Args:
        points: target positions, shape (N, 2) or (N, 3) (m).
        start: start and end point of the tour (e.g. the dock), shape (2,) or (3,) like a row of
            ``points`` (m).
        order: visiting order, a permutation of ``range(N)``.

    Returns:
        The tour length (m).

    Raises:
        ValueError: if ``points`` or ``start`` is malformed or not finite, or ``order`` is not a
            permutation of ``range(N)``.
    """
    pts = _as_points(points)
    s = _as_start(start, pts.shape[1])
    idx = _as_order(order, len(pts))
    path = np.vstack([s, pts[idx], s])
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def shortest_order(
    points: ArrayLike, start: ArrayLike, *, exact_max_n: int = EXACT_MAX_N
) -> list[int]:
    """Visiting order of the shortest closed tour start → every point once → start.

    For ``N <= exact_max_n`` the tour is optimal (Held–Karp dynamic programming, O(2^N N^2) time
    and O(2^N N) memory). Beyond that a local search is used: a nearest-neighbour tour and the
    polygon tour of :func:`polygon_order` (entered from ``start`` at its best rotation) are each
    improved by 2-opt and Or-opt moves (segments of 1–3 points, either direction) until no move
    shortens them, and the shorter result is returned. The result is therefore never longer than
    the polygon tour, but is not guaranteed optimal.

    Args:
        points: target positions, shape (N, 2) or (N, 3) (m).
        start: start and end point of the tour (e.g. the dock), shape like a row of ``points`` (m).
        exact_max_n: largest N solved exactly; 0 forces the heuristic.

    Returns:
        Indices into ``points`` in visiting order (a permutation of ``range(N)``); the tour
        starts and ends at ``start``, which has no index.

    Raises:
        ValueError: if ``points`` or ``start`` is malformed or not finite.
    """
    pts = _as_points(points)
    s = _as_start(start, pts.shape[1])
    n = len(pts)
    if n == 1:
        return [0]
    nodes = np.vstack([s, pts])  # node 0 is the start, node i + 1 is points[i]
    dist = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=-1)
    tour = _held_karp(dist) if n <= exact_max_n else _local_search_best(dist, pts)
    return [int(v) - 1 for v in tour[1:]]


def _held_karp(dist: np.ndarray) -> np.ndarray:
    """Optimal closed tour from node 0 through nodes 1..n (Held–Karp DP).

    ``cost[mask, j]`` is the length of the shortest path from node 0 through the cities in
    ``mask`` (bit j ↔ node j + 1) ending at city j. Subsets are processed by size; for each size
    and end city all subsets are handled in one vectorised step.
    """
    n = dist.shape[0] - 1
    full = 1 << n
    city = dist[1:, 1:]
    masks = np.arange(full)
    bits = (masks[:, None] >> np.arange(n)) & 1
    size = bits.sum(axis=1)
    cost = np.full((full, n), np.inf)
    parent = np.full((full, n), -1, dtype=np.int64)
    singles = 1 << np.arange(n)
    cost[singles, np.arange(n)] = dist[0, 1:]
    for k in range(2, n + 1):
        layer = masks[size == k]
        for j in range(n):
            sub = layer[bits[layer, j] == 1]
            cand = cost[sub ^ (1 << j)] + city[:, j]  # inf where the previous city is absent
            best = np.argmin(cand, axis=1)
            cost[sub, j] = cand[np.arange(len(sub)), best]
            parent[sub, j] = best
    mask = full - 1
    j = int(np.argmin(cost[mask] + dist[1:, 0]))
    reverse = []
    while j >= 0:
        reverse.append(j + 1)
        j, mask = int(parent[mask, j]), mask ^ (1 << j)
    return np.array([0, *reverse[::-1]], dtype=np.int64)


def _cycle_length(dist: np.ndarray, tour: np.ndarray) -> float:
    """Length of the closed tour ``tour`` (node indices, back to ``tour[0]``)."""
    return float(dist[tour, np.roll(tour, -1)].sum())


def _nearest_neighbour(dist: np.ndarray) -> np.ndarray:
    """Greedy tour from node 0, always to the nearest unvisited node (lowest index on ties)."""
    m = dist.shape[0]
    visited = np.zeros(m, dtype=bool)
    tour = np.empty(m, dtype=np.int64)
    current = 0
    for pos in range(m):
        tour[pos] = current
        visited[current] = True
        if pos < m - 1:
            current = int(np.argmin(np.where(visited, np.inf, dist[current])))
    return tour


def _polygon_seed(dist: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The polygon cycle entered from node 0 where that costs least.

    Entering the cycle c at c[i] and leaving it at c[i-1] replaces the edge (c[i-1], c[i]) by the
    two edges to and from the start.
    """
    cycle = np.array(polygon_order(pts), dtype=np.int64) + 1
    prev = np.roll(cycle, 1)
    extra = dist[0, cycle] + dist[prev, 0] - dist[prev, cycle]
    i = int(np.argmin(extra))
    return np.concatenate([[0], np.roll(cycle, -i)])


def _two_opt(dist: np.ndarray, tour: np.ndarray, eps: float) -> bool:
    """Applies improving 2-opt moves (segment reversals) in place until none is left.

    Node 0 stays at position 0; reversing ``tour[i..j]`` (1 <= i < j) swaps the edges
    (tour[i-1], tour[i]) and (tour[j], tour[j+1]) for (tour[i-1], tour[j]) and (tour[i], tour[j+1]).
    """
    m = len(tour)
    improved_any = False
    for _ in range(_MAX_LOCAL_SEARCH_ROUNDS):
        improved = False
        for i in range(1, m - 1):
            a, b = tour[i - 1], tour[i]
            js = np.arange(i + 1, m)
            c, e = tour[js], tour[(js + 1) % m]
            delta = dist[a, c] + dist[b, e] - dist[a, b] - dist[c, e]
            k = int(np.argmin(delta))
            if delta[k] < -eps:
                j = i + 1 + k
                tour[i : j + 1] = tour[i : j + 1][::-1].copy()
                improved = improved_any = True
        if not improved:
            break
    return improved_any


def _or_opt(dist: np.ndarray, tour: np.ndarray, eps: float) -> tuple[np.ndarray, bool]:
    """Applies improving Or-opt moves until none is left.

    A move takes a run of 1–3 consecutive nodes (never node 0) out of the tour and inserts it,
    forwards or reversed, between two other consecutive nodes.
    """
    m = len(tour)
    improved_any = False
    for _ in range(_MAX_LOCAL_SEARCH_ROUNDS):
        improved = False
        for seg_len in (1, 2, 3):
            if seg_len >= m - 1:
                break
            for i in range(1, m - seg_len + 1):
                seg = tour[i : i + seg_len]
                prev, nxt = tour[i - 1], tour[(i + seg_len) % m]
                gain = dist[prev, seg[0]] + dist[seg[-1], nxt] - dist[prev, nxt]
                rest = np.concatenate([tour[:i], tour[i + seg_len :]])
                after = np.roll(rest, -1)
                base = dist[rest, after]
                add_fwd = dist[rest, seg[0]] + dist[seg[-1], after] - base
                add_rev = dist[rest, seg[-1]] + dist[seg[0], after] - base
                kf, kr = int(np.argmin(add_fwd)), int(np.argmin(add_rev))
                if add_fwd[kf] <= add_rev[kr]:
                    k, add, piece = kf, add_fwd[kf], seg
                else:
                    k, add, piece = kr, add_rev[kr], seg[::-1]
                if add - gain < -eps:
                    tour = np.concatenate([rest[: k + 1], piece, rest[k + 1 :]])
                    improved = improved_any = True
        if not improved:
            break
    return tour, improved_any


def _local_search_best(dist: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Best of the nearest-neighbour and polygon seeds after 2-opt + Or-opt."""
    eps = 1e-12 * max(float(dist.max()), 1e-300)
    improved = []
    for seed in (_polygon_seed(dist, pts), _nearest_neighbour(dist)):
        tour = seed.copy()
        for _ in range(_MAX_LOCAL_SEARCH_ROUNDS):
            _two_opt(dist, tour, eps)
            tour, moved = _or_opt(dist, tour, eps)
            if not moved:
                break
        improved.append(tour)
    # min keeps the first (polygon-seeded) tour on ties
    return min(improved, key=lambda tour: _cycle_length(dist, tour))


# --------------------------------------------------------------------------------------------------
# moving targets
# --------------------------------------------------------------------------------------------------


def intercept_time(
    track: Callable[[float], np.ndarray],
    index: int,
    start: np.ndarray,
    t0: float,
    speed: float,
    overhead: float = 0.0,
    tolerance: float = 1e-6,
    max_iterations: int = 200,
) -> float:
    """Flight time (s) from ``start`` at time ``t0`` to target ``index`` where it will be then.

    Fixed point of T = ‖p_i(t0 + T) − start‖ / speed + overhead, iterated from T = overhead: a
    straight flight at the planning ``speed`` (m/s) to the target's future position, plus a
    fixed ``overhead`` (s; braking, matching its velocity, the capture hold). A target slower
    than ``speed`` makes the map a contraction (the error shrinks by at least the ratio of the
    speeds per iteration); iteration stops when T changes by less than ``tolerance`` (s), or
    after ``max_iterations`` (a target faster than the planning speed).

    Args:
        track: positions (N, dim) of every target at a time (s).
        index: the target.
        start: (dim,) where the chaser is at ``t0`` (m).
        t0: departure time (s).
        speed: planning speed (m/s), > 0.
        overhead: fixed time per visit (s), >= 0.
        tolerance: convergence threshold (s).
        max_iterations: iteration cap.
    """
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be > 0 m/s, got {speed!r}")
    if not (math.isfinite(overhead) and overhead >= 0):
        raise ValueError(f"overhead must be >= 0 s, got {overhead!r}")
    flight = float(overhead)
    for _ in range(max_iterations):
        gap = float(np.linalg.norm(np.asarray(track(t0 + flight))[index] - start))
        flight, before = gap / speed + overhead, flight
        if abs(flight - before) <= tolerance:
            break
    return flight


def moving_tour_time(
    track: Callable[[float], np.ndarray],
    start: ArrayLike,
    order: Sequence[int],
    speed: float,
    overhead: float = 0.0,
) -> float:
    """Estimated time (s) of the closed tour ``start`` → targets in ``order`` → ``start``, each
    target met where it will be (:func:`intercept_time`); ``start`` (the dock) does not move."""
    here = np.asarray(start, dtype=float)
    t = 0.0
    for i in order:
        t += intercept_time(track, i, here, t, speed, overhead)
        here = np.asarray(track(t))[i]
    return t + float(np.linalg.norm(here - np.asarray(start, dtype=float))) / speed


def moving_order(
    track: Callable[[float], np.ndarray],
    start: ArrayLike,
    speed: float,
    overhead: float = 0.0,
    *,
    exact_max_n: int = MOVING_EXACT_MAX_N,
) -> list[int]:
    """Visiting order of the moving targets with the least :func:`moving_tour_time`.

    Every order is tried for up to ``exact_max_n`` targets; beyond that the targets' positions
    at t = 0 go to :func:`shortest_order` (a static tour: the enumeration grows as N!).

    Args:
        track: positions (N, dim) (m) of every target at a time t (s since the mission began).
        start: the dock, (dim,) (m).
        speed: planning speed (m/s), > 0.
        overhead: fixed time per visit (s), >= 0.
        exact_max_n: largest N enumerated.

    Returns:
        Indices of the targets in visiting order.
    """
    first = _as_points(track(0.0))
    s = _as_start(start, first.shape[1])
    n = len(first)
    if n == 1:
        return [0]
    if n > exact_max_n:
        return shortest_order(first, s)
    best, best_time = list(range(n)), math.inf
    for order in itertools.permutations(range(n)):
        total = moving_tour_time(track, s, order, speed, overhead)
        if total < best_time - 1e-9:
            best, best_time = list(order), total
    return best
