"""The v2 capture rule ("hold") and the Δv budget as a failure, from outside.

Truth is computed here, independently of the library: the coasting chaser's and the target's
states come from the textbook closed-form CW solution (``tests.helpers.cw_closed_form``), and
:func:`reference_capture_step` applies the rule as docs/environments.md states it — at every
step end of the hold the chaser is within ``capture_radius`` of the target's surface, at most
``capture_speed`` relative to it, and within ``capture_drift`` of its position relative to the
target at the hold's first step end; ``1 + ceil(capture_hold / dt)`` such step ends capture.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401  (registers the IDs)
from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.common import discrete_action_table
from debris_gym.registration import ENV_SPECS, HOLD_RULES, PHYSICAL_WORLD
from debris_gym.scenario import Body, Scenario
from tests.helpers import LEO_MEAN_MOTION, MOVING_DT, MOVING_WORLD, cw_closed_form

pytestmark = pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")

N = LEO_MEAN_MOTION
DT = MOVING_DT
HOLD_WORLD = {**MOVING_WORLD, **HOLD_RULES, "capture_radius": 5.0}
"""The tests' moving world with the v2 rules (what the v2 IDs register)."""
DWELL_WORLD = {**HOLD_WORLD, "capture_rule": "dwell", "reward_budget": 0.0}
"""The same options under the v1 capture rule: the contrast that shows the v2 rule at work."""
TARGET_RADIUS = 5.0
CHASER_RADIUS = 1.0
HOLD_STEPS = 1 + math.ceil(30.0 / DT)


def test_the_v2_ids_are_the_v1_world_with_the_hold_rules():
    for env_id, spec in ENV_SPECS.items():
        if env_id.endswith("-v2") and "-Uncertain-" not in env_id:
            v1 = ENV_SPECS[env_id[:-1] + "1"]
            assert spec["kwargs"] == {**v1["kwargs"], **HOLD_RULES}, env_id
            assert spec["max_episode_steps"] == v1["max_episode_steps"]
    assert HOLD_RULES["capture_rule"] == "hold"
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    cfg = env.unwrapped.config
    assert (cfg.capture_speed, cfg.capture_drift, cfg.capture_hold) == (0.1, 1.0, 30.0)
    assert cfg.reward_budget == cfg.reward_out_of_bounds  # penalised like leaving the world


def target_state() -> np.ndarray:
    """A target on a closed relative orbit (ẏ₀ = −2n x₀) well inside the world."""
    x0, y0 = 200.0, 150.0
    return np.array([x0, y0, 0.1, -2 * N * x0])


def world(target: np.ndarray, obstacles=()) -> Scenario:
    body = Body(position=tuple(target[:2]), radius=TARGET_RADIUS, velocity=tuple(target[2:]))
    return Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0), targets=(body,),
        obstacles=tuple(obstacles), mean_motion=N, dt=DT, max_accel=0.05, motion="cwh",
        motion_faults="warn",
    )  # fmt: skip


def chaser_beside(target: np.ndarray, offset, rel_v) -> np.ndarray:
    """The chaser at ``offset`` (m) from the target's centre with velocity ``rel_v`` (m/s)
    relative to it."""
    return np.concatenate([target[:2] + np.asarray(offset), target[2:] + np.asarray(rel_v)])


