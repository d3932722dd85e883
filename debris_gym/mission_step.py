"""The compiled decision step of N missions, as a list of named phases.

One row (mission) of a step is::

    burn       the thrust model, cut to what the Δv budget still allows
    propagate  exact zero-order-hold flight over the step, sampled at the collision sub-steps
    contacts   the swept contact check along the sampled path (relative to each moving body)
    move       the bodies' own exact unforced flight over the step (moving fields)
    measure    the gaps to every body at the step's end (and the obstacle ranking, clearance)
    judge      collision (first: with the "hold" capture rule a colliding step captures
               nothing)
    captures   targets held in range at a low relative speed for long enough
    judge      bounds, success, the Δv budget; terminated and truncated
    reward     the named terms, with the potential-based progress term

Each phase is an inlined compiled function; :func:`step_rows` reads as that list.
:func:`begin_rows` starts episodes. The kernels take the named structures of
:mod:`debris_gym.mission_data` and read the arrays of ``Missions``, ``Field``, ``StepOutputs``
and ``StepScratch`` by name, once, at their top, handing each phase the arrays it reads or
writes; scalars (``Rules``, ``Shaping``) are read from their structures anywhere. Nothing is
unpacked by position, so a record's field order can change without changing what a kernel
reads.

The row loop :func:`step_rows` is compiled without numba's reference counting
(:data:`debris_gym.jit.borrowing`): with it, every array handed to an inlined phase costs an
atomic reference-count update per row that numba does not remove, and in a row of spheres only
(3D) those updates are a large part of the row (docs/benchmarks.md, "Measured design
choices"). The loop borrows its arrays from its caller, which also allocates its working
arrays (:class:`StepScratch`).

The rules are those of ``docs/environments.md``; :class:`debris_gym.mission_batch.MissionBatch`
drives these kernels and ``tests/test_mission_batch.py`` holds them to an independent reference
env.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from debris_gym.batch_geometry import field_gaps
from debris_gym.gap_order import sort_by_gap
from debris_gym.jit import borrowing, inlined, kernel, threaded
from debris_gym.mission_data import StepScratch
from debris_gym.orbit_truth import TRACK_WIDTH, truth_step
from debris_gym.potential import nearest_obstacle, potential, speed_of, tour_potential
from debris_gym.rewards import REWARD_TERMS
from debris_gym.swept_contacts import moving_path_touches, pair_distance, path_touches
from debris_gym.thrust import delta_v_rate_row, thrust_row
from debris_gym.uncertainty import err_thrust

# reward term columns, in REWARD_TERMS order
_T_CAPTURE, _T_SUCCESS, _T_PROGRESS, _T_DV, _T_COLLISION, _T_OOB, _T_TIME, _T_BUDGET = range(8)
assert REWARD_TERMS == (
    "capture", "success", "progress", "delta_v", "collision", "out_of_bounds", "time", "budget"
)  # fmt: skip

# --- phases -----------------------------------------------------------------------------------


@inlined
def burn(i, action, rules, delta_v, applied, accel, key, step):
    """Thrust: the commanded acceleration of ``action`` into ``accel`` (dim,) and
    ``applied[i]`` — with :attr:`Rules.thrust_errors` what the thrusters made of it in step
    ``step`` of the episode of error key ``key`` (:func:`~debris_gym.uncertainty.err_thrust`)
    — cut to what the Δv budget still allows (a burn that would overspend it spends it
    exactly); the Δv is added to ``delta_v[i]``. Returns the step's Δv (m/s)."""
    thrust_row(action, rules.max_accel, rules.box_thrust, accel)
    if rules.thrust_errors:
        err_thrust(key, step, rules, accel)
    dv = delta_v_rate_row(accel, rules.box_thrust) * rules.dt
    spent = delta_v[i]
    budget = rules.delta_v_budget
    if dv > 0.0 and spent + dv > budget:
        scale = max(budget - spent, 0.0) / dv
        for k in range(accel.shape[0]):
            accel[k] = accel[k] * scale
        dv = dv * scale
    for k in range(accel.shape[0]):
        applied[i, k] = accel[k]
    delta_v[i] = spent + dv
    return dv


