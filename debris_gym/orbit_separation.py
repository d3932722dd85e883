"""Whether two bodies on CWH relative orbits stay a distance apart over time (compiled).

The relative motion of two bodies (or of a body and the dock) is itself CWH motion, so their
distance is a trig function of time, given by the differences of their elements (x_c, y_c,
a = ρ cos α, b = ρ sin α, a_z, b_z; :mod:`debris_gym.relative_orbits`). In the plane, for two
drift-free orbits with relative amplitude R and along-track centre offset D, the squared
distance over the relative phase θ is R² + D² + 4DR cos θ + 3R² cos² θ, a quadratic in cos θ
whose minimum is exact: (|D| − 2R)² when |D| >= 1.5 R, else R² − D²/3 (:func:`apart`). In 3D
the cross-track term joins when the plane alone does not keep them apart, and a drifting pair
is not periodic: there the squared distance f, whose second derivative is bounded from the
pair's elements, is searched by branch and bound (:func:`search`): over an interval of width w,
f >= min(f at its ends) − max|f''| · w²/8, so the search proves the gap or finds a violation,
down to about :data:`SEARCH_TOLERANCE` m, where an undecided pair is refused. Every pair first
gets a cheap axis-separation test. Lengths in m, n in rad/s, times in s.
"""

from __future__ import annotations

import numpy as np

from debris_gym.jit import inlined

__all__ = ["SEARCH_STACK", "SEARCH_TOLERANCE", "apart", "distance2", "search"]

SEARCH_TOLERANCE = 0.25
"""Smallest distance slack (m) the branch and bound of a pair resolves: a pair whose smallest
distance it cannot place above ``need`` at that resolution is refused (conservatively)."""

SEARCH_STACK = 128
"""Intervals the branch and bound holds at once (depth-first: ~8 + one per halving)."""


@inlined
def apart(dxc, dyc, da, db, daz, dbz, need, dim, n, horizon):
    """True if two bodies whose element differences are given stay ``need`` (m) or more apart
    (centre to centre) over the checked time: all time when ``dxc == 0`` (the relative motion
    repeats), else over ``[0, horizon]``. Exact for drift-free pairs in 2D; a proven lower bound
    otherwise (module docstring), so False may be a conservative refusal."""
    rr = np.sqrt(da * da + db * db)
    rz = np.sqrt(daz * daz + dbz * dbz) if dim == 3 else 0.0
    need2 = need * need
    # cheap accept: the relative motion stays apart along x (|Δx| >= |Δx_c| − R) or along y
    # (|Δy| >= distance of the sliding centre offset from 0, less 2R)
    if abs(dxc) - rr >= need:
        return True
    slide = 1.5 * n * dxc * horizon
    lo_y = min(dyc, dyc - slide)
    hi_y = max(dyc, dyc - slide)
    y_far = lo_y if lo_y > 0.0 else (-hi_y if hi_y < 0.0 else 0.0)
    if y_far - 2.0 * rr >= need:
        return True
    if dxc == 0.0:
        # in-plane minimum, exact: min over c = cos θ of R² + D² + 4DRc + 3R²c²
        d = abs(dyc)
        if d >= 1.5 * rr:
            plane = (d - 2.0 * rr) * (d - 2.0 * rr)
        else:
            plane = rr * rr - d * d / 3.0
        if plane >= need2 or dim == 2:
            return plane >= need2
        # 3D: the cross-track term may keep them apart; search the phase θ = nt in [0, 2π].
        # d²(θ) = R² sin²u + (D + 2R cos u)² + R_z² sin²v (u, v: θ + phases) has
        # d²'' = −4DR cos u − 6R² cos 2u + 2R_z² cos 2v, so |d²''| <= 4|D|R + 6R² + 2R_z²
        bend = 4.0 * abs(dyc) * rr + 6.0 * rr * rr + 2.0 * rz * rz
        return search(0.0, da, db, dyc, daz, dbz, need, 1.0, 0.0, 2.0 * np.pi, bend)
    # drifting pair: search time t in [0, horizon]; d²'' = 2|Δv|² + 2 Δp·Δa, with
    # |Δv| <= n√(R² + (1.5|Δx_c| + 2R)² + R_z²), |Δa| <= n²√(5R² + R_z²) and |Δp| bounded by the
    # extent of the relative motion over the horizon
    speed = n * np.sqrt(rr * rr + (1.5 * abs(dxc) + 2.0 * rr) ** 2 + rz * rz)
    accel = n * n * np.sqrt(5.0 * rr * rr + rz * rz)
    far_y = max(abs(dyc), abs(dyc - slide)) + 2.0 * rr
    far = np.sqrt((abs(dxc) + rr) ** 2 + far_y * far_y + rz * rz)
    bend = 2.0 * speed * speed + 2.0 * far * accel
    return search(dxc, da, db, dyc, daz, dbz, need, n, -1.5 * n * dxc, horizon, bend)