def reference_capture_step(
    chaser0: np.ndarray, target0: np.ndarray, steps: int, opts: dict
) -> tuple[int | None, bool]:
    """The rule applied to the closed-form states of a coasting chaser: (the step whose end
    captures, or None within ``steps``; whether any step end is near a threshold, where float
    rounding may decide either way)."""
    reach = opts["capture_radius"] + CHASER_RADIUS + TARGET_RADIUS
    hold, anchor, close_call = 0, None, False
    for k in range(1, steps + 1):
        c, t = cw_closed_form(chaser0, k * DT), cw_closed_form(target0, k * DT)
        rel, rel_v = c[:2] - t[:2], c[2:] - t[2:]
        dist, speed = float(np.linalg.norm(rel)), float(np.linalg.norm(rel_v))
        if dist <= CHASER_RADIUS + TARGET_RADIUS + 0.05:
            return None, True  # a touch: not what these flights test
        in_range = dist <= reach and speed <= opts["capture_speed"]
        close_call |= abs(dist - reach) < 1e-6 or abs(speed - opts["capture_speed"]) < 1e-9
        if in_range and hold > 0 and opts["capture_rule"] == "hold":
            drift = float(np.linalg.norm(rel - anchor))
            close_call |= abs(drift - opts["capture_drift"]) < 1e-6
            if drift > opts["capture_drift"]:
                hold = 0
        if in_range and hold == 0:
            anchor = rel
        hold = hold + 1 if in_range else 0
        if hold >= HOLD_STEPS:
            return k, close_call
    return None, close_call


def env_capture_step(opts: dict, chaser0: np.ndarray, target0: np.ndarray, steps: int):
    """(The step whose end captured, or None; the info of every step) flying zero thrust."""
    env = DebrisFieldEnv(dim=2, **opts)
    env.reset(options={"scenario": world(target0), "chaser_state": chaser0})
    infos = []
    for k in range(1, steps + 1):
        *_, terminated, _, info = env.step(np.zeros(2))
        infos.append(info)
        if info["targets_captured"]:
            return k, infos
        if terminated:
            break
    return None, infos


@pytest.mark.parametrize("opts", [HOLD_WORLD, DWELL_WORLD], ids=["hold", "dwell"])
def test_a_genuine_hold_captures_after_the_hold(opts):
    """Coasting at an along-track offset with the target's velocity: a CW equilibrium of the
    relative motion, so the chaser holds still beside the target."""
    target = target_state()
    chaser = chaser_beside(target, (0.0, TARGET_RADIUS + CHASER_RADIUS + 3.0), (0.0, 0.0))
    step, infos = env_capture_step(opts, chaser, target, 10)
    assert step == HOLD_STEPS == reference_capture_step(chaser, target, 10, opts)[0]
    assert [int(i["hold"][0]) for i in infos] == [1, 2, 3, 4]
    assert infos[-1]["reward_terms"]["capture"] == pytest.approx(10.0)


def test_a_fly_by_inside_the_capture_zone_does_not_capture_under_the_hold_rule():
    """Tangentially past the target at 0.09 m/s, 3 m off its surface: under capture_speed,
    but 2.7 m of travel over the 30 s hold. The v1 rule captures it; the hold rule does not."""
    target = target_state()
    chaser = chaser_beside(target, (TARGET_RADIUS + CHASER_RADIUS + 3.0, -4.0), (0.0, 0.09))
    assert env_capture_step(HOLD_WORLD, chaser, target, 12)[0] is None
    assert reference_capture_step(chaser, target, 12, HOLD_WORLD)[0] is None
    dwell = env_capture_step(DWELL_WORLD, chaser, target, 12)[0]
    assert dwell is not None and dwell == reference_capture_step(chaser, target, 12, DWELL_WORLD)[0]


def test_drifting_off_restarts_the_hold_from_the_step_end_that_drifted():
    """0.045 m/s relative: 0, 0.45, 0.9 m from where the hold began, then 1.35 m > 1 m: the
    fourth step end starts a new hold. The hold counter in info shows it; nothing captures."""
    target = target_state()
    chaser = chaser_beside(target, (TARGET_RADIUS + CHASER_RADIUS + 2.0, -3.0), (0.0, 0.045))
    step, infos = env_capture_step(HOLD_WORLD, chaser, target, 9)
    assert step is None
    assert [int(i["hold"][0]) for i in infos] == [1, 2, 3, 1, 2, 3, 1, 2, 3]


