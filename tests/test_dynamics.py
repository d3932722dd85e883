"""Tests for :mod:`debris_gym.dynamics` against independent truth.

Every reference here is built without :func:`debris_gym.dynamics.cwh_matrices`: the CWH equations
are re-typed from the textbook (``tests.helpers.cwh_rhs``: ẍ = 3n²x + 2nẏ + u_x, ÿ = −2nẋ + u_y,
z̈ = −n²z + u_z), the closed form is re-typed in the arrangement of [Vallado13] (keys:
docs/references.md), the matrix exponential is recomputed with mpmath at 50 digits, and the full
nonlinear two-body problem is integrated in inertial coordinates.
"""

from __future__ import annotations

import dataclasses
import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from debris_gym import dynamics
from debris_gym.dynamics import (
    DEFAULT_ORBIT_RADIUS,
    MU_EARTH,
    chord_error_bound,
    cw_transition,
    discretize,
    mean_motion,
    propagate,
    substep_position_matrix,
)
from tests.helpers import cw_closed_form, integrate_cwh

MU = 3.986004418e14  # typed independently of MU_EARTH
R_ORBIT = 6_778_137.0
N_LEO = math.sqrt(MU / R_ORBIT**3)  # ≈ 1.1314e-3 rad/s
PERIOD_LEO = 2.0 * math.pi / N_LEO

DTS = [1.0, 5.0, 30.0, 100.0, 300.0, 600.0]


# ----------------------------------------------------------------------------- helpers


def vallado_coast(state0: np.ndarray, n: float, t: float) -> np.ndarray:
    """Unforced CW solution in the arrangement of [Vallado13] eq. 6-66, written independently of
    :func:`cw_transition` and of ``tests.helpers.cw_closed_form`` ([Curtis14]'s arrangement).
    Works for 2D (4,) and 3D (6,) states."""
    dim = len(state0) // 2
    x0, y0 = state0[0], state0[1]
    xd0, yd0 = state0[dim], state0[dim + 1]
    s, c = math.sin(n * t), math.cos(n * t)
    x = xd0 / n * s - (3 * x0 + 2 * yd0 / n) * c + (4 * x0 + 2 * yd0 / n)
    y = (6 * x0 + 4 * yd0 / n) * s + 2 * xd0 / n * c - (6 * n * x0 + 3 * yd0) * t
    y += y0 - 2 * xd0 / n
    xd = xd0 * c + (3 * n * x0 + 2 * yd0) * s
    yd = (6 * n * x0 + 4 * yd0) * c - 2 * xd0 * s - (6 * n * x0 + 3 * yd0)
    if dim == 2:
        return np.array([x, y, xd, yd])
    z0, zd0 = state0[2], state0[5]
    z = z0 * c + zd0 / n * s
    zd = -z0 * n * s + zd0 * c
    return np.array([x, y, z, xd, yd, zd])


def assert_state_close(got: np.ndarray, want: np.ndarray, rtol: float) -> None:
    """Relative error checked separately on the position and velocity blocks (they differ in
    scale by ~1/n), each relative to that block's norm (with a floor so an all-zero block is
    compared absolutely at the scale of the other block times rtol)."""
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    dim = want.shape[-1] // 2
    for sl in (slice(0, dim), slice(dim, 2 * dim)):
        err = np.linalg.norm(got[sl] - want[sl])
        scale = max(np.linalg.norm(want[sl]), 1e-9 * np.linalg.norm(want))
        assert err <= rtol * scale, (got, want, err / scale)


def random_state(rng: np.random.Generator, dim: int) -> np.ndarray:
    pos = rng.uniform(-500.0, 500.0, dim)
    vel = rng.uniform(-0.5, 0.5, dim)
    return np.concatenate([pos, vel])


