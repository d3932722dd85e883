"""Tests of the MPC tracker (agents.control), the A* planner (agents.planners.astar) and the
APF-MPC / A* baselines: prediction against the env's propagator, thrust bounds, closed-loop
behaviour in the env, keep-out constraints that matter, warm starts, and grid optimality against
Dijkstra."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

import debris_gym  # noqa: F401  (registers the IDs)
from agents import make_agent
from agents.control.mpc import MPCParams, MPCTracker
from agents.control.reference import PathReference, ReferenceParams
from agents.planners.astar import GridMap, astar_path
from agents.planners.mission import Goal
from agents.planners.paths import dejitter
from debris_gym.dynamics import discretize
from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Body, Scenario
from debris_gym.solvability import occupancy_grid
from tests.geometry_oracle import OracleField
from tests.helpers import flies_old_ids

N_MEAN = 1.1313666536110223e-3  # default LEO mean motion (rad/s)


def _body(position, radius) -> Body:
    return Body(position=tuple(map(float, position)), radius=float(radius), velocity=(0.0,) * 2)


def _field(obstacles=(), dim: int = 2, n: float = N_MEAN) -> Scenario:
    """A 1 km LEO field with one far-away target and the given circular obstacles."""
    zero = (0.0,) * dim
    target = Body(position=(-400.0,) * dim, radius=5.0, velocity=zero)
    obs = tuple(Body(position=tuple(p), radius=r, velocity=zero) for p, r in obstacles)
    return Scenario(
        dim=dim,
        bounds=((-500.0, 500.0),) * dim,
        dock=zero,
        targets=(target,),
        obstacles=obs,
        mean_motion=n,
        dt=10.0,
        max_accel=0.05,
    )


def _fly_line(scenario: Scenario, params: MPCParams, end=(400.0, 0.0), steps: int = 120):
    """Track the straight reference dock → ``end`` in the env; returns (env, infos, tracker)."""
    env = DebrisFieldEnv()
    env.reset(options={"scenario": scenario})
    tracker = MPCTracker(scenario, params, thrust_model="ball", chaser_radius=1.0)
    ref = PathReference(
        np.array([[0.0, 0.0], end]),
        max_accel=scenario.max_accel,
        dt=scenario.dt,
        params=ReferenceParams(end_speed=0.1),
        world_size=scenario.size,
    )
    infos, geom = [], OracleField(scenario)
    for _ in range(steps):
        state = env.chaser_state
        accel = tracker.command(state, *ref.horizon(state, tracker.N))
        sol = tracker.last_solution
        infos.append((sol, geom.signed_distance(sol.states[:, :2]).min()))
        *_, terminated, _, info = env.step(accel / scenario.max_accel)
        if terminated:
            break
    return env, info, infos, tracker


# --- the QP against the dynamics --------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
def test_prediction_matches_discretize_propagation(dim):
    scen = _field([((150.0,) * dim, 20.0)], dim=dim)
    tracker = MPCTracker(scen, chaser_radius=1.0)
    rng = np.random.default_rng(0)
    state = np.concatenate([rng.uniform(-50, 50, dim), rng.uniform(-1, 1, dim)])
    ref_pos = state[:dim] + np.outer(np.arange(1, 21) * 10.0, np.ones(dim))
    ref_vel = np.ones((20, dim))
    sol = tracker.solve(state, ref_pos, ref_vel)
    assert sol.ok
    model = discretize(scen.mean_motion, scen.dt, dim)
    x = state.copy()
    for k in range(tracker.N):
        x = model.step(x, sol.controls[k])
        np.testing.assert_allclose(sol.states[k], x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(tracker.predict(state, sol.controls), sol.states, atol=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("thrust_model", ["ball", "box"])
def test_thrust_bounds_hold_on_random_references(dim, thrust_model):
    scen = _field(dim=dim)
    tracker = MPCTracker(scen, MPCParams(keepout_per_step=0), thrust_model=thrust_model)
    rng = np.random.default_rng(1)
    a = scen.max_accel
    for _ in range(15):
        state = np.concatenate([rng.uniform(-300, 300, dim), rng.uniform(-3, 3, dim)])
        ref_pos = rng.uniform(-500, 500, (tracker.N, dim))  # wildly infeasible on purpose
        ref_vel = rng.uniform(-5, 5, (tracker.N, dim))
        sol = tracker.solve(state, ref_pos, ref_vel)
        assert sol.ok and np.all(np.isfinite(sol.controls))
        if thrust_model == "ball":
            assert np.linalg.norm(sol.controls, axis=1).max() <= a * (1 + 1e-12)
        else:
            assert np.abs(sol.controls).max() <= a * (1 + 1e-12)
        # a demanding reference saturates the engine: the bound is active, not slack
        assert np.abs(sol.controls).max() > 0.5 * a


def test_warm_start_needs_no_more_iterations():
    scen = _field()
    tracker = MPCTracker(scen, MPCParams(keepout_per_step=0))
    state = np.array([0.0, 0.0, 0.3, -0.2])
    ref_pos = np.outer(np.arange(1, 21) * 12.0, [1.0, 0.5])
    ref_vel = np.tile([1.2, 0.6], (20, 1))
    cold = tracker.solve(state, ref_pos, ref_vel)
    warm = tracker.solve(state, ref_pos, ref_vel, guess=cold.controls, dual_guess=cold.dual)
    assert cold.ok and warm.ok
    assert warm.iterations <= cold.iterations
    # the same optimum, to the solver tolerance (eps 1e-3 on the normalised problem)
    np.testing.assert_allclose(warm.controls, cold.controls, atol=0.02 * scen.max_accel)
    np.testing.assert_allclose(warm.states[:, :2], cold.states[:, :2], atol=0.5)


# --- closed loop in the env -------------------------------------------------------------------


def test_free_space_line_is_tracked_and_stops_at_the_end():
    scen = _field()
    env, info, infos, _ = _fly_line(scen, MPCParams(), steps=90)
    state = env.chaser_state
    assert not info["collision"]
    assert np.linalg.norm(state[:2] - [400.0, 0.0]) < 1.0
    assert np.linalg.norm(state[2:]) < 0.2 * env.config.capture_speed
    # it actually travelled at speed, not crept
    assert max(abs(sol.states[0, 2]) for sol, _ in infos) > 1.0


def test_keepout_constraints_keep_the_chaser_off_an_obstacle_in_the_way():
    obstacle = [((200.0, 5.0), 20.0)]  # straight across the reference line
    scen = _field(obstacle)
    params = MPCParams(keepout_margin=2.0)
    _, info, infos, tracker = _fly_line(scen, params)
    assert not info["collision"]
    assert info["min_clearance"] >= 2.0 - 0.1  # chaser surface to obstacle (m)
    # every predicted trajectory honoured the keep-out (up to solver tolerance)
    assert min(gap for _, gap in infos) >= 1.0 + 2.0 - 0.05
    assert tracker.stats["fallbacks"] == 0
    # the same reference without the constraints flies straight into the obstacle
    _, info_free, _, _ = _fly_line(scen, MPCParams(keepout_per_step=0))
    assert info_free["collision"]


# --- A* planner -------------------------------------------------------------------------------


def _dijkstra_cost(occ: np.ndarray, start, goal) -> float:
    """Shortest 8-connected path length (cells) without corner cutting, by scipy's Dijkstra."""
    nx, ny = occ.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, weights = [], [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            if dx == dy == 0:
                continue
            xs = np.arange(max(0, -dx), min(nx, nx - dx))
            ys = np.arange(max(0, -dy), min(ny, ny - dy))
            X, Y = np.meshgrid(xs, ys, indexing="ij")
            ok = ~occ[X, Y] & ~occ[X + dx, Y + dy] & ~occ[X + dx, Y] & ~occ[X, Y + dy]
            rows.append(idx[X, Y][ok])
            cols.append(idx[X + dx, Y + dy][ok])
            weights.append(np.full(ok.sum(), math.hypot(dx, dy)))
    graph = sp.csr_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
        shape=(nx * ny, nx * ny),
    )
    dist = dijkstra(graph, indices=idx[start])
    return float(dist[idx[goal]])


