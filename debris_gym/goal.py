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

    index: int
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
