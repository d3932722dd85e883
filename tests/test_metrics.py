"""[APF-MPC] Table I metrics on trajectories whose answers can be worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.experiments.evaluation.metrics import (
    fuel,
    max_acceleration_deceleration,
    path_length,
    smoothness,
    total_curvature,
    trajectory_metrics,
)


def constant_accel(a: np.ndarray, v0: np.ndarray, dt: float, steps: int):
    """Exact double-integrator samples under constant acceleration a from the origin."""
    t = dt * np.arange(steps + 1)[:, None]
    pos = v0 * t + 0.5 * a * t**2
    vel = v0 + a * t
    return pos, vel, np.tile(a, (steps, 1))


def test_straight_line_at_constant_speed():
    dt, steps, v = 2.0, 10, np.array([3.0, 4.0])  # 5 m/s
    pos, vel, acc = constant_accel(np.zeros(2), v, dt, steps)
    m = trajectory_metrics(pos, vel, acc, dt)
    assert m.path_length == pytest.approx(5.0 * dt * steps)
    assert m.fuel == 0.0
    assert m.smoothness == 0.0
    assert m.time == pytest.approx(20.0)
    assert m.max_acceleration == 0.0 and m.max_deceleration == 0.0
    assert m.waypoints == steps
    assert m.total_curvature == pytest.approx(0.0, abs=1e-12)


def test_constant_acceleration_from_rest():
    dt, steps, a = 0.5, 8, np.array([0.0, 0.3])
    pos, vel, acc = constant_accel(a, np.zeros(2), dt, steps)
    m = trajectory_metrics(pos, vel, acc, dt)
    total_t = dt * steps
    assert m.path_length == pytest.approx(0.5 * 0.3 * total_t**2)
    assert m.fuel == pytest.approx(0.3 * total_t)  # Δv = |a| t
    assert m.max_acceleration == pytest.approx(0.3)
    assert m.max_deceleration == 0.0
    assert m.smoothness == 0.0
    assert m.total_curvature == pytest.approx(0.0, abs=1e-12)


def test_braking_is_deceleration():
    dt, steps, a = 1.0, 5, np.array([-0.2, 0.0, 0.0])
    pos, vel, acc = constant_accel(a, np.array([1.0, 0.0, 0.0]), dt, steps)  # stops at t = 5
    acc_max, dec_max = max_acceleration_deceleration(vel, acc)
    assert acc_max == 0.0
    assert dec_max == pytest.approx(0.2)


def test_square_lap_turns_two_pi_in_2d_and_3d():
    # Start mid-side so that all four corners are turned: 4 × π/2.
    corners = np.array([[1, 0], [2, 0], [2, 2], [0, 2], [0, 0], [1, 0]], dtype=float)
    pts = np.concatenate([np.linspace(a, b, 5)[:-1] for a, b in zip(corners, corners[1:])])
    pts = np.vstack([pts, corners[-1]])
    assert total_curvature(pts) == pytest.approx(2 * math.pi)
    assert path_length(pts) == pytest.approx(8.0)
    pts3 = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1]])  # the same in x–z
    assert total_curvature(pts3) == pytest.approx(2 * math.pi)


def test_curvature_counts_absolute_turns_and_skips_standstill():
    zigzag = np.array([[0, 0], [1, 0], [1, 0], [2, 1], [3, 0]], dtype=float)  # +45°, −90°
    assert total_curvature(zigzag) == pytest.approx(math.pi / 4 + math.pi / 2)
    reverse = np.array([[0, 0], [1, 0], [0, 0]], dtype=float)
    assert total_curvature(reverse) == pytest.approx(math.pi)


def test_smoothness_is_mean_squared_command_change():
    u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    # changes: (1,0), (0,0), (0,2) → squared norms 1, 0, 4 → mean 5/3
    assert smoothness(u) == pytest.approx(5.0 / 3.0)
    assert smoothness(u[:1]) == 0.0


def test_fuel_follows_the_thrust_model():
    u = np.array([[3.0, 4.0], [0.0, -1.0]])
    assert fuel(u, 2.0, "ball") == pytest.approx((5.0 + 1.0) * 2.0)
    assert fuel(u, 2.0, "box") == pytest.approx((7.0 + 1.0) * 2.0)


def test_standstill_and_bad_input():
    pos = np.zeros((4, 2))
    m = trajectory_metrics(pos, np.zeros((4, 2)), np.zeros((3, 2)), 1.0)
    assert (m.path_length, m.fuel, m.total_curvature, m.waypoints) == (0.0, 0.0, 0.0, 3)
    with pytest.raises(ValueError, match="dt"):
        trajectory_metrics(pos, np.zeros((4, 2)), np.zeros((3, 2)), 0.0)
    with pytest.raises(ValueError, match="velocities"):
        trajectory_metrics(pos, np.zeros((3, 2)), np.zeros((3, 2)), 1.0)
    with pytest.raises(ValueError, match="positions"):
        path_length(np.zeros((3, 4)))