@inlined
def propagate(i, accel, matrix_t, rules, state, time, steps, start, path):
    """Fly the step: ``start`` (2·dim,) ← the state before it, ``path`` (K + 1, dim) ← its start
    and the K sub-step positions (``matrix_t``: :attr:`Rules.step_matrix_t`), ``state[i]`` ← the
    end; the clock advances."""
    dim = accel.shape[0]
    n_sub = path.shape[0] - 1
    for k in range(2 * dim):
        start[k] = state[i, k]
    for a in range(dim):
        path[0, a] = start[a]
    # [x₀, u] @ matrix_t: every sub-step position (column p·dim + a), then the end velocity.
    # Written out for 2 and 3 axes, with [x₀, u] held in locals: dim is not known at compile
    # time, and loops over it (with the inputs read again after every write to the path,
    # which might alias them) compile to far more than the 6 or 9 products of a column; each
    # sum is taken in the row order of matrix_t all the same
    x0, x1, x2, x3 = start[0], start[1], start[2], start[3]
    if dim == 2:
        x4, x5 = accel[0], accel[1]
        x6 = x7 = x8 = 0.0
    else:
        x4, x5, x6, x7, x8 = start[4], start[5], accel[0], accel[1], accel[2]
    for p in range(n_sub + 1):
        for a in range(dim):
            c = p * dim + a
            s = 0.0
            s += x0 * matrix_t[0, c]
            s += x1 * matrix_t[1, c]
            s += x2 * matrix_t[2, c]
            s += x3 * matrix_t[3, c]
            s += x4 * matrix_t[4, c]
            s += x5 * matrix_t[5, c]
            if dim == 3:
                s += x6 * matrix_t[6, c]
                s += x7 * matrix_t[7, c]
                s += x8 * matrix_t[8, c]
            if p < n_sub:
                path[1 + p, a] = s
            else:
                state[i, dim + a] = s
    for a in range(dim):
        state[i, a] = path[n_sub, a]
    time[i] += rules.dt
    steps[i] += 1


@inlined
def move_bodies(f, matrix_t, centers, velocities, polygons, attitude, turns):
    """Every body of field ``f`` flies the step unforced: its state (``centers``,
    ``velocities``) times the exact state-transition matrix Φ(dt) (``matrix_t`` = Φᵀ), and every
    polygon of the field's list ``polygons[f]`` (count, then slots) turns by its step's angle
    (``turns[f, j, 0:2]``; the other slots' attitudes are never read).

    Written out with Φ's structure (:func:`debris_gym.mission_batch.check_transition`): the
    along-track position feeds nothing but itself (Φ_yy = 1), and the cross-track pair (z, ż)
    is decoupled from the plane; the entries left out are exactly zero.
    """
    dim = centers.shape[2]
    v = dim  # index of ẋ in the state
    pxx, pxu, pxv = matrix_t[0, 0], matrix_t[v, 0], matrix_t[v + 1, 0]
    pyx, pyu, pyv = matrix_t[0, 1], matrix_t[v, 1], matrix_t[v + 1, 1]
    pux, puu, puv = matrix_t[0, v], matrix_t[v, v], matrix_t[v + 1, v]
    pvx, pvu, pvv = matrix_t[0, v + 1], matrix_t[v, v + 1], matrix_t[v + 1, v + 1]
    for b in range(centers.shape[1]):
        x, y = centers[f, b, 0], centers[f, b, 1]
        vx, vy = velocities[f, b, 0], velocities[f, b, 1]
        centers[f, b, 0] = pxx * x + pxu * vx + pxv * vy
        centers[f, b, 1] = y + pyx * x + pyu * vx + pyv * vy
        velocities[f, b, 0] = pux * x + puu * vx + puv * vy
        velocities[f, b, 1] = pvx * x + pvu * vx + pvv * vy
    if dim == 3:
        pzz, pzw = matrix_t[2, 2], matrix_t[5, 2]
        pwz, pww = matrix_t[2, 5], matrix_t[5, 5]
        for b in range(centers.shape[1]):
            z, vz = centers[f, b, 2], velocities[f, b, 2]
            centers[f, b, 2] = pzz * z + pzw * vz
            velocities[f, b, 2] = pwz * z + pww * vz
    for k in range(polygons[f, 0]):
        j = polygons[f, 1 + k]
        c, s = attitude[f, j, 0], attitude[f, j, 1]
        cd, sd = turns[f, j, 0], turns[f, j, 1]
        attitude[f, j, 0] = c * cd - s * sd
        attitude[f, j, 1] = s * cd + c * sd


