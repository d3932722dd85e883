"""Trajectory metrics of [APF-MPC] Table I, computed from a flown trajectory.

[APF-MPC] compares planners by path length, fuel,
smoothness, time, maximal acceleration, maximal deceleration, number of waypoints and total
curvature, but defines most of them in one line or not at all. The definitions used here are
stated in each function's docstring and in ``docs/baselines.md``; where the paper is silent, that
is said too.

A trajectory is what the env produced, sampled at step ends:

* ``positions``: (K + 1, d) chaser positions (m), the start first, then the end of every step;
* ``velocities``: (K + 1, d) chaser velocities (m/s) at the same instants;
* ``accelerations``: (K, d) commanded (thrust) accelerations (m/s²), held constant over each step;
* ``dt``: step length (s).

All functions are pure and take plain arrays (no env).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from debris_gym.thrust import delta_v_rate

__all__ = [
    "TrajectoryMetrics",
    "fuel",
    "max_acceleration_deceleration",
    "path_length",
    "smoothness",
    "total_curvature",
    "trajectory_metrics",
]

_TINY = 1e-12
"""Displacements (m) and speeds (m/s) below this are treated as zero (direction undefined)."""


def _points(values: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (N, 2) or (N, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def path_length(positions: ArrayLike) -> float:
    """Length (m) of the polyline through the step-end positions: Σ‖p[k+1] − p[k]‖.

    Within a step the true path bends slightly (CWH motion); step ends are what the paper's
    waypoint paths contain too.
    """
    p = _points(positions, "positions")
    if len(p) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def fuel(accelerations: ArrayLike, dt: float, thrust_model: str = "ball") -> float:
    """Fuel as Δv (m/s): Σ‖u_k‖·dt over the steps.

    [APF-MPC] reports "fuel consumption" in "units of fuel" without defining them (its numbers
    cannot be converted); we report the Δv spent, the propellant-independent measure of fuel.
    ``thrust_model="ball"`` (one gimballed engine) uses the Euclidean norm ‖u‖;
    ``"box"`` (one thruster per axis) uses Σ|u_i|, exactly as the env charges Δv.
    """
    u = _points(accelerations, "accelerations") if np.size(accelerations) else np.zeros((0, 2))
    return float(delta_v_rate(u, thrust_model).sum() * dt)


def smoothness(accelerations: ArrayLike) -> float:
    """Mean squared change of the acceleration command between steps (m²/s⁴); 0 is smoothest.

    (1 / (K − 1)) · Σ_k ‖u[k+1] − u[k]‖² over the K commands (0 when K < 2). [APF-MPC] calls its
    metric "a measure of trajectory smoothness" without a formula; we chose the mean of ‖Δu‖²
    because it is the smoothness term of the paper's own MPC cost (eq. 8, λ₂·‖Δu_j‖²). It does not
    depend on dt, so it compares commands, not jerk.
    """
    if np.size(accelerations) == 0:
        return 0.0
    u = _points(accelerations, "accelerations")
    if len(u) < 2:
        return 0.0
    du = np.diff(u, axis=0)
    return float(np.mean(np.einsum("ij,ij->i", du, du)))


def max_acceleration_deceleration(
    velocities: ArrayLike, accelerations: ArrayLike
) -> tuple[float, float]:
    """Largest acceleration and deceleration (m/s², both ≥ 0) along the direction of motion.

    For each step k the commanded acceleration u[k] is projected on the direction of the
    step's mean velocity (v[k] + v[k+1]) / 2: a positive component speeds the chaser up, a
    negative one slows it down. Returns (max positive component, max |negative component|); 0 when
    there is none. Steps without motion (mean speed ≈ 0) have no direction and count as 0.
    [APF-MPC] gives "maximal acceleration/deceleration experienced along the trajectory" without a
    formula; we use the commanded (thrust) acceleration — the part the guidance controls — which
    equals the experienced one for the paper's double integrator (n = 0).
    """
    if np.size(accelerations) == 0:
        return 0.0, 0.0
    v = _points(velocities, "velocities")
    u = _points(accelerations, "accelerations")
    if v.shape != (len(u) + 1, u.shape[1]):
        raise ValueError(
            f"velocities must have shape ({len(u) + 1}, {u.shape[1]}) for {len(u)} "
            f"accelerations, got {v.shape}"
        )
    mid = 0.5 * (v[:-1] + v[1:])
    speed = np.linalg.norm(mid, axis=1)
    moving = speed > _TINY
    along = np.zeros(len(u))
    along[moving] = np.einsum("ij,ij->i", u[moving], mid[moving]) / speed[moving]
    return float(max(0.0, along.max())), float(max(0.0, -along.min()))


def total_curvature(positions: ArrayLike) -> float:
    """Total turning (rad): the sum of the angles between successive displacement vectors.

    In 2D this is the sum of absolute heading changes (each wrapped to [0, π]); in 3D the angle
    between successive step displacements, atan2(‖a × b‖, a · b) in both cases. Zero-length
    steps (no motion, heading undefined) are skipped. A straight line gives 0, one lap of a
    convex polygon 2π. [APF-MPC]: "the sum of all angle changes in the trajectory".
    """
    p = _points(positions, "positions")
    seg = np.diff(p, axis=0)
    seg = seg[np.linalg.norm(seg, axis=1) > _TINY]
    if len(seg) < 2:
        return 0.0
    a, b = seg[:-1], seg[1:]
    dot = np.einsum("ij,ij->i", a, b)
    if p.shape[1] == 2:
        cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    else:
        cross = np.linalg.norm(np.cross(a, b), axis=1)
    return float(np.arctan2(cross, dot).sum())


@dataclass(frozen=True)
class TrajectoryMetrics:
    """[APF-MPC] Table I metrics of one trajectory (see the functions for the definitions).

    Attributes:
        path_length: m.
        fuel: Δv spent, m/s (the paper's "units of fuel" are undefined).
        smoothness: mean squared change of the acceleration command, m²/s⁴ (lower is smoother).
        time: flown time K·dt, s (simulated mission time, not computing time).
        max_acceleration: largest thrust component along the motion, m/s².
        max_deceleration: largest thrust component against the motion, m/s² (≥ 0).
        waypoints: number of steps K (positions after the start).
        total_curvature: rad.
    """

    path_length: float
    fuel: float
    smoothness: float
    time: float
    max_acceleration: float
    max_deceleration: float
    waypoints: int
    total_curvature: float

    def to_dict(self) -> dict[str, float | int]:
        """Plain dict, field order kept."""
        return asdict(self)


METRIC_UNITS: dict[str, str] = {
    "path_length": "m",
    "fuel": "m/s (Δv)",
    "smoothness": "m²/s⁴",
    "time": "s",
    "max_acceleration": "m/s²",
    "max_deceleration": "m/s²",
    "waypoints": "count",
    "total_curvature": "rad",
}
"""Unit of each :class:`TrajectoryMetrics` field."""


def trajectory_metrics(
    positions: ArrayLike,
    velocities: ArrayLike,
    accelerations: ArrayLike,
    dt: float,
    thrust_model: str = "ball",
) -> TrajectoryMetrics:
    """All Table I metrics of one trajectory.

    Args:
        positions: (K + 1, d) step-end positions, start first (m).
        velocities: (K + 1, d) velocities at the same instants (m/s).
        accelerations: (K, d) commanded accelerations, one per step (m/s²).
        dt: step length (s), > 0.
        thrust_model: "ball" or "box", how Δv is counted (as in the env).
    """
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0 s, got {dt!r}")
    p = _points(positions, "positions")
    steps = len(p) - 1
    u = np.asarray(accelerations, dtype=float).reshape(steps, p.shape[1])
    v = _points(velocities, "velocities")
    if v.shape != p.shape:
        raise ValueError(f"velocities shape {v.shape} must match positions shape {p.shape}")
    acc, dec = max_acceleration_deceleration(v, u)
    return TrajectoryMetrics(
        path_length=path_length(p),
        fuel=fuel(u, dt, thrust_model),
        smoothness=smoothness(u),
        time=steps * float(dt),
        max_acceleration=acc,
        max_deceleration=dec,
        waypoints=steps,
        total_curvature=total_curvature(p),
    )