def test_a_closing_course_does_not_capture_and_ends_in_a_collision():
    """Straight at the target at 0.095 m/s from 4 m off its surface: in range and under
    capture_speed at every step end, but closing 2.85 m over the hold. No capture, then the
    impact."""
    target = target_state()
    start = TARGET_RADIUS + CHASER_RADIUS + 4.0
    chaser = chaser_beside(target, (0.0, start), (0.0, -0.095))
    env = DebrisFieldEnv(dim=2, **HOLD_WORLD)
    env.reset(options={"scenario": world(target), "chaser_state": chaser})
    for _ in range(20):
        *_, terminated, _, info = env.step(np.zeros(2))
        assert info["targets_captured"] == 0
        if terminated:
            break
    assert info["collision"] and not info["is_success"]


def test_a_step_that_captures_and_collides_is_a_collision_only():
    """Three step ends of a slow creep toward the target (0.028 m/s), then the fourth step
    touches it. The v1 rule pays the capture and the collision in that step; the hold rule
    only the collision."""
    target = target_state()
    chaser = chaser_beside(target, (0.0, TARGET_RADIUS + CHASER_RADIUS + 1.0), (0.0, -0.028))
    for opts, captured in ((DWELL_WORLD, True), (HOLD_WORLD, False)):
        env = DebrisFieldEnv(dim=2, **opts)
        env.reset(options={"scenario": world(target), "chaser_state": chaser})
        steps, terminated = 0, False
        while not terminated and steps < 10:
            *_, terminated, _, info = env.step(np.zeros(2))
            steps += 1
        assert steps == 4 and info["collision"], (opts["capture_rule"], steps)
        assert (info["targets_captured"] == 1) is captured
        assert (info["reward_terms"]["capture"] > 0) is captured


def test_touching_a_target_that_is_not_solid_breaks_the_hold():
    """With soft targets (solid_targets=False) a slow touch is no collision; under the hold
    rule the step ends spent touching the target do not count toward its capture. (The target
    sits still, on a CW equilibrium, because the soft-target rule judges the chaser's own
    speed.)"""
    target = np.array([0.0, 150.0, 0.0, 0.0])
    chaser = chaser_beside(target, (0.0, TARGET_RADIUS + CHASER_RADIUS + 0.05), (0.0, -0.02))
    soft = {"solid_targets": False}
    dwell_step, _ = env_capture_step({**DWELL_WORLD, **soft}, chaser, target, 8)
    hold_step, infos = env_capture_step({**HOLD_WORLD, **soft}, chaser, target, 8)
    assert dwell_step == HOLD_STEPS
    assert hold_step is None and not any(i["collision"] for i in infos)
    assert all(int(i["hold"][0]) == 0 for i in infos)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    along=st.floats(-12.0, 12.0),
    radial=st.floats(-12.0, 12.0),
    vx=st.floats(-0.12, 0.12),
    vy=st.floats(-0.12, 0.12),
    rule=st.sampled_from(["hold", "dwell"]),
)
def test_coasting_flights_capture_when_the_closed_form_says(along, radial, vx, vy, rule):
    target = target_state()
    offset = np.array([radial, along])
    if np.linalg.norm(offset) < TARGET_RADIUS + CHASER_RADIUS + 0.5:
        return  # starting in contact: a collision, not a capture question
    chaser = chaser_beside(target, offset, (vx, vy))
    opts = HOLD_WORLD if rule == "hold" else DWELL_WORLD
    expected, close_call = reference_capture_step(chaser, target, 8, opts)
    if close_call:
        return  # a touch or a threshold within rounding: either answer is right
    assert env_capture_step(opts, chaser, target, 8)[0] == expected