@inlined
def fly_truth(i, f, rules, state, start, accel, field, scratch):
    """The truth model's step of row ``i`` (one chaser per field: its field ``f``): the chaser
    from ``start`` under ``accel`` and every body of the field from its state before the step
    fly absolute orbits with J2 and drag (:func:`~debris_gym.orbit_truth.truth_step`), the
    reference orbit ``field.reference[f]`` with them; their end states replace the CW model's
    in ``state[i]`` and the field. Called before the bodies' CW move (whose polygon turns are
    kept). A 2D world keeps the in-plane part."""
    dim = accel.shape[0]
    states, accels, inv = scratch.truth_states, scratch.truth_accels, scratch.truth_inv
    centers, velocities = field.centers, field.velocities
    n_bodies = centers.shape[1]
    for c in range(6):
        states[0, c] = 0.0
    for a in range(3):
        accels[0, a] = 0.0
    for a in range(dim):
        states[0, a] = start[a]
        states[0, 3 + a] = start[dim + a]
        accels[0, a] = accel[a]
    inv[0] = rules.chaser_inv_ballistic
    for b in range(n_bodies):
        r = 1 + b
        for c in range(6):
            states[r, c] = 0.0
        for a in range(3):
            accels[r, a] = 0.0
        for a in range(dim):
            states[r, a] = centers[f, b, a]
            states[r, 3 + a] = velocities[f, b, a]
        inv[r] = field.inv_ballistic[f, b]
    truth_step(
        field.reference[f], states, accels, inv, rules.chaser_inv_ballistic, True, rules.dt,
        rules.truth_substeps, rules.atmosphere, scratch.truth_work,
    )  # fmt: skip


@inlined
def land_truth(i, f, dim, state, field, scratch):
    """Put the end states of :func:`fly_truth` into ``state[i]`` and the field's bodies."""
    states = scratch.truth_states
    for a in range(dim):
        state[i, a] = states[0, a]
        state[i, dim + a] = states[0, 3 + a]
    for b in range(field.centers.shape[1]):
        for a in range(dim):
            field.centers[f, b, a] = states[1 + b, a]
            field.velocities[f, b, a] = states[1 + b, 3 + a]


@inlined
def measure(
    i, f, state, gaps, nearest, centers, radii, polygon_start, polygons, n_vertices, vertices,
    attitude,
):  # fmt: skip
    """Gaps (m) from mission ``i``'s chaser centre to every body of its field ``f`` into
    ``gaps[i]``,
    and its ranked obstacles ``nearest[i]`` re-sorted by gap (:func:`sort_by_gap`).

    The gaps are exact for every body: computing all of them in one tight loop costs less than
    culling polygons with bounds (the bookkeeping of a culled selection outweighs the polygon
    edges it saves at the default obstacle count; docs/benchmarks.md, "Measured design choices").
    """
    dim = centers.shape[2]
    field_gaps(
        state[i, :dim], f, centers, radii, polygon_start, polygons, n_vertices, vertices,
        attitude, gaps[i],
    )  # fmt: skip
    sort_by_gap(gaps[i], nearest[i])