def test_astar_path_matches_dijkstra_and_is_collision_free():
    obstacles = [((0.0, 0.0), 60.0), ((-150.0, 120.0), 40.0), ((130.0, -90.0), 50.0)]
    scen = _field(obstacles)
    start, goal = np.array([-250.0, -200.0]), np.array([240.0, 210.0])
    result = astar_path(scen, start, goal, cell=8.0, inflate=4.0)
    assert result.success
    info = result.info
    reference = _dijkstra_cost(info["occupancy"], info["start_cell"], info["goal_cell"])
    assert info["grid_cost"] == pytest.approx(reference * 8.0, rel=1e-12)
    w = result.waypoints
    np.testing.assert_allclose(w[0], start)
    np.testing.assert_allclose(w[-1], goal)
    assert OracleField(scen, inflate=4.0).first_hit(w) == -1
    straight = np.linalg.norm(goal - start)
    assert straight <= result.cost <= info["grid_cost"] + 2 * 8.0


def test_astar_path_reports_failure_when_the_goal_is_walled_in():
    ring = [((60.0 * math.cos(t), 60.0 * math.sin(t)), 30.0) for t in np.linspace(0, 2 * np.pi, 9)]
    scen = _field(ring[:-1])
    result = astar_path(scen, np.array([-300.0, 0.0]), np.array([0.0, 0.0]), cell=8.0, inflate=3.0)
    assert not result.success
    assert result.info["reason"] == "no_path"


