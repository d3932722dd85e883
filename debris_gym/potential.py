"""The shaping potential Φ of a mission row, and the row quantities it reads (compiled).

:func:`potential` (the goal potential) and :func:`tour_potential` (the shortest remaining
mission, ``shaping_potential="tour"``), each less the optional terms of :func:`shaping_terms`;
the rules are those of :mod:`debris_gym.rewards` and ``docs/environments.md``. The step
(:mod:`debris_gym.mission_step`) inlines them. No gymnasium import.
"""

from __future__ import annotations

import math

from debris_gym.goal import DOCK_GOAL, NO_GOAL, current_goal, remaining_tour
from debris_gym.jit import inlined, kernel


@inlined
def nearest_obstacle(i, n_targets, gaps, clearance):
    """The smaller of ``clearance`` and the gaps (m) to the obstacles (bodies from
    ``n_targets`` on) of row ``i``."""
    for b in range(n_targets, gaps.shape[1]):
        clearance = min(clearance, gaps[i, b])
    return clearance


@inlined
def speed_of(i, state):
    """The chaser's speed (m/s) in row ``i`` of ``state`` (N, 2·dim)."""
    dim = state.shape[1] // 2
    s = 0.0
    for a in range(dim):
        s += state[i, dim + a] * state[i, dim + a]
    return math.sqrt(s)


@inlined
def potential(
    i, f, rules, shaping, state, gaps, captured, centers, dock, length_scale, speed_scale
):  # fmt: skip
    """Φ of mission ``i`` (in field ``f``): −(gap to the current goal / L + goals after it),
    less the optional terms of ``shaping`` (:func:`shaping_terms`; see :mod:`debris_gym.rewards`).

    ``shaping`` is None when those terms are off (:func:`debris_gym.mission_data.make_shaping`):
    numba then compiles the kernels without the call, whose mere presence cost time in every
    step (docs/benchmarks.md, "Measured design choices").
    """
    goal, gap, after = current_goal(
        i, gaps, captured, rules.queued, rules.return_to_dock, rules.chaser_radius
    )
    if goal == DOCK_GOAL:  # the distance to the dock, written out for 2 or 3 axes (no loop)
        off = state[i, 0] - dock[i, 0]
        s = off * off
        off = state[i, 1] - dock[i, 1]
        s += off * off
        if dock.shape[1] == 3:
            off = state[i, 2] - dock[i, 2]
            s += off * off
        gap = math.sqrt(s)
    goal_gap = max(gap, 0.0)
    phi = -(goal_gap / length_scale[f] + after)
    if shaping is not None:
        phi = shaping_terms(
            phi, goal, goal_gap, i, f, rules, shaping, state, gaps, centers, speed_scale[f]
        )
    return phi


@inlined
def tour_potential(
    i, f, rules, shaping, state, gaps, captured, centers, radii, dock, length_scale, speed_scale,
    order, counters, legs, homes,
):  # fmt: skip
    """Φ of mission ``i`` (in field ``f``) with ``shaping_potential="tour"`` (the v1 world):
    −(the shortest remaining mission / L) (:func:`debris_gym.goal.remaining_tour`), less the
    optional terms of ``shaping`` as :func:`potential` applies them. ``order``, ``counters``
    (T,), ``legs`` (T, T) and ``homes`` (T,) are scratch
    (:func:`~debris_gym.goal.remaining_tour`)."""
    tour = remaining_tour(
        i, f, gaps, captured, rules.queued, rules.return_to_dock, rules.chaser_radius, centers,
        radii, dock, state, order, counters, legs, homes,
    )  # fmt: skip
    phi = -tour / length_scale[f]
    if shaping is not None:
        goal, gap, _ = current_goal(
            i, gaps, captured, rules.queued, rules.return_to_dock, rules.chaser_radius
        )
        phi = shaping_terms(
            phi, goal, max(gap, 0.0), i, f, rules, shaping, state, gaps, centers, speed_scale[f]
        )
    return phi


@kernel  # not inlined: off by default (see potential's ``shaping``)
def shaping_terms(phi, goal, goal_gap, i, f, rules, shaping, state, gaps, centers, speed_scale):
    """Φ less the optional approach-speed, clearance and closing terms: ``shaping.speed`` ·
    max(0, speed − (capture_speed + slope · goal gap)) / V; ``shaping.clearance`` ·
    max(0, 1 − c / d)² (c: the chaser surface's gap to the nearest obstacle);
    ``shaping.closing`` · the largest, over bodies b other than the goal within
    ``closing_distance`` d, of max(0, v_b − capture_speed) / V · (1 − c_b / d) (v_b: the
    chaser's speed toward b's centre). ``speed_scale`` is the row's V (m/s)."""
    dim = centers.shape[2]
    n_targets, chaser_r = rules.n_targets, rules.chaser_radius
    if shaping.speed > 0.0 and goal != NO_GOAL:
        allowed = rules.capture_speed + shaping.speed_slope * goal_gap
        phi -= shaping.speed * max(speed_of(i, state) - allowed, 0.0) / speed_scale
    if shaping.clearance > 0.0 and gaps.shape[1] > n_targets:
        clearance = max(nearest_obstacle(i, n_targets, gaps, math.inf) - chaser_r, 0.0)
        closeness = max(1.0 - clearance / shaping.clearance_distance, 0.0)
        phi -= shaping.clearance * closeness * closeness
    if shaping.closing > 0.0:
        worst = 0.0
        reach = shaping.closing_distance
        for b in range(gaps.shape[1]):
            c = gaps[i, b] - chaser_r
            if b == goal or not c < reach:
                continue
            toward = 0.0
            dist2 = 0.0
            for a in range(dim):
                rel = centers[f, b, a] - state[i, a]
                toward += rel * state[i, dim + a]
                dist2 += rel * rel
            closing = toward / math.sqrt(dist2) if dist2 > 0.0 else 0.0
            excess = max(closing - rules.capture_speed, 0.0) / speed_scale
            worst = max(worst, excess * (1.0 - max(c, 0.0) / reach))
        phi -= shaping.closing * worst
    return phi
