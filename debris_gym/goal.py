"""The goal rule: which target (or the dock) a mission is heading for now.

One compiled function, :func:`current_goal`, serves the envs' step (its shaping potential and
the goal observation) and Python callers (``DebrisFieldEnv.current_goal``, planners and
agents) alike, so the rule exists once. No gymnasium import.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from debris_gym.jit import inlined

TARGET_GOAL_MIN = 0
"""Goal indices ≥ this are targets (their index in the scenario's target list)."""
DOCK_GOAL = -1
"""Goal index of the dock (every target captured, a return required)."""
NO_GOAL = -2
"""Goal index when nothing is left (every target captured, no return required)."""


class Goal(NamedTuple):
    """A mission's current goal (see :func:`current_goal`)."""

    index: int  # type: ignore[assignment]  # the public name; shadows tuple.index on purpose
    """Target index (≥ 0), :data:`DOCK_GOAL` (−1) or :data:`NO_GOAL` (−2)."""
    gap: float
    """For a target, the gap from the chaser's surface to the target's surface (m, negative
    when they overlap); for the dock, the distance from the chaser's centre to the dock (m);
    0.0 when nothing is left."""
    goals_after: int
    """Goals still to reach after this one (targets, plus the dock if a return is required)."""


@inlined
def current_goal(i, gaps, captured, queued, return_to_dock, chaser_radius):
    """The current goal of mission (row) ``i``: ``(index, gap, goals_after)``.

    The rule: while a target is uncaptured the goal is a target — with ``queued`` the first
    uncaptured one in index order (the queue head), else the uncaptured target with the
    smallest gap (the lowest index among equal gaps). Once every target is captured the goal is
    the dock (index −1) if ``return_to_dock``, else nothing (index −2).

    Rows of 2D arrays rather than 1D arrays: the compiled step calls it in its row loop, where
    a row view would cost a reference-count update per call. From Python, for one mission:
    ``current_goal(0, gaps[None], captured[None], ...)``.

    Args:
        i: the row.
        gaps: (N, ≥ T) float, row i: the gaps from the chaser's centre to each body's surface
            (m); only the first T entries (the targets, in scenario order) are read.
        captured: (N, T) bool, row i: which targets are captured.
        queued: the ``target_order == "queued"`` rule.
        return_to_dock: the ``return_to_dock`` rule.
        chaser_radius: chaser radius (m), subtracted from the target's gap.

    Returns:
        ``index`` (int), ``gap`` (float, m) — for a target ``gaps[i, index] − chaser_radius``,
        the chaser-surface-to-target-surface gap; 0.0 for the dock and for nothing (the dock's
        distance is the caller's to measure) — and ``goals_after`` (int): uncaptured targets
        after this one, plus 1 for the dock if ``return_to_dock``; 0 at the dock or when
        nothing is left.
    """
    goal = NO_GOAL
    gap = math.inf
    left = 0
    for j in range(captured.shape[1]):
        if not captured[i, j]:
            if (not queued or left == 0) and gaps[i, j] < gap:
                gap = gaps[i, j]
                goal = j
            left += 1
    if left:
        return goal, gap - chaser_radius, left - 1 + (1 if return_to_dock else 0)
    return (DOCK_GOAL if return_to_dock else NO_GOAL), 0.0, 0


EXACT_TOUR_TARGETS = 6
"""Most uncaptured targets :func:`remaining_tour` orders exactly (every order: 720 for 6);
beyond, it follows the nearest-neighbour order."""


@inlined
def _leg(f, a, b, centers, radii):
    """Surface-to-surface distance (m, at least 0) between targets ``a`` and ``b`` of field
    ``f``."""
    s = 0.0
    for k in range(centers.shape[2]):
        d = centers[f, a, k] - centers[f, b, k]
        s += d * d
    return max(math.sqrt(s) - radii[f, a] - radii[f, b], 0.0)


@inlined
def _home(i, f, j, centers, radii, dock):
    """Distance (m, at least 0) from target ``j``'s surface (field ``f``) to row ``i``'s
    dock."""
    s = 0.0
    for k in range(centers.shape[2]):
        d = centers[f, j, k] - dock[i, k]
        s += d * d
    return max(math.sqrt(s) - radii[f, j], 0.0)


@inlined
def _order_length(
    i, f, order, m, start, return_to_dock, gaps, chaser_radius, centers, radii, dock
):  # fmt: skip
    """Length (m) of the tour chaser → targets ``order[:m]`` in turn (→ dock)."""
    total = max(gaps[i, order[0]] - chaser_radius, 0.0) if start else 0.0
    for k in range(1, m):
        total += _leg(f, order[k - 1], order[k], centers, radii)
    if return_to_dock:
        total += _home(i, f, order[m - 1], centers, radii, dock)
    return total


@inlined
def _tabulate_legs(i, f, order, m, return_to_dock, centers, radii, dock, legs, homes):
    """legs[a, b] = :func:`_leg` (f, a, b) for the targets a ≠ b in ``order[:m]`` (one square
    root per pair), homes[a] = :func:`_home` (i, f, a) when the mission returns to the dock."""
    for p in range(m):
        a = order[p]
        for q in range(p + 1, m):
            b = order[q]
            s = 0.0
            for k in range(centers.shape[2]):
                d = centers[f, a, k] - centers[f, b, k]
                s += d * d
            root = math.sqrt(s)
            legs[a, b] = max(root - radii[f, a] - radii[f, b], 0.0)
            legs[b, a] = max(root - radii[f, b] - radii[f, a], 0.0)
        if return_to_dock:
            homes[a] = _home(i, f, a, centers, radii, dock)


@inlined
def _tabulated_length(i, order, m, return_to_dock, gaps, chaser_radius, legs, homes):
    """:func:`_order_length` of ``order[:m]`` from the chaser, over tabulated legs (the same
    sum in the same order, so the same number)."""
    total = max(gaps[i, order[0]] - chaser_radius, 0.0)
    for k in range(1, m):
        total += legs[order[k - 1], order[k]]
    if return_to_dock:
        total += homes[order[m - 1]]
    return total


@inlined
def _short_tour(i, order, m, return_to_dock, gaps, chaser_radius, legs, homes):
    """The shortest of every order of the m <= 3 targets ``order[:m]``, each order's length
    the sum :func:`_tabulated_length` takes, in its order: the orders written out (Heap's loop
    over 6 orders costs about as much again in branches)."""
    a = order[0]
    ga = max(gaps[i, a] - chaser_radius, 0.0)
    if m == 1:
        return ga + homes[a] if return_to_dock else ga
    b = order[1]
    gb = max(gaps[i, b] - chaser_radius, 0.0)
    if m == 2:
        ab = ga + legs[a, b]
        ba = gb + legs[b, a]
        if return_to_dock:
            ab += homes[b]
            ba += homes[a]
        return min(ab, ba)
    c = order[2]
    gc = max(gaps[i, c] - chaser_radius, 0.0)
    abc = ga + legs[a, b] + legs[b, c]
    acb = ga + legs[a, c] + legs[c, b]
    bac = gb + legs[b, a] + legs[a, c]
    bca = gb + legs[b, c] + legs[c, a]
    cab = gc + legs[c, a] + legs[a, b]
    cba = gc + legs[c, b] + legs[b, a]
    if return_to_dock:
        abc += homes[c]
        acb += homes[b]
        bac += homes[c]
        bca += homes[a]
        cab += homes[b]
        cba += homes[a]
    return min(min(min(abc, acb), min(bac, bca)), min(cab, cba))


@inlined
def remaining_tour(
    i, f, gaps, captured, queued, return_to_dock, chaser_radius, centers, radii, dock, state, order,
    counters, legs, homes,
):  # fmt: skip
    """Length (m) of the shortest remaining mission of row ``i`` (in field ``f``) as it stands
    now: from the
    chaser's surface through every uncaptured target (surface to surface) and, if a return is
    required, on to the dock — in the queue's order for ``queued``, else in the best order
    (every order for up to :data:`EXACT_TOUR_TARGETS` targets, nearest-neighbour beyond). With
    every target captured it is the distance from the chaser's centre to the dock (or 0).

    The shaping potential of the v1 world (``shaping_potential="tour"``) is minus this over L:
    an agent following any shortest tour gains potential from its first step, whichever target
    it heads for first. ``order`` and ``counters`` are (T,) int64 scratch, ``legs`` (T, T)
    and ``homes`` (T,) float scratch: the exact search tabulates every leg once (each equal to
    :func:`_leg` of its pair, so every order's length is the sum :func:`_order_length` gives).
    """
    m = 0
    for j in range(captured.shape[1]):
        if not captured[i, j]:
            order[m] = j
            m += 1
    if m == 0:
        if not return_to_dock:
            return 0.0
        s = 0.0
        for k in range(dock.shape[1]):
            d = state[i, k] - dock[i, k]
            s += d * d
        return math.sqrt(s)
    if queued:
        return _order_length(
            i, f, order, m, True, return_to_dock, gaps, chaser_radius, centers, radii, dock
        )
    if m > EXACT_TOUR_TARGETS:  # nearest neighbour from the chaser, then from each target
        for k in range(m):
            best = k
            for q in range(k + 1, m):
                if k == 0:
                    closer = gaps[i, order[q]] < gaps[i, order[best]]
                else:
                    closer = _leg(f, order[k - 1], order[q], centers, radii) < _leg(
                        f, order[k - 1], order[best], centers, radii
                    )
                if closer:
                    best = q
            order[k], order[best] = order[best], order[k]
        return _order_length(
            i, f, order, m, True, return_to_dock, gaps, chaser_radius, centers, radii, dock
        )
    # every order, over the legs tabulated once
    _tabulate_legs(i, f, order, m, return_to_dock, centers, radii, dock, legs, homes)
    if m <= 3:
        return _short_tour(i, order, m, return_to_dock, gaps, chaser_radius, legs, homes)
    # by Heap's algorithm (iterative)
    best = _tabulated_length(i, order, m, return_to_dock, gaps, chaser_radius, legs, homes)
    for k in range(m):
        counters[k] = 0
    k = 1
    while k < m:
        if counters[k] < k:
            if k % 2 == 0:
                order[0], order[k] = order[k], order[0]
            else:
                c = counters[k]
                order[c], order[k] = order[k], order[c]
            best = min(
                best,
                _tabulated_length(i, order, m, return_to_dock, gaps, chaser_radius, legs, homes),
            )
            counters[k] += 1
            k = 1
        else:
            counters[k] = 0
            k += 1
    return best