def augmented_reference(n: float, dt: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Φ and Γ from mpmath.expm of [[A, B], [0, 0]]·dt at 50 significant digits."""
    m = 2 * dim
    size = m + dim
    with mpmath.workdps(50):
        nn = mpmath.mpf(n)
        big = mpmath.zeros(size, size)
        for i in range(dim):
            big[i, dim + i] = 1  # ṗ = v
            big[dim + i, m + i] = 1  # v̇ ← u
        big[dim + 0, 0] = 3 * nn**2
        big[dim + 0, dim + 1] = 2 * nn
        big[dim + 1, dim + 0] = -2 * nn
        if dim == 3:
            big[dim + 2, 2] = -(nn**2)
        e = mpmath.expm(big * mpmath.mpf(dt))
        full = np.array([[float(e[i, j]) for j in range(size)] for i in range(size)])
    return full[:m, :m], full[:m, m:]


# ----------------------------------------------------------------------------- 11. constants


def test_mean_motion_and_period_leo():
    n = mean_motion(DEFAULT_ORBIT_RADIUS)
    assert DEFAULT_ORBIT_RADIUS == R_ORBIT
    assert MU_EARTH == MU
    assert n == pytest.approx(1.1314e-3, rel=1e-4)
    assert n == pytest.approx(N_LEO, rel=1e-15)
    assert 2 * math.pi / n == pytest.approx(5553.6, abs=0.5)
    # 400 km altitude, ~92.6 minutes
    assert 92.0 < 2 * math.pi / n / 60 < 93.0


# ----------------------------------------------------------------------------- 1. closed form


def test_the_two_textbook_arrangements_agree():
    """The tests' two oracles, typed independently, check each other."""
    rng = np.random.default_rng(0)
    for dim in (2, 3):
        for t in [*DTS, 3000.0, PERIOD_LEO, -700.0]:
            s0 = random_state(rng, dim)
            assert_state_close(cw_closed_form(s0, t, N_LEO), vallado_coast(s0, N_LEO, t), 1e-9)


def test_cw_transition_matches_the_textbook_solution():
    rng = np.random.default_rng(1)
    for dim in (2, 3):
        for t in [*DTS, 3000.0, PERIOD_LEO, 12345.6, -700.0]:
            s0 = random_state(rng, dim)
            got = cw_transition(N_LEO, t, dim) @ s0
            assert_state_close(got, vallado_coast(s0, N_LEO, t), 1e-9)
            assert_state_close(got, cw_closed_form(s0, t, N_LEO), 1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_cw_transition_off_the_step_grid_matches_solve_ivp(dim):
    rng = np.random.default_rng(20 + dim)
    for t in (3.7, 370.0, 5000.0):
        s0 = random_state(rng, dim)
        truth = integrate_cwh(N_LEO, dim, s0, np.zeros(dim), t)
        assert_state_close(cw_transition(N_LEO, t, dim) @ s0, truth, 1e-6)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dt", [1.0, 60.0, 600.0])
def test_cw_transition_is_the_discrete_models_state_matrix(dim, dt):
    want = discretize(N_LEO, dt, dim).ad
    assert np.linalg.norm(cw_transition(N_LEO, dt, dim) - want) <= 1e-9 * np.linalg.norm(want)
    # two spans in a row are one span
    np.testing.assert_allclose(
        cw_transition(N_LEO, 250.0, dim) @ cw_transition(N_LEO, 130.0, dim),
        cw_transition(N_LEO, 380.0, dim),
        rtol=1e-9,
        atol=1e-12,
    )


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dt", DTS)
def test_discretize_coast_matches_closed_form(dim, dt):
    rng = np.random.default_rng(int(dt) * 10 + dim)
    model = discretize(N_LEO, dt, dim)
    for _ in range(5):
        s0 = random_state(rng, dim)
        got = model.step(s0, np.zeros(dim))
        assert_state_close(got, cw_closed_form(s0, dt, N_LEO), 1e-6)
        assert_state_close(got, vallado_coast(s0, N_LEO, dt), 1e-6)
    # Tiny components: a purely cross-track state must not leak into the plane and vice versa.
    if dim == 3:
        only_z = np.array([0.0, 0.0, 100.0, 0.0, 0.0, 0.1])
        out = model.step(only_z, np.zeros(3))
        assert np.all(out[[0, 1, 3, 4]] == 0.0)
        assert_state_close(out, vallado_coast(only_z, N_LEO, dt), 1e-9)


def test_discretize_coast_closed_relative_orbit_is_periodic():
    """ẏ₀ = −2n x₀ gives a closed 2:1 ellipse: after one period the state returns."""
    s0 = np.array([100.0, 0.0, 20.0, 0.0, -2 * N_LEO * 100.0, 0.05])
    steps = 100
    model = discretize(N_LEO, PERIOD_LEO / steps, 3)
    s = s0.copy()
    max_y = 0.0
    for _ in range(steps):
        s = model.step(s, np.zeros(3))
        max_y = max(max_y, abs(s[1]))
    assert_state_close(s, s0, 1e-9)
    assert max_y == pytest.approx(200.0, rel=1e-3)  # along-track semi-axis is 2 x₀


# ----------------------------------------------------------------------------- 2. solve_ivp


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dt", [1.0, 10.0, 60.0, 300.0, 600.0])
def test_constant_thrust_matches_solve_ivp(dim, dt):
    rng = np.random.default_rng(1000 + int(dt) + dim)
    model = discretize(N_LEO, dt, dim)
    for _ in range(3):
        s0 = random_state(rng, dim)
        u = rng.uniform(-0.01, 0.01, dim)
        truth = integrate_cwh(N_LEO, dim, s0, u, dt)
        assert_state_close(model.step(s0, u), truth, 1e-6)
    # thrust alone from rest: checks bd in isolation
    u = rng.uniform(-0.01, 0.01, dim)
    truth = integrate_cwh(N_LEO, dim, np.zeros(2 * dim), u, dt)
    assert_state_close(model.bd @ u, truth, 1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_constant_thrust_larger_mean_motion(dim):
    """A faster (lower, hypothetical) orbit so n·dt reaches several radians."""
    n = 2e-3
    rng = np.random.default_rng(7)
    for dt in (600.0, 2000.0):
        s0 = random_state(rng, dim)
        u = rng.uniform(-0.01, 0.01, dim)
        assert_state_close(
            discretize(n, dt, dim).step(s0, u), integrate_cwh(n, dim, s0, u, dt), 1e-6
        )


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dt", [1e-3, 1.0, 60.0, 600.0])
def test_zero_mean_motion_is_double_integrator(dim, dt):
    rng = np.random.default_rng(3)
    model = discretize(0.0, dt, dim)
    s0 = random_state(rng, dim)
    u = rng.uniform(-0.01, 0.01, dim)
    pos0, vel0 = s0[:dim], s0[dim:]
    want = np.concatenate([pos0 + vel0 * dt + 0.5 * u * dt * dt, vel0 + u * dt])
    assert_state_close(model.step(s0, u), want, 1e-12)
    expected_ad = np.block([[np.eye(dim), dt * np.eye(dim)], [np.zeros((dim, dim)), np.eye(dim)]])
    expected_bd = np.vstack([0.5 * dt * dt * np.eye(dim), dt * np.eye(dim)])
    np.testing.assert_allclose(model.ad, expected_ad, rtol=1e-12, atol=0)
    np.testing.assert_allclose(model.bd, expected_bd, rtol=1e-12, atol=0)
    # cw_transition's n = 0 branch is the straight line
    coast = cw_transition(0.0, dt, dim) @ s0
    assert_state_close(coast, model.step(s0, np.zeros(dim)), 1e-12)


# ----------------------------------------------------------------------------- 3. mpmath expm


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dt", [1e-3, 1e-2, 600.0])
def test_matrix_exponential_matches_mpmath(dim, dt):
    ad_ref, bd_ref = augmented_reference(N_LEO, dt, dim)
    model = discretize(N_LEO, dt, dim)
    # structural zeros must be exact zeros
    np.testing.assert_array_equal(model.ad[ad_ref == 0.0], 0.0)
    np.testing.assert_array_equal(model.bd[bd_ref == 0.0], 0.0)
    # norm-relative agreement of the whole matrices
    assert np.linalg.norm(model.ad - ad_ref) <= 1e-12 * np.linalg.norm(ad_ref)
    assert np.linalg.norm(model.bd - bd_ref) <= 1e-12 * np.linalg.norm(bd_ref)
    # elementwise: every non-zero entry relative to itself, including the tiny coupling terms
    # (e.g. 3n²·dt ≈ 4e-12 at dt = 1 ms next to 1 on the diagonal); 1e-12 leaves room above the
    # rounding of a double-precision matrix exponential while catching any dropped term.
    for got, ref in ((model.ad, ad_ref), (model.bd, bd_ref)):
        nz = ref != 0.0
        rel = np.abs(got - ref)[nz] / np.abs(ref)[nz]
        assert np.max(rel) <= 1e-12, np.max(rel)


def test_mpmath_reference_is_independent_of_closed_form():
    """Sanity check of the mpmath reference itself: its Φ equals the [Vallado13] closed form."""
    dt = 600.0
    ad_ref, _ = augmented_reference(N_LEO, dt, 3)
    for j in range(6):
        e = np.zeros(6)
        e[j] = 1.0
        np.testing.assert_allclose(ad_ref[:, j], vallado_coast(e, N_LEO, dt), rtol=1e-9, atol=1e-12)


# ----------------------------------------------------------------------------- 4. two-body truth


def _two_body_rhs(_t: float, s: np.ndarray) -> np.ndarray:
    """Chaser (0:6) and reference point (6:12), both under point-mass gravity, inertial frame."""
    out = np.empty(12)
    for k in (0, 6):
        r = s[k : k + 3]
        out[k : k + 3] = s[k + 3 : k + 6]
        out[k + 3 : k + 6] = -MU * r / np.linalg.norm(r) ** 3
    return out


def _lvlh_basis(r: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows = LVLH unit vectors expressed inertially; plus the frame angular velocity in LVLH."""
    h = np.cross(r, v)
    x_hat = r / np.linalg.norm(r)
    z_hat = h / np.linalg.norm(h)
    y_hat = np.cross(z_hat, x_hat)
    omega = np.array([0.0, 0.0, np.linalg.norm(h) / np.dot(r, r)])
    return np.vstack([x_hat, y_hat, z_hat]), omega


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def two_body_vs_cwh(rel0_lvlh: np.ndarray, samples: int = 120) -> tuple[float, float, float]:
    """Max position error (m), max velocity error (m/s) and max separation (m) over one period."""
    # Inclined circular reference orbit (ISS-like inclination, arbitrary node and phase)
    q = _rot(2, 0.7) @ _rot(0, math.radians(51.6)) @ _rot(2, 0.3)
    r_ref0 = q @ np.array([R_ORBIT, 0.0, 0.0])
    v_ref0 = q @ np.array([0.0, math.sqrt(MU / R_ORBIT), 0.0])
    rot0, omega0 = _lvlh_basis(r_ref0, v_ref0)
    dr_l, dv_l = rel0_lvlh[:3], rel0_lvlh[3:]
    # v_rel_LVLH = R (v_c − v_ref) − ω × r_rel   ⇒   v_c − v_ref = Rᵀ (v_rel_LVLH + ω × r_rel)
    r_c0 = r_ref0 + rot0.T @ dr_l
    v_c0 = v_ref0 + rot0.T @ (dv_l + np.cross(omega0, dr_l))

    t_eval = np.linspace(0.0, PERIOD_LEO, samples + 1)
    sol = solve_ivp(
        _two_body_rhs,
        (0.0, PERIOD_LEO),
        np.concatenate([r_c0, v_c0, r_ref0, v_ref0]),
        method="DOP853",
        rtol=1e-12,
        atol=1e-6,
        t_eval=t_eval,
    )
    assert sol.success

    # The integrated reference point must itself stay on the analytic circular orbit (this bounds
    # the integrator's own error far below the linearisation error being measured).
    ang = N_LEO * t_eval
    ref_analytic = q @ np.vstack([R_ORBIT * np.cos(ang), R_ORBIT * np.sin(ang), 0 * ang])
    assert np.max(np.linalg.norm(sol.y[6:9] - ref_analytic, axis=0)) < 1e-3

    model = discretize(N_LEO, PERIOD_LEO / samples, 3)
    cw = rel0_lvlh.copy()
    pos_err = vel_err = sep = 0.0
    for k in range(samples + 1):
        if k > 0:
            cw = model.step(cw, np.zeros(3))
        y = sol.y[:, k]
        rot, omega = _lvlh_basis(y[6:9], y[9:12])
        r_rel = rot @ (y[0:3] - y[6:9])
        v_rel = rot @ (y[3:6] - y[9:12]) - np.cross(omega, r_rel)
        pos_err = max(pos_err, float(np.linalg.norm(r_rel - cw[:3])))
        vel_err = max(vel_err, float(np.linalg.norm(v_rel - cw[3:])))
        sep = max(sep, float(np.linalg.norm(r_rel)))
    return pos_err, vel_err, sep


def test_two_body_closed_relative_orbit_in_plane():
    x0 = 100.0
    rel0 = np.array([x0, 0.0, 0.0, 0.0, -2 * N_LEO * x0, 0.0])
    pos_err, vel_err, sep = two_body_vs_cwh(rel0)
    # CWH drops terms of relative order separation / orbit radius (3e-5 at 200 m), so 1e-3 of the
    # separation bounds the linearisation error with room to spare
    assert sep == pytest.approx(200.0, rel=0.01)
    assert pos_err < 0.01 * sep
    assert pos_err < 1.0
    assert pos_err < 1e-3 * sep
    assert vel_err < 1e-4


def test_two_body_generic_3d():
    n = N_LEO
    rel0 = np.array([60.0, -70.0, 40.0, 0.02, -2 * n * 60.0 + 0.004, -0.03])
    pos_err, vel_err, sep = two_body_vs_cwh(rel0)
    # the same bounds as in-plane: the cross-track motion is linearised to the same order
    assert sep > 100.0
    assert pos_err < 0.01 * sep
    assert pos_err < 1.0
    assert pos_err < 1e-3 * sep
    assert vel_err < 1e-4


def test_two_body_error_is_quadratic_in_separation():
    """The CWH error is pure linearisation error: doubling the offset quadruples it. A wrong sign
    or coefficient in the linear model would instead give an error growing linearly."""
    n = N_LEO
    base = np.array([50.0, 30.0, 20.0, 0.01, -2 * n * 50.0, 0.02])
    e1, _, _ = two_body_vs_cwh(base, samples=60)
    e2, _, _ = two_body_vs_cwh(2 * base, samples=60)
    assert 3.5 < e2 / e1 < 4.5, (e1, e2)


# ----------------------------------------------------------------------------- 5. batching


@pytest.mark.parametrize("batch_shape", [(7,), (3, 5)])
@pytest.mark.parametrize("dim", [2, 3])
def test_propagate_batch_equals_loop(batch_shape, dim):
    rng = np.random.default_rng(11)
    model = discretize(N_LEO, 10.0, dim)
    states = rng.normal(size=(*batch_shape, 2 * dim)) * 100
    accels = rng.normal(size=(*batch_shape, dim)) * 0.01
    out = propagate(states, accels, model.ad, model.bd)
    assert out.shape == states.shape
    np.testing.assert_array_equal(model.step(states, accels), out)
    for idx in np.ndindex(*batch_shape):
        single = model.ad @ states[idx] + model.bd @ accels[idx]
        np.testing.assert_allclose(out[idx], single, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(
            propagate(states[idx], accels[idx], model.ad, model.bd), single, rtol=1e-13, atol=1e-12
        )


def test_propagate_batch_explicit_shapes():
    rng = np.random.default_rng(12)
    m2 = discretize(N_LEO, 5.0, 2)
    s = rng.normal(size=(7, 4))
    u = rng.normal(size=(7, 2))
    np.testing.assert_allclose(
        m2.step(s, u), np.stack([m2.step(s[i], u[i]) for i in range(7)]), rtol=1e-14, atol=1e-14
    )
    m3 = discretize(N_LEO, 5.0, 3)
    s = rng.normal(size=(3, 5, 6))
    u = rng.normal(size=(3, 5, 3))
    loop = np.array([[m3.step(s[i, j], u[i, j]) for j in range(5)] for i in range(3)])
    np.testing.assert_allclose(m3.step(s, u), loop, rtol=1e-14, atol=1e-14)


# ----------------------------------------------------------------------------- 6. substeps


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(("dt", "substeps"), [(10.0, 1), (10.0, 4), (60.0, 7), (600.0, 16)])
def test_substep_position_matrix(dim, dt, substeps):
    rng = np.random.default_rng(21)
    mat = substep_position_matrix(N_LEO, dt, dim, substeps)
    assert mat.shape == (substeps * dim, 3 * dim)
    s0 = random_state(rng, dim)
    u = rng.uniform(-0.01, 0.01, dim)
    positions = (mat @ np.concatenate([s0, u])).reshape(substeps, dim)
    for k in range(1, substeps + 1):
        want = discretize(N_LEO, k * dt / substeps, dim).step(s0, u)[:dim]
        np.testing.assert_allclose(positions[k - 1], want, rtol=1e-11, atol=1e-9)
        # and against the independent ODE integration
        truth = integrate_cwh(N_LEO, dim, s0, u, k * dt / substeps)[:dim]
        np.testing.assert_allclose(positions[k - 1], truth, rtol=1e-8, atol=1e-6)
    end = discretize(N_LEO, dt, dim).step(s0, u)[:dim]
    np.testing.assert_allclose(positions[-1], end, rtol=1e-11, atol=1e-9)


# ----------------------------------------------------------------------------- 7. caching


def test_discretize_is_cached_and_read_only():
    a = discretize(N_LEO, 12.5, 3)
    b = discretize(N_LEO, 12.5, 3)
    assert a is b
    assert discretize(N_LEO, 12.5, 2) is not a
    assert discretize(N_LEO, 13.0, 3) is not a
    for arr in (a.ad, a.bd):
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.ad = np.eye(6)  # type: ignore[misc]
    assert a.n == N_LEO and a.dt == 12.5 and a.dim == 3
    assert a.ad.shape == (6, 6) and a.bd.shape == (6, 3)

    m1 = substep_position_matrix(N_LEO, 12.5, 3, 5)
    assert substep_position_matrix(N_LEO, 12.5, 3, 5) is m1
    assert not m1.flags.writeable
    with pytest.raises(ValueError):
        m1[0, 0] = 1.0


# ----------------------------------------------------------------------------- 8. validation


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n": N_LEO, "dt": 1.0, "dim": 1}, "dim"),
        ({"n": N_LEO, "dt": 1.0, "dim": 4}, "dim"),
        ({"n": -1e-3, "dt": 1.0, "dim": 2}, "n"),
        ({"n": math.nan, "dt": 1.0, "dim": 2}, "n"),
        ({"n": math.inf, "dt": 1.0, "dim": 3}, "n"),
        ({"n": N_LEO, "dt": 0.0, "dim": 2}, "dt"),
        ({"n": N_LEO, "dt": -1.0, "dim": 2}, "dt"),
        ({"n": N_LEO, "dt": math.nan, "dim": 3}, "dt"),
        ({"n": N_LEO, "dt": math.inf, "dim": 3}, "dt"),
    ],
)
def test_discretize_validation(kwargs, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        discretize(**kwargs)


def test_other_validation():
    with pytest.raises(ValueError, match=r"\bsubsteps\b"):
        substep_position_matrix(N_LEO, 1.0, 2, 0)
    with pytest.raises(ValueError, match=r"\bdt\b"):
        substep_position_matrix(N_LEO, -1.0, 2, 3)
    with pytest.raises(ValueError, match=r"\bdim\b"):
        substep_position_matrix(N_LEO, 1.0, 5, 3)
    with pytest.raises(ValueError, match=r"\borbit_radius\b"):
        mean_motion(0.0)
    with pytest.raises(ValueError, match=r"\borbit_radius\b"):
        mean_motion(math.nan)
    with pytest.raises(ValueError, match=r"\bdim\b"):
        dynamics.cwh_matrices(N_LEO, 1)
    with pytest.raises(ValueError, match=r"\bn\b"):
        dynamics.cwh_matrices(-N_LEO, 2)
    with pytest.raises(ValueError, match=r"\bdim\b"):
        cw_transition(N_LEO, 1.0, 4)
    with pytest.raises(ValueError, match=r"\bn\b"):
        cw_transition(-N_LEO, 1.0, 2)
    with pytest.raises(ValueError, match=r"\bt\b"):
        cw_transition(N_LEO, math.inf, 2)


# ----------------------------------------------------------------------------- 9. semigroup


@settings(max_examples=150, deadline=None)
@given(
    n=st.floats(0.0, 2e-3),
    dt=st.floats(1e-3, 600.0),
    dim=st.sampled_from([2, 3]),
    seed=st.integers(0, 2**32 - 1),
)
def test_two_half_steps_equal_one_full_step(n, dt, dim, seed):
    rng = np.random.default_rng(seed)
    s0 = random_state(rng, dim)
    u = rng.uniform(-0.05, 0.05, dim)
    full = discretize(n, dt, dim)
    half = discretize(n, dt / 2, dim)
    one = full.step(s0, u)
    two = half.step(half.step(s0, u), u)
    # scale-aware tolerance: a few ulps of the magnitudes flowing through the product
    scale = np.abs(full.ad) @ np.abs(s0) + np.abs(full.bd) @ np.abs(u)
    assert np.all(np.abs(one - two) <= 1e-12 * scale + 1e-300), np.max(np.abs(one - two) / scale)
    # the matrices themselves: Φ(dt) = Φ(dt/2)², Γ(dt) = Φ(dt/2) Γ(dt/2) + Γ(dt/2)
    np.testing.assert_allclose(half.ad @ half.ad, full.ad, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(half.ad @ half.bd + half.bd, full.bd, rtol=1e-12, atol=1e-13 * dt)


# ----------------------------------------------------------------------------- 10. chord bound


def _fine_path(n: float, dt: float, dim: int, s0: np.ndarray, u: np.ndarray, samples: int):
    fine = discretize(n, dt / samples, dim)
    states = [s0]
    for _ in range(samples):
        states.append(fine.step(states[-1], u))
    return np.array(states)


def _total_accel(n: float, dim: int, states: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Acceleration along the path straight from the ODE (gravity-gradient + Coriolis + thrust)."""
    x, vx, vy = states[:, 0], states[:, dim], states[:, dim + 1]
    acc = np.empty((len(states), dim))
    acc[:, 0] = 3 * n * n * x + 2 * n * vy + u[0]
    acc[:, 1] = -2 * n * vx + u[1]
    if dim == 3:
        acc[:, 2] = -n * n * states[:, 2] + u[2]
    return acc


@pytest.mark.parametrize("dim", [2, 3])
def test_chord_error_bound_holds(dim):
    rng = np.random.default_rng(31)
    n = N_LEO
    per_sub = 50
    worst_ratio = 0.0
    for trial in range(12):
        dt = float(rng.choice([10.0, 60.0, 300.0]))
        substeps = int(rng.choice([1, 2, 4, 8]))
        s0 = random_state(rng, dim)
        # mix of thrust-dominated and dynamics-dominated cases
        u = rng.uniform(-1, 1, dim) * (0.05 if trial % 2 else 1e-4)
        path = _fine_path(n, dt, dim, s0, u, substeps * per_sub)
        pos = path[:, :dim]
        a_max = float(np.max(np.linalg.norm(_total_accel(n, dim, path, u), axis=1)))
        bound = chord_error_bound(a_max, dt, substeps)
        # chord end points agree with the substep matrix
        knots = (substep_position_matrix(n, dt, dim, substeps) @ np.concatenate([s0, u])).reshape(
            substeps, dim
        )
        np.testing.assert_allclose(knots, pos[per_sub::per_sub], rtol=1e-10, atol=1e-8)
        dev = 0.0
        for k in range(substeps):
            seg = pos[k * per_sub : (k + 1) * per_sub + 1]
            frac = np.linspace(0.0, 1.0, per_sub + 1)[:, None]
            chord = seg[0] + frac * (seg[-1] - seg[0])
            dev = max(dev, float(np.max(np.linalg.norm(seg - chord, axis=1))))
        assert dev <= bound * (1 + 1e-6) + 1e-12, (dev, bound)
        worst_ratio = max(worst_ratio, dev / bound)
    # the bound is tight for near-constant acceleration (thrust-dominated, short sub-steps):
    # the deviation of a parabola from its chord is exactly a h²/8
    assert worst_ratio > 0.95


def test_chord_error_bound_formula():
    # constant acceleration parabola: midpoint deviation from the chord is exactly a h²/8
    a, dt, k = 0.02, 60.0, 3
    h = dt / k
    assert chord_error_bound(a, dt, k) == pytest.approx(a * h * h / 8, rel=1e-15)
    p = 0.5 * a * np.linspace(0.0, h, 101) ** 2
    chord = np.linspace(0.0, p[-1], 101)
    assert np.max(np.abs(p - chord)) == pytest.approx(chord_error_bound(a, dt, k), rel=1e-9)
    assert chord_error_bound(a, dt, 2 * k) == pytest.approx(chord_error_bound(a, dt, k) / 4)