@inlined
def captures(i, f, rules, state, gaps, centers, velocities, touched, captured, hold, anchor):
    """Count a step end toward each target's capture: the chaser within ``capture_radius`` of
    the target's surface (surface to surface) with its velocity relative to the target's at
    most ``capture_speed``; a target held so for :attr:`Rules.hold_steps` consecutive step ends
    is captured (queued: only the queue head counts). Returns how many were captured now.

    With :attr:`Rules.hold_capture` a step end also counts only if the target was not
    ``touched`` during the step and the chaser's position relative to the target is within
    ``capture_drift`` of ``anchor[i, j]``, its relative position at the hold's first step end;
    a step end in range and speed that drifted further starts a new hold from itself.
    """
    dim = velocities.shape[2]
    new = 0
    reach = rules.capture_radius + rules.chaser_radius
    for j in range(rules.n_targets):
        if captured[i, j]:
            continue
        rel2 = 0.0
        for a in range(dim):
            dv = state[i, dim + a] - velocities[f, j, a]
            rel2 += dv * dv
        held = gaps[i, j] <= reach and math.sqrt(rel2) <= rules.capture_speed
        if rules.hold_capture:
            held = held and not touched[j]
            if held and hold[i, j] > 0:
                drift2 = 0.0
                for a in range(dim):
                    d = state[i, a] - centers[f, j, a] - anchor[i, j, a]
                    drift2 += d * d
                if drift2 > rules.capture_drift * rules.capture_drift:
                    hold[i, j] = 0  # drifted off: this step end starts a new hold
            if held and hold[i, j] == 0:
                for a in range(dim):
                    anchor[i, j, a] = state[i, a] - centers[f, j, a]
        if held:
            hold[i, j] += 1
        else:
            hold[i, j] = 0
        if hold[i, j] >= rules.hold_steps:
            captured[i, j] = True
            new += 1
        if rules.queued:
            break  # only the queue head can be captured
    return new


@inlined
def collides(i, f, start, touched, slow, rules, state, centers):
    """Did the step collide? Any contact with debris that is not a target; with
    ``solid_targets`` any contact with a target too. Otherwise (the v0 rule) a target touched
    too fast (not ``slow``) unless the chaser is leaving it: moving away from its centre at
    both ends of the step and over the step as a whole (departing after a gentle contact is not
    an impact)."""
    dim = start.shape[0] // 2
    n_targets = rules.n_targets
    first = 0 if rules.solid_targets else n_targets
    for b in range(first, touched.shape[0]):
        if touched[b]:
            return True
    hit = False
    if not slow:
        for j in range(n_targets):
            if touched[j]:
                closing0 = 0.0
                closing1 = 0.0
                closing_step = 0.0
                for a in range(dim):
                    toward = centers[f, j, a] - start[a]
                    closing0 += toward * start[dim + a]
                    closing1 += (centers[f, j, a] - state[i, a]) * state[i, dim + a]
                    closing_step += toward * (state[i, a] - start[a])
                if closing0 > 0.0 or closing1 > 0.0 or closing_step > 0.0:
                    hit = True
    return hit


@inlined
def outside(i, f, state, low, high):
    """Is the chaser of row ``i`` on or beyond the bounds of its field ``f``?"""
    oob = False
    for a in range(low.shape[1]):
        if state[i, a] <= low[f, a] or state[i, a] >= high[f, a]:
            oob = True
    return oob


@inlined
def succeeds(i, slow, rules, state, captured, dock):
    """Every target captured and (if a return is required) the chaser within
    ``capture_radius`` of the dock, slow."""
    done = True
    for j in range(captured.shape[1]):
        done = done and captured[i, j]
    if done and rules.return_to_dock:
        s = 0.0
        for a in range(dock.shape[1]):
            off = state[i, a] - dock[i, a]
            s += off * off
        done = math.sqrt(s) <= rules.capture_radius and slow
    return done


