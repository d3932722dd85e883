"""A truth model beyond CW: every body on an absolute orbit with J2 and drag, seen in LVLH.

The reference orbit (radius ``orbit_radius``, inclination ``i``) starts circular at its
ascending node (:func:`reference_start`) and is then flown, like every body, under the full
equations of motion in the Earth-centred inertial frame (ECI, z along the Earth's axis)::

    r̈ = −μ r/|r|³ + a_J2(r) + a_drag(r, ṙ) + u

- J2 ([Vallado13] ch. 8): with (x, y, z) = r, k = −(3/2) J2 μ R_E² / |r|⁵ and s = 5 z²/|r|²,
  a_J2 = k · (x (1 − s), y (1 − s), z (3 − s)).
- Drag ([Vallado13] ch. 8): a_drag = −½ ρ(h) B |v_rel| v_rel, with B = C_D A / m (m²/kg, the
  inverse ballistic coefficient; 0 = no drag), the altitude h = |r| − R_E over a spherical
  Earth, and the velocity relative to an atmosphere turning with the Earth,
  v_rel = ṙ − ω_E e_z × r (e_z the ECI z axis). The density ρ(h) is the piecewise-exponential
  model of [Vallado13] table 8-4 (:data:`ATMOSPHERE`): ρ = ρ₀ exp(−(h − h₀)/H) in the band
  whose base h₀ is the highest at or below h (the lowest band below 0 km, the highest above
  1 000 km).
- u: a body's thrust, given in LVLH axes and held constant in that frame over a step.

The world stays the LVLH frame of the *actual* reference orbit, (R, V) with its perturbing
acceleration a_p = a_J2 + a_drag:

    x̂ = R/|R|,  ẑ = H/|H| (H = R × V),  ŷ = ẑ × x̂,
    ω = (|H|/|R|²) ẑ + (|R| (a_p · ẑ)/|H|) x̂   (the frame's angular velocity, ECI)

(the two-body term of the reference's acceleration lies along x̂ and adds nothing to ω). With
C the matrix of rows x̂, ŷ, ẑ, a body at (r, ṙ) has the LVLH state

    ρ = C (r − R),   ρ̇ = C (ṙ − V − ω × (r − R))

and back: r = R + Cᵀρ, ṙ = V + Cᵀρ̇ + ω × Cᵀρ. On an unperturbed circular reference this is the
CW frame of :mod:`debris_gym.dynamics` (ω = n ẑ), and ρ, ρ̇ obey CW to first order in |ρ|/|R|.

:func:`truth_step` integrates the reference and each body's ECI offset δ = r − R with the
classical fourth-order Runge-Kutta rule at a fixed sub-step, the offset's acceleration written
as a difference that loses no digits to cancellation: the two-body part as
−μ/|R + δ|³ (δ − R f(q)) with q = δ·(2R + δ)/|R|² and f(q) = (1 + q)^{3/2} − 1 (evaluated with
log1p/expm1), the J2 and drag parts as a(R + δ) − a(R). A body at the reference with the
reference's B therefore stays at the origin exactly.

Compiled (numba, via :mod:`debris_gym.jit`) so the mission step can call it; no gymnasium.
Units: m, s, m/s, m/s², kg/m³, m²/kg, rad. Keys in square brackets: docs/references.md.
"""

from __future__ import annotations

import math

import numpy as np

from debris_gym.dynamics import MU_EARTH, R_EARTH
from debris_gym.jit import inlined, kernel

__all__ = [
    "ATMOSPHERE",
    "DEFAULT_INCLINATION",
    "DEFAULT_SUBSTEPS",
    "EARTH_ROTATION_RATE",
    "FRAME_WIDTH",
    "J2",
    "MAX_SUBSTEP",
    "TRACK_WIDTH",
    "density",
    "eci_acceleration",
    "eci_from_lvlh",
    "lvlh_from_eci",
    "reference_frame",
    "reference_start",
    "substeps_for",
    "truth_step",
    "truth_work",
]

J2 = 1.08262668e-3
"""Earth's second zonal harmonic (dimensionless)."""

EARTH_ROTATION_RATE = 7.292115e-5
"""Earth's rotation rate ω_E (rad/s), about the ECI z axis."""

DEFAULT_INCLINATION = math.radians(51.6)
"""Inclination (rad) of a reference orbit when none is given: a space-station-like 51.6°."""

