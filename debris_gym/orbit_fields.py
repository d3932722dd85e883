"""Seeded moving (v1) debris fields: every body on a natural CWH relative orbit.

A moving field (``FieldSpec.motion`` ``"bounded"`` or ``"drifting"``) puts each body on the
unforced CWH trajectory ([Clohessy60]; [Curtis14] §7.4) with elements (see
:mod:`debris_gym.relative_orbits`)::

    x(t) = x_c + ρ sin(nt + α)
    y(t) = y_c − (3/2) n x_c t + 2ρ cos(nt + α)
    z(t) = ρ_z sin(nt + β)                                     (3D)

``"bounded"`` (the default of v1) draws x_c = 0 (ẏ₀ = −2n x₀): closed 2:1 ellipses about the
V-bar that repeat every orbit 2π/n, so a field valid over one orbit is valid for ever.
``"drifting"`` draws |x_c| in ``drift_offset``: the ellipse's centre slides along-track at
−(3/2) n x_c, and the field is checked over ``horizon`` (at least one orbit).

Placement (:func:`_draw_orbits`), body after body (targets first), each at its first candidate
orbit that keeps, over the checked time (all time for ``"bounded"``):

* inside the bounds with ``min_gap`` to spare (the orbit's extent, exact: |x − x_c| ≤ ρ,
  |y − y_c(t)| ≤ 2ρ, |z| ≤ ρ_z);
* its surface ``dock_clearance`` from the dock at the origin (where the chaser starts and ends),
  and a target's centre ``min_target_distance`` from it at t = 0;
* a centre distance of at least r_i + r_j + max(s_i, s_j) to every body placed before it
  (s = ``min_gap``, plus ``target_clearance`` around targets).

The relative motion of two bodies (or of a body and the dock) is itself CWH motion, so their
distance is a trig function of time. In the plane, for two drift-free orbits, with relative
amplitude R and along-track centre offset D, the squared distance over the relative phase θ is
R² + D² + 4DR cos θ + 3R² cos² θ, a quadratic in cos θ whose minimum is exact:
(|D| − 2R)² when |D| ≥ 1.5 R, else R² − D²/3 (:func:`_apart`). In 3D the cross-track term
joins when the plane alone does not keep them apart, and a drifting pair is not periodic: there
the squared distance f, whose second derivative is bounded from the pair's elements (relative
amplitudes, speed and acceleration), is searched by branch and bound (:func:`_search`): over an
interval of width w, f >= min(f at its ends) − max|f''| · w²/8, so the search proves the gap or
finds a violation, down to about :data:`SEARCH_TOLERANCE` m, where an undecided pair is refused.
Every pair first gets a cheap axis-separation test.

Solvability in space-time (the argument; tested against an independent time-expanded search in
``tests/test_orbit_fields.py``). With ``min_gap > 2 · chaser_radius`` and the other conditions
of :func:`~debris_gym.generators.route_by_construction` (required of a moving spec), the checks
above give at *every* instant what the v0 disjoint-balls proof needs: the bodies' balls,
inflated by the chaser radius c, are pairwise disjoint and strictly inside the bounds and off the
dock, so the free space is connected at every t and each target has a free capture point. Each
body also carries a collar, the shell r_i + c < |p − p_i(t)| < r_i + s_i/2, that no other body
enters at any time. The chaser moves with authority to spare: a body moves at most
n·√(4ρ² + ρ_z²) (+ 1.5 n |x_c|), ≈ 0.63 m/s at ρ = ρ_z = 250 m in LEO, and accelerates at most
n²·√(4ρ² + ρ_z²) < 1e-3 m/s², against the chaser's 0.05 m/s² (1 m/s within 20 s); riding a
collar at a fixed offset d from a body costs a thrust (3n² d_x, 0, −n² d_z), at most 3n²|d|
≈ 2e-4 m/s² at 50 m (chaser and body obey the same law, Coriolis terms included);
the dock is an equilibrium kept clear at all times, where the chaser can wait. So the chaser can
wait (at the dock or in a collar) for a gap and cross the connected free space faster than it
deforms, reach a target's collar, match the target's velocity (≤ 0.6 m/s: ≤ 12 s of thrust)
there, and return. This is an argument, not a proof for every conceivable field; the search in
the tests confirms it on a seeded sample of fields.

Draws take a fixed block of uniform numbers from each field's own generator
(:func:`orbit_draw_size`), so a field depends only on its generator.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from debris_gym.generators import (
    _POLYGON_DRAWS,
    FIELD_MOTIONS,
    MAX_POLYGON_VERTICES,
    FieldArrays,
    FieldSpec,
    _convex_polygon,
    route_by_construction,
)
from debris_gym.jit import inlined, kernel
from debris_gym.scenario_checks import MAX_SPIN, number

__all__ = [
    "ORBIT_CANDIDATES",
    "check_motion",
    "checked_horizon",
    "moving_unplaceable",
    "orbit_draw_size",
    "random_orbit_fields",
]

ORBIT_CANDIDATES = {2: 64, 3: 32}
"""Candidate orbits per body in one draw, by dim (a fixed number, so a draw's block has a fixed
size): enough that a default field places every body in ~99.8 % (2D) / ~99.9 % (3D) of draws
(measured: 16 candidates place 74 % of 2D fields, 32 96 %, 64 99.8 %; 3D places ~100 % from 16
on); a field that fails is drawn again from its next block."""

SEARCH_TOLERANCE = 0.25
"""Smallest distance slack (m) the branch and bound of a pair resolves: a pair whose smallest
distance it cannot place above ``need`` at that resolution is refused (conservatively)."""

SEARCH_STACK = 128
"""Intervals the branch and bound holds at once (depth-first: ~8 + one per halving)."""

_CHUNK = 64
"""Most fields drawn in one set of array operations."""


def check_motion(spec: FieldSpec) -> None:
    """Check the motion keys of ``spec`` (``FieldSpec.__post_init__`` calls this).

    Raises:
        ValueError: naming the key (``FieldSpec.<key>``) and its allowed range.
    """
    if spec.motion not in FIELD_MOTIONS:
        raise ValueError(f"FieldSpec.motion={spec.motion!r}; allowed: {FIELD_MOTIONS}")
    low_n = 0.0 if spec.motion == "frozen" else 1e-9  # moving bodies need n > 0
    number(spec.mean_motion, "FieldSpec.mean_motion", low=low_n, high=1.0, unit="rad/s")
    number(spec.horizon, "FieldSpec.horizon", low=0.0, high=1e7, unit="s")
    number(spec.rho_max, "FieldSpec.rho_max", low=0.0, high=1e6, unit="m")
    number(spec.spin_max, "FieldSpec.spin_max", low=0.0, high=MAX_SPIN, unit="rad/s")
    offset = spec.drift_offset
    if not (isinstance(offset, tuple) and len(offset) == 2):
        raise ValueError(f"FieldSpec.drift_offset must be a (min, max) pair in m, got {offset!r}")
    low = number(offset[0], "FieldSpec.drift_offset[0]", low=0.0, high=1e6, unit="m")
    number(offset[1], "FieldSpec.drift_offset[1]", low=low, high=1e6, unit="m")


def checked_horizon(spec: FieldSpec) -> float:
    """The time span (s) a moving field of ``spec`` is checked over: ``horizon``, at least one
    orbit 2π/n (a drift-free field is then valid for ever, since its motion repeats)."""
    return max(float(spec.horizon), 2.0 * math.pi / spec.mean_motion)


def _params_per_candidate(spec: FieldSpec) -> int:
    """Uniform numbers per candidate orbit: ρ, α, y_c; + ρ_z, β in 3D; + x_c when drifting."""
    return 3 + (2 if spec.dim == 3 else 0) + (1 if spec.motion == "drifting" else 0)


@functools.lru_cache(maxsize=64)  # called on every reset; the spec is frozen
def orbit_draw_size(spec: FieldSpec) -> int:
    """Uniform numbers one draw of one moving field takes from its generator (a fixed block):
    B radii, in 2D O polygon flags, O polygon shapes and O spins, then B × C candidates."""
    bodies = spec.n_targets + spec.n_obstacles
    polygons = spec.n_obstacles * (2 + _POLYGON_DRAWS) if spec.dim == 2 else 0
    return bodies + polygons + bodies * ORBIT_CANDIDATES[spec.dim] * _params_per_candidate(spec)


def moving_unplaceable(spec: FieldSpec) -> str | None:
    """Why no moving field of ``spec`` can ever be placed, or None.

    Every drift-free orbit is centred on the V-bar (x = 0), so the smallest body must fit at
    its dock distance along it; a drifting body's centre slides 1.5 n |x_c| · horizon along-track,
    which must fit in the box."""
    half = spec.field_size / 2.0
    kinds = [("target", spec.target_radius[0], max(spec.min_target_distance, spec.dock_clearance))]
    if spec.n_obstacles:
        kinds.append(("obstacle", spec.obstacle_radius[0], spec.dock_clearance))
    for kind, radius, dock_distance in kinds:
        lim = half - radius - spec.min_gap
        if lim < dock_distance + radius:
            return (
                f"no moving {kind} of radius {radius:g} m fits: every drift-free orbit is "
                f"centred on the along-track axis, where its centre must lie "
                f"{dock_distance + radius:g} m or more from the dock and {radius + spec.min_gap:g}"
                f" m or more inside the bounds, which are {half:g} m from the dock"
            )
        if spec.motion == "drifting":
            slide = 1.5 * spec.mean_motion * spec.drift_offset[0] * checked_horizon(spec)
            if slide > 2.0 * lim or spec.drift_offset[0] > lim:
                return (
                    f"FieldSpec.drift_offset={spec.drift_offset!r} m: a {kind} with the smallest "
                    f"offset slides {slide:g} m along-track over the horizon "
                    f"{checked_horizon(spec):g} s, more than the {2.0 * lim:g} m it has; lower "
                    "drift_offset or horizon"
                )
    return None


def random_orbit_fields(
    rngs: Sequence[np.random.Generator],
    spec: FieldSpec,
    *,
    capture_radius: float,
    max_tries: int = 50,
) -> FieldArrays:
    """Draw one moving field per generator (the moving branch of
    :func:`~debris_gym.generators.random_fields`); ``velocities`` and ``spins`` are filled.

    Raises:
        ValueError: the spec breaks the solvability conditions (naming them), can never be
            placed, or some field found no valid draw in ``max_tries``.
    """
    if not route_by_construction(spec, capture_radius):
        raise ValueError(
            "a moving field needs the disjoint-balls conditions at every instant (the "
            "solvability argument, module docstring): FieldSpec.min_gap > 2·chaser_radius and "
            "> chaser_radius + capture_radius/2, min_gap + target_clearance > 2·chaser_radius + "
            "capture_radius/2, dock_clearance > chaser_radius and capture_radius > 0; got "
            f"min_gap={spec.min_gap}, target_clearance={spec.target_clearance}, "
            f"dock_clearance={spec.dock_clearance}, chaser_radius={spec.chaser_radius}, "
            f"capture_radius={capture_radius}: raise min_gap or lower chaser_radius"
        )
    why = moving_unplaceable(spec)
    if why is not None:
        raise ValueError(why)
    rngs = list(rngs)
    if len(rngs) > _CHUNK:  # bounded temporaries: a big batch goes in chunks (same fields)
        parts = [
            random_orbit_fields(rngs[i : i + _CHUNK], spec, capture_radius=capture_radius,
                                max_tries=max_tries)
            for i in range(0, len(rngs), _CHUNK)
        ]  # fmt: skip
        names = ("centers", "radii", "vertices", "n_vertices", "velocities", "spins")
        return FieldArrays(
            parts[0].dim, parts[0].half_size, parts[0].n_targets,
            **{k: np.concatenate([getattr(p, k) for p in parts]) for k in names},
        )  # fmt: skip
    num = len(rngs)
    block = np.empty((num, orbit_draw_size(spec)))
    out: tuple[np.ndarray, ...] | None = None
    pending = np.arange(num)
    for _ in range(max_tries):
        u = block[: pending.size]
        for row, i in zip(u, pending.tolist()):
            rngs[i].random(out=row)
        *arrays, placed = _draw_fields(u, spec)
        if out is None:
            if placed.all():  # every field on its first draw (the usual case)
                return _arrays(spec, arrays)
            out = tuple(np.zeros((num, *a.shape[1:]), a.dtype) for a in arrays)
        done = pending[placed]
        for target, source in zip(out, arrays):
            target[done] = source[placed]
        pending = pending[~placed]
        if pending.size == 0:
            return _arrays(spec, out)
    raise ValueError(
        f"could not place n_targets={spec.n_targets} and n_obstacles={spec.n_obstacles} on "
        f"relative orbits (motion={spec.motion!r}) in field_size={spec.field_size} m with "
        f"min_gap={spec.min_gap} m after {max_tries} draws; lower n_obstacles or the radii, "
        "raise field_size, or give the orbits room (rho_max: every drift-free orbit is centred "
        "on the along-track axis, so small amplitudes crowd it)"
    )


def _arrays(spec: FieldSpec, arrays) -> FieldArrays:
    centers, velocities, radii, vertices, n_vertices, spins = arrays
    return FieldArrays(
        spec.dim, spec.field_size / 2.0, spec.n_targets, centers, radii, vertices, n_vertices,
        velocities=velocities, spins=spins,
    )  # fmt: skip


def _draw_fields(u: np.ndarray, spec: FieldSpec):
    """Place the bodies of K moving fields from their blocks ``u`` (K, :func:`orbit_draw_size`).

    Returns ``(centers, velocities, radii, vertices, n_vertices, spins, placed)``."""
    return _draw_orbits(
        np.ascontiguousarray(u), spec.dim, spec.n_targets, spec.n_obstacles,
        *spec.target_radius, *spec.obstacle_radius, spec.polygon_fraction, spec.field_size,
        spec.min_gap, spec.target_clearance, spec.dock_clearance,
        max(spec.min_target_distance, spec.dock_clearance), spec.mean_motion,
        checked_horizon(spec), spec.motion == "drifting", *spec.drift_offset, spec.rho_max,
        spec.spin_max, ORBIT_CANDIDATES[spec.dim],
    )  # fmt: skip


@kernel
def _draw_orbits(
    u, dim, t, o, target_lo, target_hi, obstacle_lo, obstacle_hi, polygon_fraction, field_size,
    min_gap, target_clearance, dock_clearance, target_start, n, horizon, drifting, drift_lo,
    drift_hi, rho_max, spin_max, n_cand,
):  # fmt: skip
    """The bodies of K moving fields from their blocks ``u`` (see the module docstring).

    Block layout: B radii (targets first); in 2D O polygon flags, O × 10 polygon shape numbers
    and O spins; then B × C candidates of P numbers: ρ, α, y_c (+ ρ_z, β in 3D; + x_c when
    drifting). Candidates are decoded only as far as they are tried. A body's elements
    (x_c, y_c, a = ρ cos α, b = ρ sin α, a_z = ρ_z cos β, b_z = ρ_z sin β) give x = x_c +
    a sin nt + b cos nt, y = y_c − 1.5 n x_c t + 2(a cos nt − b sin nt), z = a_z sin nt +
    b_z cos nt; its state at t = 0 is what the field hands out.
    """
    num = u.shape[0]
    b_all = t + o
    p = 3 + (2 if dim == 3 else 0) + (1 if drifting else 0)
    radii = np.empty((num, b_all))
    v_max = MAX_POLYGON_VERTICES if dim == 2 else 0
    vertices = np.zeros((num, o, v_max, 2))
    n_vertices = np.zeros((num, o), dtype=np.int64)
    spins = np.zeros((num, b_all))
    centers = np.zeros((num, b_all, dim))
    velocities = np.zeros((num, b_all, dim))
    placed = np.ones(num, dtype=np.bool_)
    start = b_all + (o * (2 + _POLYGON_DRAWS) if dim == 2 else 0)
    spacing = np.full(b_all, float(min_gap))
    for b in range(t):
        spacing[b] += target_clearance
    elem = np.zeros((b_all, 6))  # x_c, y_c, a, b, a_z, b_z of the bodies placed so far
    half = field_size / 2.0
    for k in range(num):
        for b in range(b_all):
            if b < t:
                radii[k, b] = target_lo + (target_hi - target_lo) * u[k, b]
            else:
                radii[k, b] = obstacle_lo + (obstacle_hi - obstacle_lo) * u[k, b]
        if dim == 2:
            for j in range(o):
                if u[k, b_all + j] < polygon_fraction:
                    first = b_all + o + j * _POLYGON_DRAWS
                    n_vertices[k, j] = _convex_polygon(
                        u[k, first : first + _POLYGON_DRAWS], radii[k, t + j], vertices[k, j]
                    )
                    spin_u = u[k, b_all + o + o * _POLYGON_DRAWS + j]
                    spins[k, t + j] = spin_max * (2.0 * spin_u - 1.0)
        for b in range(b_all):
            r = radii[k, b]
            lim = half - r - min_gap
            dock_need = dock_clearance + r
            found = False
            for c in range(n_cand):
                q = start + (b * n_cand + c) * p
                xc = 0.0
                if drifting:
                    w = u[k, q + p - 1]
                    mag = drift_lo + (drift_hi - drift_lo) * (2.0 * w if w < 0.5 else 2.0 * w - 1.0)
                    xc = -mag if w < 0.5 else mag
                slide = -1.5 * n * xc * horizon  # along-track displacement of the centre
                cap = min(rho_max, lim - abs(xc), (2.0 * lim - abs(slide)) / 4.0)
                if cap < 0.0:
                    continue
                rho = cap * np.sqrt(u[k, q])  # area-uniform in the (x, y/2) disc
                alpha = 2.0 * np.pi * u[k, q + 1]
                ea = rho * np.cos(alpha)
                eb = rho * np.sin(alpha)
                y_lo = -lim + 2.0 * rho - min(slide, 0.0)
                y_hi = lim - 2.0 * rho - max(slide, 0.0)
                yc = y_lo + (y_hi - y_lo) * u[k, q + 2]
                ez = 0.0
                fz = 0.0
                if dim == 3:
                    rho_z = min(rho_max, lim) * u[k, q + 3]
                    beta = 2.0 * np.pi * u[k, q + 4]
                    ez = rho_z * np.cos(beta)
                    fz = rho_z * np.sin(beta)
                if b < t:  # a target starts min_target_distance from the dock
                    x0 = xc + eb
                    y0 = yc + 2.0 * ea
                    reach = target_start + r
                    if x0 * x0 + y0 * y0 + fz * fz < reach * reach:
                        continue
                if not _apart(xc, yc, ea, eb, ez, fz, dock_need, dim, n, horizon):
                    continue
                clear = True
                for j in range(b):
                    need = r + radii[k, j] + max(spacing[b], spacing[j])
                    if not _apart(
                        xc - elem[j, 0], yc - elem[j, 1], ea - elem[j, 2], eb - elem[j, 3],
                        ez - elem[j, 4], fz - elem[j, 5], need, dim, n, horizon,
                    ):  # fmt: skip
                        clear = False
                        break
                if clear:
                    elem[b, 0] = xc
                    elem[b, 1] = yc
                    elem[b, 2] = ea
                    elem[b, 3] = eb
                    elem[b, 4] = ez
                    elem[b, 5] = fz
                    centers[k, b, 0] = xc + eb
                    centers[k, b, 1] = yc + 2.0 * ea
                    velocities[k, b, 0] = n * ea
                    velocities[k, b, 1] = -1.5 * n * xc - 2.0 * n * eb
                    if dim == 3:
                        centers[k, b, 2] = fz
                        velocities[k, b, 2] = n * ez
                    found = True
                    break
            if not found:
                placed[k] = False
                break
    return centers, velocities, radii, vertices, n_vertices, spins, placed


@inlined
def _apart(dxc, dyc, da, db, daz, dbz, need, dim, n, horizon):
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
        return _search(0.0, da, db, dyc, daz, dbz, need, 1.0, 0.0, 2.0 * np.pi, bend)
    # drifting pair: search time t in [0, horizon]; d²'' = 2|Δv|² + 2 Δp·Δa, with
    # |Δv| <= n√(R² + (1.5|Δx_c| + 2R)² + R_z²), |Δa| <= n²√(5R² + R_z²) and |Δp| bounded by the
    # extent of the relative motion over the horizon
    speed = n * np.sqrt(rr * rr + (1.5 * abs(dxc) + 2.0 * rr) ** 2 + rz * rz)
    accel = n * n * np.sqrt(5.0 * rr * rr + rz * rz)
    far_y = max(abs(dyc), abs(dyc - slide)) + 2.0 * rr
    far = np.sqrt((abs(dxc) + rr) ** 2 + far_y * far_y + rz * rz)
    bend = 2.0 * speed * speed + 2.0 * far * accel
    return _search(dxc, da, db, dyc, daz, dbz, need, n, -1.5 * n * dxc, horizon, bend)


@inlined
def _distance2(dxc, da, db, dyc, daz, dbz, rate, slope, s):
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
def _search(dxc, da, db, dyc, daz, dbz, need, rate, slope, span, bend):
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
    f_lo = _distance2(dxc, da, db, dyc, daz, dbz, rate, slope, 0.0)
    if f_lo < need2:
        return False
    for i in range(pieces):
        lo = span * i / pieces
        hi = span * (i + 1) / pieces
        f_hi = _distance2(dxc, da, db, dyc, daz, dbz, rate, slope, hi)
        if f_hi < need2:
            return False
        stack[top, 0] = lo
        stack[top, 1] = hi
        stack[top, 2] = f_lo
        stack[top, 3] = f_hi
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
        f_mid = _distance2(dxc, da, db, dyc, daz, dbz, rate, slope, mid)
        if f_mid < need2:
            return False
        stack[top, 0] = lo
        stack[top, 1] = mid
        stack[top, 2] = f_lo
        stack[top, 3] = f_mid
        stack[top + 1, 0] = mid
        stack[top + 1, 1] = hi
        stack[top + 1, 2] = f_mid
        stack[top + 1, 3] = f_hi
        top += 2
    return True
