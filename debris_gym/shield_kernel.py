"""The compiled safety shield: every row's command checked against the bodies' predicted motion
and replaced by the closest safe one when it would lead to a collision.

The same decisions as the run-time assurance filter of the agents package
(``agents.policies.shield.SafetyShield`` with its default tunables; the tests hold the two to
each other), for a batch of missions with one chaser per field, inside the envs' step:

* a command is *safe* when, after flying it for one step, at least one backup manoeuvre keeps
  the chaser clear of every body for the rest of a horizon of H steps; the backups brake to
  rest in LVLH or to the velocity of one of the nearest bodies (deadbeat: the acceleration
  that cancels the relative velocity at the step's end, cut by the thrust model or to the
  nearest discrete action), then hold it;
* the chaser is predicted by exact zero-order-hold CWH propagation, sampled S times per step;
  each body as its circumscribed circle / sphere, grown by the chaser's radius, on its exact
  unforced CWH motion from its state now (the batch's ``centers`` and ``velocities``);
* between samples chaser and body centre are both replaced by chords, the distance of the
  relative segment to the origin is exact, and the chords' error (a·h²/8, a the largest
  acceleration, 5 % spare) is added to each body's radius;
* clearance kept: the chaser's radius from debris, none from targets (touching is still
  refused); a body already closer than that must only not come closer than it is now;
* a safe command passes unchanged; otherwise the candidates (scaled copies of the command,
  blends of it with each backup's first action, a grid of the action space — or every
  discrete action) are tried in order of distance to the command (of the accelerations they
  command, as the env's thrust model flies them), and the first safe one is flown; if none
  is safe, the one with the largest predicted clearance.

Work is saved without changing a decision: a command is judged by its first safe backup, a
backup by its first body in contact, a body whose distance bound (centres' and paths'
excursions from where they are now) keeps it clear is not checked, and a body's motion is
sampled only when a check or the choice of the backups needs it. The candidates are flown and
judged in order, and the first safe one ends the search. The chord error bound of the Python
shield takes the largest natural acceleration over *all* candidates' paths; each candidate is
therefore judged with the largest one flown so far (a lower bound: unsafe then is unsafe) and
with an upper bound from the present state and the thrust limit (safe then is safe), and only
when the two disagree are all paths flown for the exact value.

:class:`~debris_gym.shield_model.ShieldModel` holds the fixed data; :func:`shield_rows` is the
kernel, one call per step.
"""

from __future__ import annotations

import math

import numpy as np

from debris_gym.jit import inlined, kernel
from debris_gym.shield_model import BLENDS, SCALES
from debris_gym.thrust import thrust_row

_PRUNE_SLACK = 1e-6
"""Distance (m) a body's bound must clear it by beyond its required clearance before the body
is skipped: far above the round-off of the bound at world scale."""


@inlined
def _natural_square(x, n, d):
    """‖natural CWH acceleration‖² (m²/s⁴) of the state ``x`` (2·d,), the terms rounded as
    :func:`debris_gym.dynamics.cwh_acceleration` rounds them (its square root is the norm
    numpy gives: the largest of the roots is the root of the largest)."""
    ax = 3.0 * n * n * x[0] + 2.0 * n * x[d + 1]
    ay = -2.0 * n * x[d]
    s = ax * ax + ay * ay
    if d == 3:
        az = -n * n * x[2]
        s += az * az
    return s


@inlined
def _saturate(model, u, work, out):
    """``u`` (m/s²) cut to what the env flies into ``out``: the thrust model, or the nearest
    discrete action (``work`` (dim,) scratch)."""
    d = u.shape[0]
    if model.discrete:
        grid = model.grid
        best, best_norm = 0, math.inf
        for m in range(grid.shape[0]):
            s = 0.0
            for k in range(d):
                e = u[k] - grid[m, k]
                s += e * e
            norm = math.sqrt(s)
            if norm < best_norm:
                best, best_norm = m, norm
        for k in range(d):
            out[k] = grid[best, k]
        return
    for k in range(d):
        work[k] = u[k] / model.max_accel
    thrust_row(work, model.max_accel, model.box_thrust, out)