MAX_SUBSTEP = 10.0
"""Longest Runge-Kutta sub-step (s) of :func:`substeps_for`: short enough that the default field
stays well within 1 cm of an independent integration over 10 000 s; the error grows as the
sub-step's fourth power (measured in docs/environments.md, "Truth model beyond CW")."""

DEFAULT_SUBSTEPS = 1
"""Runge-Kutta sub-steps per call of :func:`truth_step` at the default 10 s step
(``substeps_for(10.0)``)."""


# [Vallado13] table 8-4: base altitude (km), nominal density (kg/m³), scale height (km)
_VALLADO_TABLE = (
    (0.0, 1.225, 7.249),
    (25.0, 3.899e-2, 6.349),
    (30.0, 1.774e-2, 6.682),
    (40.0, 3.972e-3, 7.554),
    (50.0, 1.057e-3, 8.382),
    (60.0, 3.206e-4, 7.714),
    (70.0, 8.770e-5, 6.549),
    (80.0, 1.905e-5, 5.799),
    (90.0, 3.396e-6, 5.382),
    (100.0, 5.297e-7, 5.877),
    (110.0, 9.661e-8, 7.263),
    (120.0, 2.438e-8, 9.473),
    (130.0, 8.484e-9, 12.636),
    (140.0, 3.845e-9, 16.149),
    (150.0, 2.070e-9, 22.523),
    (180.0, 5.464e-10, 29.740),
    (200.0, 2.789e-10, 37.105),
    (250.0, 7.248e-11, 45.546),
    (300.0, 2.418e-11, 53.628),
    (350.0, 9.518e-12, 53.298),
    (400.0, 3.725e-12, 58.515),
    (450.0, 1.585e-12, 60.828),
    (500.0, 6.967e-13, 63.822),
    (600.0, 1.454e-13, 71.835),
    (700.0, 3.614e-14, 88.667),
    (800.0, 1.170e-14, 124.64),
    (900.0, 5.245e-15, 181.05),
    (1000.0, 3.019e-15, 268.00),
)

ATMOSPHERE = np.ascontiguousarray(
    [(h0 * 1e3, rho0, scale * 1e3) for h0, rho0, scale in _VALLADO_TABLE], dtype=np.float64
)
"""The exponential atmosphere of [Vallado13] table 8-4, shape (28, 3): per band its base
altitude h₀ (m, ascending), nominal density ρ₀ (kg/m³) and scale height H (m). Read-only."""
ATMOSPHERE.setflags(write=False)

FRAME_WIDTH = 12
"""Length of a frame record (:func:`reference_frame`): x̂, ŷ, ẑ (ECI unit vectors), ω (rad/s)."""

TRACK_WIDTH = 21
"""Columns of a row of :func:`truth_work`: the reference's R (m), V (m/s), perturbing
acceleration a_p (m/s²), then its frame record (:data:`FRAME_WIDTH`)."""

_FRAME = 9  # column of the frame record in a track row


def reference_start(
    orbit_radius: float, inclination_rad: float = DEFAULT_INCLINATION
) -> np.ndarray:
    """ECI state of a circular reference orbit at its ascending node.

    Args:
        orbit_radius: orbit radius R (m), above the Earth's surface (> R_EARTH).
        inclination_rad: inclination i (rad), in [0, π].

    Returns:
        (6,) array ``[R, 0, 0, 0, V cos i, V sin i]`` with V = sqrt(μ/R) (m, m/s).
    """
    if not (math.isfinite(orbit_radius) and orbit_radius > R_EARTH):
        raise ValueError(
            f"orbit_radius must be finite and > R_EARTH = {R_EARTH} m, got {orbit_radius!r}"
        )
    if not (math.isfinite(inclination_rad) and 0.0 <= inclination_rad <= math.pi):
        raise ValueError(f"inclination_rad must be in [0, π] rad, got {inclination_rad!r}")
    speed = math.sqrt(MU_EARTH / orbit_radius)
    return np.array(
        [
            orbit_radius,
            0.0,
            0.0,
            0.0,
            speed * math.cos(inclination_rad),
            speed * math.sin(inclination_rad),
        ]
    )


def substeps_for(dt: float) -> int:
    """Sub-steps that cut a step of ``dt`` seconds (> 0) into RK4 sub-steps of at most
    :data:`MAX_SUBSTEP`."""
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    return max(1, math.ceil(dt / MAX_SUBSTEP - 1e-9))