@inlined
def reward(
    i, new, dv, ended, phi, before, rules, success, collision, out_of_bounds, budget_spent, terms
):  # fmt: skip
    """The named reward terms of the step into ``terms[i]`` (potential Φ ``before`` and ``phi``
    after it); returns their sum."""
    terms[i, _T_CAPTURE] = rules.reward_capture * new
    terms[i, _T_SUCCESS] = rules.reward_success * success[i]
    terms[i, _T_PROGRESS] = rules.reward_progress * (rules.gamma * phi - before)
    terms[i, _T_DV] = -rules.reward_delta_v * dv
    terms[i, _T_COLLISION] = -rules.reward_collision * collision[i]
    terms[i, _T_OOB] = -rules.reward_out_of_bounds * out_of_bounds[i]
    terms[i, _T_TIME] = -rules.reward_time
    terms[i, _T_BUDGET] = -rules.reward_budget * budget_spent[i]
    if ended and rules.terminal_zero:
        terms[i, _T_PROGRESS] -= rules.reward_progress * rules.gamma * phi  # Φ(terminal) = 0
    total = 0.0
    for k in range(terms.shape[1]):
        total += terms[i, k]
    return total


# --- kernels ----------------------------------------------------------------------------------


@inlined
def tour_scratch(n_targets):
    """The tour potential's scratch for ``n_targets`` targets: order, counters (int64, (T,)),
    legs (T, T) and homes (T,)."""
    return (
        np.empty(n_targets, dtype=np.int64),
        np.empty(n_targets, dtype=np.int64),
        np.empty((n_targets, n_targets)),
        np.empty(n_targets),
    )


@kernel
def begin_rows(rows, states, rules, shaping, missions, field):
    """Start new episodes in ``rows``: the chaser at ``states`` (R, 2·dim) or, if None, at rest
    at the dock; clocks, Δv and flags cleared; gaps, clearance and potential computed."""
    state, time, steps, delta_v = missions.state, missions.time, missions.steps, missions.delta_v
    captured, hold, score = missions.captured, missions.hold, missions.score
    collision, out_of_bounds, success = missions.collision, missions.out_of_bounds, missions.success
    nearest, accel, budget_spent = missions.nearest, missions.accel, missions.budget_spent
    dock = field.dock
    dim = dock.shape[1]
    n_targets = rules.n_targets
    order, counters, legs, homes = tour_scratch(n_targets)
    for r in range(rows.shape[0]):
        i = rows[r]
        f = i // rules.n_chasers
        for k in range(nearest.shape[1]):  # a new field: sort from index order
            nearest[i, k] = n_targets + k
        for a in range(dim):
            if states is None:
                state[i, a] = dock[i, a]
                state[i, dim + a] = 0.0
            else:
                state[i, a] = states[r, a]
                state[i, dim + a] = states[r, dim + a]
            accel[i, a] = 0.0
        time[i] = 0.0
        steps[i] = 0
        delta_v[i] = 0.0
        score[i] = 0.0
        for j in range(n_targets):
            captured[i, j] = not missions.assigned[i, j]  # another chaser's: not this one's task
            hold[i, j] = 0
        collision[i] = False
        out_of_bounds[i] = False
        success[i] = False
        budget_spent[i] = False
        missions.teammate_collision[i] = False
        missions.separation[i] = math.inf
        settle_row(i, f, rules, shaping, missions, field, order, counters, legs, homes)


@inlined
def settle_row(i, f, rules, shaping, missions, field, order, counters, legs, homes):
    """Row ``i`` where it now is, in field ``f``, as an episode's first state: its gaps and
    ranked obstacles, its clearance so far (this state's) and its shaping potential
    (``order`` … ``homes``: the tour potential's scratch)."""
    state, gaps, captured = missions.state, missions.gaps, missions.captured
    centers, radii, dock = field.centers, field.radii, field.dock
    measure(
        i, f, state, gaps, missions.nearest, centers, radii, field.polygon_start,
        field.polygons, field.n_vertices, field.vertices, field.attitude,
    )  # fmt: skip
    missions.min_clearance[i] = nearest_obstacle(i, rules.n_targets, gaps, math.inf)
    if rules.tour_potential:
        missions.potential[i] = tour_potential(
            i, f, rules, shaping, state, gaps, captured, centers, radii, dock,
            field.length_scale, field.speed_scale, order, counters, legs, homes,
        )  # fmt: skip
    else:
        missions.potential[i] = potential(
            i, f, rules, shaping, state, gaps, captured, centers, dock, field.length_scale,
            field.speed_scale,
        )  # fmt: skip


