"""The J2 + drag truth model (debris_gym.orbit_truth) against independent truth: absolute
orbits integrated by scipy (tests/orbit_oracle.py), the closed-form CW motion and the CW
zero-order hold (debris_gym.dynamics), and figures worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from debris_gym import orbit_truth as ot
from debris_gym.dynamics import cw_transition, discretize
from tests.orbit_oracle import (
    EARTH_RATE,
    INCLINATION,
    MU,
    N0,
    R0,
    TABLE,
    acceleration,
    air_density,
    circular_start,
    default_field,
    dense_orbit,
    fly,
    from_lvlh,
    lvlh_axes,
    oracle,
    to_lvlh,
)


def run_truth(rel0, b, b_ref, j2, dt, steps, accels=None, substeps=None, inclination=INCLINATION):
    substeps = ot.substeps_for(dt) if substeps is None else substeps
    ref = ot.reference_start(R0, inclination)
    states = np.array(rel0, dtype=float).reshape(-1, 6).copy()
    accels = np.zeros((len(states), 3)) if accels is None else np.asarray(accels, dtype=float)
    work = ot.truth_work(substeps)
    b = np.asarray(b, dtype=float)
    for _ in range(steps):
        ot.truth_step(ref, states, accels, b, b_ref, j2, dt, substeps, ot.ATMOSPHERE, work)
    return states, ref


# --- against the independent integration -------------------------------------------------------


@pytest.mark.parametrize(("dt", "steps"), [(10.0, 1000), (40.0, 250)])
def test_the_truth_agrees_with_independent_absolute_orbits_to_1_cm_over_10000_s(dt, steps):
    """Six bodies (positions up to 1 km, speeds up to 1 m/s, B from 0 to 0.05 m²/kg against
    the reference's 0.01), J2 and drag on, at the default sub-step count for ``dt``."""
    rel0 = default_field(np.random.default_rng(1), 6)
    b = np.array([0.0, 0.005, 0.01, 0.02, 0.03, 0.05])
    truth = oracle(rel0, b, 0.01, True, 10_000.0)
    states, _ = run_truth(rel0, b, 0.01, True, dt, steps)
    assert np.abs(states[:, :3] - truth[:, :3]).max() < 0.01  # m (measured 1.0e-3)
    assert np.abs(states[:, 3:] - truth[:, 3:]).max() < 2e-6  # m/s (measured 2.0e-7)
    assert np.abs(truth[:, :3] - rel0[:, :3]).max() > 100.0  # the bodies did move


def test_a_planar_field_and_a_polar_reference_agree_with_the_oracle_too():
    rel0 = default_field(np.random.default_rng(2), 4)
    rel0[:, [2, 5]] = 0.0
    b = np.array([0.002, 0.01, 0.04, 0.0])
    ref0 = circular_start(inclination=math.radians(97.0))
    times = np.array([0.0, 5_000.0])
    ref_end = fly(ref0, 0.02, True, times)[-1]
    truth = [
        to_lvlh(ref_end, fly(from_lvlh(ref0, r, 0.02, True), bi, True, times)[-1], 0.02, True)
        for r, bi in zip(rel0, b)
    ]
    states, _ = run_truth(rel0, b, 0.02, True, 10.0, 500, inclination=math.radians(97.0))
    assert np.abs(states[:, :3] - np.array(truth)[:, :3]).max() < 0.01


def test_thrust_held_in_the_turning_lvlh_frame_agrees_with_the_oracle():
    """Piecewise-constant LVLH thrust (a new value every 1000 s); the oracle flies reference and
    body together so that it can turn the thrust with its own frame at every instant."""
    rng = np.random.default_rng(3)
    thrusts = rng.uniform(-2e-4, 2e-4, size=(10, 3))
    rel0 = np.array([300.0, -500.0, 100.0, 0.2, 0.1, -0.3])
    b_body, b_ref = 0.02, 0.01

    def joint(t, y, u):
        axes, _ = lvlh_axes(y[:6], b_ref, True)
        a_ref = acceleration(y[:3], y[3:6], b_ref, True)
        a_body = acceleration(y[6:9], y[9:], b_body, True) + axes.T @ u
        return np.concatenate([y[3:6], a_ref, y[9:], a_body])

    y = np.concatenate([circular_start(), from_lvlh(circular_start(), rel0, b_ref, True)])
    for u in thrusts:
        sol = solve_ivp(joint, (0, 1000.0), y, method="DOP853", rtol=1e-12, atol=1e-7, args=(u,))
        y = sol.y[:, -1]
    truth = to_lvlh(y[:6], y[6:], b_ref, True)

    ref = ot.reference_start(R0, INCLINATION)
    states, work = rel0.reshape(1, 6).copy(), ot.truth_work(1)
    for u in thrusts:
        for _ in range(100):
            ot.truth_step(
                ref, states, u.reshape(1, 3), np.array([b_body]), b_ref, True, 10.0, 1,
                ot.ATMOSPHERE, work,
            )  # fmt: skip
    assert np.abs(states[0, :3] - truth[:3]).max() < 0.01
    assert np.abs(states[0, 3:] - truth[3:]).max() < 2e-6
    assert np.linalg.norm(truth[:3] - rel0[:3]) > 1000.0  # the thrust mattered


def test_the_frame_velocity_is_the_rate_of_the_lvlh_position():
    """ρ̇ from :func:`lvlh_from_eci` equals the time derivative of ρ = C(t)(r − R) (central
    differences of the oracle's dense orbits), the frame's out-of-plane turn included."""
    ref0 = circular_start()
    body0 = from_lvlh(ref0, np.array([800.0, -600.0, 400.0, 0.0, 0.0, 0.0]), 0.01, True)
    ref_sol, body_sol = dense_orbit(ref0, 0.01), dense_orbit(body0, 0.03)

    def position(t):
        axes, _ = lvlh_axes(ref_sol(t), 0.01, True)
        return axes @ (body_sol(t)[:3] - ref_sol(t)[:3])

    t, h = 700.0, 0.5
    rate = (position(t + h) - position(t - h)) / (2 * h)
    frame, out = np.empty(ot.FRAME_WIDTH), np.empty(6)
    ot.reference_frame(ref_sol(t), 0.01, True, ot.ATMOSPHERE, frame)
    ot.lvlh_from_eci(ref_sol(t), frame, body_sol(t), out)
    assert np.abs(out[3:] - rate).max() < 1e-6
    # the out-of-plane term of ω is large enough here for the check to see it
    in_plane_only = frame.copy()
    in_plane_only[9:] = (in_plane_only[9:] @ frame[6:9]) * frame[6:9]
    ot.lvlh_from_eci(ref_sol(t), in_plane_only, body_sol(t), out)
    assert np.abs(out[3:] - rate).max() > 1e-4


# --- against CW when the perturbations are off --------------------------------------------------


def test_without_j2_and_drag_the_truth_leaves_cw_by_the_second_order_drift_only():
    """Over one orbit of a circular reference, CW and the exact two-body motion differ mainly by
    a drift: CW moves along-track at −(3/2)n x_c with the linear semi-major-axis offset
    x_c = 4x₀ + 2ẏ₀/n, the exact body at −(3/2)n Δa with its true Δa (vis-viva), so after one
    period the gap is 3π|Δa − x_c|, of order s²/R for offsets of size s. What remains is
    periodic second-order motion, here below s²/R (1.5 mm at s = 100 m)."""
    period = 2 * math.pi / N0
    dt = period / 555
    s = 100.0
    cases = [
        [s, 0, 0, 0, -2 * N0 * s, 0],
        [0, s, 0, 0, 0, 0],
        [0, 0, 0, N0 * s, 0, 0],
        [0, 0, s, 0, 0, 0],
        [s / 2, s / 2, s / 2, 0, -N0 * s, 0],
        [-s, s, 0, 0, 2 * N0 * s, N0 * s],
    ]
    states, _ = run_truth(cases, np.zeros(len(cases)), 0.0, False, dt, 555)
    ref0 = circular_start()
    for rel, end in zip(np.array(cases), states):
        body = from_lvlh(ref0, rel, 0.0, False)
        true_da = -MU / (2 * (body[3:] @ body[3:] / 2 - MU / np.linalg.norm(body[:3]))) - R0
        x_c = 4 * rel[0] + 2 * rel[4] / N0
        gap = np.linalg.norm(end[:3] - (cw_transition(N0, period, 3) @ rel)[:3])
        assert abs(gap - 3 * math.pi * abs(true_da - x_c)) < s * s / R0
        assert gap < 0.03


def test_a_body_on_the_reference_circle_keeps_its_lvlh_position_where_cw_would_not():
    theta = 150.0 / R0
    rel = np.array([R0 * (math.cos(theta) - 1.0), R0 * math.sin(theta), 0, 0, 0, 0])
    states, _ = run_truth(rel, [0.0], 0.0, False, 10.0, 555)
    np.testing.assert_allclose(states[0], rel, atol=1e-6)
    cw = cw_transition(N0, 5550.0, 3) @ rel
    assert np.linalg.norm(cw[:3] - rel[:3]) > 0.01  # the linear model drifts away


def test_constant_thrust_follows_the_cw_zero_order_hold_to_second_order():
    """Constant LVLH thrust from the origin for 3000 s: the gap to the CW zero-order hold
    (dynamics.discretize) is below ρ_max²/R (ρ_max the largest distance reached) and grows as
    the thrust squared — the signature of the neglected quadratic terms."""
    model = discretize(N0, 10.0, 3)
    gaps = []
    for u in (np.array([1e-4, -1e-4, 5e-5]), np.array([2e-4, -2e-4, 1e-4])):
        cw, far = np.zeros(6), 0.0
        for _ in range(300):
            cw = model.ad @ cw + model.bd @ u
            far = max(far, np.linalg.norm(cw[:3]))
        states, _ = run_truth(np.zeros(6), [0.0], 0.0, False, 10.0, 300, accels=u.reshape(1, 3))
        gaps.append(np.linalg.norm(states[0, :3] - cw[:3]))
        assert gaps[-1] < far**2 / R0
    assert 3.6 < gaps[1] / gaps[0] < 4.4


# --- exactness and the size of the effects ------------------------------------------------------


def test_a_body_at_the_reference_with_its_ballistic_coefficient_stays_at_the_origin():
    b_ref = 0.01
    states, _ = run_truth(np.zeros((2, 6)), [b_ref, 0.02], b_ref, True, 10.0, 1000)
    np.testing.assert_array_equal(states[0], np.zeros(6))
    assert abs(states[1, 1]) > 10.0  # a different coefficient does drift


def _hand_drag_drift(delta_b: float, t: float) -> tuple[float, float]:
    """(x, y) of a body that starts at the reference and feels Δa = −½ρ|v_air|v_air·ΔB more
    drag, by CW with a constant along-track acceleration a from rest:
    x = (2a/n²)(nt − sin nt), y = (a/n²)(4(1 − cos nt) − (3/2)(nt)²).
    The air moves along-track at ω_E R cos i and cross-track by up to ω_E R sin i."""
    speed = math.sqrt(MU / R0)
    along = speed - EARTH_RATE * R0 * math.cos(INCLINATION)  # 7 361.6 m/s
    cross_rms = EARTH_RATE * R0 * math.sin(INCLINATION) / math.sqrt(2)
    a = -0.5 * 3.725e-12 * delta_b * math.hypot(along, cross_rms) * along  # −1.009e-6 m/s²
    nt = N0 * t
    return 2 * a / N0**2 * (nt - math.sin(nt)), a / N0**2 * (4 * (1 - math.cos(nt)) - 1.5 * nt**2)


def test_differential_drag_drift_over_3000_s_matches_the_hand_figure():
    """ΔB = 0.01 m²/kg at 400 km: the body with more drag sinks and moves ahead by
    x ≈ −5.74 m, y ≈ +7.41 m after 3000 s. With J2 the reference's altitude also dips (by up to
    11.5 km over an orbit), the air is denser, and the drift is a few per cent larger."""
    x_hand, y_hand = _hand_drag_drift(0.01, 3000.0)
    assert -5.8 < x_hand < -5.7 and 7.35 < y_hand < 7.45
    states, _ = run_truth(np.zeros(6), [0.02], 0.01, False, 10.0, 300)
    assert states[0, 0] == pytest.approx(x_hand, rel=0.01)
    assert states[0, 1] == pytest.approx(y_hand, rel=0.01)
    states, _ = run_truth(np.zeros(6), [0.02], 0.01, True, 10.0, 300)
    assert 1.0 < states[0, 1] / y_hand < 1.1


# --- the atmosphere, the frame, the inputs ------------------------------------------------------


def test_the_density_is_the_tables_value_at_each_base_altitude():
    assert ot.density(0.0, ot.ATMOSPHERE) == pytest.approx(1.225, rel=1e-12)
    assert ot.density(400e3, ot.ATMOSPHERE) == pytest.approx(3.725e-12, rel=1e-12)
    assert ot.density(1000e3, ot.ATMOSPHERE) == pytest.approx(3.019e-15, rel=1e-12)
    # inside a band: 3.725e-12 · exp(−25/58.515)
    assert ot.density(425e3, ot.ATMOSPHERE) == pytest.approx(2.4299e-12, rel=1e-4)
    for h0, rho0, _ in TABLE:
        assert ot.density(h0 * 1e3, ot.ATMOSPHERE) == pytest.approx(rho0, rel=1e-12)
        assert ot.density(h0 * 1e3 + 777.0, ot.ATMOSPHERE) == pytest.approx(
            air_density(h0 * 1e3 + 777.0), rel=1e-12
        )


def test_the_density_falls_with_altitude_and_is_continuous_to_the_tables_rounding():
    heights = np.linspace(0.0, 1_200e3, 24_001)
    rho = np.array([ot.density(h, ot.ATMOSPHERE) for h in heights])
    assert np.all(np.diff(rho) < 0)
    for h0, _, _ in TABLE[1:]:
        below = ot.density(h0 * 1e3 - 1e-3, ot.ATMOSPHERE)
        assert below == pytest.approx(ot.density(h0 * 1e3, ot.ATMOSPHERE), rel=2e-3)


_unit = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v))