def truth_work(substeps: int = DEFAULT_SUBSTEPS) -> np.ndarray:
    """Scratch array for :func:`truth_step` with ``substeps`` sub-steps: (4·substeps + 1,
    :data:`TRACK_WIDTH`), the reference at every Runge-Kutta stage and at the step's end."""
    if not (isinstance(substeps, (int, np.integer)) and substeps >= 1):
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
    return np.zeros((4 * int(substeps) + 1, TRACK_WIDTH))


@inlined
def density(altitude, atmosphere):
    """Air density (kg/m³) at ``altitude`` (m) in a piecewise-exponential ``atmosphere``
    (rows h₀ (m, ascending), ρ₀ (kg/m³), H (m), as :data:`ATMOSPHERE`)."""
    i = atmosphere.shape[0] - 1
    while i > 0 and altitude < atmosphere[i, 0]:
        i -= 1
    return atmosphere[i, 1] * math.exp(-(altitude - atmosphere[i, 0]) / atmosphere[i, 2])


@inlined
def _perturbation(x, y, z, vx, vy, vz, inv_ballistic, j2, atmosphere):
    """J2 and drag acceleration (m/s²) at ECI position (m) and velocity (m/s)."""
    r2 = x * x + y * y + z * z
    r = math.sqrt(r2)
    ax = 0.0
    ay = 0.0
    az = 0.0
    if j2:
        k = -1.5 * J2 * MU_EARTH * R_EARTH * R_EARTH / (r2 * r2 * r)
        s = 5.0 * z * z / r2
        ax = k * x * (1.0 - s)
        ay = k * y * (1.0 - s)
        az = k * z * (3.0 - s)
    if inv_ballistic != 0.0:
        wx = vx + EARTH_ROTATION_RATE * y
        wy = vy - EARTH_ROTATION_RATE * x
        speed = math.sqrt(wx * wx + wy * wy + vz * vz)
        c = -0.5 * density(r - R_EARTH, atmosphere) * inv_ballistic * speed
        ax += c * wx
        ay += c * wy
        az += c * vz
    return ax, ay, az


@inlined
def _frame(rx, ry, rz, vx, vy, vz, px, py, pz):
    """LVLH axes x̂, ŷ, ẑ and angular velocity ω (rad/s) of a reference at (R, V) with
    perturbing acceleration a_p: 12 floats (module docstring)."""
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    xx, xy, xz = rx / r, ry / r, rz / r
    hx = ry * vz - rz * vy
    hy = rz * vx - rx * vz
    hz = rx * vy - ry * vx
    h = math.sqrt(hx * hx + hy * hy + hz * hz)
    zx, zy, zz = hx / h, hy / h, hz / h
    yx = zy * xz - zz * xy
    yy = zz * xx - zx * xz
    yz = zx * xy - zy * xx
    w_in = h / (r * r)
    w_out = r * (px * zx + py * zy + pz * zz) / h
    return (
        xx,
        xy,
        xz,
        yx,
        yy,
        yz,
        zx,
        zy,
        zz,
        w_in * zx + w_out * xx,
        w_in * zy + w_out * xy,
        w_in * zz + w_out * xz,
    )


@inlined
def _fill_track_row(work, row, inv_ballistic, j2, atmosphere):
    """Complete row ``row`` of a track whose first 6 columns hold the reference's state:
    its perturbing acceleration and its frame record."""
    x, y, z = work[row, 0], work[row, 1], work[row, 2]
    vx, vy, vz = work[row, 3], work[row, 4], work[row, 5]
    px, py, pz = _perturbation(x, y, z, vx, vy, vz, inv_ballistic, j2, atmosphere)
    work[row, 6] = px
    work[row, 7] = py
    work[row, 8] = pz
    f = _frame(x, y, z, vx, vy, vz, px, py, pz)
    for k in range(FRAME_WIDTH):
        work[row, _FRAME + k] = f[k]


