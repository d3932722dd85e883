"""APF-RRT's local-minimum escape in the moving world (v1): the stall test against hand values,
the watch-only flight against plain APF, and a hand-built moving trap whose goal an independent
grid search reaches, which APF-RRT reaches and plain APF does not.

The trap is a cup of touching circles that translates rigidly with the target (every body on
the same velocity, a near-zero mean motion so the CWH terms cannot shear it apart): in the
target's frame it is a fixed concave trap for the whole episode, so plain APF stays caught in it
and the test isolates the moving-world detection (goal frame, moving geometry, the moving stall
rule) from the trap's dispersal. On LEO fields the bodies drift apart and traps dissolve; that
case is what the ``hard`` suite covers (tests/test_hard_suite.py)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

import agents
import debris_gym  # noqa: F401  (registers the IDs)
from agents.planners.apf import APFParams, is_held_back, is_local_minimum
from agents.planners.mission import Goal
from agents.planners.rrt import RRTParams
from debris_gym.scenario import Body, Scenario

pytestmark = pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")

SLOW_N = 1e-6
"""Mean motion (rad/s) of the translating trap: an orbit of 73 days, so over an episode the CWH
terms move the bodies apart by micrometres while they travel hundreds of metres."""

DRIFT = (0.05, 0.02)
"""Common velocity (m/s) of every body of the translating fields."""


def _moving_field(obstacles: bool, target=(15.0, 260.0)) -> Scenario:
    """The test cup (a U of touching circles of radius 9 m opening toward the dock, the target
    right behind its bottom), every body moving with :data:`DRIFT`; without obstacles, the same
    target in an empty field (a free straight run)."""
    r, wall_y, half, arm = 9.0, 200.0, 60.0, 60.0
    xs = np.arange(-half, half + 1e-9, 2.0 * r)
    centres = [(float(x), wall_y) for x in xs]
    for y in np.arange(wall_y - 2.0 * r, wall_y - arm - 1e-9, -2.0 * r):
        centres += [(float(xs[0]), float(y)), (float(xs[-1]), float(y))]
    return Scenario(
        dim=2,
        bounds=((-500.0, 500.0),) * 2,
        dock=(0.0, 0.0),
        targets=(Body(position=target, radius=5.0, velocity=DRIFT),),
        obstacles=tuple(Body(position=c, radius=r, velocity=DRIFT) for c in centres)
        if obstacles
        else (),
        mean_motion=SLOW_N,
        dt=10.0,
        max_accel=0.05,
        motion="cwh",
        name="translating cup" if obstacles else "translating free run",
        motion_faults="warn",  # the drifting cup leaves the world late in a registered episode
    )


def _env(steps: int = 400):
    return gym.make("DebrisGym/Rendezvous2D-v2", mean_motion=SLOW_N, max_episode_steps=steps)


def _fly(agent, env, scenario):
    obs, info = env.reset(options={"scenario": scenario})
    done = False
    while not done:
        action, _ = agent.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info, env.unwrapped.trail.copy()


def _grid_reachable(scenario: Scenario, start, goal, clearance: float, cell: float = 2.0) -> bool:
    """Independent truth: whether ``goal`` is reachable from ``start`` through grid cells whose
    centres keep ``clearance`` (m) from every circle (exact circle distance, typed here), by
    8-connected components (scipy.ndimage.label) — no library geometry or planner involved."""
    (x0, x1), (y0, y1) = scenario.bounds
    xs = np.arange(x0 + cell / 2, x1, cell)
    ys = np.arange(y0 + cell / 2, y1, cell)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(gx.shape, dtype=bool)
    for body in scenario.bodies[1:]:  # the goal target itself is where the path ends
        cx, cy = body.position
        free &= np.hypot(gx - cx, gy - cy) - body.radius > clearance
    labels, _ = ndimage.label(free, structure=np.ones((3, 3)))

    def cell_of(p):
        return int((p[0] - x0) // cell), int((p[1] - y0) // cell)

    a, b = labels[cell_of(start)], labels[cell_of(goal)]
    return bool(a and a == b)


# --- the stall test -------------------------------------------------------------------------------

P = APFParams()


def test_held_back_against_hand_values():
    f_att = np.array([0.02, 0.0])
    assert is_held_back(f_att, np.array([-0.05, 0.0]), P)  # pushed back harder than pulled
    assert is_held_back(f_att, np.array([-0.01, 0.0]), P)  # half as strong: the bound
    assert not is_held_back(f_att, np.array([-0.0099, 0.0]), P)  # weaker than half
    assert not is_held_back(f_att, np.array([0.0, -0.05]), P)  # across, not against
    # 20 degrees off opposite: cos = -0.940 < -0.9 passes; 30 degrees: cos = -0.866 fails
    for degrees, expected in ((20.0, True), (30.0, False)):
        a = math.radians(180.0 - degrees)
        assert is_held_back(f_att, 0.04 * np.array([math.cos(a), math.sin(a)]), P) is expected
    assert not is_held_back(np.zeros(2), np.array([-1.0, 0.0]), P)
    # eq. 14's two-sided balance misses the strong push the one-sided test catches
    assert not is_local_minimum(f_att, np.array([-0.05, 0.0]), P)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
)
def test_every_eq14_minimum_is_held_back(ax, ay, rx, ry):
    """‖F_att + F_rep‖ < 0.5‖F_att‖ implies ‖F_rep‖ > 0.5‖F_att‖ (triangle inequality), so the
    one-sided test keeps every minimum eq. 14 finds."""
    f_att, f_rep = np.array([ax, ay]), np.array([rx, ry])
    if is_local_minimum(f_att, f_rep, P):
        assert is_held_back(f_att, f_rep, P)


# --- flights in the moving world ------------------------------------------------------------------


def test_the_translating_trap_is_solvable_and_apf_rrt_escapes_where_apf_stays_caught():
    scenario = _moving_field(obstacles=True)
    env = _env()
    goal = np.array([15.0, 260.0 - 5.0 - 1.0 - 2.5])  # approach point below the target
    # the field is rigid in the target's frame, so its t = 0 layout is the truth for all times
    assert _grid_reachable(scenario, scenario.dock, goal, clearance=1.0 + 2.0)

    plain_info, plain_trail = _fly(agents.make_agent("apf", env), env, scenario)
    assert not plain_info["is_success"] and not plain_info["collision"]

    escape = agents.make_agent("apf-rrt", env)
    info, _ = _fly(escape, env, scenario)
    assert info["is_success"] and not info["collision"]
    assert escape.detections >= 1 and escape.escapes >= 1

    watch = agents.make_agent("apf-rrt", env, rrt=RRTParams(max_escapes=0))
    watch_info, watch_trail = _fly(watch, env, scenario)
    assert watch.detections >= 1 and watch.escapes == 0
    np.testing.assert_array_equal(watch_trail, plain_trail)  # watching alone changes nothing
    assert watch_info["is_success"] == plain_info["is_success"]


def test_no_stall_is_detected_on_a_free_straight_run():
    scenario = _moving_field(obstacles=False)
    env = _env()
    plain_info, plain_trail = _fly(agents.make_agent("apf", env), env, scenario)
    agent = agents.make_agent("apf-rrt", env)
    info, trail = _fly(agent, env, scenario)
    assert info["is_success"] and plain_info["is_success"]
    assert agent.detections == 0 and agent.escapes == 0
    np.testing.assert_array_equal(trail, plain_trail)


def _stall_agent():
    """An APF-RRT agent on the translating cup's episode, watching only, its goal state fresh."""
    env = _env()
    scenario = _moving_field(obstacles=True)
    env.reset(options={"scenario": scenario})
    agent = agents.make_agent("apf-rrt", env, rrt=RRTParams(max_escapes=0))
    agent.plan(env.unwrapped.scenario)
    goal = Goal("target", 0, np.array([0.0, 300.0]), np.array([0.0, 310.0]))
    return agent, goal