@settings(max_examples=60, deadline=None)
@given(
    direction=_unit,
    heading=_unit,
    radius=st.floats(6.6e6, 8.0e6),
    speed=st.floats(6.5e3, 8.5e3),
    b_ref=st.floats(0.0, 0.1),
    j2=st.booleans(),
    rel=st.tuples(*[st.floats(-5e3, 5e3)] * 3, *[st.floats(-10.0, 10.0)] * 3),
)
def test_lvlh_and_eci_convert_both_ways_as_the_frames_definition_says(
    direction, heading, radius, speed, b_ref, j2, rel
):
    r = radius * np.array(direction) / np.linalg.norm(direction)
    v = speed * np.array(heading) / np.linalg.norm(heading)
    if np.linalg.norm(np.cross(r, v)) < 0.2 * radius * speed:
        v = v + speed * np.cross([0.3, 0.5, 0.8], r) / radius
    ref, rel = np.concatenate([r, v]), np.array(rel)
    frame, eci, back = np.empty(ot.FRAME_WIDTH), np.empty(6), np.empty(6)
    ot.reference_frame(ref, b_ref, j2, ot.ATMOSPHERE, frame)
    ot.eci_from_lvlh(ref, frame, rel, eci)
    ot.lvlh_from_eci(ref, frame, eci, back)
    np.testing.assert_allclose(back[:3], rel[:3], rtol=0, atol=1e-8)  # 1e-9 m: ulp of |r|
    np.testing.assert_allclose(back[3:], rel[3:], rtol=0, atol=1e-10)
    mine = from_lvlh(ref, rel, b_ref, j2)
    np.testing.assert_allclose(eci[:3], mine[:3], rtol=0, atol=1e-8)
    np.testing.assert_allclose(eci[3:], mine[3:], rtol=0, atol=1e-10)