@kernel
def step_all(live, actions, rules, shaping, missions, field, out):
    """One step of every mission in ``live`` (see :meth:`MissionBatch.step`)."""
    scratch = step_scratch(rules, field)
    if not rules.field_loop:
        step_rows(0, live.shape[0], live, actions, rules, shaping, missions, field, out, scratch)
    else:
        n_fields = live.shape[0] // rules.n_chasers
        step_fields(0, n_fields, live, actions, rules, shaping, missions, field, out, scratch)


@threaded
def step_all_threaded(n_chunks, live, actions, rules, shaping, missions, field, out):
    """:func:`step_all` with the fields split into ``n_chunks`` ranges run in parallel."""
    num = live.shape[0] // rules.n_chasers
    for c in numba.prange(n_chunks):
        lo, hi = c * num // n_chunks, (c + 1) * num // n_chunks
        scratch = step_scratch(rules, field)
        if not rules.field_loop:
            step_rows(lo, hi, live, actions, rules, shaping, missions, field, out, scratch)
        else:
            step_fields(lo, hi, live, actions, rules, shaping, missions, field, out, scratch)


@inlined
def step_scratch(rules, field):
    """The :class:`StepScratch` of one row loop for ``rules`` and ``field``."""
    dim = field.dock.shape[1]
    n_path = rules.step_matrix_t.shape[1] // dim  # start + every sub-step
    n_targets = rules.n_targets
    n_chasers = rules.n_chasers
    n_truth = n_chasers + field.centers.shape[1] if rules.truth_orbits else 0
    return StepScratch(
        np.empty((n_chasers, n_path, dim)),
        np.empty((n_chasers, 2 * dim)),
        np.empty(dim),
        np.empty((n_chasers, field.centers.shape[1]), dtype=np.bool_),
        np.empty((n_path, dim)),
        np.empty(n_targets, dtype=np.int64),
        np.empty(n_targets, dtype=np.int64),
        np.empty((n_targets, n_targets)),
        np.empty(n_targets),
        np.empty(n_chasers),
        np.empty(n_chasers, dtype=np.bool_),
        np.zeros((n_truth, 6)),
        np.zeros((n_truth, 3)),
        np.zeros(n_truth),
        np.zeros((4 * rules.truth_substeps + 1 if rules.truth_orbits else 0, TRACK_WIDTH)),
    )


@inlined
def fly_row(i, f, k, actions, rules, missions, field, scratch, dvs):
    """The first half of row ``i``'s step (chaser ``k`` of field ``f``): burn, propagate, and
    the contacts along its path relative to the bodies' start-of-step states. The path, start
    state and touched bodies stay in ``scratch``'s slot ``k`` and the step's Δv in
    ``dvs[k]`` for :func:`land_row`."""
    centers, radii, polygon_start = field.centers, field.radii, field.polygon_start
    n_vertices, vertices = field.n_vertices, field.vertices
    path, start, touched = scratch.path[k], scratch.start[k], scratch.touched[k]
    accel = scratch.accel
    dvs[k] = burn(
        i, actions[i], rules, missions.delta_v, missions.accel, accel, missions.noise_key[i],
        missions.steps[i],
    )  # fmt: skip
    propagate(
        i, accel, rules.step_matrix_t, rules, missions.state, missions.time, missions.steps,
        start, path,
    )  # fmt: skip
    if rules.moving:
        moving_path_touches(
            path, rules.step_matrix_t, rules.reach_position, rules.reach_velocity,
            missions.gaps[i], rules.chaser_radius, f, centers, field.velocities, radii,
            polygon_start, n_vertices, vertices, field.attitude, field.turns, rules.swept_turns,
            scratch.relative_path, touched,
        )  # fmt: skip
    else:
        path_touches(
            path, missions.gaps[i], rules.chaser_radius, f, centers, radii, polygon_start,
            n_vertices, vertices, touched,
        )  # fmt: skip