def _feed(agent, goal, distances, f_att, f_rep) -> int:
    """Step the stall rule by hand: the chaser on the goal's axis at these goal distances (m)."""
    for d in distances:
        pos = goal.point - np.array([0.0, d])
        agent.observe_forces(pos, np.zeros(2), goal, f_att, f_rep)
    return agent.detections


@pytest.mark.parametrize(
    ("distances", "detected"),
    [
        # wandering ±20 m about 200 m with no new closest approach after the first 30 s: a stall
        (200.0 + 20.0 * np.cos(np.arange(60) / 5.0), True),
        # closing in 2 m per step: progress, never a stall
        (300.0 - 2.0 * np.arange(60), False),
    ],
)
def test_moving_stall_rule_measures_progress_by_the_closest_approach(distances, detected):
    """Opposed forces with the repulsion twice the attraction (a body pushing the chaser back)
    and no new closest approach over one window (stall_time / dt = 30 steps) is a stall; the same
    forces while the chaser closes in are not."""
    agent, goal = _stall_agent()
    assert agent.stall_steps == 30
    f_att, f_rep = np.array([0.0, 0.02]), np.array([0.0, -0.04])
    assert (_feed(agent, goal, distances, f_att, f_rep) >= 1) is detected


def test_moving_stall_rule_needs_the_forces_opposed():
    agent, goal = _stall_agent()
    distances = np.full(60, 200.0)  # not moving at all
    across = _feed(agent, goal, distances, np.array([0.0, 0.02]), np.array([0.04, 0.0]))
    assert across == 0