def test_the_hold_progress_is_observed():
    target = target_state()
    chaser = chaser_beside(target, (0.0, TARGET_RADIUS + CHASER_RADIUS + 3.0), (0.0, 0.0))
    env = DebrisFieldEnv(dim=2, **HOLD_WORLD)
    obs, _ = env.reset(options={"scenario": world(target), "chaser_state": chaser})
    names = env.observation_names()
    slot = names.index("target0_hold")
    assert obs[slot] == 0.0
    for k in range(1, HOLD_STEPS + 1):
        obs, *_ = env.step(np.zeros(2))
        assert obs[slot] == pytest.approx(k / HOLD_STEPS)
    without = DebrisFieldEnv(dim=2, **{**HOLD_WORLD, "obs_hold": False})
    assert not any(name.endswith("_hold") for name in without.observation_names())
    assert len(names) == len(without.observation_names()) + env.config.obs_targets


def hold_controller(table: np.ndarray, max_accel: float, dt: float):
    """A position-hold law for discrete actions: the action whose velocity change best matches
    the one that would null the relative velocity and pull back toward the anchor."""

    def act(rel: np.ndarray, rel_v: np.ndarray, anchor: np.ndarray) -> int:
        wanted = -rel_v - 0.05 * (rel - anchor)
        changes = table * max_accel * dt
        return int(np.argmin(np.linalg.norm(changes - wanted, axis=1)))

    return act


@pytest.mark.parametrize("action", ["continuous", "discrete"])
def test_a_hold_is_flyable_with_the_registered_actions(action):
    """From 3 m off the surface, drifting at 0.04 m/s relative, a simple hold law captures:
    continuous thrust, and the discrete actions with the v2 IDs' fine thrust (10 %)."""
    target = target_state()
    chaser = chaser_beside(target, (0.0, TARGET_RADIUS + CHASER_RADIUS + 3.0), (0.03, -0.027))
    opts = {**HOLD_WORLD, "action": action, "fine_thrust": PHYSICAL_WORLD["fine_thrust"]}
    env = DebrisFieldEnv(dim=2, **opts)
    env.reset(options={"scenario": world(target), "chaser_state": chaser})
    act = hold_controller(discrete_action_table(2, opts["fine_thrust"]), 0.05, DT)
    anchor = chaser[:2] - target[:2]
    for _ in range(30):
        state, body = env.unwrapped.chaser_state, env.unwrapped.body_states[0]
        rel, rel_v = state[:2] - body[:2], state[2:] - body[2:]
        if action == "discrete":
            command = act(rel, rel_v, anchor)
        else:
            wanted = (-rel_v - 0.05 * (rel - anchor)) / DT / 0.05
            command = np.clip(wanted, -1.0, 1.0).astype(np.float32)
        *_, terminated, _, info = env.step(command)
        if info["targets_captured"] or terminated:
            break
    assert info["targets_captured"] == 1 and not info["collision"]


def test_running_out_of_delta_v_is_a_penalised_failure():
    """Full thrust back and forth at the dock with a 2 m/s budget: the step that spends the
    last of it ends the mission, flagged and penalised (reward_budget); the v1 rule ends it
    the same way without the penalty."""
    target = target_state()
    for opts, penalty in ((HOLD_WORLD, 50.0), (DWELL_WORLD, 0.0)):
        env = DebrisFieldEnv(dim=2, **{**opts, "delta_v_budget": 2.0})
        env.reset(options={"scenario": world(target), "chaser_state": np.zeros(4)})
        for k in range(1, 20):
            u = np.array([1.0 if k % 4 in (1, 0) else -1.0, 0.0], dtype=np.float32)
            _, reward, terminated, truncated, info = env.step(u)
            if terminated:
                break
        assert k == 4 and info["delta_v"] == pytest.approx(2.0)
        assert info["budget_spent"] and not info["collision"] and not info["is_success"]
        assert info["reward_terms"]["budget"] == -penalty
        assert reward == pytest.approx(sum(info["reward_terms"].values()))


def test_the_budget_flag_is_clear_while_there_is_delta_v_left():
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    _, info = env.reset(seed=0)
    assert info["budget_spent"] is False and info["reward_terms"]["budget"] == 0.0
    for _ in range(5):
        *_, info = env.step(np.zeros(2, dtype=np.float32))
        assert info["budget_spent"] is False and info["reward_terms"]["budget"] == 0.0