@inlined
def land_row(i, f, k, rules, shaping, missions, field, out, scratch, dv, teammate):
    """The second half of row ``i``'s step, once its field's bodies have flown the step:
    measure, judge (``teammate``: it touched another chaser of its field), captures, reward."""
    state, captured, hold = missions.state, missions.captured, missions.hold
    collision, out_of_bounds, success = missions.collision, missions.out_of_bounds, missions.success
    gaps, budget_spent, potential_of = missions.gaps, missions.budget_spent, missions.potential
    centers, radii, dock = field.centers, field.radii, field.dock
    length_scale, speed_scale = field.length_scale, field.speed_scale
    n_targets = rules.n_targets
    start, touched = scratch.start[k], scratch.touched[k]
    measure(
        i, f, state, gaps, missions.nearest, centers, radii, field.polygon_start, field.polygons,
        field.n_vertices, field.vertices, field.attitude,
    )  # fmt: skip
    missions.min_clearance[i] = nearest_obstacle(i, n_targets, gaps, missions.min_clearance[i])
    # judge contacts, then captures (with hold_capture a colliding step captures nothing)
    slow = speed_of(i, state) <= rules.capture_speed
    if teammate:
        missions.teammate_collision[i] = True
    collision[i] = (
        collision[i] or teammate or collides(i, f, start, touched, slow, rules, state, centers)
    )
    new = 0
    if not (rules.hold_capture and collision[i]):
        new = captures(
            i, f, rules, state, gaps, centers, field.velocities, touched, captured, hold,
            missions.hold_anchor,
        )  # fmt: skip
    # judge the rest
    out_of_bounds[i] = outside(i, f, state, field.low, field.high)
    success[i] = success[i] or (
        not collision[i] and succeeds(i, slow, rules, state, captured, dock)
    )
    spent = missions.delta_v[i] >= rules.delta_v_budget
    budget_spent[i] = spent and not (success[i] or collision[i] or out_of_bounds[i])
    ended = success[i] or collision[i] or out_of_bounds[i] or spent
    out.terminated[i] = ended
    out.truncated[i] = rules.max_steps > 0 and missions.steps[i] >= rules.max_steps
    # reward
    if rules.tour_potential:
        phi = tour_potential(
            i, f, rules, shaping, state, gaps, captured, centers, radii, dock, length_scale,
            speed_scale, scratch.order, scratch.counters, scratch.legs, scratch.homes,
        )  # fmt: skip
    else:
        phi = potential(
            i, f, rules, shaping, state, gaps, captured, centers, dock, length_scale, speed_scale
        )
    before = potential_of[i]
    potential_of[i] = phi
    terms = out.terms
    out.reward[i] = reward(
        i, new, dv, ended, phi, before, rules, success, collision, out_of_bounds, budget_spent,
        terms,
    )  # fmt: skip
    for c in range(terms.shape[1]):  # the task score: every term but the shaping
        if c != _T_PROGRESS:
            missions.score[i] += terms[i, c]


@inlined
def idle_row(i, out):
    """Row ``i`` did not step: its outputs are zero / False."""
    terms = out.terms
    for c in range(terms.shape[1]):
        terms[i, c] = 0.0
    out.reward[i] = 0.0
    out.terminated[i] = False
    out.truncated[i] = False


@borrowing  # called once per row range: no need to inline it
def step_rows(lo, hi, live, actions, rules, shaping, missions, field, out, scratch):
    """One step of the missions ``lo … hi − 1`` that are ``live``, one chaser per field (row
    i flies in field i): the phases in order (``scratch``: a :class:`StepScratch` of this
    loop's own)."""
    dvs = scratch.dvs
    for i in range(lo, hi):
        if not live[i]:
            idle_row(i, out)
            continue
        fly_row(i, i, 0, actions, rules, missions, field, scratch, dvs)
        if rules.truth_orbits:  # from the states before the step
            fly_truth(i, i, rules, missions.state, scratch.start[0], scratch.accel, field, scratch)
        if rules.moving:  # the bodies fly once the path has been checked against them
            move_bodies(i, rules.body_matrix_t, field.centers, field.velocities, field.polygons,
                        field.attitude, field.turns)  # fmt: skip
        if rules.truth_orbits:
            land_truth(i, i, scratch.accel.shape[0], missions.state, field, scratch)
        land_row(i, i, 0, rules, shaping, missions, field, out, scratch, dvs[0], False)


