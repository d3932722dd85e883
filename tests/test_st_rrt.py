"""Tube-ST-RRT* ("st-rrt"): the space-time search, its tube, the minimum-snap smoothing, the agent.

Independent truth: the bodies' positions come from the textbook closed-form CW solution typed in
below ([Curtis14] eq. 7.53), not from the library's matrix exponential; distances to circles and
convex polygons are computed here from those positions (point–circle, point–segment); edges are
checked against dense sampling of that motion; the env judges the mission.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents import make_agent
from agents.planners.motion import FieldMotion
from agents.planners.spacetime import SpaceTimeField
from agents.planners.st_rrt import STRRTParams, st_rrt_star
from agents.planners.tube import SmoothParams, build_tube, smooth_in_tube
from debris_gym.scenario import Body, Scenario

N = 1.1313666536110223e-3  # rad/s, 400 km LEO
DT = 10.0
MARGIN = 3.0  # m: what every body is grown by in these tests


def cw_position(state0: np.ndarray, t, n: float = N) -> np.ndarray:
    """Closed-form unforced CW position at ``t`` (s, a number or an array; 2D): [Curtis14]
    eq. 7.53, typed in here. Returns (2,) or (..., 2) positions (m)."""
    x0, y0, vx0, vy0 = state0
    s, c = np.sin(n * np.asarray(t)), np.cos(n * np.asarray(t))
    x = (4 - 3 * c) * x0 + s / n * vx0 + 2 / n * (1 - c) * vy0
    y = 6 * (s - n * t) * x0 + y0 - 2 / n * (1 - c) * vx0 + (4 * s - 3 * n * t) / n * vy0
    return np.stack([x, y], axis=-1)


def orbit_body(radius: float, rho: float, alpha: float, y_c: float, vertices=None) -> Body:
    """A body on the drift-free relative orbit x = ρ sin α, y = y_c + 2ρ cos α at t = 0."""
    pos = (rho * math.sin(alpha), y_c + 2 * rho * math.cos(alpha))
    vel = (rho * N * math.cos(alpha), -2 * rho * N * math.sin(alpha))
    return Body(pos, radius, vel, vertices)


def make_field() -> Scenario:
    """Two targets and six obstacles drifting across the line from the dock to the targets."""
    targets = (orbit_body(6.0, 60.0, 0.3, 320.0), orbit_body(5.0, 40.0, 2.0, -300.0))
    obstacles = (
        orbit_body(30.0, 120.0, 0.0, 150.0),
        orbit_body(25.0, 90.0, 1.5, 200.0),
        orbit_body(35.0, 150.0, 3.0, 80.0),
        orbit_body(20.0, 70.0, 4.0, -150.0),
        orbit_body(28.0, 110.0, 5.0, 250.0),
        orbit_body(15.0, 50.0, 0.8, -80.0, vertices=((15.0, 0.0), (-7.5, 12.99), (-7.5, -12.99))),
    )
    return Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0), targets=targets,
        obstacles=obstacles, mean_motion=N, dt=DT, max_accel=0.05, motion="cwh",
    )  # fmt: skip


SCEN = make_field()
STATES = np.array([[*b.position, *b.velocity] for b in SCEN.bodies])


def true_gaps(point: np.ndarray, t: float) -> np.ndarray:
    """Distance (m) from an LVLH point to every body's surface at time t, computed here: circles
    exactly, the polygon by point–segment distances to its edges turned through (spin − n)·t."""
    out = np.empty(len(SCEN.bodies))
    for b, body in enumerate(SCEN.bodies):
        centre = cw_position(STATES[b], t)
        if body.vertices is None:
            out[b] = np.linalg.norm(point - centre) - body.radius
            continue
        ang = -N * t  # an inertially fixed attitude turns at −n in LVLH
        rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
        verts = centre + np.asarray(body.vertices) @ rot.T
        dists = []
        for a, c in zip(verts, np.roll(verts, -1, axis=0), strict=True):
            s = np.clip(np.dot(point - a, c - a) / np.dot(c - a, c - a), 0.0, 1.0)
            dists.append(np.linalg.norm(point - (a + s * (c - a))))
        out[b] = min(dists)  # the points tested are outside (the planner keeps them out)
    return out


def plan(frame: int | None = 0, seed: int = 0, t0: float = 0.0, **params):
    """Plan from the dock to target ``frame``'s near side (or from target 0 to the dock)."""
    motion = FieldMotion(SCEN)
    field = SpaceTimeField(motion, t0, 3000.0, frame, np.full(len(SCEN.bodies), MARGIN))
    origin = np.zeros(2) if frame is None else cw_position(STATES[frame], t0)
    if frame is None:
        start = cw_position(STATES[0], t0) + np.array([0.0, 20.0])
        goal = np.zeros(2)
    else:
        start = -origin  # the dock, seen from the target
        goal = np.array([0.0, -(SCEN.bodies[frame].radius + MARGIN + 2.0)])
    p = STRRTParams(**{"sample_padding": 150.0, **params})
    result = st_rrt_star(field, start, goal, p, np.random.default_rng(seed))
    return field, result, start, goal, p


