"""Reference profiles: how fast a chaser may fly a path and still stop where it must.

:class:`PathReference` turns a waypoint path into the time-parametrised reference the MPC tracker
(:class:`agents.control.mpc.MPCTracker`) follows: positions and tangent velocities over the
horizon from a speed profile that respects a cruise speed, the path's curvature and a braking
distance to a stop at the path's end. :func:`braking_speed` is the stopping-distance limit with
one step of reaction lag that the APF agent applies toward its goal and every nearby body.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PathReference", "ReferenceParams", "braking_speed"]


def braking_speed(distance: float, decel: float, dt: float) -> float:
    """Largest speed (m/s) from which a chaser that reacts one step late can still stop within
    ``distance`` (m) at deceleration ``decel`` (m/s²): v·dt + v²/(2·decel) = distance."""
    if distance <= 0.0:
        return 0.0
    lag = decel * dt
    return -lag + math.sqrt(lag * lag + 2.0 * decel * distance)


@dataclass(frozen=True)
class ReferenceParams:
    """Speed profile of :class:`PathReference` (accelerations as fractions of max_accel).

    Attributes:
        cruise_speed: top speed along the path (m/s); None derives it from the field: the speed
            that needs a braking distance of 1/20 of the world size, sqrt(2·a_brake·size/20)
            (1.3 m/s on the default env).
        brake_fraction: a_brake / max_accel, the deceleration the profile plans with.
        accel_fraction: a_accel / max_accel, the acceleration ramp from the current speed.
        lateral_fraction: a_lat / max_accel, the largest centripetal acceleration in bends
            (v ≤ sqrt(a_lat / κ)).
        end_speed: creep speed (m/s) added to the braking profile, so the reference reaches the
            path's end in finite time; keep it below the capture speed.
        bend_window: distance (m) over which the path's turning angle is measured for the curvature
            κ ≈ angle / window; None: max(2·max_accel·dt², 1 % of the world size) (10 m on the
            1 km fields, 0.2 on the 20-unit paper field).
    """

    cruise_speed: float | None = None
    brake_fraction: float = 0.35
    accel_fraction: float = 0.5
    lateral_fraction: float = 0.3
    end_speed: float = 0.1
    bend_window: float | None = None

    def __post_init__(self) -> None:
        if self.cruise_speed is not None and not self.cruise_speed > 0:
            raise ValueError(f"cruise_speed must be > 0 m/s or None, got {self.cruise_speed!r}")
        for name in ("brake_fraction", "accel_fraction", "lateral_fraction"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {value!r}")
        if not self.end_speed >= 0:
            raise ValueError(f"end_speed must be >= 0 m/s, got {self.end_speed!r}")
        if self.bend_window is not None and not self.bend_window > 0:
            raise ValueError(f"bend_window must be > 0 m or None, got {self.bend_window!r}")


class PathReference:
    """A waypoint path with a speed profile, sampled as a reference over the MPC horizon.

    The path is resampled at a uniform spacing. Speed limit at arc length s (m)::

        v(s) = min(v_cruise, sqrt(a_lat / κ(s)), sqrt(2 a_brake (S_bend − s)) …) + end_speed

    computed by a backward pass over the samples (so the chaser can always brake with a_brake
    for the next bend and to a stop at the end, S), then clipped to the cruise speed. The
    reference over the horizon starts at the chaser's projection on the path and advances with
    speed min(v(s), v₀ + a_accel t), v₀ the chaser's speed along the path; reference velocities
    follow the (smoothed) path tangent, and are zero once the end is reached.

    Args:
        waypoints: (K, dim) path (m), start first; K = 1 is a hold point.
        max_accel: thrust limit (m/s²).
        dt: step length (s).
        params: speed profile.
        world_size: world extent (m), for the default cruise speed.
    """

    def __init__(
        self,
        waypoints: np.ndarray,
        *,
        max_accel: float,
        dt: float,
        params: ReferenceParams | None = None,
        world_size: float = 1000.0,
    ) -> None:
        params = params or ReferenceParams()
        pts = np.asarray(waypoints, dtype=float)
        if pts.ndim != 2 or pts.shape[0] < 1 or not np.all(np.isfinite(pts)):
            raise ValueError(f"waypoints must be a finite (K, dim) array, got shape {pts.shape}")
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9
        pts = pts[keep]
        self.dim = pts.shape[1]
        self.dt = float(dt)
        self.a_brake = params.brake_fraction * max_accel
        self.a_accel = params.accel_fraction * max_accel
        a_lat = params.lateral_fraction * max_accel
        self.end_speed = float(params.end_speed)
        self.cruise = (
            params.cruise_speed
            if params.cruise_speed is not None
            else math.sqrt(2.0 * self.a_brake * world_size / 20.0)
        )
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(cum[-1])
        ell = max_accel * dt * dt
        spacing = max(ell / 5.0, self.length / 4000.0, 1e-9)
        count = max(2, math.ceil(self.length / spacing) + 1)
        s = np.linspace(0.0, self.length, count)
        if self.length > 0:
            self.points = np.stack([np.interp(s, cum, pts[:, i]) for i in range(self.dim)], 1)
        else:
            self.points = np.repeat(pts[:1], count, axis=0)
        self.s = s
        self.spacing = float(s[1] - s[0]) if self.length > 0 else spacing
        window = (
            params.bend_window
            if params.bend_window is not None
            else max(2.0 * ell, 0.01 * world_size)
        )
        m = max(1, round(window / max(self.spacing, 1e-12)))
        idx = np.arange(count)
        ahead = self.points[np.minimum(idx + m, count - 1)]
        behind = self.points[np.maximum(idx - m, 0)]
        tangent = ahead - behind
        norm = np.linalg.norm(tangent, axis=1, keepdims=True)
        self.tangents = np.where(norm > 1e-12, tangent / np.maximum(norm, 1e-12), 0.0)
        d_in = self.points - behind
        d_out = ahead - self.points
        n_in = np.linalg.norm(d_in, axis=1)
        n_out = np.linalg.norm(d_out, axis=1)
        cos = np.einsum("ij,ij->i", d_in, d_out) / np.maximum(n_in * n_out, 1e-300)
        angle = np.where((n_in > 1e-12) & (n_out > 1e-12), np.arccos(np.clip(cos, -1, 1)), 0.0)
        kappa = angle / max(m * self.spacing, 1e-12)
        vlim = np.minimum(self.cruise, np.sqrt(a_lat / np.maximum(kappa, 1e-12)))
        # Backward pass: from every sample the chaser can brake to every later limit and to rest.
        profile = np.empty(count)
        profile[-1] = 0.0
        two_a_ds = 2.0 * self.a_brake * self.spacing
        for i in range(count - 2, -1, -1):
            profile[i] = min(vlim[i], math.sqrt(profile[i + 1] ** 2 + two_a_ds))
        self.profile = np.minimum(profile + self.end_speed, max(self.cruise, self.end_speed))
        self._profile_list = self.profile.tolist()
        self._back = ell  # the projection moves back at most this far (m)
        self.progress = 0
        self.deviation = 0.0

    @property
    def end(self) -> np.ndarray:
        """The path's last point (m)."""
        return self.points[-1].copy()

    def project(self, position: np.ndarray, lookahead: float) -> tuple[int, float]:
        """Nearest sample to ``position`` at or ahead of the current progress (minus a little).

        Args:
            position: (dim,) chaser position (m).
            lookahead: how far ahead (m) along the path to search.

        Returns:
            ``(index, distance (m))``; also stored as :attr:`progress` / :attr:`deviation`.
        """
        back = max(2, round(self._back / self.spacing))
        lo = max(0, self.progress - back)
        hi = min(len(self.s), self.progress + max(2, math.ceil(lookahead / self.spacing)) + 1)
        diff = self.points[lo:hi] - position
        dist2 = np.einsum("ij,ij->i", diff, diff)
        k = int(np.argmin(dist2))
        self.progress = lo + k
        self.deviation = math.sqrt(float(dist2[k]))
        return self.progress, self.deviation

    def horizon(self, state: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Reference positions and velocities for the next ``steps`` steps.

        Args:
            state: chaser state [position (m), velocity (m/s)].
            steps: horizon length N.

        Returns:
            ``(positions (N, dim) [m], velocities (N, dim) [m/s])`` at t = dt, 2 dt, …, N dt.
        """
        d = self.dim
        pos, vel = state[:d], state[d:]
        if self.length == 0.0:  # a hold point
            self.project(pos, lookahead=0.0)
            return np.repeat(self.points[:1], steps, axis=0), np.zeros((steps, d))
        speed = math.sqrt(float(vel @ vel))
        self.project(pos, lookahead=3.0 * (speed + self.cruise) * self.dt + 10 * self.spacing)
        i0 = self.progress
        s = float(self.s[i0])
        v = max(0.0, float(vel @ self.tangents[i0]))
        ds, length, last = self.spacing, self.length, len(self.s) - 1
        prof = self._profile_list
        substeps = 4
        h = self.dt / substeps
        out_s = np.empty(steps)
        out_v = np.empty(steps)
        for k in range(steps):
            for _ in range(substeps):
                x = s / ds
                j = min(int(x), last - 1)
                f = x - j
                limit = prof[j] + (prof[j + 1] - prof[j]) * f if j >= 0 else prof[0]
                v = min(limit, v + self.a_accel * h)
                s = min(length, s + v * h)
            out_s[k] = s
            out_v[k] = 0.0 if s >= length else v
        ref_pos = np.stack([np.interp(out_s, self.s, self.points[:, i]) for i in range(d)], 1)
        idx = np.minimum(np.rint(out_s / max(ds, 1e-300)).astype(int), last)
        ref_vel = self.tangents[idx] * out_v[:, None]
        return ref_pos, ref_vel