@inlined
def _backup(model, x, ref, raw, work, out):
    """The deadbeat braking acceleration (m/s²) from state ``x`` to the reference state
    ``ref``, saturated, into ``out``."""
    d = model.dim
    gain = model.brake_gain
    for r in range(d):
        s = 0.0
        for c in range(2 * d):
            s += (x[c] - ref[c]) * gain[r, c]
        raw[r] = s
    _saturate(model, raw, work, out)


@inlined
def _fly_step(model, x, u, bu, xn, path, t, x0, far, natural):
    """Fly the acceleration ``u`` for one step from ``x`` (updated), its sample positions into
    ``path`` after sample ``t``; returns the largest squared excursion from ``x0`` and squared
    natural acceleration so far."""
    d, n = model.dim, model.mean_motion
    ad, bd = model.sub_ad, model.sub_bd
    for r in range(2 * d):  # the same every sample of the step
        s = 0.0
        for c in range(d):
            s += u[c] * bd[r, c]
        bu[r] = s
    for q in range(model.substeps):
        for r in range(2 * d):
            s = 0.0
            for c in range(2 * d):
                s += x[c] * ad[r, c]
            xn[r] = s + bu[r]
        e = 0.0
        for c in range(2 * d):
            x[c] = xn[c]
        for c in range(d):
            path[t + q + 1, c] = x[c]
            e += (x[c] - x0[c]) * (x[c] - x0[c])
        far = max(far, e)
        natural = max(natural, _natural_square(x, n, d))
    return far, natural


@inlined
def _fly(model, x0, accel, refs, n_refs, paths, dev, scratch):
    """Fly ``accel`` (m/s²) for one step from ``x0``, then each backup: the positions on the
    sample grid into ``paths`` (F, T + 1, dim), each path's largest excursion from ``x0``
    (m) into ``dev`` (F,). Returns the largest natural CWH acceleration (m/s²) on the paths.
    ``scratch``: working arrays."""
    x, xn, x1, bu, u, raw, work = scratch
    d, n, subs = model.dim, model.mean_motion, model.substeps
    for c in range(2 * d):
        x1[c] = x0[c]
    for c in range(d):
        u[c] = accel[c]
        paths[0, 0, c] = x0[c]
    # the first step is the same for every backup: flown once
    far1, natural = _fly_step(model, x1, u, bu, xn, paths[0], 0, x0, 0.0, _natural_square(x0, n, d))
    for j in range(n_refs):
        for c in range(2 * d):
            x[c] = x1[c]
        if j > 0:
            for t in range(subs + 1):
                for c in range(d):
                    paths[j, t, c] = paths[0, t, c]
        far = far1
        for k in range(1, model.horizon_steps):
            _backup(model, x, refs[k, j], raw, work, u)
            far, natural = _fly_step(model, x, u, bu, xn, paths[j], k * subs, x0, far, natural)
        dev[j] = math.sqrt(far)
    return math.sqrt(natural)


@inlined
def _body_gap(path, bodies, b, need, limit, inclusive):
    """The least distance (m) between ``path`` (T + 1, dim) and body ``b``'s centres on the
    sample grid (``bodies`` (T + 1, B, dim)), chords between samples, minus ``need``; with
    the first one found below ``limit`` (or equal to it, ``inclusive``) instead: enough to know
    that the least one is too."""
    d = path.shape[1]
    best = math.inf
    for k in range(path.shape[0] - 1):
        ss = 0.0
        sa = 0.0
        for c in range(d):
            a = path[k, c] - bodies[k, b, c]
            seg = (path[k + 1, c] - bodies[k + 1, b, c]) - a
            ss += seg * seg
            sa += a * seg
        s = min(max(-sa / max(ss, 1e-300), 0.0), 1.0)
        dist = 0.0
        for c in range(d):
            a = path[k, c] - bodies[k, b, c]
            seg = (path[k + 1, c] - bodies[k + 1, b, c]) - a
            near = a + s * seg
            dist += near * near
        best = min(best, dist)
        gap = math.sqrt(dist) - need
        if gap < limit or (inclusive and gap == limit):
            break
    return math.sqrt(best) - need