def frame_origin(frame: int | None, t: float) -> np.ndarray:
    return np.zeros(2) if frame is None else cw_position(STATES[frame], t)


# --- the search ---------------------------------------------------------------------------------


@pytest.mark.parametrize("frame", [0, 1, None])
def test_path_is_collision_free_against_the_moving_bodies_at_every_time_sample(frame):
    field, result, start, goal, _ = plan(frame)
    assert result.success
    times = np.arange(result.times[0], result.times[-1], 0.5)
    for t in times:
        rel = np.array([np.interp(t, result.times, result.positions[:, i]) for i in range(2)])
        gaps = true_gaps(rel + frame_origin(frame, t), t)
        assert gaps.min() >= MARGIN - 1e-6, (t, gaps.min())


@pytest.mark.parametrize("frame", [0, None])
def test_every_node_radius_is_at_most_the_true_clearance_at_its_time(frame):
    field, result, *_ = plan(frame)
    assert result.success
    for t, p, r in zip(result.times, result.positions, result.radii, strict=True):
        truth = true_gaps(p + frame_origin(frame, t), t) - MARGIN
        assert 0.0 <= r <= truth.min() + 1e-9
        # tight for circles: only the interpolation bound (≪ 1 m) and the polygon's circumcircle
        circles = [b for b, body in enumerate(SCEN.bodies) if body.vertices is None]
        if np.argmin(truth) in circles:
            assert r >= truth.min() - 0.05


def test_edges_go_forward_in_time_within_the_speed_limit():
    _, result, start, goal, p = plan(0)
    dt = np.diff(result.times)
    dp = np.linalg.norm(np.diff(result.positions, axis=0), axis=1)
    assert np.all(dt > 0)
    assert np.all(dp <= p.max_speed * dt * (1 + 1e-9))
    assert np.allclose(result.positions[0], start)


def test_goal_region_the_path_ends_at_the_goal_no_earlier_than_the_speed_allows():
    field, result, start, goal, p = plan(1)
    assert np.allclose(result.positions[-1], goal)
    assert result.arrival == result.times[-1]
    assert result.arrival >= field.t0 + np.linalg.norm(goal - start) / p.max_speed - 1e-9
    assert result.arrival <= field.t0 + p.horizon
    assert result.info["time_range"] >= result.arrival - field.t0  # a goal state was sampled there


def test_the_goal_time_range_grows_when_the_first_range_has_no_solution():
    # An initial range of exactly the least arrival time admits only the straight line at
    # full speed; a body in the way forces later goal states, so the range must grow.
    field, result, start, goal, p = plan(0, initial_range=1.0, batch_size=10)
    assert result.success
    least = np.linalg.norm(goal - start) / p.max_speed
    assert result.info["time_range"] > least * 1.0 + 1e-9


