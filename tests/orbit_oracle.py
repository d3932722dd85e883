"""An independent truth for the J2 + drag model: absolute orbits integrated by scipy.

The oracle shares no code with :mod:`debris_gym`: the ECI accelerations (two-body, J2,
drag in an atmosphere turning with the Earth), the exponential atmosphere table of
[Vallado13] table 8-4 (typed again), the LVLH frame of the reference and its angular velocity
are written afresh from their definitions (docs/environments.md, "Truth model beyond CW"), and
every orbit — the reference's and each body's — is integrated on its own as an absolute orbit
by DOP853 at rtol 1e-12 (its own error against rtol 3e-14: about 1e-4 m over 10 000 s).

    PYTHONPATH=$PWD python -m tests.orbit_oracle

prints the accuracy of :func:`debris_gym.orbit_truth.truth_step` against it for the default
field over 10 000 s at several sub-step lengths (the figures of the docs).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from debris_gym import orbit_truth as ot  # only for the accuracy table at the end

MU = 3.986004418e14
EARTH_RADIUS = 6_378_137.0
J2 = 1.08262668e-3
EARTH_RATE = 7.292115e-5
INCLINATION = math.radians(51.6)
R0 = 6_778_137.0
N0 = math.sqrt(MU / R0**3)

# Vallado, Fundamentals of Astrodynamics (4th ed.), table 8-4: km, kg/m³, km
TABLE = [
    (0, 1.225, 7.249), (25, 3.899e-2, 6.349), (30, 1.774e-2, 6.682), (40, 3.972e-3, 7.554),
    (50, 1.057e-3, 8.382), (60, 3.206e-4, 7.714), (70, 8.770e-5, 6.549), (80, 1.905e-5, 5.799),
    (90, 3.396e-6, 5.382), (100, 5.297e-7, 5.877), (110, 9.661e-8, 7.263),
    (120, 2.438e-8, 9.473), (130, 8.484e-9, 12.636), (140, 3.845e-9, 16.149),
    (150, 2.070e-9, 22.523), (180, 5.464e-10, 29.740), (200, 2.789e-10, 37.105),
    (250, 7.248e-11, 45.546), (300, 2.418e-11, 53.628), (350, 9.518e-12, 53.298),
    (400, 3.725e-12, 58.515), (450, 1.585e-12, 60.828), (500, 6.967e-13, 63.822),
    (600, 1.454e-13, 71.835), (700, 3.614e-14, 88.667), (800, 1.170e-14, 124.64),
    (900, 5.245e-15, 181.05), (1000, 3.019e-15, 268.00),
]  # fmt: skip


def air_density(altitude: float) -> float:
    km = altitude / 1000.0
    base = [row for row in TABLE if row[0] <= km] or [TABLE[0]]
    h0, rho0, scale = base[-1]
    return rho0 * math.exp(-(km - h0) / scale)


def acceleration(r: np.ndarray, v: np.ndarray, b: float, j2: bool) -> np.ndarray:
    """ECI acceleration: two-body, J2 (zonal harmonic potential gradient), co-rotating drag."""
    dist = np.linalg.norm(r)
    a = -MU / dist**3 * r
    if j2:
        factor = 1.5 * J2 * MU * EARTH_RADIUS**2 / dist**5
        z2 = 5.0 * r[2] ** 2 / dist**2
        a = a - factor * r * np.array([1.0 - z2, 1.0 - z2, 3.0 - z2])
    if b:
        v_air = v - np.cross([0.0, 0.0, EARTH_RATE], r)
        a = a - 0.5 * air_density(dist - EARTH_RADIUS) * b * np.linalg.norm(v_air) * v_air
    return a


def lvlh_axes(ref: np.ndarray, b_ref: float, j2: bool) -> tuple[np.ndarray, np.ndarray]:
    """Rows x̂, ŷ, ẑ of the reference's LVLH frame and its angular velocity ω (ECI)."""
    r, v = ref[:3], ref[3:]
    h = np.cross(r, v)
    x_hat, z_hat = r / np.linalg.norm(r), h / np.linalg.norm(h)
    perturbation = acceleration(r, v, b_ref, j2) + MU * r / np.linalg.norm(r) ** 3
    omega = np.linalg.norm(h) / (r @ r) * z_hat
    omega = omega + np.linalg.norm(r) * (perturbation @ z_hat) / np.linalg.norm(h) * x_hat
    return np.array([x_hat, np.cross(z_hat, x_hat), z_hat]), omega


def to_lvlh(ref: np.ndarray, body: np.ndarray, b_ref: float, j2: bool) -> np.ndarray:
    axes, omega = lvlh_axes(ref, b_ref, j2)
    dr, dv = body[:3] - ref[:3], body[3:] - ref[3:]
    return np.concatenate([axes @ dr, axes @ (dv - np.cross(omega, dr))])