@inlined
def _reach_bounds(model, radius, speed_p, speed_v):
    """Lower and upper bounds (m) of a body's reach (radius + chaser radius + its chords'
    error) from its position and velocity norms, before its motion is sampled."""
    low = radius + model.chaser_radius
    if not model.moving:
        return low, low
    accel = model.accel_position * speed_p + model.accel_velocity * speed_v
    h = model.h
    return low, (low + 1.05 * accel * h * h / 8.0) * (1.0 + 1e-9) + 1e-12


@inlined
def _sample_body(model, b, center, velocity, radius, bodies, x, xn):
    """Body ``b``'s centres on the sample grid into ``bodies`` (T + 1, B, dim), flown exactly
    from its state now; returns its reach (m: radius + chaser radius + the chords' error) and
    its largest excursion from where it is (m)."""
    d, n = model.dim, model.mean_motion
    sub = model.sub_ad
    samples = bodies.shape[0]
    for c in range(d):
        x[c] = center[c]
        x[d + c] = velocity[c]
        bodies[0, b, c] = center[c]
    accel = _natural_square(x, n, d) if model.moving else 0.0
    far = 0.0
    for k in range(1, model.body_samples):
        if model.moving:
            for r in range(2 * d):
                s = 0.0
                for c in range(2 * d):
                    s += x[c] * sub[r, c]
                xn[r] = s
            for c in range(2 * d):
                x[c] = xn[c]
            accel = max(accel, _natural_square(x, n, d))
        if k < samples:
            e = 0.0
            for c in range(d):
                bodies[k, b, c] = x[c]
                e += (x[c] - center[c]) * (x[c] - center[c])
            far = max(far, e)
    accel = math.sqrt(accel)
    h = model.h
    return radius + model.chaser_radius + 1.05 * accel * h * h / 8.0, math.sqrt(far)


@inlined
def _need(reach, slack, gap_now, margin):
    """The centre distance (m) a path must keep from a body of ``reach`` (m), given the chord
    error ``slack`` (m) of the chaser's paths: reach + margin, or for a body already within its
    margin its present clearance less 1 µm (so rounding never makes the present state
    unsafe)."""
    r = reach + slack
    now = gap_now - r
    return r + (now - 1e-6 if now < margin else margin)


@inlined
def _slack(model, natural):
    """The chaser's chord error (m) on paths whose largest natural acceleration is ``natural``
    (m/s²), 5 % spare."""
    h = model.h
    return 1.05 * (model.thrust_bound + natural) * (h * h) / 8.0


@inlined
def _path_gap(model, path, dev, slack, limit, inclusive, state):
    """The least clearance (m, beyond each body's required distance) of one path over every
    body that its bound does not keep clear (+inf when all are), or the first one found below
    ``limit`` (or equal to it, ``inclusive``): enough to know that the least one is too.
    ``state``: the row's bodies and working arrays (see
    :func:`shield_rows`); a body's motion is sampled here when first needed."""
    center, velocity, radius, margins, bodies, sampled, reach, reach_hi, devs, gap_now, x, xn = (
        state
    )
    worst = math.inf
    for b in range(radius.shape[0]):
        bound = gap_now[b] - devs[b] - dev - (reach_hi[b] + slack + margins[b])
        if bound > _PRUNE_SLACK * (1.0 + gap_now[b]):
            continue
        if not sampled[b]:
            reach[b], devs[b] = _sample_body(
                model, b, center[b], velocity[b], radius[b], bodies, x, xn
            )
            reach_hi[b] = reach[b]
            sampled[b] = True
            bound = gap_now[b] - devs[b] - dev - (reach[b] + slack + margins[b])
            if bound > _PRUNE_SLACK * (1.0 + gap_now[b]):
                continue
        need = _need(reach[b], slack, gap_now[b], margins[b])
        gap = _body_gap(path, bodies, b, need, limit, inclusive)
        worst = min(worst, gap)
        if worst < limit or (inclusive and worst == limit):
            break
    return worst