@borrowing  # called once per field range
def step_fields(lo, hi, live, actions, rules, shaping, missions, field, out, scratch):
    """One step of the fields ``lo … hi − 1``, :attr:`Rules.n_chasers` K chasers each (rows
    f·K … f·K + K − 1 of field f), those ``live`` flying: every chaser flies and is checked
    against the bodies' start-of-step states, the bodies fly once, every pair of live chasers
    is checked against each other along their paths (:func:`pair_touches`; a contact is a
    collision for both), then every chaser is measured, judged and rewarded; last, the field's
    captures are shared (a target captured by one chaser is captured for all; the capture
    bonus goes to the chaser that held it; only the targets assigned to a chaser,
    :attr:`Missions.assigned`, are its to capture). With :attr:`Rules.arrived_stay`, a chaser
    that succeeded stays in the pair checks, held where it ended (a contact with it is a
    collision for the chaser flying). With K = 1 this is :func:`step_rows`, phase for phase."""
    n_chasers = rules.n_chasers
    dvs, mates, separation = scratch.dvs, scratch.mates, missions.separation
    captured, assigned, success = missions.captured, missions.assigned, missions.success
    state, dim = missions.state, field.dock.shape[1]
    for f in range(lo, hi):
        first = f * n_chasers
        flying = False
        for k in range(n_chasers):
            i = first + k
            mates[k] = False
            if live[i]:
                fly_row(i, f, k, actions, rules, missions, field, scratch, dvs)
                flying = True
            else:
                idle_row(i, out)
        if not flying:
            continue
        if rules.moving:
            move_bodies(f, rules.body_matrix_t, field.centers, field.velocities, field.polygons,
                        field.attitude, field.turns)  # fmt: skip
        if rules.arrived_stay:  # the arrived chasers' paths: held where they ended
            for k in range(n_chasers):
                i = first + k
                if not live[i] and success[i]:
                    for p in range(scratch.path.shape[1]):
                        for a in range(dim):
                            scratch.path[k, p, a] = state[i, a]
        for k in range(n_chasers):
            present_k = live[first + k] or (rules.arrived_stay and success[first + k])
            if not present_k:
                continue
            for q in range(k + 1, n_chasers):
                if not live[first + k] and not live[first + q]:
                    continue  # two held chasers: neither moves
                if not (live[first + q] or (rules.arrived_stay and success[first + q])):
                    continue
                closest = pair_distance(scratch.path[k], scratch.path[q])
                separation[first + k] = min(separation[first + k], closest)
                separation[first + q] = min(separation[first + q], closest)
                if closest <= rules.chaser_separation:
                    mates[k] = True
                    mates[q] = True
        for k in range(n_chasers):
            if live[first + k]:
                land_row(
                    first + k, f, k, rules, shaping, missions, field, out, scratch, dvs[k],
                    mates[k],
                )  # fmt: skip
        for j in range(rules.n_targets):  # share the captures (a chaser's own, not the
            taken = False  # flags it starts with for the targets assigned to others)
            for k in range(n_chasers):
                taken = taken or (captured[first + k, j] and assigned[first + k, j])
            if taken:
                for k in range(n_chasers):
                    captured[first + k, j] = True


@kernel
def count_rows(flags, out):
    """out[i] = number of True in flags[i] (cheaper than numpy's bool sum along a short axis)."""
    for i in range(flags.shape[0]):
        count = 0
        for j in range(flags.shape[1]):
            count += flags[i, j]
        out[i] = count
