"""An independent dense check of contacts between a thrusting chaser and a turning polygon.

Nothing here shares code with :mod:`debris_gym`: the chaser's motion relative to a free body is
the closed-form CW solution with the step's constant thrust (typed in below; the unforced part
is :func:`tests.helpers.cw_closed_form`), the polygon is turned by its exact angle at each
instant, and the distance from a point to a convex polygon is plain numpy (held to pymunk in
``tests/test_turning_contacts.py``). The gap is sampled at 2 001 instants a step and more where
it could be smaller, until the true minimum over the step is within :data:`SAMPLING_ERROR` of
the sampled one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SAMPLING_ERROR = 1e-3
"""Largest amount (m) by which the true smallest gap over a step can lie below the sampled one."""

COARSE = 2000
"""Intervals per step of the first pass (the refinement adds instants where the gap is small)."""


def thrust_response(accel: np.ndarray, t: np.ndarray, n: float) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and velocity (m/s) reached from rest at times ``t`` (s) under the constant
    in-plane acceleration ``accel`` (m/s²): the particular solution of the CW equations
    ẍ = 3n²x + 2nẏ + a_x, ÿ = −2nẋ + a_y (integrate ÿ once, ẏ = a_y·t − 2n·x, and solve
    ẍ + n²x = a_x + 2n·a_y·t from rest). Shapes (len(t), 2)."""
    ax, ay = float(accel[0]), float(accel[1])
    t = np.asarray(t, dtype=float)
    nt = n * t
    s, c = np.sin(nt), np.cos(nt)
    x = (ax * (1 - c) + 2 * ay * (nt - s)) / n**2
    y = (-2 * ax * (nt - s) + ay * (4 * (1 - c) - 1.5 * nt**2)) / n**2
    vx = (ax * s + 2 * ay * (1 - c)) / n
    vy = (-2 * ax * (1 - c) + ay * (4 * s - 3 * nt)) / n
    return np.stack([x, y], axis=-1), np.stack([vx, vy], axis=-1)


def coast(state0: np.ndarray, t: np.ndarray, n: float) -> tuple[np.ndarray, np.ndarray]:
    """Unforced CW motion of the 2D state ``state0`` at times ``t`` ([Curtis14] eq. 7.53, the
    closed form of :func:`tests.helpers.cw_closed_form`, over an array of times)."""
    x0, y0, vx0, vy0 = (float(v) for v in state0)
    t = np.asarray(t, dtype=float)
    s, c = np.sin(n * t), np.cos(n * t)
    x = (4 - 3 * c) * x0 + s / n * vx0 + 2 / n * (1 - c) * vy0
    y = 6 * (s - n * t) * x0 + y0 - 2 / n * (1 - c) * vx0 + (4 * s - 3 * n * t) / n * vy0
    vx = 3 * n * s * x0 + c * vx0 + 2 * s * vy0
    vy = -6 * n * (1 - c) * x0 - 2 * s * vx0 + (4 * c - 3) * vy0
    return np.stack([x, y], axis=-1), np.stack([vx, vy], axis=-1)


def relative_motion(
    state0: np.ndarray, accel: np.ndarray, t: np.ndarray, n: float
) -> tuple[np.ndarray, np.ndarray]:
    """Relative position and velocity at times ``t`` (s) after a step's start, from the relative
    state ``state0`` with the chaser's thrust ``accel`` held (the body is free)."""
    p0, v0 = coast(state0, t, n)
    p1, v1 = thrust_response(accel, t, n)
    return p0 + p1, v0 + v1


