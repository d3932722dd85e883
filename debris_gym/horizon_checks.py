"""The rules a moving field keeps over an episode: bodies inside the bounds and apart at every
instant of ``[0, T]``, not only at t = 0.

A pinned moving field (``motion="cwh"``) is checked as the generators check a drawn one: every
body, judged by its bounding circle / sphere (the area a turning polygon sweeps), stays wholly
inside the bounds, and no two bodies overlap, at every instant of the horizon T (the env's
episode: its registered time limit in steps times the scenario's ``dt``). Touching is allowed, to
a relative :data:`~debris_gym.scenario_values.RELATIVE_TOLERANCE` of the world's size. The dock
is checked at t = 0 only (:mod:`debris_gym.scenario_checks`): a body whose later path crosses the
start is a legitimate test case.

The check is exact up to that tolerance, not sampled. Bodies are propagated to every step end
with the exact CW transition (:func:`debris_gym.dynamics.discretize`, as the envs move them);
between two step ends a quantity g that must stay >= 0 (a body's distance inside a bound; a
pair's squared centre distance less the squared sum of radii) is at least
``min(g(ends)) − max|g''| · h² / 8`` over an interval of length h, and ``max|g''|`` is bounded
for all time by the motion's invariants (below). An interval this cannot decide is halved, with
the exact transition over the half, until it is decided or its margin is below the tolerance.

Invariants of unforced CW motion (x radial, y along-track, z cross-track, n the mean motion),
from a state (x, y, z, vx, vy, vz), division-free so that n = 0 (straight lines) is included:
the in-plane amplitude times n, ``nR = √(vx² + (3n·x + 2vy)²)``; the drift rate's radial offset
times n, ``n·x_c = 4n·x + 2vy``; the cross-track amplitude times n, ``nR_z = √(vz² + n²z²)``.
Then at every t: ``|vx| ≤ nR``, ``|vy| ≤ 1.5·n|x_c| + 2nR``, ``|vz| ≤ nR_z``, and
``|ax| ≤ n·nR``, ``|ay| ≤ 2n·nR``, ``|az| ≤ n·nR_z`` ([Curtis14] §7.4 in the element form of
:mod:`debris_gym.relative_orbits`). Two bodies' relative motion is itself CW motion, so a pair's
bounds come from its relative state the same way.

Positions in m, velocities in m/s, times in s. No gymnasium: the env passes its horizon in steps.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from debris_gym.dynamics import discretize
from debris_gym.scenario_values import RELATIVE_TOLERANCE
from debris_gym.sweep_prune import overlapping_intervals

__all__ = [
    "BLOCK_STEPS",
    "MAX_HALVINGS",
    "MotionFault",
    "describe",
    "first_motion_fault",
    "rate_bounds",
]

BLOCK_STEPS = 32
"""Step ends per block in a large field: the bodies' swept boxes over a block pick the pairs
worth testing."""

WHOLE_PAIRS = 1 << 19
"""A field whose pairs times step ends stay below this is tested in one block, every pair (no
boxes: the default field's 253 pairs over 1 000 steps; temporaries of at most ~25 MB)."""

MAX_HALVINGS = 48
"""Deepest halving of a step an undecided interval gets (its margin is far below the tolerance
long before)."""

_PAIR_CHUNK = 1 << 13
"""Candidate pairs tested at once (bounds the temporaries of a dense field)."""


class MotionFault(NamedTuple):
    """An instant at which a moving field breaks a rule.

    Attributes:
        time: when (s since t = 0): a step end or an instant between two.
        first: index of the body (targets first) that leaves the bounds, or the lower index of
            the pair that overlaps.
        second: the other body of the pair, or -1 for a body leaving the bounds.
        positions: (2, dim) centres (m) of ``first`` and ``second`` at ``time`` (row 1 unused
            for a body leaving the bounds).
    """

    time: float
    first: int
    second: int
    positions: np.ndarray


def first_motion_fault(
    states: np.ndarray,
    radii: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    mean_motion: float,
    dt: float,
    steps: int,
) -> MotionFault | None:
    """An instant in ``[0, steps · dt]`` at which a body's ball leaves the bounds or two balls
    overlap (the earliest the check meets: blocks of steps are searched in time order), or None
    if the motion keeps every rule (module docstring).

    Args:
        states: (B, 2·dim) body positions (m) and velocities (m/s) at t = 0.
        radii: (B,) bounding radii (m).
        low, high: (dim,) world bounds (m).
        mean_motion: n (rad/s), >= 0.
        dt: step length (s), > 0.
        steps: steps in the horizon, >= 0.
    """
    states = np.asarray(states, dtype=float)
    radii = np.asarray(radii, dtype=float)
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    dim = states.shape[1] // 2
    tol = RELATIVE_TOLERANCE * float(np.max(high - low))
    velocity, accel = rate_bounds(states, mean_motion, dim)
    steps = max(int(steps), 0)
    # what the orbit elements prove for all of [0, T] is left out of the search over time
    horizon = steps * dt
    unproven = ~proven_inside(states, radii, low, high, mean_motion, horizon, tol)
    apart = _Apart(states, radii, mean_motion, horizon, tol)
    pairs = len(radii) * (len(radii) - 1) // 2
    whole = pairs * (steps + 1) <= WHOLE_PAIRS
    if whole and not unproven.any() and not apart.unproven(*np.triu_indices(len(radii), 1)).any():
        return None  # the elements prove every rule: no search over time
    length = max(steps, 1) if whole else BLOCK_STEPS
    powers = _powers(mean_motion, dt, dim, length)
    start = states
    for first in range(0, steps + 1, length):
        count = min(length, steps - first)  # intervals in this block (0: t = 0 alone)
        samples = np.einsum("kij,bj->kbi", powers[: count + 1], start)  # (count + 1, B, 2·dim)
        block = _Block(samples, first * dt, dt, mean_motion, tol, whole)
        found = [
            fault
            for fault in (
                _inside_fault(block, radii, low, high, accel, unproven),
                _apart_fault(block, radii, states, velocity, apart),
            )
            if fault is not None
        ]
        if found:
            return min(found, key=lambda fault: fault.time)
        if count == 0:
            break
        start = samples[count]
    return None


class _Block(NamedTuple):
    """Step ends ``t0, t0 + dt, …`` of one block and what the checks of a block need."""

    samples: np.ndarray  # (K+1, B, 2·dim) body states at the step ends
    t0: float  # time of samples[0] (s)
    dt: float  # step (s)
    n: float  # mean motion (rad/s)
    tol: float  # allowed overlap, distance (m)
    every_pair: bool  # test every pair (else those whose swept boxes meet)

    @property
    def dim(self) -> int:
        return self.samples.shape[2] // 2


def rate_bounds(states: np.ndarray, n: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(…, dim) bounds on |velocity| (m/s) and |acceleration| (m/s²) per axis, for all time, of
    the CW motions from ``states`` (…, 2·dim) (module docstring)."""
    x, vx, vy = states[..., 0], states[..., dim], states[..., dim + 1]
    n_r = np.hypot(vx, 3.0 * n * x + 2.0 * vy)
    n_xc = np.abs(4.0 * n * x + 2.0 * vy)
    velocity = [n_r, 1.5 * n_xc + 2.0 * n_r]
    accel = [n * n_r, 2.0 * n * n_r]
    if dim == 3:
        n_rz = np.hypot(states[..., 5], n * states[..., 2])
        velocity.append(n_rz)
        accel.append(n * n_rz)
    return np.stack(velocity, axis=-1), np.stack(accel, axis=-1)


def orbit_elements(states: np.ndarray, n: float) -> tuple[np.ndarray, ...]:
    """``(x_c, y_c, R, R_z)`` (m) of the CW motions from ``states`` (…, 2·dim), n > 0: radial
    offset and along-track position at t = 0 of the ellipse's centre, in-plane and cross-track
    amplitudes (:mod:`debris_gym.relative_orbits`; R_z = 0 in 2D)."""
    dim = states.shape[-1] // 2
    x, y, vx, vy = (states[..., k] for k in (0, 1, dim, dim + 1))
    x_c = (4.0 * n * x + 2.0 * vy) / n
    a = vx / n
    amplitude = np.hypot(a, -3.0 * x - 2.0 * vy / n)
    r_z = np.hypot(states[..., 5] / n, states[..., 2]) if dim == 3 else np.zeros_like(x)
    return x_c, y - 2.0 * a, amplitude, r_z


_ROUNDING = 1e-12
"""Relative error allowed for the element forms (a few thousand times the double epsilon)."""


def proven_inside(states, radii, low, high, n, horizon, tol) -> np.ndarray:
    """(B,) True for each body whose ball the orbit elements keep inside the bounds over
    ``[0, horizon]``: x within x_c ± R, y within 2R of the sliding centre y_c − 1.5 n x_c t,
    z within ±R_z (all False when n = 0)."""
    if n <= 0.0:
        return np.zeros(len(radii), dtype=bool)
    x_c, y_c, amplitude, r_z = orbit_elements(states, n)
    slide = 1.5 * n * x_c * horizon
    extent_lo = [x_c - amplitude, np.minimum(y_c, y_c - slide) - 2.0 * amplitude]
    extent_hi = [x_c + amplitude, np.maximum(y_c, y_c - slide) + 2.0 * amplitude]
    if states.shape[1] == 6:
        extent_lo.append(-r_z)
        extent_hi.append(r_z)
    slack = _ROUNDING * (np.abs(x_c) + np.abs(y_c) + 3.0 * amplitude + r_z + np.abs(slide))
    reach = (radii + slack - tol)[:, None]
    return np.all(
        (np.stack(extent_lo, axis=1) - reach >= low)
        & (np.stack(extent_hi, axis=1) + reach <= high),
        axis=1,
    )


_PHASES = 256
"""Phases of the relative ellipse at which a 3D pair's distance is evaluated (the bound between
them comes from the curvature)."""


_PHASE_CHUNK = 2048
"""Pairs whose phases are evaluated at once."""


class _Apart:
    """Which pairs the orbit elements keep apart over ``[0, horizon]``.

    The relative motion is a periodic ellipse (relative elements a, b, a_z, b_z and along-track
    centre offset D) displaced by (Δx_c, −1.5 n Δx_c t, 0), which moves it at most
    |Δx_c| (1 + 1.5 n T) over the horizon T. In the plane the ellipse's smallest distance is
    exact: |D| − 2R when |D| >= 1.5 R, else √(R² − D²/3) (as in
    :func:`debris_gym.orbit_separation.apart`). In 3D its squared distance over the phase θ is
    evaluated on :data:`_PHASES` phases, less the curvature bound (4|D|R + 6R² + 2R_z²) · h²/8
    between them.
    """

    def __init__(self, states, radii, n, horizon, tol) -> None:
        self.states, self.radii, self.n, self.horizon, self.tol = states, radii, n, horizon, tol

    def unproven(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(P,) True for the pairs (i, j) not proven apart."""
        n = self.n
        if n <= 0.0:
            return np.ones(len(i), dtype=bool)
        rel = self.states[i] - self.states[j]
        dim = rel.shape[1] // 2
        x_c, d, amplitude, r_z = orbit_elements(rel, n)
        if dim == 2:
            dd = np.abs(d)
            nearest = np.where(
                dd >= 1.5 * amplitude,
                np.abs(dd - 2.0 * amplitude),
                np.sqrt(np.maximum(amplitude * amplitude - dd * dd / 3.0, 0.0)),
            )
        else:
            a, b = rel[:, dim] / n, -3.0 * rel[:, 0] - 2.0 * rel[:, dim + 1] / n
            a_z, b_z = rel[:, 5] / n, rel[:, 2]
            theta = np.linspace(0.0, 2.0 * np.pi, _PHASES + 1)[:, None]
            sn, co = np.sin(theta), np.cos(theta)
            smallest = np.empty(len(i))
            for k in range(0, len(i), _PHASE_CHUNK):  # bounded temporaries (phases × pairs)
                part = slice(k, k + _PHASE_CHUNK)
                f = (
                    (a[part] * sn + b[part] * co) ** 2
                    + (d[part] + 2.0 * (a[part] * co - b[part] * sn)) ** 2
                    + (a_z[part] * sn + b_z[part] * co) ** 2
                )
                smallest[part] = f.min(axis=0)
            bend = 4.0 * np.abs(d) * amplitude + 6.0 * amplitude**2 + 2.0 * r_z**2
            low = smallest - bend * (2.0 * np.pi / _PHASES) ** 2 / 8.0
            nearest = np.sqrt(np.maximum(low, 0.0))
        drift = np.abs(x_c) * (1.0 + 1.5 * n * self.horizon)
        slack = _ROUNDING * (np.abs(d) + 3.0 * amplitude + r_z + drift)
        return nearest - drift - slack < self.radii[i] + self.radii[j] - self.tol


def _powers(n: float, dt: float, dim: int, count: int) -> np.ndarray:
    """(count + 1, 2·dim, 2·dim) transitions over 0, dt, …, count·dt (repeated steps, as the
    envs move their bodies)."""
    ad = discretize(n, dt, dim).ad
    out = np.empty((count + 1, 2 * dim, 2 * dim))
    out[0] = np.eye(2 * dim)
    for k in range(count):
        out[k + 1] = ad @ out[k]
    return out


# --- bodies inside the bounds -------------------------------------------------------------------


def _inside_fault(block: _Block, radii, low, high, accel, unproven) -> MotionFault | None:
    """An instant of the block at which a body's ball crosses a bound (g < 0 below); only the
    bodies in ``unproven`` (B,) bool are searched."""
    bodies = np.flatnonzero(unproven)
    if bodies.size == 0:
        return None
    fault = _inside_fault_of(block._replace(samples=block.samples[:, bodies]), radii[bodies],
                             low, high, accel[bodies])  # fmt: skip
    if fault is None:
        return None
    return fault._replace(first=int(bodies[fault.first]))


def _inside_fault_of(block: _Block, radii, low, high, accel) -> MotionFault | None:
    dim, tol = block.dim, block.tol
    pos = block.samples[:, :, :dim]
    # g >= 0 inside: distance left to the upper, then to the lower bound, per axis (K+1, B, 2d)
    g = np.concatenate([high - radii[:, None] - pos, pos - radii[:, None] - low], axis=2)
    bend = np.concatenate([accel, accel], axis=1)  # (B, 2·dim): bounds on |g''|
    best = None
    bad = np.argwhere(g < -tol)
    if bad.size:
        k0, b0 = int(bad[0, 0]), int(bad[0, 1])
        best = MotionFault(block.t0 + k0 * block.dt, b0, -1, _positions(pos[k0, b0]))
    if g.shape[0] < 2:
        return best
    lo, hi = g[:-1], g[1:]
    dip = bend[None] * block.dt**2 / 8.0
    k, b, q = np.nonzero((lo >= -tol) & (hi >= -tol) & (np.minimum(lo, hi) - dip < -tol))
    if k.size == 0:
        return best
    axis, upper = q % dim, q < dim

    def value(s: np.ndarray, rows: np.ndarray) -> np.ndarray:
        p = s[np.arange(len(rows)), axis[rows]]
        r = radii[b[rows]]
        return np.where(upper[rows], high[axis[rows]] - r - p, p - r - low[axis[rows]])

    def margin(rows, h, g_lo, g_hi):
        return bend[b[rows], q[rows]] * h * h / 8.0

    found = _halve(
        block.samples[k, b], lo[k, b, q], hi[k, b, q], block.t0 + k * block.dt, block.dt,
        block.n, np.full(k.size, tol), value, margin,
    )  # fmt: skip
    if found is not None and (best is None or found[0] < best.time):
        time, row, state = found
        best = MotionFault(time, int(b[row]), -1, _positions(state[:dim]))
    return best


# --- pairs apart --------------------------------------------------------------------------------


def _apart_fault(block: _Block, radii, states, velocity, apart: _Apart) -> MotionFault | None:
    """An instant of the block at which two balls overlap. Tested: every pair, or (a large
    field) the pairs whose swept boxes over the block (samples ± how far a body strays between
    two of them) meet — less those ``apart`` proves apart."""
    dim = block.dim
    pos = block.samples[:, :, :dim]
    if pos.shape[1] < 2:
        return None
    if block.every_pair:
        chunks = [np.triu_indices(pos.shape[1], k=1)]
    else:
        stray = velocity * (block.dt / 2.0)
        box_lo = pos.min(axis=0) - stray - radii[:, None]
        box_hi = pos.max(axis=0) + stray + radii[:, None]
        chunks = _box_pairs(box_lo, box_hi)
    best = None
    for i, j in chunks:
        keep = apart.unproven(i, j)
        if not keep.any():
            continue
        fault = _pairs_fault(block, radii, states, i[keep], j[keep])
        if fault is not None and (best is None or fault.time < best.time):
            best = fault
    return best


def _box_pairs(lo: np.ndarray, hi: np.ndarray):
    """Yield ``(i, j)`` index arrays (i < j; chunks of at most :data:`_PAIR_CHUNK`) of the pairs
    whose boxes ``[lo, hi]`` (B, dim) meet on every axis: sweep and prune on the widest axis."""
    axis = int(np.argmax(hi.max(axis=0) - lo.min(axis=0)))
    for a, b in overlapping_intervals(lo[:, axis], hi[:, axis], _PAIR_CHUNK, touching=True):
        meet = np.all((lo[a] <= hi[b]) & (lo[b] <= hi[a]), axis=1)
        if meet.any():
            yield np.minimum(a[meet], b[meet]), np.maximum(a[meet], b[meet])


def _pairs_fault(block: _Block, radii, states, i, j) -> MotionFault | None:
    """An instant of the block at which a pair (i[p], j[p]) overlaps (f < 0 below)."""
    dim, dt = block.dim, block.dt
    rel = block.samples[:, i] - block.samples[:, j]  # (K+1, P, 2·dim): CW motion too
    need2 = (radii[i] + radii[j]) ** 2
    tol = 2.0 * (radii[i] + radii[j]) * block.tol  # on the squared distance
    f = np.einsum("kpd,kpd->kp", rel[:, :, :dim], rel[:, :, :dim]) - need2
    best = None
    bad = np.argwhere(f < -tol)
    if bad.size:
        k0, p0 = int(bad[0, 0]), int(bad[0, 1])
        best = _pair_fault(block.t0 + k0 * dt, i[p0], j[p0], block.samples[k0], dim)
    if f.shape[0] < 2:
        return best
    velocity, accel = rate_bounds(states[i] - states[j], block.n, dim)
    speed = np.sqrt((velocity**2).sum(axis=1))
    pull = np.sqrt((accel**2).sum(axis=1))

    def margin(rows, h, f_lo, f_hi):
        # |f''| = |2|Δv|² + 2Δp·Δa| <= 2 speed² + 2 |Δp| pull, |Δp| at most the farther end's
        # distance plus the stray over half the interval
        far = np.sqrt(np.maximum(np.maximum(f_lo, f_hi) + need2[rows], 0.0)) + speed[rows] * h / 2
        return (2.0 * speed[rows] ** 2 + 2.0 * far * pull[rows]) * h * h / 8.0

    lo, hi = f[:-1], f[1:]
    every = np.broadcast_to(np.arange(len(i)), lo.shape)
    dip = margin(every, dt, lo, hi)
    k, p = np.nonzero((lo >= -tol) & (hi >= -tol) & (np.minimum(lo, hi) - dip < -tol))
    if k.size == 0:
        return best

    def value(s: np.ndarray, rows: np.ndarray) -> np.ndarray:
        return np.einsum("pd,pd->p", s[:, :dim], s[:, :dim]) - need2[p[rows]]

    def item_margin(rows, h, f_lo, f_hi):
        return margin(p[rows], h, f_lo, f_hi)

    found = _halve(
        rel[k, p], lo[k, p], hi[k, p], block.t0 + k * dt, dt, block.n, tol[p], value,
        item_margin,
    )  # fmt: skip
    if found is not None and (best is None or found[0] < best.time):
        time, row, _ = found
        step, m = int(k[row]), int(p[row])
        # both bodies at that instant, from their states at the step end before it
        ad = discretize(block.n, time - (block.t0 + step * dt), dim).ad
        best = _pair_fault(time, i[m], j[m], block.samples[step] @ ad.T, dim)
    return best


def _pair_fault(time: float, i: int, j: int, states: np.ndarray, dim: int) -> MotionFault:
    return MotionFault(float(time), int(i), int(j), np.stack([states[i, :dim], states[j, :dim]]))


def _positions(p: np.ndarray) -> np.ndarray:
    """Row 0: ``p``; row 1: NaN (no second body)."""
    return np.stack([p, np.full_like(p, np.nan)])


# --- halving undecided intervals ----------------------------------------------------------------


def _halve(states, g_lo, g_hi, t_lo, h, n, tol, value, margin):
    """Decide the intervals ``[t_lo, t_lo + h]`` the endpoint bound left open (one per row:
    ``states`` the CW state at the start, ``g_lo``/``g_hi`` the quantity at the ends) by
    halving them with the exact transition over the half.

    ``value(s, rows)`` is the quantity at states ``s`` of rows ``rows``; ``margin(rows, h, g_lo,
    g_hi)`` the most it can dip below its ends' minimum over an interval of length h. An
    interval whose margin falls below ``tol`` is decided (its quantity is >= −2 · tol).

    Returns:
        ``(time, row, state)`` of the earliest instant met where the quantity is below ``−tol``,
        or None if every interval holds.
    """
    rows = np.arange(len(states))
    dim = states.shape[1] // 2
    best = None
    for _ in range(MAX_HALVINGS):
        if rows.size == 0:
            break
        h = h / 2.0
        mid = states @ discretize(n, h, dim).ad.T
        g_mid = value(mid, rows)
        bad = np.flatnonzero(g_mid < -tol[rows])
        if bad.size:
            m = int(bad[np.argmin(t_lo[bad])])
            if best is None or t_lo[m] + h < best[0]:
                best = (float(t_lo[m] + h), int(rows[m]), mid[m])
        # the halves [lo, mid] and [mid, hi] of every interval whose middle held
        held = g_mid >= -tol[rows]
        states = np.concatenate([states[held], mid[held]])
        g_lo, g_hi = (
            np.concatenate([g_lo[held], g_mid[held]]),
            np.concatenate([g_mid[held], g_hi[held]]),
        )
        t_lo = np.concatenate([t_lo[held], t_lo[held] + h])
        rows = np.concatenate([rows[held], rows[held]])
        dip = margin(rows, h, g_lo, g_hi)
        open_ = (np.minimum(g_lo, g_hi) - dip < -tol[rows]) & (dip >= tol[rows])
        if best is not None:
            open_ &= t_lo < best[0]  # only an earlier fault could still matter
        states, g_lo, g_hi, t_lo, rows = (
            states[open_],
            g_lo[open_],
            g_hi[open_],
            t_lo[open_],
            rows[open_],
        )
    return best


def describe(fault: MotionFault, names: list[str], radii: np.ndarray) -> str:
    """The fault in words, naming the bodies by their key paths ``names``."""
    if fault.second < 0:
        b = fault.first
        return (
            f"{names[b]} (radius {radii[b]:g} m) leaves the bounds at t = {fault.time:g} s "
            f"(centre {np.round(fault.positions[0], 6).tolist()!r} m)"
        )
    i, j = fault.first, fault.second
    dist = float(math.dist(fault.positions[0], fault.positions[1]))
    return (
        f"{names[i]} and {names[j]} overlap at t = {fault.time:g} s (centres {dist:.6g} m "
        f"apart, radii {radii[i]:g} and {radii[j]:g} m)"
    )