@settings(max_examples=40, deadline=None)
@given(
    altitude=st.floats(150e3, 1_200e3),
    lat=st.floats(-1.5, 1.5),
    lon=st.floats(-3.1, 3.1),
    heading=_unit,
    b=st.floats(0.0, 0.2),
    j2=st.booleans(),
)
def test_the_compiled_acceleration_is_the_oracles(altitude, lat, lon, heading, b, j2):
    # at a band's base the table itself jumps (by up to 0.14 %): rounding picks either side
    assume(min(abs(altitude - h0 * 1e3) for h0, _, _ in TABLE) > 1e-3)
    radius = 6_378_137.0 + altitude
    r = radius * np.array(
        [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
    )
    v = 7_600.0 * np.array(heading) / np.linalg.norm(heading)
    out = np.empty(3)
    ot.eci_acceleration(np.concatenate([r, v]), b, j2, ot.ATMOSPHERE, out)
    np.testing.assert_allclose(out, acceleration(r, v, b, j2), rtol=1e-12, atol=1e-12)


def test_the_reference_starts_circular_at_its_ascending_node():
    np.testing.assert_allclose(ot.reference_start(R0, INCLINATION), circular_start(), rtol=1e-15)
    with pytest.raises(ValueError, match="orbit_radius"):
        ot.reference_start(6_000e3)
    with pytest.raises(ValueError, match="inclination_rad"):
        ot.reference_start(R0, 4.0)


def test_the_sub_step_count_keeps_sub_steps_at_most_10_s():
    assert [ot.substeps_for(dt) for dt in (0.5, 10.0, 10.5, 40.0, 600.0)] == [1, 1, 2, 4, 60]
    assert ot.substeps_for(10.0) == ot.DEFAULT_SUBSTEPS
    with pytest.raises(ValueError, match="dt"):
        ot.substeps_for(0.0)
    with pytest.raises(ValueError, match="substeps"):
        ot.truth_work(0)


def test_a_work_array_too_small_for_the_sub_steps_is_refused():
    ref, states = ot.reference_start(R0), np.zeros((1, 6))
    with pytest.raises(ValueError, match="work"):
        ot.truth_step(
            ref, states, np.zeros((1, 3)), np.zeros(1), 0.0, True, 10.0, 2, ot.ATMOSPHERE,
            ot.truth_work(1),
        )  # fmt: skip