def polygon_distance(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Signed distance (m, negative inside) from each point (M, 2) to the convex polygon with
    counter-clockwise ``vertices`` (V, 2)."""
    p = np.asarray(points, dtype=float)[:, None, :]
    a = np.asarray(vertices, dtype=float)[None, :, :]
    e = np.roll(a, -1, axis=1) - a
    ap = p - a
    u = np.clip((ap * e).sum(-1) / (e * e).sum(-1), 0.0, 1.0)
    gap = ap - u[..., None] * e
    dist = np.sqrt((gap * gap).sum(-1)).min(axis=1)
    cross = e[..., 0] * ap[..., 1] - e[..., 1] * ap[..., 0]  # ≥ 0 on the inner side of an edge
    inside = (cross >= 0.0).all(axis=1)
    return np.where(inside, -dist, dist)


def turned(points: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``points`` (M, 2) turned by −``angles`` (M,): LVLH offsets seen from a body at that
    attitude."""
    c, s = np.cos(angles), np.sin(angles)
    x, y = points[:, 0], points[:, 1]
    return np.stack([c * x + s * y, c * y - s * x], axis=-1)


@dataclass(frozen=True)
class StepTruth:
    """What the dense check finds over one step."""

    gap: float
    """Smallest gap (m) from the chaser's centre to the polygon over the step (sampled: the true
    one is at most :data:`SAMPLING_ERROR` lower)."""
    chord_error: float
    """Largest distance (m) between the exact relative path and the chords between its
    collision sub-step samples (the error every swept check carries, whatever turns)."""


SPLIT = 16
"""Pieces each interval of the refinement is cut into."""


def step_truth(
    state0: np.ndarray,
    accel: np.ndarray,
    start_time: float,
    rate: float,
    vertices: np.ndarray,
    n: float,
    dt: float,
    substeps: int,
) -> StepTruth:
    """The dense check of one step: relative state ``state0`` at its start ``start_time`` (s),
    thrust ``accel`` (m/s²), polygon ``vertices`` at the angle ``rate · t`` (rad) at time t.

    The gap is sampled at :data:`COARSE` + 1 instants, then every interval between samples whose
    gap could dip below the smallest found by more than :data:`SAMPLING_ERROR` is cut into
    :data:`SPLIT` and sampled again, until none could: the gap changes at most at the speed of
    the chaser in the polygon's frame, |relative velocity| + |rate|·|relative position|, bounded
    over the step (the velocity grows by at most 0.1 m/s² of thrust and CW terms between samples).
    """

    def gap_at(times: np.ndarray) -> np.ndarray:
        pos, _ = relative_motion(state0, accel, times, n)
        return polygon_distance(turned(pos, rate * (start_time + times)), vertices)

    times = np.linspace(0.0, dt, COARSE + 1)
    pos, vel = relative_motion(state0, accel, times, n)
    # the chords between sub-step samples (the exact path at k·dt/K, linear in between)
    knots = np.linspace(0.0, dt, substeps + 1)
    knot_pos, _ = relative_motion(state0, accel, knots, n)
    chords = np.stack([np.interp(times, knots, knot_pos[:, a]) for a in range(2)], axis=-1)
    chord_error = float(np.sqrt(((pos - chords) ** 2).sum(-1)).max())
    width = dt / COARSE
    speed = float(np.sqrt((vel**2).sum(-1)).max()) + 0.1 * width
    reach = float(np.sqrt((pos**2).sum(-1)).max()) + speed * width
    lipschitz = speed + abs(rate) * reach
    gaps = gap_at(times)
    best = float(gaps.min())
    starts = times[:-1]
    lows = np.minimum(gaps[:-1], gaps[1:]) - lipschitz * width / 2
    while True:
        keep = lows < best - SAMPLING_ERROR
        if not keep.any():
            return StepTruth(gap=best, chord_error=chord_error)
        width /= SPLIT
        grid = starts[keep][:, None] + width * np.arange(SPLIT + 1)[None, :]
        gaps = gap_at(grid.ravel()).reshape(grid.shape)
        best = min(best, float(gaps.min()))
        starts = grid[:, :-1].ravel()
        lows = (np.minimum(gaps[:, :-1], gaps[:, 1:]) - lipschitz * width / 2).ravel()


def flight_truth(
    state0: np.ndarray,
    accels: np.ndarray,
    rate: float,
    vertices: np.ndarray,
    n: float,
    dt: float,
    substeps: int,
) -> list[StepTruth]:
    """:func:`step_truth` of every step of a flight: relative state ``state0`` at t = 0 and the
    thrust ``accels`` (steps, 2) of each step."""
    out = []
    state = np.asarray(state0, dtype=float)
    for k, accel in enumerate(np.asarray(accels, dtype=float)):
        out.append(step_truth(state, accel, k * dt, rate, vertices, n, dt, substeps))
        pos, vel = relative_motion(state, accel, np.array([dt]), n)
        state = np.concatenate([pos[0], vel[0]])
    return out