@inlined
def _offset_from_lvlh(f, c, lvlh):
    """ECI offset (δr, δv) from the LVLH state ``lvlh`` (6,) in the frame record at
    ``f[c:c + 12]``: δr = Cᵀρ, δv = Cᵀρ̇ + ω × δr."""
    px, py, pz = lvlh[0], lvlh[1], lvlh[2]
    qx, qy, qz = lvlh[3], lvlh[4], lvlh[5]
    dx = f[c + 0] * px + f[c + 3] * py + f[c + 6] * pz
    dy = f[c + 1] * px + f[c + 4] * py + f[c + 7] * pz
    dz = f[c + 2] * px + f[c + 5] * py + f[c + 8] * pz
    wx, wy, wz = f[c + 9], f[c + 10], f[c + 11]
    ex = f[c + 0] * qx + f[c + 3] * qy + f[c + 6] * qz + (wy * dz - wz * dy)
    ey = f[c + 1] * qx + f[c + 4] * qy + f[c + 7] * qz + (wz * dx - wx * dz)
    ez = f[c + 2] * qx + f[c + 5] * qy + f[c + 8] * qz + (wx * dy - wy * dx)
    return dx, dy, dz, ex, ey, ez


@inlined
def _lvlh_from_offset(f, c, dx, dy, dz, ex, ey, ez, out):
    """LVLH state into ``out`` (6,) of the ECI offset (δr, δv) in the frame record at
    ``f[c:c + 12]``: ρ = C δr, ρ̇ = C (δv − ω × δr)."""
    wx, wy, wz = f[c + 9], f[c + 10], f[c + 11]
    gx = ex - (wy * dz - wz * dy)
    gy = ey - (wz * dx - wx * dz)
    gz = ez - (wx * dy - wy * dx)
    for k in range(3):
        out[k] = f[c + 3 * k] * dx + f[c + 3 * k + 1] * dy + f[c + 3 * k + 2] * dz
        out[3 + k] = f[c + 3 * k] * gx + f[c + 3 * k + 1] * gy + f[c + 3 * k + 2] * gz


@kernel
def eci_acceleration(state, inv_ballistic, j2, atmosphere, out):
    """Full acceleration (m/s²) into ``out`` (3,) of a free body at the ECI ``state`` (6,):
    two-body + J2 (if ``j2``) + drag with inverse ballistic coefficient ``inv_ballistic``
    (m²/kg) in ``atmosphere`` (:data:`ATMOSPHERE`)."""
    x, y, z = state[0], state[1], state[2]
    r = math.sqrt(x * x + y * y + z * z)
    g = -MU_EARTH / (r * r * r)
    px, py, pz = _perturbation(x, y, z, state[3], state[4], state[5], inv_ballistic, j2, atmosphere)
    out[0] = g * x + px
    out[1] = g * y + py
    out[2] = g * z + pz


@kernel
def reference_frame(reference, inv_ballistic, j2, atmosphere, out):
    """The LVLH frame record of the reference at the ECI state ``reference`` (6,), whose
    inverse ballistic coefficient is ``inv_ballistic`` (m²/kg), into ``out``
    (:data:`FRAME_WIDTH`,): x̂, ŷ, ẑ (ECI unit vectors) and ω (rad/s, ECI)."""
    x, y, z = reference[0], reference[1], reference[2]
    vx, vy, vz = reference[3], reference[4], reference[5]
    px, py, pz = _perturbation(x, y, z, vx, vy, vz, inv_ballistic, j2, atmosphere)
    f = _frame(x, y, z, vx, vy, vz, px, py, pz)
    for k in range(FRAME_WIDTH):
        out[k] = f[k]


@kernel
def eci_from_lvlh(reference, frame, lvlh, out):
    """ECI state (m, m/s) into ``out`` (6,) of the LVLH state ``lvlh`` (6,) relative to the
    reference at ECI ``reference`` (6,) with frame record ``frame`` (:func:`reference_frame`)."""
    d = _offset_from_lvlh(frame, 0, lvlh)
    for k in range(6):
        out[k] = reference[k] + d[k]


@kernel
def lvlh_from_eci(reference, frame, eci, out):
    """LVLH state (m, m/s) into ``out`` (6,) of the ECI state ``eci`` (6,) relative to the
    reference at ECI ``reference`` (6,) with frame record ``frame`` (:func:`reference_frame`)."""
    _lvlh_from_offset(
        frame,
        0,
        eci[0] - reference[0],
        eci[1] - reference[1],
        eci[2] - reference[2],
        eci[3] - reference[3],
        eci[4] - reference[4],
        eci[5] - reference[5],
        out,
    )


