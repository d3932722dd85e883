"""Prioritised space-time planning: an "st-rrt" chaser plans around the plans its teammates
ahead of it have shared, as moving spheres.

Independent truth: the teammate's track is a straight line typed in here, and both tracks are
compared by sampling them densely (linear interpolation of the plan's nodes, of the
trajectory's samples), not through the planner's own clearance; the env judges the missions.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("pettingzoo")

from agents import make_agent
from agents.control.mpc import MPCParams
from agents.planners.motion import FieldMotion
from agents.planners.spacetime import SpaceTimeField
from agents.planners.st_rrt import STRRTParams, st_rrt_star
from agents.planners.teammates import MovingSpheres
from agents.policies.chaser_view import ChaserView, TeamPlans
from agents.policies.team import TeamOfSingles, start_episode
from debris_gym import swarm
from debris_gym.scenario import Body, Scenario

N = 1.1313666536110223e-3  # rad/s, 400 km LEO
DT = 10.0
R_MATE = 1.0  # m: a teammate's sphere, r_col − chaser_radius with the default r_col = 2 m
CHASER = 1.0  # m: the chaser's radius
SEPARATION = R_MATE + CHASER  # m: centre distance at or below which the two collide
GROW = 3.0  # m: what the planner grows the teammate by (chaser radius + 2 m margin)


def empty_field(max_accel: float = 0.05, dt: float = DT) -> Scenario:
    """A frozen 2D field whose one body (a target) is far from every test's paths."""
    return Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, -400.0),
        targets=(Body((420.0, 420.0), 5.0, (0.0, 0.0)),), obstacles=(), mean_motion=N, dt=dt,
        max_accel=max_accel,
    )  # fmt: skip


