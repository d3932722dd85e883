"""The compiled decision step of N missions, as a list of named phases.

One row (mission) of a step is::

    burn       the thrust model, cut to what the Δv budget still allows
    propagate  exact zero-order-hold flight over the step, sampled at the collision sub-steps
    contacts   the swept contact check along the sampled path
    measure    the gaps to every body at the step's end (and the obstacle ranking, clearance)
    captures   targets reached slowly enough
    judge      collision, bounds, success; terminated and truncated
    reward     the named terms, with the potential-based progress term

Each phase is an inlined compiled function over the named structures of
:mod:`debris_gym.mission_data`; :func:`step_rows` reads as that list. :func:`begin_rows` starts
episodes. The rules are those of ``docs/environments.md``; :class:`debris_gym.mission_batch.
MissionBatch` drives these kernels and ``tests/test_mission_batch.py`` holds them to an
independent reference env.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from debris_gym.batch_geometry import field_gaps, path_touches
from debris_gym.goal import DOCK_GOAL, NO_GOAL, current_goal
from debris_gym.jit import inlined, kernel, threaded
from debris_gym.thrust import delta_v_rate_row, thrust_row

# reward term columns, in REWARD_TERMS order (mission_data.RewardWeights checks that order)
_T_CAPTURE, _T_SUCCESS, _T_PROGRESS, _T_DV, _T_COLLISION, _T_OOB, _T_TIME = range(7)

# --- phases -----------------------------------------------------------------------------------


@inlined
def burn(i, action, rules, missions, accel):
    """Thrust: the commanded acceleration of ``action`` into ``accel`` (dim,) and into
    ``missions.accel[i]``, cut to what the Δv budget still allows (a burn that would overspend
    it spends it exactly); the Δv is added to the mission's. Returns the step's Δv (m/s)."""
    thrust_row(action, rules.max_accel, rules.box_thrust, accel)
    dv = delta_v_rate_row(accel, rules.box_thrust) * rules.dt
    spent = missions.delta_v[i]
    budget = rules.delta_v_budget
    if dv > 0.0 and spent + dv > budget:
        scale = max(budget - spent, 0.0) / dv
        for k in range(accel.shape[0]):
            accel[k] = accel[k] * scale
        dv = dv * scale
    for k in range(accel.shape[0]):
        missions.accel[i, k] = accel[k]
    missions.delta_v[i] = spent + dv
    return dv


@inlined
def propagate(i, accel, rules, missions, start, path):
    """Fly the step: ``start`` (2·dim,) ← the state before it, ``path`` (K + 1, dim) ← its start
    and the K sub-step positions, the mission's state ← the end; the clock advances."""
    state = missions.state
    matrix_t = rules.step_matrix_t
    dim = accel.shape[0]
    n_sub = path.shape[0] - 1
    for k in range(2 * dim):
        start[k] = state[i, k]
    for a in range(dim):
        path[0, a] = start[a]
    # [x₀, u] @ matrix_t: every sub-step position, then the end velocity
    for c in range(matrix_t.shape[1]):
        s = 0.0
        for k in range(2 * dim):
            s += start[k] * matrix_t[k, c]
        for k in range(dim):
            s += accel[k] * matrix_t[2 * dim + k, c]
        if c < n_sub * dim:
            path[1 + c // dim, c % dim] = s
        else:
            state[i, dim + c - n_sub * dim] = s
    for a in range(dim):
        state[i, a] = path[n_sub, a]
    missions.time[i] += rules.dt
    missions.steps[i] += 1


@inlined
def contacts(i, path, rules, missions, field, touched):
    """Which bodies the chaser touched along ``path`` into ``touched`` (B,), swept from the
    gaps at its start (the gaps of the step before)."""
    path_touches(
        path, missions.gaps[i], rules.chaser_radius, i, field.centers, field.radii,
        field.polygon_start, field.n_vertices, field.vertices, touched,
    )  # fmt: skip


@inlined
def measure(i, rules, missions, field):
    """Gaps from the chaser to every body (:func:`measure_gaps`) and the smallest obstacle gap
    of the episode so far."""
    measure_gaps(i, rules, missions, field)
    n_targets, n_bodies = rules.n_targets, missions.gaps.shape[1]
    if n_bodies > n_targets:  # clearance to debris other than targets
        clearance = missions.min_clearance[i]
        for b in range(n_targets, n_bodies):
            clearance = min(clearance, missions.gaps[i, b])
        missions.min_clearance[i] = clearance


@inlined
def measure_gaps(i, rules, missions, field):
    """Gaps (m) from mission ``i``'s chaser centre to every body, and its ranked obstacles
    ``missions.nearest[i]`` re-sorted by gap (:func:`sort_by_gap`).

    The gaps are exact for every body: computing all of them in one tight loop costs less than
    culling polygons with bounds (the bookkeeping of a culled selection outweighs the polygon
    edges it saves at the default obstacle count; docs/benchmarks.md).
    """
    dim = field.dock.shape[1]
    field_gaps(
        missions.state[i, :dim], i, field.centers, field.radii, field.polygon_start,
        field.polygons, field.n_vertices, field.vertices, missions.gaps[i],
    )  # fmt: skip
    sort_by_gap(missions.gaps[i], missions.nearest[i])


@inlined
def captures(i, rules, missions):
    """Capture the targets within ``capture_radius`` of the chaser's surface while its speed is
    at most ``capture_speed`` (targets are at rest in LVLH); queued, only the queue head.
    Returns ``(targets captured now, slow)``."""
    state = missions.state
    dim = state.shape[1] // 2
    s = 0.0
    for a in range(dim):
        s += state[i, dim + a] * state[i, dim + a]
    slow = math.sqrt(s) <= rules.capture_speed
    new = 0
    reach = rules.capture_radius + rules.chaser_radius
    for j in range(rules.n_targets):
        if missions.captured[i, j]:
            continue
        if slow and missions.gaps[i, j] <= reach:
            missions.captured[i, j] = True
            new += 1
        if rules.queued:
            break  # only the queue head can be captured
    return new, slow


@inlined
def judge(i, start, touched, slow, rules, missions, field, out):
    """Collision, bounds and success after the step; ``out.terminated`` (any of them, or the
    budget spent) and ``out.truncated`` (the step limit). Returns terminated."""
    state = missions.state
    dim = start.shape[0] // 2
    n_targets = rules.n_targets
    hit = False
    for b in range(n_targets, touched.shape[0]):
        if touched[b]:
            hit = True  # any contact with debris that is not a target
            break
    if not hit and not slow:
        # a target touched too fast is a collision unless the chaser is leaving it: moving
        # away from its centre at both ends of the step and over the step as a whole
        # (departing after a gentle contact is not an impact)
        for j in range(n_targets):
            if touched[j]:
                closing0 = 0.0
                closing1 = 0.0
                closing_step = 0.0
                for a in range(dim):
                    toward = field.centers[i, j, a] - start[a]
                    closing0 += toward * start[dim + a]
                    closing1 += (field.centers[i, j, a] - state[i, a]) * state[i, dim + a]
                    closing_step += toward * (state[i, a] - start[a])
                if closing0 > 0.0 or closing1 > 0.0 or closing_step > 0.0:
                    hit = True
    missions.collision[i] = missions.collision[i] or hit
    oob = False
    for a in range(dim):
        if state[i, a] <= field.low[i, a] or state[i, a] >= field.high[i, a]:
            oob = True
    missions.out_of_bounds[i] = oob
    done = not missions.collision[i]
    for j in range(n_targets):
        done = done and missions.captured[i, j]
    if done and rules.return_to_dock:
        s = 0.0
        for a in range(dim):
            off = state[i, a] - field.dock[i, a]
            s += off * off
        done = math.sqrt(s) <= rules.capture_radius and slow
    missions.success[i] = missions.success[i] or done
    spent = missions.delta_v[i] >= rules.delta_v_budget
    ended = missions.success[i] or missions.collision[i] or missions.out_of_bounds[i] or spent
    out.terminated[i] = ended
    out.truncated[i] = rules.max_steps > 0 and missions.steps[i] >= rules.max_steps
    return ended


@inlined
def reward(i, new, dv, ended, rules, shaping, missions, field, out):
    """The named reward terms of the step into ``out.terms[i]`` and their sum into
    ``out.reward[i]``; the mission's potential becomes Φ(s′)."""
    w = rules.weights
    phi = potential(i, rules, shaping, missions, field)
    progress = rules.gamma * phi - missions.potential[i]
    missions.potential[i] = phi
    terms = out.terms
    terms[i, _T_CAPTURE] = w.capture * new
    terms[i, _T_SUCCESS] = w.success * missions.success[i]
    terms[i, _T_PROGRESS] = w.progress * progress
    terms[i, _T_DV] = -w.delta_v * dv
    terms[i, _T_COLLISION] = -w.collision * missions.collision[i]
    terms[i, _T_OOB] = -w.out_of_bounds * missions.out_of_bounds[i]
    terms[i, _T_TIME] = -w.time
    if ended and rules.terminal_zero:
        terms[i, _T_PROGRESS] -= w.progress * rules.gamma * phi  # Φ(terminal) = 0
    total = 0.0
    for k in range(terms.shape[1]):
        total += terms[i, k]
    out.reward[i] = total


@inlined
def idle(i, out):
    """The outputs of a mission that does not step: zero reward and terms, no end."""
    for k in range(out.terms.shape[1]):
        out.terms[i, k] = 0.0
    out.reward[i] = 0.0
    out.terminated[i] = False
    out.truncated[i] = False


# --- the potential ----------------------------------------------------------------------------


@inlined
def potential(i, rules, shaping, missions, field):
    """Φ of mission ``i``: −(gap to the current goal / L + goals after it), less the optional
    terms of ``shaping`` (:func:`shaping_terms`; see :mod:`debris_gym.rewards`).

    ``shaping`` is None when those terms are off (:func:`debris_gym.mission_data.make_shaping`):
    numba then compiles the kernels without the call, whose mere presence cost time in every
    step (docs/benchmarks.md).
    """
    state = missions.state
    goal, gap, after = current_goal(
        missions.gaps[i], missions.captured[i], rules.queued, rules.return_to_dock,
        rules.chaser_radius,
    )  # fmt: skip
    dock = field.dock
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
    phi = -(goal_gap / field.length_scale[i] + after)
    if shaping is not None:
        phi = shaping_terms(phi, goal, goal_gap, i, rules, shaping, missions, field)
    return phi


@kernel  # not inlined: off by default (see potential's ``shaping``)
def shaping_terms(phi, goal, goal_gap, i, rules, shaping, missions, field):
    """Φ less the optional approach-speed, clearance and closing terms: ``shaping.speed`` ·
    max(0, speed − (capture_speed + slope · goal gap)) / V; ``shaping.clearance`` ·
    max(0, 1 − c / d)² (c: the chaser surface's gap to the nearest obstacle);
    ``shaping.closing`` · the largest, over bodies b other than the goal within
    ``closing_distance`` d, of max(0, v_b − capture_speed) / V · (1 − c_b / d) (v_b: the
    chaser's speed toward b's centre)."""
    state, gaps, centers = missions.state, missions.gaps, field.centers
    dim = centers.shape[2]
    n_targets, chaser_r = rules.n_targets, rules.chaser_radius
    speed_scale = field.speed_scale[i]
    if shaping.speed > 0.0 and goal != NO_GOAL:
        s = 0.0
        for a in range(dim):
            s += state[i, dim + a] * state[i, dim + a]
        allowed = rules.capture_speed + shaping.speed_slope * goal_gap
        phi -= shaping.speed * max(math.sqrt(s) - allowed, 0.0) / speed_scale
    if shaping.clearance > 0.0 and gaps.shape[1] > n_targets:
        nearest = math.inf
        for b in range(n_targets, gaps.shape[1]):
            nearest = min(nearest, gaps[i, b])
        clearance = max(nearest - chaser_r, 0.0)
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
                rel = centers[i, b, a] - state[i, a]
                toward += rel * state[i, dim + a]
                dist2 += rel * rel
            closing = toward / math.sqrt(dist2) if dist2 > 0.0 else 0.0
            excess = max(closing - rules.capture_speed, 0.0) / speed_scale
            worst = max(worst, excess * (1.0 - max(c, 0.0) / reach))
        phi -= shaping.closing * worst
    return phi


@inlined
def sort_by_gap(gaps, order):
    """Sort the body indices ``order`` by ``gaps`` (B,), nearest first, equal gaps by index.

    An insertion sort, started from the order of the step before: the chaser moves little in a
    step, so the order is nearly sorted already and the sort costs about one comparison per
    body, with branches that predict well (selecting the nearest few afresh every step, by
    insertion into a short sorted list, costs more: its branches mispredict). The result is the
    same (gap, index) order whatever the starting permutation.
    """
    for j in range(1, order.shape[0]):
        x = order[j]
        g = gaps[x]
        k = j - 1
        while k >= 0:
            y = order[k]
            h = gaps[y]
            if h < g or (h == g and y < x):
                break
            order[k + 1] = y
            k -= 1
        order[k + 1] = x


# --- kernels ----------------------------------------------------------------------------------


@kernel
def begin_rows(rows, states, rules, shaping, missions, field):
    """Start new episodes in ``rows``: the chaser at ``states`` (R, 2·dim) or, if None, at rest
    at the dock; clocks, Δv and flags cleared; gaps, clearance and potential computed."""
    dim = field.dock.shape[1]
    n_targets, n_bodies = rules.n_targets, field.centers.shape[1]
    state = missions.state
    for r in range(rows.shape[0]):
        i = rows[r]
        for k in range(missions.nearest.shape[1]):  # a new field: sort from index order
            missions.nearest[i, k] = n_targets + k
        for a in range(dim):
            if states is None:
                state[i, a] = field.dock[i, a]
                state[i, dim + a] = 0.0
            else:
                state[i, a] = states[r, a]
                state[i, dim + a] = states[r, dim + a]
            missions.accel[i, a] = 0.0
        missions.time[i] = 0.0
        missions.steps[i] = 0
        missions.delta_v[i] = 0.0
        for j in range(n_targets):
            missions.captured[i, j] = False
        missions.collision[i] = False
        missions.out_of_bounds[i] = False
        missions.success[i] = False
        measure_gaps(i, rules, missions, field)
        clearance = math.inf
        for b in range(n_targets, n_bodies):
            clearance = min(clearance, missions.gaps[i, b])
        missions.min_clearance[i] = clearance
        missions.potential[i] = potential(i, rules, shaping, missions, field)


@kernel
def step_all(live, actions, rules, shaping, missions, field, out):
    """One step of every mission in ``live`` (see :meth:`MissionBatch.step`)."""
    step_rows(0, live.shape[0], live, actions, rules, shaping, missions, field, out)


@threaded
def step_all_threaded(n_chunks, live, actions, rules, shaping, missions, field, out):
    """:func:`step_all` with the missions split into ``n_chunks`` row ranges run in parallel."""
    num = live.shape[0]
    for c in numba.prange(n_chunks):
        lo, hi = c * num // n_chunks, (c + 1) * num // n_chunks
        step_rows(lo, hi, live, actions, rules, shaping, missions, field, out)


@kernel  # called once per row range: no need to inline it
def step_rows(lo, hi, live, actions, rules, shaping, missions, field, out):
    """One step of the missions ``lo … hi − 1`` that are ``live``: the phases in order."""
    dim = field.dock.shape[1]
    path = np.empty((rules.step_matrix_t.shape[1] // dim, dim))  # start + every sub-step
    start = np.empty(2 * dim)
    accel = np.empty(dim)
    touched = np.empty(field.centers.shape[1], dtype=np.bool_)
    for i in range(lo, hi):
        if not live[i]:
            idle(i, out)
            continue
        dv = burn(i, actions[i], rules, missions, accel)
        propagate(i, accel, rules, missions, start, path)
        contacts(i, path, rules, missions, field, touched)
        measure(i, rules, missions, field)
        new, slow = captures(i, rules, missions)
        ended = judge(i, start, touched, slow, rules, missions, field, out)
        reward(i, new, dv, ended, rules, shaping, missions, field, out)


@kernel
def count_rows(flags, out):
    """out[i] = number of True in flags[i] (cheaper than numpy's bool sum along a short axis)."""
    for i in range(flags.shape[0]):
        count = 0
        for j in range(flags.shape[1]):
            count += flags[i, j]
        out[i] = count