@inlined
def _reference_rk4(work, dt, substeps, inv_ballistic, j2, atmosphere):
    """Integrate the reference from ``work[0, :6]`` over ``dt`` with RK4, filling every
    stage row and the end row of the track (:func:`truth_work`)."""
    h = dt / substeps
    stage_scale = (0.5 * h, 0.5 * h, h)
    _fill_track_row(work, 0, inv_ballistic, j2, atmosphere)
    for s in range(substeps):
        base = 4 * s
        # Σ w_k k_k over the stages (w = 1, 2, 2, 1): velocity part s[xyz], acceleration s[uvw]
        sx = sy = sz = su = sv = sw = 0.0
        for k in range(4):
            row = base + k
            rx, ry, rz = work[row, 0], work[row, 1], work[row, 2]
            r = math.sqrt(rx * rx + ry * ry + rz * rz)
            g = -MU_EARTH / (r * r * r)
            kvx, kvy, kvz = work[row, 3], work[row, 4], work[row, 5]
            kax = g * rx + work[row, 6]
            kay = g * ry + work[row, 7]
            kaz = g * rz + work[row, 8]
            weight = 1.0 if (k == 0 or k == 3) else 2.0
            sx += weight * kvx
            sy += weight * kvy
            sz += weight * kvz
            su += weight * kax
            sv += weight * kay
            sw += weight * kaz
            nxt = base + k + 1
            if k < 3:
                _advance_row(work, nxt, base, stage_scale[k], kvx, kvy, kvz, kax, kay, kaz)
                _fill_track_row(work, nxt, inv_ballistic, j2, atmosphere)
        end = base + 4
        _advance_row(work, end, base, h / 6.0, sx, sy, sz, su, sv, sw)
        _fill_track_row(work, end, inv_ballistic, j2, atmosphere)


@inlined
def _advance_row(work, row, base, scale, vx, vy, vz, ax, ay, az):
    """``work[row, :6]`` ← ``work[base, :6]`` + ``scale`` · (v, a): one RK4 stage or the
    step's end from the step's start state."""
    work[row, 0] = work[base, 0] + scale * vx
    work[row, 1] = work[base, 1] + scale * vy
    work[row, 2] = work[base, 2] + scale * vz
    work[row, 3] = work[base, 3] + scale * ax
    work[row, 4] = work[base, 4] + scale * ay
    work[row, 5] = work[base, 5] + scale * az


@inlined
def _two_body_difference(rx, ry, rz, dx, dy, dz):
    """−μ (R + δ)/|R + δ|³ + μ R/|R|³ (m/s²) without cancellation (module docstring)."""
    r2 = rx * rx + ry * ry + rz * rz
    q = (dx * (2.0 * rx + dx) + dy * (2.0 * ry + dy) + dz * (2.0 * rz + dz)) / r2
    f = math.expm1(1.5 * math.log1p(q))  # (1 + q)^{3/2} − 1
    c = -MU_EARTH / (r2 * math.sqrt(r2) * (1.0 + f))
    return c * (dx - rx * f), c * (dy - ry * f), c * (dz - rz * f)


@inlined
def _offset_derivative(
    work, row, d0, d1, d2, d3, d4, d5, ux, uy, uz, inv_ballistic, j2, atmosphere
):
    """Acceleration (m/s²) of a body's ECI offset δ = (d0..d2, d3..d5) from the reference at
    track row ``row``, with LVLH thrust u rotated by that row's frame."""
    rx, ry, rz = work[row, 0], work[row, 1], work[row, 2]
    gx, gy, gz = _two_body_difference(rx, ry, rz, d0, d1, d2)
    px, py, pz = _perturbation(
        rx + d0,
        ry + d1,
        rz + d2,
        work[row, 3] + d3,
        work[row, 4] + d4,
        work[row, 5] + d5,
        inv_ballistic,
        j2,
        atmosphere,
    )
    c = _FRAME
    tx = work[row, c + 0] * ux + work[row, c + 3] * uy + work[row, c + 6] * uz
    ty = work[row, c + 1] * ux + work[row, c + 4] * uy + work[row, c + 7] * uz
    tz = work[row, c + 2] * ux + work[row, c + 5] * uy + work[row, c + 8] * uz
    return (
        gx + (px - work[row, 6]) + tx,
        gy + (py - work[row, 7]) + ty,
        gz + (pz - work[row, 8]) + tz,
    )