def straight_track(p0: np.ndarray, velocity: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(len(times), dim) positions of a constant-velocity track (m)."""
    return np.asarray(p0, float) + np.asarray(times, float)[:, None] * np.asarray(velocity, float)


def sampled(times: np.ndarray, knots: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Piecewise-linear positions through ``points`` at ``knots``, at ``times`` (held after)."""
    return np.stack([np.interp(times, knots, points[:, i]) for i in range(points.shape[1])], -1)


PARAMS = STRRTParams(
    max_speed=1.0, steer_range=60.0, horizon=1000.0, sample_padding=100.0, bounds_margin=1.0
)


def plan(start, goal, mate: MovingSpheres | None, seed: int):
    field = SpaceTimeField(
        FieldMotion(empty_field()), 0.0, PARAMS.horizon, inflation=np.zeros(1), movers=mate,
        mover_inflation=GROW, mover_thrust=0.05,
    )  # fmt: skip
    return st_rrt_star(field, start, goal, PARAMS, np.random.default_rng(seed))


def closest(result, p0: np.ndarray, velocity: np.ndarray) -> float:
    """The least distance (m) between the plan and the straight track, sampled every 0.1 s."""
    times = np.arange(result.times[0], result.times[-1], 0.1)
    mine = sampled(times, result.times, result.positions)
    return float(np.linalg.norm(mine - straight_track(p0, velocity, times), axis=1).min())


def test_a_plan_keeps_clear_of_a_teammate_crossing_its_straight_line_at_the_same_time():
    """Chaser 1 flies (−150, 0) → (150, 0) at 1 m/s at best; chaser 0's plan crosses the
    origin northward at 1 m/s when chaser 1's straight line does, at t = 150 s."""
    start, goal = np.array([-150.0, 0.0]), np.array([150.0, 0.0])
    p0, velocity = np.array([0.0, -150.0]), np.array([0.0, 1.0])
    line = straight_track(start, (goal - start) / 300.0, np.array([150.0]))
    assert np.allclose(line, straight_track(p0, velocity, np.array([150.0])))  # they meet
    mate = MovingSpheres(straight_track(p0, velocity, DT * np.arange(101))[None], [R_MATE])
    blind, aware = plan(start, goal, None, seed=0), plan(start, goal, mate, seed=0)
    assert blind.success and aware.success
    assert closest(blind, p0, velocity) < SEPARATION  # it flies into the teammate
    assert closest(aware, p0, velocity) >= SEPARATION
    assert closest(aware, p0, velocity) >= R_MATE + GROW - 1e-6  # and keeps its margin


@settings(max_examples=12, deadline=None)
@given(
    angle=st.floats(0.3, np.pi - 0.3),
    speed=st.floats(0.2, 1.0),
    meet=st.floats(80.0, 220.0),
    radius=st.floats(0.5, 15.0),
    seed=st.integers(0, 2**16),
)
def test_a_plan_around_any_crossing_track_keeps_the_sphere_clear(angle, speed, meet, radius, seed):
    """Tracks crossing the straight line at its middle at ``meet`` seconds, from any side at
    any speed: wherever the plan goes, it keeps the grown sphere clear at every instant."""
    start, goal = np.array([-150.0, 0.0]), np.array([150.0, 0.0])
    velocity = speed * np.array([np.cos(angle), np.sin(angle)])
    p0 = -meet * velocity  # at the origin at t = meet
    mate = MovingSpheres(straight_track(p0, velocity, DT * np.arange(101))[None], [radius])
    result = plan(start, goal, mate, seed)
    assert result.success
    assert closest(result, p0, velocity) >= radius + GROW - 1e-6


def test_movers_must_cover_the_planning_window_and_the_switch_is_a_bool():
    short = MovingSpheres(np.zeros((1, 5, 2)), [1.0])
    with pytest.raises(ValueError, match="cover the window"):
        SpaceTimeField(FieldMotion(empty_field()), 0.0, 100.0, movers=short)
    env, _ = crossing_swarm()
    with pytest.raises(ValueError, match="teammates must be True or False"):
        make_agent("st-rrt", ChaserView(env.core, 1), teammates="yes")


# --- the agent on a swarm -------------------------------------------------------------------


def crossing_swarm() -> tuple[object, Scenario]:
    """Two chasers in an empty frozen field: chaser 1 flies north from (0, −200) to a target
    at (0, 230); chaser 0 is placed where a test wants it."""
    env = swarm.make(
        "DebrisGym/Swarm2D-Easy-v0", assignment="given", debris_motion="frozen", n_obstacles=0
    )
    cfg = env.core.config
    field = Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, -400.0),
        targets=(Body((420.0, 420.0), 5.0, (0.0, 0.0)), Body((0.0, 230.0), 5.0, (0.0, 0.0))),
        obstacles=(), mean_motion=N, dt=cfg.dt, max_accel=cfg.max_accel,
    )  # fmt: skip
    return env, field


def collision_distance(env) -> float:
    """The centre distance (m) at or below which two chasers of ``env`` collide."""
    r_col = env.core.swarm.r_col
    return float(2.0 * env.core.config.chaser_radius if r_col is None else r_col)


def first_trajectory(env, field, chaser0: np.ndarray, plans: TeamPlans, **params):
    """Chaser 1's first trajectory (times, LVLH positions) planned by "st-rrt" on its view."""
    starts = np.array([chaser0, [0.0, -200.0, 0.0, 0.0]])
    observations, _ = env.reset(
        seed=0, options={"scenario": field, "chaser_state": starts, "assignment": [[0], [1]]}
    )
    agent = make_agent("st-rrt", ChaserView(env.core, 1, plans=plans), **params)
    agent.predict(observations["chaser_1"])
    return agent.trajectory_log[0]