def test_grid_map_agrees_with_occupancy_grid():
    scen = _field([((50.0, -40.0), 30.0), ((-200.0, 100.0), 12.0)])
    grid = GridMap(scen, 10.0)
    occ = grid.occupancy(grid.body_inflation(3.0), conservative=False)
    reference, _ = occupancy_grid(scen, 3.0, 10.0)
    np.testing.assert_array_equal(occ, reference)


# --- the baselines ----------------------------------------------------------------------------


def test_dejitter_removes_back_and_forth_but_keeps_the_course():
    forward = np.stack([np.arange(0.0, 50.0, 2.0), np.zeros(25)], axis=1)
    zigzag = np.array([[50.0 + 0.3 * k, 2.0 * (k % 2)] for k in range(20)])  # ±2 m chatter
    tail = np.stack([np.arange(56.0, 100.0, 2.0), np.zeros(22)], axis=1)
    path = np.vstack([forward, zigzag, tail])
    out = dejitter(path, reach=10.0, clear=lambda a, b: True)
    np.testing.assert_array_equal(out[0], path[0])
    np.testing.assert_array_equal(out[-1], path[-1])
    assert len(out) < 0.4 * len(path)
    assert np.all(np.diff(out[:, 0]) > 0)  # monotone progress: no back-and-forth left
    assert np.linalg.norm(np.diff(out, axis=0), axis=1).max() <= 10.0
    # a hop the collision test refuses is not taken
    blocked = dejitter(path, reach=10.0, clear=lambda a, b: False)
    np.testing.assert_array_equal(blocked, path)


def test_apf_mpc_completes_a_stalled_apf_path_with_astar():
    # touching circles, clear of the dock at the origin (a pinned field's bodies must not
    # overlap or cover the dock): a local minimum in front
    wall = [((40.0, y), 20.0) for y in (-80.0, -40.0, 0.0, 40.0, 80.0)]
    scen = _field(wall)
    env = DebrisFieldEnv()
    env.reset(options={"scenario": scen, "chaser_state": [-150.0, 0.0, 0.0, 0.0]})
    agent = make_agent("apf-mpc", env)
    agent.plan(scen)
    goal = Goal("dock", None, np.array([150.0, 0.0]), np.array([150.0, 0.0]))
    result = agent.plan_path(np.array([-150.0, 0.0]), goal)
    assert result.success and result.info["fallback"] == "astar"
    assert agent.stats["apf_stalls"] == 1 and agent.stats["astar_fallbacks"] == 1
    np.testing.assert_allclose(result.waypoints[-1], [150.0, 0.0])
    assert OracleField(scen, inflate=1.0).first_hit(result.waypoints) == -1


@flies_old_ids
@pytest.mark.parametrize("name", ["apf-mpc", "astar"])
def test_baselines_fly_seeded_missions_without_collision(name):
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    agent = make_agent(name, env)
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        while True:
            action, _ = agent.predict(obs)
            assert np.all(np.isfinite(action)) and np.abs(action).max() <= 1.0 + 1e-9
            obs, _, terminated, truncated, info = env.step(action)
            assert np.all(np.isfinite(obs))
            if terminated or truncated:
                break
        assert not info["collision"]
        assert info["is_success"], f"{name} failed seed {seed}"
        assert agent.tracker.stats["fallbacks"] == 0


@flies_old_ids
def test_predict_single_and_batched():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    agent = make_agent("apf-mpc", env)
    obs, _ = env.reset(seed=5)
    action, state = agent.predict(obs)
    assert action.shape == env.action_space.shape and state is None
    obs, *_ = env.step(action)
    batched, _ = agent.predict(obs[None])
    assert batched.shape == (1, *env.action_space.shape)
    assert np.all(np.isfinite(batched))


@pytest.mark.parametrize("name", ["astar", "st-rrt"])
def test_a_tracking_agent_names_its_missing_tracker_before_it_first_acts(name):
    """The tracker is built by the episode's first predict(): before it, asking for it raises
    a RuntimeError that says so; after it, the tracker is there."""
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    agent = make_agent(name, env)
    with pytest.raises(RuntimeError, match="no tracker before it first acts"):
        _ = agent.tracker
    obs, _ = env.reset(seed=3)
    agent.predict(obs)
    assert isinstance(agent.tracker, MPCTracker)