@inlined
def _natural_bound(model, x0):
    """An upper bound (m/s²) of the natural CWH acceleration on every path from ``x0`` whose
    thrust never exceeds the thrust limit (:attr:`~debris_gym.shield_model.ShieldModel.
    natural_phi`, ``natural_gain``)."""
    d = model.dim
    phi, gain = model.natural_phi, model.natural_gain
    best = 0.0
    for k in range(phi.shape[0]):
        s = 0.0
        for r in range(d):
            a = 0.0
            for c in range(2 * d):
                a += phi[k, r, c] * x0[c]
            s += a * a
        best = max(best, math.sqrt(s) + gain[k] * model.thrust_bound)
    return best * (1.0 + 1e-9) + 1e-15


@inlined
def _action_of(model, accel, act):
    """The float32-rounded normalised action that commands ``accel`` (m/s²), into ``act``:
    the inverse of the thrust model inside the limit, the nearest feasible one outside."""
    d = accel.shape[0]
    for k in range(d):
        act[k] = accel[k] / model.max_accel
    if model.box_thrust:
        for k in range(d):
            act[k] = min(max(act[k], -1.0), 1.0)
    else:
        s = 0.0
        for k in range(d):
            s += act[k] * act[k]
        norm = math.sqrt(s)
        if norm > 1.0:
            for k in range(d):
                act[k] = act[k] / norm
    for k in range(d):
        act[k] = np.float64(np.float32(act[k]))


@inlined
def _sample(model, b, state):
    """Sample body ``b``'s motion (once): its centres, exact reach and excursion."""
    center, velocity, radius, _, bodies, sampled, reach, reach_hi, devs, _, x, xn = state
    if not sampled[b]:
        reach[b], devs[b] = _sample_body(model, b, center[b], velocity[b], radius[b], bodies, x, xn)
        reach_hi[b] = reach[b]
        sampled[b] = True


@inlined
def _references(model, state, chosen, refs):
    """The backups' references into ``refs`` (H, F, 2·dim): rest in LVLH (zeros), then the
    states at each step of the horizon of the bodies nearest by centre distance less reach (a
    stable order: ties by index), their indices into ``chosen``. Returns F."""
    center, velocity, radius, _, _, sampled, reach, reach_hi, _, gap_now, x, xn = state
    d = model.dim
    n_bodies = radius.shape[0]
    if not model.moving or model.fallback_bodies == 0 or n_bodies == 0:
        return 1
    count = min(model.fallback_bodies, n_bodies)
    # the count-th smallest upper bound of (gap − reach) over the bodies: a body whose lower
    # bound exceeds it has at least count bodies before it, so only the others are sampled
    for j in range(count):
        chosen[j] = -1
    for b in range(n_bodies):  # the count smallest upper bounds, kept in chosen by body index
        high = gap_now[b] - (radius[b] + model.chaser_radius)
        m = count - 1
        if chosen[m] >= 0 and high >= gap_now[chosen[m]] - (
            radius[chosen[m]] + model.chaser_radius
        ):
            continue
        while m > 0 and (
            chosen[m - 1] < 0
            or high < gap_now[chosen[m - 1]] - (radius[chosen[m - 1]] + model.chaser_radius)
        ):
            chosen[m] = chosen[m - 1]
            m -= 1
        chosen[m] = b
    last = chosen[count - 1]
    limit = gap_now[last] - (radius[last] + model.chaser_radius)
    for b in range(n_bodies):
        if gap_now[b] - reach_hi[b] <= limit:
            _sample(model, b, state)
    # a stable selection of the smallest gap − reach among the sampled bodies
    for j in range(count):
        best = -1
        for b in range(n_bodies):
            if not sampled[b]:
                continue
            taken = False
            for q in range(j):
                taken = taken or chosen[q] == b
            if taken:
                continue
            if best < 0 or gap_now[b] - reach[b] < gap_now[best] - reach[best]:
                best = b
        chosen[j] = best
    for j in range(count):
        b = chosen[j]
        for c in range(d):
            x[c] = center[b, c]
            x[d + c] = velocity[b, c]
        for k in range(model.horizon_steps):
            for c in range(2 * d):
                refs[k, j + 1, c] = x[c]
            for r in range(2 * d):
                s = 0.0
                for c in range(2 * d):
                    s += x[c] * model.step_ad[r, c]
                xn[r] = s
            for c in range(2 * d):
                x[c] = xn[c]
    return count + 1