def test_the_same_seed_gives_the_same_path_and_another_seed_another():
    a = plan(0, seed=5)[1]
    b = plan(0, seed=5)[1]
    c = plan(0, seed=6)[1]
    assert np.array_equal(a.times, b.times) and np.array_equal(a.positions, b.positions)
    assert not (len(a.times) == len(c.times) and np.array_equal(a.positions, c.positions))


def test_a_walled_in_goal_fails_explicitly():
    # the goal inside a body at every time: no goal state exists
    motion = FieldMotion(SCEN)
    field = SpaceTimeField(motion, 0.0, 500.0, 0, np.full(len(SCEN.bodies), MARGIN))
    result = st_rrt_star(field, -cw_position(STATES[0], 0.0), np.zeros(2),
                         STRRTParams(max_iterations=50))  # fmt: skip
    assert not result.success and result.arrival == math.inf and len(result.times) == 1


# --- edges against dense sampling -----------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    p0=st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    p1=st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    t0=st.floats(0.0, 1500.0),
    span=st.floats(1.0, 400.0),
)
def test_edge_gap_is_never_more_than_the_sampled_truth_and_close_to_it(p0, p1, t0, span):
    field = SpaceTimeField(FieldMotion(SCEN), 0.0, 2000.0, None, np.full(len(SCEN.bodies), 0.0))
    p0, p1 = np.array(p0), np.array(p1)
    gap = field.edge_gap(p0, t0, p1, t0 + span)
    times = np.linspace(t0, t0 + span, 801)
    # circumscribed circles, exactly, from the typed-in motion, at every sample
    points = p0 + ((times - t0) / span)[:, None] * (p1 - p0)  # (T, 2)
    centres = np.stack([cw_position(s, times) for s in STATES], axis=1)  # (T, B, 2)
    radii = np.array([b.radius for b in SCEN.bodies])
    truth = float(np.min(np.linalg.norm(centres - points[:, None], axis=2) - radii))
    assert gap <= truth + 1e-6
    # the sampling misses at most the relative speed × half a sample interval
    rel_speed = np.linalg.norm(p1 - p0) / span + 1.0
    assert gap >= truth - rel_speed * span / 800 / 2 - 0.1


# --- tube and smoothing -----------------------------------------------------------------------


@pytest.mark.parametrize("frame", [0, 1])
def test_smoothed_trajectory_stays_in_its_tube_and_clear_of_the_bodies(frame):
    field, result, start, goal, _ = plan(frame)
    tube = build_tube(field, result.times, result.positions)
    traj = smooth_in_tube(tube, np.array([0.3, -0.2]), SCEN.max_accel)
    assert traj.success
    dist = np.linalg.norm(traj.positions - tube.centres, axis=1)
    assert np.all(dist <= tube.radii + 1e-9)
    assert np.allclose(traj.positions[0], start) and np.allclose(traj.positions[-3:], goal)
    for t, p, r, c in zip(tube.times, traj.positions, tube.radii, tube.centres, strict=True):
        gaps = true_gaps(p + frame_origin(frame, t), t)
        assert gaps.min() >= MARGIN - 1e-6
        assert r <= true_gaps(c + frame_origin(frame, t), t).min() - MARGIN + 1e-9
    assert np.allclose(np.diff(tube.times), DT)


