"""Natural relative orbits under CWH: the element form of unforced motion.

Every unforced CWH trajectory ([Clohessy60]; [Curtis14] §7.4) is a drifting ellipse. In the
along-track-centred elements used here (n > 0)::

    x(t) = x_c + ρ sin(nt + α)
    y(t) = y_c − (3/2) n x_c t + 2ρ cos(nt + α)
    z(t) = ρ_z sin(nt + β)

``x_c = 4x₀ + 2ẏ₀/n`` is the radial offset of the ellipse's centre, which drifts along-track at
−(3/2) n x_c; with ``x_c = 0`` (ẏ₀ = −2n x₀) the motion is a closed 2:1 ellipse about
(0, y_c), the bounded relative orbit a debris field can be drawn from. The dock, at the origin,
is the ellipse of size zero.

Plain numpy, no gymnasium. Positions in m, velocities in m/s, angles in rad, n in rad/s, t in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RelativeOrbit"]


@dataclass(frozen=True)
class RelativeOrbit:
    """The elements of one unforced CWH trajectory (see the module docstring).

    Attributes:
        n: mean motion of the reference orbit (rad/s), > 0.
        rho: in-plane amplitude ρ (m), >= 0: the radial half-width; the along-track half-width
            is 2ρ.
        alpha: in-plane phase α (rad) at t = 0.
        x_center: radial offset x_c of the ellipse's centre (m); 0 for a bounded orbit.
        y_center: along-track position y_c of the centre at t = 0 (m).
        rho_z: cross-track amplitude ρ_z (m), >= 0 (3D only; 0 in the plane).
        beta: cross-track phase β (rad) at t = 0.
    """

    n: float
    rho: float
    alpha: float = 0.0
    x_center: float = 0.0
    y_center: float = 0.0
    rho_z: float = 0.0
    beta: float = 0.0

    def __post_init__(self) -> None:
        values = {
            "n": self.n, "rho": self.rho, "alpha": self.alpha, "x_center": self.x_center,
            "y_center": self.y_center, "rho_z": self.rho_z, "beta": self.beta,
        }  # fmt: skip
        for name, value in values.items():
            if not math.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value!r}")
        if self.n <= 0.0:
            raise ValueError(f"n must be > 0 rad/s (n = 0 has no relative orbits), got {self.n!r}")
        for name in ("rho", "rho_z"):
            if values[name] < 0.0:
                raise ValueError(f"{name} must be >= 0 m, got {values[name]!r}")

    @property
    def drift_rate(self) -> float:
        """Along-track drift of the ellipse's centre (m/s): −(3/2) n x_c."""
        return -1.5 * self.n * self.x_center

    @property
    def is_bounded(self) -> bool:
        """True when the orbit closes (no drift)."""
        return self.x_center == 0.0

    def state(self, t: float | np.ndarray, dim: int = 3) -> np.ndarray:
        """The state [position (m), velocity (m/s)] at time(s) ``t`` (s): shape (2·dim,) for a
        scalar ``t``, (len(t), 2·dim) for an array."""
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {dim!r}")
        t_arr = np.asarray(t, dtype=float)
        n = self.n
        phase = n * t_arr + self.alpha
        s, c = np.sin(phase), np.cos(phase)
        x = self.x_center + self.rho * s
        y = self.y_center + self.drift_rate * t_arr + 2.0 * self.rho * c
        vx = self.rho * n * c
        vy = self.drift_rate - 2.0 * self.rho * n * s
        if dim == 2:
            out = np.stack([x, y, vx, vy], axis=-1)
        else:
            phase_z = n * t_arr + self.beta
            z = self.rho_z * np.sin(phase_z)
            vz = self.rho_z * n * np.cos(phase_z)
            out = np.stack([x, y, z, vx, vy, vz], axis=-1)
        return out

    @classmethod
    def from_state(cls, state: np.ndarray, n: float) -> RelativeOrbit:
        """The elements of the unforced trajectory through ``state`` (2·dim,) at t = 0."""
        state = np.asarray(state, dtype=float)
        if state.shape not in ((4,), (6,)):
            raise ValueError(f"state must have shape (4,) or (6,) (dim 2 or 3), got {state.shape}")
        if not np.all(np.isfinite(state)):
            raise ValueError(f"state must be finite, got {state}")
        if not (math.isfinite(n) and n > 0.0):
            raise ValueError(f"n must be > 0 rad/s, got {n!r}")
        dim = state.shape[0] // 2
        x0, y0, vx0, vy0 = state[0], state[1], state[dim], state[dim + 1]
        x_center = 4.0 * x0 + 2.0 * vy0 / n
        # x − x_c = ρ sin α, ẋ / n = ρ cos α
        sin_part, cos_part = x0 - x_center, vx0 / n
        rho = math.hypot(sin_part, cos_part)
        alpha = math.atan2(sin_part, cos_part)
        y_center = y0 - 2.0 * cos_part  # y₀ = y_c + 2ρ cos α
        rho_z = beta = 0.0
        if dim == 3:
            z0, vz0 = state[2], state[5]
            rho_z = math.hypot(z0, vz0 / n)
            beta = math.atan2(z0, vz0 / n)
        return cls(n, rho, alpha, x_center, y_center, rho_z, beta)

    def extent(self, duration: float) -> tuple[np.ndarray, np.ndarray]:
        """An axis-aligned box (low, high), each (3,) in m, that holds the whole trajectory over
        ``0 <= t <= duration`` (s): the ellipse's full extent widened along-track by the
        interval the centre drifts over. The smallest such box once ``duration`` covers a
        period and there is no drift; larger than needed for shorter durations."""
        if not (math.isfinite(duration) and duration >= 0.0):
            raise ValueError(f"duration must be a finite number of s >= 0, got {duration!r}")
        drift = self.drift_rate * duration
        x = (self.x_center - self.rho, self.x_center + self.rho)
        y = (
            self.y_center + min(drift, 0.0) - 2.0 * self.rho,
            self.y_center + max(drift, 0.0) + 2.0 * self.rho,
        )
        z = (-self.rho_z, self.rho_z)
        low = np.array([x[0], y[0], z[0]])
        high = np.array([x[1], y[1], z[1]])
        return low, high