@inlined
def _first_safe(model, paths, devs, n_refs, slack, state):
    """Whether some backup of the paths ``paths`` (F, T + 1, dim) keeps clear of every body."""
    for j in range(n_refs):
        if _path_gap(model, paths[j], devs[j], slack, 0.0, False, state) >= 0.0:
            return True
    return False


@kernel
def shield_rows(model, live, actions, state, centers, velocities, radii, out, intervened):
    """Filter every live row's command (see the module docstring).

    Args:
        model: the :class:`~debris_gym.shield_model.ShieldModel`.
        live: (N,) bool, the rows to filter (the others pass unchanged, not intervened).
        actions: (N, dim) finite normalised commands (a discrete env's: its table's rows).
        state: (N, 2·dim) chaser states (m, m/s).
        centers, velocities: (N, B, dim) the bodies' states now (m, m/s).
        radii: (N, B) the bodies' circumscribed radii (m).
        out: (N, dim) the commands to fly (written).
        intervened: (N,) bool, whether a row's command was replaced (written).
    """
    d = model.dim
    n_rows, n_bodies = radii.shape
    samples = model.horizon_steps * model.substeps + 1
    n_grid = model.grid.shape[0]
    f_max = 1 + min(model.fallback_bodies, n_bodies) if model.moving else 1
    c_max = n_grid if model.discrete else len(SCALES) + len(BLENDS) * f_max + n_grid
    scales = np.array(SCALES)
    blends = np.array(BLENDS)
    # per row: the bodies on the sample grid, sampled when first needed
    bodies = np.empty((samples, n_bodies, d))
    sampled = np.zeros(n_bodies, dtype=np.bool_)
    reach = np.empty(n_bodies)
    reach_hi = np.empty(n_bodies)
    devs = np.empty(n_bodies)
    gap_now = np.empty(n_bodies)
    margins = np.empty(n_bodies)
    chosen = np.empty(max(model.fallback_bodies, 1), dtype=np.int64)
    refs = np.zeros((model.horizon_steps, f_max, 2 * d))
    # per candidate: its acceleration, action, distance to the command, rank, paths
    accels = np.empty((c_max, d))
    acts = np.empty((c_max, d))
    dist = np.empty(c_max)
    rank = np.empty(c_max, dtype=np.int64)
    flown = np.zeros(c_max, dtype=np.bool_)
    paths = np.empty((c_max, f_max, samples, d))
    path_devs = np.empty((c_max, f_max))
    x0 = np.empty(2 * d)
    x = np.empty(2 * d)
    xn = np.empty(2 * d)
    u = np.empty(d)
    u_cmd = np.empty(d)
    raw = np.empty(d)
    work = np.empty(d)
    scratch = (x, xn, np.empty(2 * d), np.empty(2 * d), u, raw, work)
    for b in range(n_bodies):
        margins[b] = model.target_margin if b < model.n_targets else model.margin
    for i in range(n_rows):
        for k in range(d):
            out[i, k] = actions[i, k]
        intervened[i] = False
        if not live[i]:
            continue
        for c in range(2 * d):
            x0[c] = state[i, c]
        center, velocity, radius = centers[i], velocities[i], radii[i]
        for b in range(n_bodies):
            e = 0.0
            for c in range(d):
                e += (x0[c] - center[b, c]) * (x0[c] - center[b, c])
            gap_now[b] = math.sqrt(e)
            p = 0.0
            v = 0.0
            for c in range(d):
                p += center[b, c] * center[b, c]
                v += velocity[b, c] * velocity[b, c]
            p, v = math.sqrt(p), math.sqrt(v)
            _, reach_hi[b] = _reach_bounds(model, radius[b], p, v)
            devs[b] = (model.reach_position * p + model.reach_velocity * v) * (1.0 + 1e-9)
            sampled[b] = False
        row = (
            center, velocity, radius, margins, bodies, sampled, reach, reach_hi, devs, gap_now,
            x, xn,
        )  # fmt: skip
        n_refs = _references(model, row, chosen, refs)
        # the command
        thrust_row(actions[i], model.max_accel, model.box_thrust, u_cmd)
        natural = _fly(model, x0, u_cmd, refs, n_refs, paths[0], path_devs[0], scratch)
        if _first_safe(model, paths[0], path_devs[0], n_refs, _slack(model, natural), row):
            continue
        # the candidates and what the env flies for each
        count = 0
        if model.discrete:
            for m in range(n_grid):
                for k in range(d):
                    accels[m, k] = model.grid[m, k]
                    acts[m, k] = model.table[m, k]
            count = n_grid
        else:
            for m in range(len(SCALES)):
                for k in range(d):
                    raw[k] = scales[m] * u_cmd[k]
                _action_of(model, raw, acts[count])
                count += 1
            for m in range(len(BLENDS)):
                for j in range(n_refs):
                    _backup(model, x0, refs[0, j], raw, work, u)
                    for k in range(d):
                        raw[k] = (1.0 - blends[m]) * u_cmd[k] + blends[m] * u[k]
                    _action_of(model, raw, acts[count])
                    count += 1
            for m in range(n_grid):
                _action_of(model, model.grid[m], acts[count])
                count += 1
            for m in range(count):
                thrust_row(acts[m], model.max_accel, model.box_thrust, accels[m])
        for m in range(count):
            s = 0.0
            for k in range(d):
                s += (accels[m, k] - u_cmd[k]) * (accels[m, k] - u_cmd[k])
            dist[m] = math.sqrt(s)
            flown[m] = False
            # stable insertion by distance: the order of a stable argsort
            p = m
            while p > 0 and dist[rank[p - 1]] > dist[m]:
                rank[p] = rank[p - 1]
                p -= 1
            rank[p] = m
        # the candidates in order, each flown when reached: judged with the largest natural
        # acceleration of the paths flown so far (a lower bound of the decisive one, so unsafe
        # then is unsafe) and with an upper bound of it (safe then is safe); a candidate that
        # is safe by the first and not the second needs every path flown
        low = 0.0
        high = _natural_bound(model, x0)
        best = -1
        exact = False
        for q in range(count):
            m = rank[q]
            low = max(
                low, _fly(model, x0, accels[m], refs, n_refs, paths[m], path_devs[m], scratch)
            )
            flown[m] = True
            if not _first_safe(model, paths[m], path_devs[m], n_refs, _slack(model, low), row):
                continue
            if _first_safe(model, paths[m], path_devs[m], n_refs, _slack(model, high), row):
                best = m
            else:
                exact = True
            break
        if exact:  # every path flown: the decisive acceleration itself
            for m in range(count):
                if not flown[m]:
                    nat = _fly(model, x0, accels[m], refs, n_refs, paths[m], path_devs[m], scratch)
                    low = max(low, nat)
            slack = _slack(model, low)
            for q in range(count):
                if _first_safe(model, paths[rank[q]], path_devs[rank[q]], n_refs, slack, row):
                    best = rank[q]
                    break
        slack = _slack(model, low)  # nothing safe: every path was flown
        if best < 0:  # nothing is safe: the largest predicted clearance
            best_score = -math.inf
            for m in range(count):
                # a backup whose clearance is found at or below the best so far cannot make
                # this candidate the first with the largest: its search stops there
                score = -math.inf
                for j in range(n_refs):
                    gap = _path_gap(
                        model, paths[m, j], path_devs[m, j], slack, best_score, True, row
                    )
                    score = max(score, gap)
                if best < 0 or score > best_score:
                    best, best_score = m, score
        if dist[best] / model.max_accel == 0.0:  # the command's own twin: fly the command
            continue
        finite = True
        for k in range(d):
            finite = finite and math.isfinite(acts[best, k])
        if finite:
            for k in range(d):
                out[i, k] = acts[best, k]
            intervened[i] = True