@inlined
def distance2(dxc, da, db, dyc, daz, dbz, rate, slope, s):
    """Squared centre distance (m²) of a pair at parameter ``s``: phase ``rate · s`` (rad),
    along-track centre offset ``dyc + slope · s`` (m)."""
    th = rate * s
    sn = np.sin(th)
    co = np.cos(th)
    ex = dxc + da * sn + db * co
    ey = dyc + slope * s + 2.0 * (da * co - db * sn)
    ez = daz * sn + dbz * co
    return ex * ex + ey * ey + ez * ez


@inlined
def _push(stack, top, lo, hi, f_lo, f_hi):
    """Put the interval [lo, hi] with its end values into row ``top`` of ``stack``."""
    stack[top, 0] = lo
    stack[top, 1] = hi
    stack[top, 2] = f_lo
    stack[top, 3] = f_hi


@inlined
def search(dxc, da, db, dyc, daz, dbz, need, rate, slope, span, bend):
    """True if the pair's distance (:func:`_distance2`) is >= ``need`` for every s in
    ``[0, span]``, proven by branch and bound on the squared distance f: on an interval of
    width w whose ends are known, f >= min(f(ends)) − ``bend`` · w² / 8 (``bend`` >= |f''|, the
    error of linear interpolation). An interval that cannot be decided once that margin is below
    2 · need · :data:`SEARCH_TOLERANCE` (about :data:`SEARCH_TOLERANCE` m of distance) counts
    as too close, so a pair that stays ``need`` + :data:`SEARCH_TOLERANCE` apart always passes.
    """
    need2 = need * need
    tol2 = 2.0 * need * SEARCH_TOLERANCE
    stack = np.empty((SEARCH_STACK, 4))  # lo, hi, f(lo), f(hi)
    top = 0
    pieces = 16
    f_lo = distance2(dxc, da, db, dyc, daz, dbz, rate, slope, 0.0)
    if f_lo < need2:
        return False
    for i in range(pieces):
        lo = span * i / pieces
        hi = span * (i + 1) / pieces
        f_hi = distance2(dxc, da, db, dyc, daz, dbz, rate, slope, hi)
        if f_hi < need2:
            return False
        _push(stack, top, lo, hi, f_lo, f_hi)
        top += 1
        f_lo = f_hi
    while top > 0:
        top -= 1
        lo = stack[top, 0]
        hi = stack[top, 1]
        f_lo = stack[top, 2]
        f_hi = stack[top, 3]
        margin = bend * (hi - lo) * (hi - lo) / 8.0
        if min(f_lo, f_hi) - margin >= need2:
            continue
        if margin < tol2 or top + 2 > SEARCH_STACK:
            return False
        mid = 0.5 * (lo + hi)
        f_mid = distance2(dxc, da, db, dyc, daz, dbz, rate, slope, mid)
        if f_mid < need2:
            return False
        _push(stack, top, lo, mid, f_lo, f_mid)
        _push(stack, top + 1, mid, hi, f_mid, f_hi)
        top += 2
    return True