def from_lvlh(ref: np.ndarray, rel: np.ndarray, b_ref: float, j2: bool) -> np.ndarray:
    axes, omega = lvlh_axes(ref, b_ref, j2)
    dr = axes.T @ rel[:3]
    return np.concatenate([ref[:3] + dr, ref[3:] + axes.T @ rel[3:] + np.cross(omega, dr)])


def circular_start(radius: float = R0, inclination: float = INCLINATION) -> np.ndarray:
    speed = math.sqrt(MU / radius)
    return np.array([radius, 0, 0, 0, speed * math.cos(inclination), speed * math.sin(inclination)])


def fly(
    y0: np.ndarray, b: float, j2: bool, times, rtol: float = 1e-12, atol: float = 1e-7
) -> np.ndarray:
    """Absolute orbit of one free body at ``times`` (DOP853)."""
    sol = solve_ivp(
        lambda t, y: np.concatenate([y[3:], acceleration(y[:3], y[3:], b, j2)]),
        (0.0, times[-1]),
        y0,
        method="DOP853",
        rtol=rtol,
        atol=atol,
        t_eval=times,
    )
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol.y.T


def dense_orbit(y0: np.ndarray, b: float, horizon: float = 800.0):
    """Continuous absolute orbit of one free body over [0, horizon] (DOP853 dense output)."""
    sol = solve_ivp(
        lambda t, y: np.concatenate([y[3:], acceleration(y[:3], y[3:], b, True)]),
        (0.0, horizon),
        y0,
        method="DOP853",
        rtol=1e-13,
        atol=1e-8,
        dense_output=True,
    )
    return sol.sol


def oracle(
    rel0: np.ndarray,
    b: np.ndarray,
    b_ref: float,
    j2: bool,
    horizon: float,
    ref0: np.ndarray | None = None,
    rtol: float = 1e-12,
    atol: float = 1e-7,
) -> np.ndarray:
    """LVLH states at ``horizon`` (s) of bodies starting at the LVLH states ``rel0`` (M, 6) with
    inverse ballistic coefficients ``b`` (M,), each flown on its own as an absolute orbit, in the
    frame of the reference (starting at ``ref0``, default :func:`circular_start`)."""
    ref0 = circular_start() if ref0 is None else ref0
    times = np.array([0.0, horizon])
    ref_end = fly(ref0, b_ref, j2, times, rtol, atol)[-1]
    ends = [
        fly(from_lvlh(ref0, r, b_ref, j2), bi, j2, times, rtol, atol)[-1] for r, bi in zip(rel0, b)
    ]
    return np.array([to_lvlh(ref_end, e, b_ref, j2) for e in ends])


def default_field(rng: np.random.Generator, count: int) -> np.ndarray:
    """Bodies 200–1000 m from the origin moving at 0.1–1 m/s, in random directions."""

    def directions():
        d = rng.normal(size=(count, 3))
        return d / np.linalg.norm(d, axis=1)[:, None]

    rel = np.zeros((count, 6))
    rel[:, :3] = directions() * rng.uniform(200.0, 1000.0, count)[:, None]
    rel[:, 3:] = directions() * rng.uniform(0.1, 1.0, count)[:, None]
    return rel


def _accuracy_table() -> None:
    rel0 = default_field(np.random.default_rng(1), 6)
    b = np.array([0.0, 0.005, 0.01, 0.02, 0.03, 0.05])
    b_ref, horizon = 0.01, 10_000.0
    truth = oracle(rel0, b, b_ref, True, horizon)
    tight = oracle(rel0, b, b_ref, True, horizon, rtol=3e-14, atol=1e-9)
    print("6 bodies 200-1000 m, 0.1-1 m/s, B = 0 ... 0.05 m²/kg (reference 0.01), J2 and drag,")
    print(f"{horizon:.0f} s; largest error of any body and axis at the end")
    print(f"oracle itself (rtol 1e-12 vs 3e-14): {np.abs(truth - tight)[:, :3].max():.1e} m")
    print("| dt (s) | sub-steps | position (m) | velocity (m/s) |")
    print("|---|---|---|---|")
    for dt, substeps in ((5.0, 1), (10.0, 1), (10.0, 2), (20.0, 1), (40.0, 4), (40.0, 1)):
        ref, states = ot.reference_start(R0, INCLINATION), rel0.copy()
        work, accels = ot.truth_work(substeps), np.zeros((len(b), 3))
        steps = round(horizon / dt)
        for _ in range(steps):
            ot.truth_step(ref, states, accels, b, b_ref, True, dt, substeps, ot.ATMOSPHERE, work)
        pos, vel = np.abs(states - truth)[:, :3].max(), np.abs(states - truth)[:, 3:].max()
        print(f"| {dt:g} | {substeps} | {pos:.1e} | {vel:.1e} |")


if __name__ == "__main__":
    _accuracy_table()