def test_smoothing_prefers_the_snap_free_path_a_straight_tube_gives_a_straight_line():
    # wide balls along a straight line from rest to rest: the minimum-snap answer stays on the
    # line (by symmetry) and is monotone along it
    times = np.arange(0.0, 310.0, DT)
    centres = np.stack([np.clip(times, 0, 280) * 1.0, np.zeros_like(times)], 1)
    from agents.planners.tube import Tube

    tube = Tube(times, centres, np.full(len(times), 50.0), DT)
    traj = smooth_in_tube(tube, np.zeros(2), 0.05, SmoothParams())
    assert traj.success
    assert np.allclose(traj.positions[:, 1], 0.0, atol=1e-3)
    assert np.all(np.diff(traj.positions[:, 0]) >= -1e-6)
    accel = np.diff(traj.positions[:, 0], 2) / DT**2
    assert np.max(np.abs(accel)) <= 0.5 * 0.05 / math.sqrt(2) + 1e-6


# --- parameters ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"max_speed": 0.0}, "max_speed"),
        ({"steer_range": -1.0}, "steer_range"),
        ({"goal_probability": 0.0}, "goal_probability"),
        ({"goal_probability": 1.5}, "goal_probability"),
        ({"range_factor": 1.0}, "range_factor"),
        ({"initial_range": 0.5}, "initial_range"),
        ({"batch_size": 0}, "batch_size"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"improve_iterations": -1}, "improve_iterations"),
        ({"rewire_neighbours": 0}, "rewire_neighbours"),
        ({"connect_steps": 0}, "connect_steps"),
        ({"horizon": math.inf}, "horizon"),
        ({"sample_padding": -1.0}, "sample_padding"),
        ({"bounds_margin": math.nan}, "bounds_margin"),
    ],
)
def test_bad_planner_parameters_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        STRRTParams(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"w_snap": -1.0}, "w_snap"),
        ({"w_start": math.nan}, "w_start"),
        ({"w_spine": -0.1}, "w_spine"),
        ({"accel_fraction": 0.0}, "accel_fraction"),
        ({"facets": 3}, "facets"),
        ({"hold_steps": 2}, "hold_steps"),
        ({"max_iter": 0}, "max_iter"),
    ],
)
def test_bad_smoothing_parameters_raise_value_errors_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SmoothParams(**kwargs)


def test_bad_field_and_agent_arguments_raise_value_errors_naming_them():
    motion = FieldMotion(SCEN)
    with pytest.raises(ValueError, match="horizon"):
        SpaceTimeField(motion, 0.0, 0.0)
    with pytest.raises(ValueError, match="start_time"):
        SpaceTimeField(motion, -1.0, 100.0)
    with pytest.raises(ValueError, match="frame"):
        SpaceTimeField(motion, 0.0, 100.0, frame=99)
    with pytest.raises(ValueError, match="inflation"):
        SpaceTimeField(motion, 0.0, 100.0, inflation=np.zeros(3))
    with pytest.raises(ValueError, match="max_accel"):
        smooth_in_tube(build_tube(SpaceTimeField(motion, 0.0, 100.0), [0.0, 10.0],
                                  [[0.0, 0.0], [1.0, 0.0]]), np.zeros(2), 0.0)  # fmt: skip
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    for kwargs, name in (
        ({"seed": -1}, "seed"),
        ({"stall_steps": 0}, "stall_steps"),
        ({"retry_steps": 1.5}, "retry_steps"),
        ({"replan_distance": 0.0}, "replan_distance"),
    ):
        with pytest.raises(ValueError, match=name):
            make_agent("st-rrt", env, **kwargs)


# --- the agent ----------------------------------------------------------------------------------


def test_the_agent_flies_a_default_mission_to_success_without_contact_and_repeats_it():
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    outcomes = []
    for _ in range(2):
        agent = make_agent("st-rrt", env)
        obs, info = env.reset(seed=0)
        done, actions = False, []
        while not done:
            action, _ = agent.predict(obs)
            actions.append(action)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        outcomes.append((info["is_success"], info["collision"], np.array(actions)))
        assert agent.stats["plans"] >= 4  # one per leg: three targets and the dock
    assert outcomes[0][0] and not outcomes[0][1]
    assert np.array_equal(outcomes[0][2], outcomes[1][2])