def test_an_st_rrt_chaser_plans_around_the_plan_a_teammate_ahead_shared():
    """Chaser 0's shared plan (typed in here: straight east at 0.4 m/s) crosses chaser 1's
    blind trajectory where and when that trajectory crosses y = 0; planning around the
    teammates ahead, chaser 1's trajectory keeps clear of it at every sampled instant."""
    env, field = crossing_swarm()
    dt = field.dt
    none = TeamPlans(2)
    times, path = first_trajectory(env, field, np.array([300.0, 300.0, 0.0, 0.0]), none,
                                   teammates=False)  # fmt: skip
    i = int(np.flatnonzero(path[:-1, 1] * path[1:, 1] <= 0.0)[0])  # crosses y = 0
    f = -path[i, 1] / (path[i + 1, 1] - path[i, 1])
    t_cross, x_cross = (
        times[i] + f * (times[i + 1] - times[i]),
        path[i, 0] + f * (path[i + 1, 0] - path[i, 0]),
    )
    velocity = np.array([0.4, 0.0])
    steps = np.arange(121)
    track = straight_track([x_cross - 0.4 * t_cross, 0.0], velocity, dt * steps)
    shared = np.hstack([track, np.tile(velocity, (len(steps), 1))])  # (P + 1, 4) states
    plans = TeamPlans(2)
    plans.post(0, (0.0, shared))
    instants = np.arange(0.0, min(times[-1], dt * steps[-1]), 0.5)
    mate = sampled(instants, dt * steps, track)
    for flag, keeps_clear in ((False, False), (True, True)):
        t, p = first_trajectory(env, field, shared[0], plans, teammates=flag)
        gaps = np.linalg.norm(sampled(instants, t, p) - mate, axis=1)
        assert (gaps.min() >= collision_distance(env)) == keeps_clear, (flag, gaps.min())
        if not flag:  # the blind plan does not depend on where chaser 0 is
            assert np.array_equal(t, times) and np.array_equal(p, path)


def test_a_view_gives_the_teammates_ahead_and_the_held_ones():
    env = swarm.make("DebrisGym/Reconfigure2D-v0", n_chasers=3, n_obstacles=2)
    env.reset(seed=0)
    views = [ChaserView(env.core, k) for k in range(3)]
    assert [v.teammates(4).count for v in views] == [2, 2, 2]
    assert [v.teammates(4, ahead=True).count for v in views] == [0, 1, 2]
    ahead = views[2].teammates(4, ahead=True).tracks[:, 0]
    assert np.allclose(ahead, [v.chaser_state[:2] for v in views[:2]])
    # chaser 2 starts at rest at its formation slot, arrives and is held: ahead of everyone
    starts = np.array([v.chaser_state for v in views])
    starts[2, :2] = views[2].scenario.dock
    observations, _ = env.reset(seed=0, options={"chaser_state": starts})
    while "chaser_2" in env.agents:
        env.step({a: np.zeros(2, dtype=np.float32) for a in env.agents})
    assert env.core.shell.batch_in_use.missions.success[2]
    held = views[0].teammates(4, ahead=True)
    assert held.count == 1 and np.allclose(held.tracks[0], views[2].chaser_state[:2])
    assert views[1].teammates(4, ahead=True).count == 2


@pytest.mark.parametrize(("members", "clean"), [("aware", True), ("blind", False)])
def test_an_st_rrt_team_reconfigures_without_contact_only_when_it_plans_around_its_mates(
    members, clean
):
    """Six chasers leave their dock lattice for the formation on Reconfigure2D-v0 (seed 1)."""
    env = swarm.make("DebrisGym/Reconfigure2D-v0")
    blind = {"teammates": False, "mpc": MPCParams(teammates_per_step=0)}
    team = TeamOfSingles(env, "st-rrt", "balanced", **(blind if members == "blind" else {}))
    observations, _, _ = start_episode(env, team, seed=1)
    while env.agents:
        observations, *_ = env.step(team.predict(observations))
    missions = env.core.shell.batch_in_use.missions
    contact = bool(np.any(missions.teammate_collision[: env.core.chasers]))
    assert contact != clean
    if clean:
        assert env.team_success()
        assert env.core.min_separation()[0] > collision_distance(env)