@kernel
def truth_step(
    reference,
    states,
    accels,
    inv_ballistic,
    reference_inv_ballistic,
    j2,
    dt,
    substeps,
    atmosphere,
    work,
):
    """Advance the reference orbit and M bodies by ``dt`` under two-body + J2 + drag + thrust.

    Classical RK4 with ``substeps`` equal sub-steps; each body is integrated as its ECI offset
    from the reference (module docstring), and its LVLH state is taken in and given back in
    the frame of the reference's actual state at the start and at the end of the step. Nothing
    is allocated.

    Args:
        reference: (6,) ECI state of the reference (m, m/s); updated in place.
        states: (M, 6) LVLH states of the bodies (m, m/s); updated in place. A planar caller
            passes z = ż = 0 (J2 and the turning atmosphere then make them small, not zero).
        accels: (M, 3) thrust of each body (m/s²) in LVLH axes, held constant in the turning
            LVLH frame over the step; zeros for free bodies.
        inv_ballistic: (M,) inverse ballistic coefficient C_D·A/m of each body (m²/kg), >= 0;
            0 = no drag.
        reference_inv_ballistic: the reference's C_D·A/m (m²/kg).
        j2: whether the J2 term acts.
        dt: step length (s), > 0.
        substeps: RK4 sub-steps per step, >= 1 (:func:`substeps_for`).
        atmosphere: (K, 3) density table, as :data:`ATMOSPHERE`.
        work: scratch of at least (4·substeps + 1, :data:`TRACK_WIDTH`) (:func:`truth_work`);
            on return its row 4·substeps holds the reference's end state, its perturbing
            acceleration and its frame record.
    """
    m = states.shape[0]
    if substeps < 1 or work.shape[0] < 4 * substeps + 1 or work.shape[1] < TRACK_WIDTH:
        raise ValueError("truth_step: substeps must be >= 1 and work (4*substeps+1, TRACK_WIDTH)")
    if accels.shape[0] != m or inv_ballistic.shape[0] != m or states.shape[1] != 6:
        raise ValueError("truth_step: states (M, 6), accels (M, 3), inv_ballistic (M,) differ")
    for k in range(6):
        work[0, k] = reference[k]
    _reference_rk4(work, dt, substeps, reference_inv_ballistic, j2, atmosphere)
    h = dt / substeps
    half = 0.5 * h
    sixth = h / 6.0
    last = 4 * substeps
    for i in range(m):
        ux, uy, uz = accels[i, 0], accels[i, 1], accels[i, 2]
        b = inv_ballistic[i]
        d0, d1, d2, d3, d4, d5 = _offset_from_lvlh(work[0], _FRAME, states[i])
        for s in range(substeps):
            row = 4 * s
            a1x, a1y, a1z = _offset_derivative(
                work, row, d0, d1, d2, d3, d4, d5, ux, uy, uz, b, j2, atmosphere
            )
            e0, e1, e2 = d0 + half * d3, d1 + half * d4, d2 + half * d5
            e3, e4, e5 = d3 + half * a1x, d4 + half * a1y, d5 + half * a1z
            a2x, a2y, a2z = _offset_derivative(
                work, row + 1, e0, e1, e2, e3, e4, e5, ux, uy, uz, b, j2, atmosphere
            )
            f0, f1, f2 = d0 + half * e3, d1 + half * e4, d2 + half * e5
            f3, f4, f5 = d3 + half * a2x, d4 + half * a2y, d5 + half * a2z
            a3x, a3y, a3z = _offset_derivative(
                work, row + 2, f0, f1, f2, f3, f4, f5, ux, uy, uz, b, j2, atmosphere
            )
            g0, g1, g2 = d0 + h * f3, d1 + h * f4, d2 + h * f5
            g3, g4, g5 = d3 + h * a3x, d4 + h * a3y, d5 + h * a3z
            a4x, a4y, a4z = _offset_derivative(
                work, row + 3, g0, g1, g2, g3, g4, g5, ux, uy, uz, b, j2, atmosphere
            )
            d0 += sixth * (d3 + 2.0 * (e3 + f3) + g3)
            d1 += sixth * (d4 + 2.0 * (e4 + f4) + g4)
            d2 += sixth * (d5 + 2.0 * (e5 + f5) + g5)
            d3 += sixth * (a1x + 2.0 * (a2x + a3x) + a4x)
            d4 += sixth * (a1y + 2.0 * (a2y + a3y) + a4y)
            d5 += sixth * (a1z + 2.0 * (a2z + a3z) + a4z)
        _lvlh_from_offset(work[last], _FRAME, d0, d1, d2, d3, d4, d5, states[i])
    for k in range(6):
        reference[k] = work[last, k]
