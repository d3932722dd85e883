"""Tests of the APF planners (agents.planners.apf, agents.planners.rrt) and agents: forces
against hand values and an independent finite-difference gradient, the planners in open,
one-obstacle and trap fields, and the agents flying the envs (default fields and pinned trap
fields)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import agents
import debris_gym  # noqa: F401  (registers the IDs)
from agents.planners.apf import (
    APFParams,
    apf_path,
    attractive_force,
    is_local_minimum,
    repulsive_field,
    total_force,
)
from agents.planners.rrt import apf_rrt_path
from debris_gym.config import DEFAULT_ORBIT_RADIUS
from debris_gym.dynamics import mean_motion
from debris_gym.generators import paper_field
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Body, Scenario
from tests.geometry_oracle import OracleField
from tests.helpers import flies_old_ids

# the agents fly the frozen-world default field (v0) too, as docs/baselines.md does
pytestmark = flies_old_ids

# --------------------------------------------------------------------------------------------------
# fields
# --------------------------------------------------------------------------------------------------

N_LEO = mean_motion(DEFAULT_ORBIT_RADIUS)  # the envs' default orbit, as the envs compute it


def _field(obstacles, dim=2, target=(400.0, 400.0), target_radius=5.0, n=N_LEO) -> Scenario:
    pad = (0.0,) * (dim - 2)
    return Scenario(
        dim=dim,
        bounds=((-500.0, 500.0),) * dim,
        dock=(0.0,) * dim,
        targets=(Body(position=tuple(target) + pad, radius=target_radius),),
        obstacles=tuple(obstacles),
        mean_motion=n,
        dt=10.0,
        max_accel=0.05,
        name="test",
    )


def _circle(x, y, r, dim=2) -> Body:
    return Body(position=(x, y) + (0.0,) * (dim - 2), radius=r)


def _cup(dim=2, target_x=15.0, target_y=260.0, half=60.0, r=9.0) -> Scenario:
    """A U of touching circles opening toward the dock, the target right behind its bottom: the
    straight descent from the dock runs into the cup and stops there. (Touching, not
    overlapping: a pinned scenario's bodies must not overlap.)"""
    wall_y, arm = 200.0, 60.0
    xs = np.arange(-half, half + 1e-9, 2.0 * r)
    bodies = [_circle(float(x), wall_y, r, dim) for x in xs]
    for y in np.arange(wall_y - 2.0 * r, wall_y - arm - 1e-9, -2.0 * r):
        for x in (xs[0], xs[-1]):
            bodies.append(_circle(float(x), float(y), r, dim))
    return _field(bodies, dim=dim, target=(target_x, target_y))


def _dense_clearance(scenario: Scenario, waypoints: np.ndarray, inflate: float) -> float:
    """Smallest clearance (m) to the inflated bodies along the polyline, sampled every 0.1 m."""
    geometry = OracleField(scenario)
    pieces = [waypoints[:1]]
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        k = max(2, math.ceil(float(np.linalg.norm(b - a)) / 0.1))
        pieces.append(a + (b - a) * np.linspace(0.0, 1.0, k)[1:, None])
    return float((geometry.signed_distance(np.concatenate(pieces)) - inflate).min())


# --------------------------------------------------------------------------------------------------
# forces
# --------------------------------------------------------------------------------------------------


def test_forces_match_hand_computed_values():
    params = APFParams(k_att=2e-3, d_star=10.0, k_rep=24.0, d0=60.0, margin=0.0)
    geometry = FieldGeometry(_field([_circle(0.0, 0.0, 10.0)]))
    # repulsion: clearance 10 m → η(1/10 − 1/60)/10² = 24 · (1/12) / 100 = 0.02 m/s², along +x
    f = repulsive_field(np.array([20.0, 0.0]), geometry, params)[1]
    np.testing.assert_allclose(f, [0.02, 0.0], atol=1e-12)
    # inflate and margin shrink the clearance: 10 − 3 − 2 = 5 m → 24 (1/5 − 1/60)/25 = 0.176
    p2 = APFParams(k_att=2e-3, d_star=10.0, k_rep=24.0, d0=60.0, margin=2.0)
    np.testing.assert_allclose(
        repulsive_field(np.array([0.0, 20.0]), geometry, p2, inflate=3.0)[1],
        [0.0, 0.176],
        rtol=1e-12,
    )
    # beyond d0, or ignored: nothing (body 1 is the obstacle; body 0 the far target)
    assert not repulsive_field(np.array([71.0, 0.0]), geometry, params)[1].any()
    assert not repulsive_field(np.array([20.0, 0.0]), geometry, params, ignore=(1,))[1].any()
    # attraction: quadratic inside d*, conic (magnitude ζd* = 0.02) beyond
    np.testing.assert_allclose(
        attractive_force(np.array([3.0, 4.0]), np.zeros(2), params), [-0.006, -0.008]
    )
    far = attractive_force(np.array([20.0, 0.0]), np.array([20.0, 100.0]), params)
    np.testing.assert_allclose(far, [0.0, 0.02], atol=1e-15)
    x, goal = np.array([20.0, 0.0]), np.array([20.0, 100.0])
    total, f_att, f_rep = total_force(x, goal, geometry, params)
    np.testing.assert_allclose(total, f_att + f_rep)
    np.testing.assert_allclose(f_rep, [0.02, 0.0], atol=1e-12)


def _polygon_distance(p: np.ndarray, verts: np.ndarray) -> float:
    """Distance from an outside point to a polygon's boundary (min over edges)."""
    best = math.inf
    for a, b in zip(verts, np.roll(verts, -1, axis=0)):
        t = min(1.0, max(0.0, float((p - a) @ (b - a)) / float((b - a) @ (b - a))))
        best = min(best, float(np.linalg.norm(p - a - t * (b - a))))
    return best


def _potential(x, goal, bodies, params, inflate, shield=0.0) -> float:
    """[Choset05] eq. 4.2-4.6 written out independently of agents.planners.apf."""
    rho = float(np.linalg.norm(x - goal))
    if rho <= params.d_star:
        u_att = 0.5 * params.k_att * rho**2
    else:
        u_att = params.k_att * params.d_star * rho - 0.5 * params.k_att * params.d_star**2
    u_rep = 0.0
    for body in bodies:
        if body.vertices is None:
            gap = float(np.linalg.norm(x - np.asarray(body.position))) - body.radius
        else:
            verts = np.asarray(body.vertices) + np.asarray(body.position)
            gap = _polygon_distance(x, verts)
        d = gap - inflate - params.margin
        if d <= params.d0:
            u_rep += 0.5 * params.k_rep * (1.0 / d - 1.0 / params.d0) ** 2
    if shield:
        u_rep *= rho**2 / (rho**2 + shield**2)
    return u_att + u_rep


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("shield", [0.0, 30.0])
def test_total_force_is_minus_the_finite_difference_gradient(dim, shield):
    rng = np.random.default_rng(3)
    obstacles = [_circle(0.0, 0.0, 10.0, dim), _circle(45.0, 10.0, 6.0, dim)]
    if dim == 2:
        square = ((8.0, 0.0), (0.0, 8.0), (-8.0, 0.0), (0.0, -8.0))
        obstacles.append(Body(position=(10.0, 45.0), radius=8.0, vertices=square))
    scenario = _field(obstacles, dim=dim)
    geometry = FieldGeometry(scenario)
    params = APFParams(k_att=2e-3, d_star=30.0, k_rep=24.0, d0=40.0, margin=2.0, goal_shield=shield)
    goal = np.array([60.0, 70.0] + [5.0] * (dim - 2))
    bodies = scenario.bodies
    checked = 0
    while checked < 12:
        x = rng.uniform(-30.0, 70.0, size=dim)
        if dim == 3:
            x[2] = rng.uniform(-10.0, 10.0)
        gaps = geometry.signed_distance(x) - 1.0 - params.margin
        if gaps.min() < 2.0:  # keep off the surfaces (and off polygon corners' kinks)
            continue
        force = total_force(x, goal, geometry, params, inflate=1.0)[0]
        h = 1e-4
        grad = np.array(
            [
                (
                    _potential(x + h * e, goal, bodies, params, 1.0, shield)
                    - _potential(x - h * e, goal, bodies, params, 1.0, shield)
                )
                / (2 * h)
                for e in np.eye(dim)
            ]
        )
        np.testing.assert_allclose(force, -grad, rtol=1e-5, atol=1e-9)
        checked += 1


def test_local_minimum_test_is_seed_003_eq_14():
    params = APFParams()
    f_att = np.array([1.0, 0.0])
    assert is_local_minimum(f_att, np.array([-0.9, 0.05]), params)
    assert not is_local_minimum(f_att, np.array([-0.3, 0.0]), params)  # unbalanced
    assert not is_local_minimum(f_att, np.array([-0.5, 0.8]), params)  # not opposed
    assert not is_local_minimum(np.zeros(2), np.array([-1.0, 0.0]), params)


def test_params_validate_and_paper_values():
    with pytest.raises(ValueError, match="d0"):
        APFParams(d0=-1.0)
    paper = APFParams.paper()
    assert (paper.step_size, paper.max_steps, paper.d0) == (0.01, 400, 1.0)
    assert not paper.normalized_step


# --------------------------------------------------------------------------------------------------
# planners
# --------------------------------------------------------------------------------------------------


def test_apf_path_reaches_the_goal_in_an_open_field(capsys):
    scenario = _field([])
    start, goal = np.array([0.0, 0.0]), np.array([300.0, -200.0])
    result = apf_path(scenario, start, goal, inflate=1.0)
    assert result.success and not result.info["stalled"]
    np.testing.assert_array_equal(result.waypoints[0], [0.0, 0.0])
    np.testing.assert_array_equal(result.waypoints[-1], goal)
    assert result.cost == pytest.approx(math.hypot(300.0, 200.0), rel=1e-6)
    np.testing.assert_array_equal(start, [0.0, 0.0])  # inputs untouched
    assert capsys.readouterr().out == ""  # silent


def test_apf_path_bends_round_an_obstacle_without_entering_it():
    scenario = _field([_circle(150.0, 0.0, 25.0)])
    start, goal = np.array([0.0, 0.0]), np.array([300.0, 5.0])
    result = apf_path(scenario, start, goal, inflate=1.0)
    assert result.success
    assert _dense_clearance(scenario, result.waypoints, 1.0) > 0.0
    assert result.cost > float(np.linalg.norm(goal - start)) + 1.0  # it did bend
    assert np.abs(result.waypoints[:, 1]).max() > 25.0


def test_apf_path_stalls_in_a_trap_and_apf_rrt_escapes():
    scenario = _cup()
    start = np.zeros(2)
    goal = np.array([15.0, 260.0 - 5.0 - 1.0 - 2.5])  # the target's approach point (body 0)
    plain = apf_path(scenario, start, goal, inflate=1.0, ignore=(0,))
    assert not plain.success and plain.info["stalled"]
    stall = plain.info["stall_point"]
    assert abs(stall[0]) < 60.0 and 140.0 < stall[1] < 190.0  # inside the cup

    escaped = apf_rrt_path(
        scenario, start, goal, inflate=1.0, ignore=(0,), rng=np.random.default_rng(7)
    )
    assert escaped.success and escaped.info["escapes"] >= 1
    np.testing.assert_array_equal(escaped.waypoints[0], start)
    np.testing.assert_array_equal(escaped.waypoints[-1], goal)
    assert _dense_clearance(scenario, escaped.waypoints, 1.0) > 0.0
    again = apf_rrt_path(
        scenario, start, goal, inflate=1.0, ignore=(0,), rng=np.random.default_rng(7)
    )
    np.testing.assert_array_equal(again.waypoints, escaped.waypoints)  # seeded


def test_paper_parameters_plan_seed_000_world_within_400_steps():
    scenario = paper_field()
    dock = np.asarray(scenario.dock)
    here = dock
    for i in (3, 2, 1, 0):  # every leg of the paper's tour, then home
        centre = np.asarray(scenario.targets[i].position)
        goal = centre + (here - centre) / np.linalg.norm(here - centre) * 0.5
        result = apf_path(scenario, here, goal, APFParams.paper(), inflate=0.1, ignore=(i,))
        assert result.success and result.info["steps"] <= 400
        assert _dense_clearance(scenario, result.waypoints, 0.1) > 0.0
        here = goal
    assert apf_path(scenario, here, dock, APFParams.paper(), inflate=0.1).success


# --------------------------------------------------------------------------------------------------
# agents
# --------------------------------------------------------------------------------------------------


def _fly(agent, env, seed=None, scenario=None):
    options = None if scenario is None else {"scenario": scenario}
    obs, info = env.reset(seed=seed, options=options)
    done = False
    while not done:
        action, _ = agent.predict(obs)
        assert action.shape == env.action_space.shape and np.all(np.isfinite(action))
        assert np.all(np.abs(action) <= 1.0 + 1e-6)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info


@pytest.mark.parametrize("name", ["apf", "apf-rrt"])
def test_agents_fly_the_default_field(name):
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    agent = agents.make_agent(name, env)
    infos = [_fly(agent, env, seed=s) for s in range(5)]
    assert not any(i["collision"] or i["out_of_bounds"] for i in infos)
    assert sum(i["is_success"] for i in infos) >= 4  # one miss tolerated; rates: docs/baselines.md


@pytest.mark.parametrize(
    ("env_id", "seed"), [("DebrisGym/Rendezvous3D-v0", 0), ("DebrisGym/PaperField2D-v0", 0)]
)
def test_apf_agent_scales_to_3d_and_the_paper_world(env_id, seed):
    env = gym.make(env_id)
    info = _fly(agents.make_agent("apf", env), env, seed=seed)
    assert info["is_success"] and not info["collision"]


def test_apf_rrt_agent_escapes_traps_where_apf_stalls():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    traps = [_cup(), _cup(target_x=-20.0), _cup(target_x=30.0, half=80.0)]
    plain, escape = agents.make_agent("apf", env), agents.make_agent("apf-rrt", env)
    wins = {"apf": 0, "apf-rrt": 0}
    for scenario in traps:
        for name, agent in (("apf", plain), ("apf-rrt", escape)):
            info = _fly(agent, env, scenario=scenario)
            assert not info["collision"]
            wins[name] += info["is_success"]
        assert escape.escapes >= 1
    assert wins["apf-rrt"] >= wins["apf"]
    assert wins["apf-rrt"] == len(traps)  # every cup is escaped (plain APF stops inside)


def test_apf_rrt_agent_repeats_its_episode_exactly():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    agent = agents.make_agent("apf-rrt", env, seed=3)
    trails = []
    for _ in range(2):
        _fly(agent, env, scenario=_cup(target_x=-20.0))
        trails.append(env.unwrapped.trail.copy())
    np.testing.assert_array_equal(trails[0], trails[1])


def test_predict_accepts_single_and_batched_observations():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    obs, _ = env.reset(seed=1)
    agent = agents.make_agent("apf", env)
    single, state = agent.predict(obs)
    batched, _ = agent.predict(obs[None])
    assert single.shape == (2,) and batched.shape == (1, 2) and state is None
    np.testing.assert_allclose(batched[0], single)
