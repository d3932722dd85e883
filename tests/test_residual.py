"""The base law (debris_gym.base_law), the ``action="residual"`` mode and the ``base-law`` agent.

The law's command is held to the CW formula computed here independently: the natural flight
of the step from the textbook closed form (``tests.helpers.cw_closed_form``) and the thrust's
effect on the end velocity by integrating the CWH equations (``tests.helpers.cwh_rhs``)
numerically (scipy's ODE solver), never the library's matrix exponential.
"""

from __future__ import annotations

import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

import debris_gym  # noqa: F401  (registers the IDs)
from agents import make_agent
from debris_gym import base_law
from debris_gym.config import EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Body, Scenario
from tests.helpers import LEO_MEAN_MOTION, cw_closed_form, cwh_rhs

pytestmark = pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")

N = LEO_MEAN_MOTION
DT = 10.0
MAX_ACCEL = 0.05
TARGET_RADIUS = 5.0
CHASER_RADIUS = 1.0
CAPTURE_RADIUS = 5.0
STANDOFF = CAPTURE_RADIUS / 2  # the hold point's surface-to-surface gap
EASY = "DebrisGym/Rendezvous2D-Easy-v2"
DEFAULT = "DebrisGym/Rendezvous2D-v2"


def one_target_env(
    target: np.ndarray, moving: bool, obstacles: tuple[Body, ...] = (), **options
) -> tuple[DebrisFieldEnv, Scenario]:
    """An env and a field with one target (state ``target``) in a 1 km world."""
    body = Body(
        position=tuple(target[:2]), radius=TARGET_RADIUS,
        velocity=tuple(target[2:]) if moving else (),
    )  # fmt: skip
    scenario = Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0), targets=(body,),
        obstacles=obstacles, mean_motion=N, dt=DT, max_accel=MAX_ACCEL,
        motion="cwh" if moving else "frozen", motion_faults="warn" if moving else "refuse",
    )  # fmt: skip
    world = {"debris_motion": "bounded", "solid_targets": True} if moving else {}
    env = DebrisFieldEnv(
        dim=2, mean_motion=N, dt=DT, max_accel=MAX_ACCEL, capture_radius=CAPTURE_RADIUS,
        chaser_radius=CHASER_RADIUS, capture_speed=0.1, **world, **options,
    )  # fmt: skip
    return env, scenario


def command_at(
    target: np.ndarray, chaser: np.ndarray, moving: bool = False, **options
) -> tuple[np.ndarray, DebrisFieldEnv]:
    """The base law's command for ``chaser`` beside a lone target, and the env (reset there)."""
    env, scenario = one_target_env(target, moving, **options)
    env.reset(options={"scenario": scenario, "chaser_state": chaser})
    return env.batch.base_commands()[0], env


def end_velocity(state: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """The velocity after one step of ``accel`` (m/s²) held constant, integrated numerically."""
    sol = solve_ivp(cwh_rhs(N, 2, accel), (0.0, DT), state, method="DOP853", rtol=1e-12, atol=1e-12)
    return sol.y[2:, -1]


def expected_command(chaser: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """The normalised thrust that ends the step at velocity ``wanted`` (a target at rest):
    u = Γ_v⁻¹ (w − v_natural), Γ_v's columns the end-velocity change per unit acceleration."""
    natural = cw_closed_form(chaser, DT)[2:]
    gamma = np.column_stack(
        [end_velocity(chaser, unit) - end_velocity(chaser, np.zeros(2)) for unit in np.eye(2)]
    )
    return np.linalg.solve(gamma, wanted - natural) / MAX_ACCEL


def wanted_speed(togo: float) -> float:
    """v(s) of the law as its docs state it (s outside the capture zone)."""
    return min(1.0, math.sqrt(2 * 0.25 * MAX_ACCEL * togo), 0.3 / DT * togo)


# --- the law against hand-computable cases ------------------------------------------------------


def test_a_chaser_at_rest_at_a_frozen_targets_hold_point_commands_nothing():
    """A target at rest on the V-bar (a CW equilibrium), the chaser at rest beside it at the hold
    point: no thrust, and a residual step with a zero action stays put."""
    target = np.array([0.0, 150.0, 0.0, 0.0])
    offset = TARGET_RADIUS + CHASER_RADIUS + STANDOFF
    chaser = np.array([0.0, 150.0 - offset, 0.0, 0.0])
    command, env = command_at(target, chaser, action="residual")
    np.testing.assert_array_equal(command, [0.0, 0.0])
    *_, info = env.step(np.zeros(2))
    np.testing.assert_array_equal(info["applied_accel"], [0.0, 0.0])
    np.testing.assert_array_equal(info["chaser_state"], [0.0, 150.0 - offset, 0.0, 0.0])


def test_a_chaser_at_rest_beside_a_moving_target_along_track_commands_nothing():
    """The chaser at the hold point along-track of a target on a relative orbit, at its
    velocity: the relative state is a CW equilibrium and the law's thrust is exactly zero."""
    target = np.array([200.0, 150.0, 0.1, -2 * N * 200.0])
    offset = TARGET_RADIUS + CHASER_RADIUS + STANDOFF
    command, _ = command_at(target, target - np.array([0.0, offset, 0.0, 0.0]), moving=True)
    np.testing.assert_array_equal(command, [0.0, 0.0])


@pytest.mark.parametrize("axis", [0, 1], ids=["radial", "along-track"])
def test_an_offset_along_one_axis_gets_the_cw_deadbeat_command(axis):
    """The chaser at rest 3 m short of the hold point of a frozen target, below it (radial) or
    behind it (along-track): the law wants v(3 m) toward the target at the step's end, and
    the command is the thrust that gives it under CW — Coriolis coupling and the radial
    gravity-gradient drift included."""
    target = np.array([0.0, 150.0, 0.0, 0.0])
    togo = 3.0
    chaser = target.copy()
    chaser[axis] -= TARGET_RADIUS + CHASER_RADIUS + STANDOFF + togo
    command, _ = command_at(target, chaser)
    wanted = np.zeros(2)
    wanted[axis] = wanted_speed(togo)
    expected = expected_command(chaser, wanted)
    assert np.linalg.norm(expected) < 1.0  # inside the thrust limit: nothing scaled
    assert abs(expected[1 - axis]) > 1e-4 * abs(expected[axis])  # the CW coupling shows
    np.testing.assert_allclose(command, expected, rtol=1e-8, atol=1e-12)


def test_far_from_the_goal_the_command_is_full_thrust_toward_it():
    """400 m away at rest: the wanted speed is the 1 m/s limit, beyond one step's Δv (0.5 m/s),
    so the command is the deadbeat thrust scaled onto the unit ball ("ball" thrust) or clipped
    per axis ("box")."""
    target = np.array([0.0, 150.0, 0.0, 0.0])
    chaser = np.array([0.0, -250.0, 0.0, 0.0])
    expected = expected_command(chaser, np.array([0.0, 1.0]))
    assert np.linalg.norm(expected) > 1.0
    ball, _ = command_at(target, chaser)
    np.testing.assert_allclose(ball, expected / np.linalg.norm(expected), rtol=1e-8)
    box, _ = command_at(target, chaser, thrust_model="box")
    np.testing.assert_allclose(box, np.clip(expected, -1, 1), rtol=1e-8)


def test_a_body_in_the_way_bends_the_approach():
    """An obstacle 10 m from the chaser's surface on the line of sight to the target: the
    command turns away from the straight line (the law's one avoidance term); without the
    obstacle it points along it."""
    target = np.array([0.0, 150.0, 0.0, 0.0])
    chaser = np.array([0.0, -100.0, 0.0, 0.0])
    straight, _ = command_at(target, chaser)
    assert abs(straight[0]) < 0.05 * abs(straight[1])
    rock = Body(position=(0.0, -100.0 + CHASER_RADIUS + 10.0 + 4.0), radius=4.0)
    env, scenario = one_target_env(target, False, obstacles=(rock,))
    env.reset(options={"scenario": scenario, "chaser_state": chaser})
    bent = env.batch.base_commands()[0]
    assert abs(bent[0]) > 0.3 and bent[1] < straight[1]


# --- the residual mode --------------------------------------------------------------------------


def fly(env, policy, seed: int) -> list[tuple]:
    """Every step of one episode: (state, reward, terminated, truncated, accel, is_success)."""
    obs, _ = env.reset(seed=seed)
    steps, done = [], False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        done = terminated or truncated
        steps.append(
            (info["chaser_state"], reward, terminated, truncated, info["applied_accel"],
             info["is_success"])
        )  # fmt: skip
    return steps


@pytest.mark.parametrize("env_id", [EASY, DEFAULT])
def test_a_zero_residual_flies_the_base_law_agent_bit_for_bit(env_id):
    """The residual mode with a zero action and the ``base-law`` agent in the continuous env:
    the same mission, step for step, to the last bit (the default rung: three captures, the
    departures past captured targets and the return to the dock)."""
    env = gym.make(env_id)
    agent = make_agent("base-law", env)
    flown = fly(env, lambda obs: agent.predict(obs)[0], seed=0)
    residual = gym.make(env_id, action="residual")
    zero = np.zeros(2, dtype=np.float32)
    again = fly(residual, lambda obs: zero, seed=0)
    assert len(flown) == len(again) and flown[-1][-1]  # a whole mission, flown to success
    for k, (a, b) in enumerate(zip(flown, again)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"state at step {k}")
        np.testing.assert_array_equal(a[4], b[4], err_msg=f"accel at step {k}")
        assert a[1:4] == b[1:4] and a[5] == b[5], k


def test_the_base_law_alone_captures_on_the_easy_rung():
    """20 seeded Easy-v2 missions flown by the base law: at least 18 captures (it captured in
    every one of them when this was written)."""
    env = gym.make(EASY)
    agent = make_agent("base-law", env)
    wins = sum(fly(env, lambda obs: agent.predict(obs)[0], seed=s)[-1][-1] for s in range(20))
    assert wins >= 18


def test_the_sum_is_clipped_per_axis_before_the_thrust_model():
    env = gym.make(EASY, action="residual")
    env.reset(seed=3)
    batch = env.unwrapped.batch
    base = batch.base_commands()[0]
    action = np.array([3.0, -0.25], dtype=np.float32)
    command = np.clip(base + action.astype(float), -1.0, 1.0)
    assert command[0] == 1.0  # the first axis saturates
    *_, info = env.step(action)
    scale = max(1.0, float(np.linalg.norm(command)))  # then the "ball" thrust model
    np.testing.assert_allclose(info["applied_accel"], MAX_ACCEL * command / scale, rtol=1e-12)


def test_the_observation_and_the_spaces_are_those_of_the_continuous_env():
    plain, residual = gym.make(DEFAULT), gym.make(DEFAULT, action="residual")
    assert plain.observation_space == residual.observation_space
    assert plain.action_space == residual.action_space
    np.testing.assert_array_equal(plain.reset(seed=4)[0], residual.reset(seed=4)[0])


def test_the_vector_env_rows_fly_as_single_envs():
    """The native vector env in the residual mode against gymnasium's SyncVectorEnv of single
    envs: the same observations, rewards and states, row for row, through autoresets."""
    kwargs = {"num_envs": 3, "action": "residual", "max_episode_steps": 60}
    native = gym.make_vec(EASY, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(EASY, vectorization_mode="sync", **kwargs)
    obs_n, _ = native.reset(seed=7)
    obs_s, _ = sync.reset(seed=7)
    np.testing.assert_array_equal(obs_n, obs_s)
    rng = np.random.default_rng(0)
    ended = 0
    for step in range(90):
        actions = (0.3 * rng.uniform(-1, 1, (3, 2))).astype(np.float32)
        out_n, out_s = native.step(actions), sync.step(actions)
        for a, b in zip(out_n[:4], out_s[:4]):
            np.testing.assert_array_equal(a, b, err_msg=f"step {step}")
        np.testing.assert_array_equal(out_n[4]["chaser_state"], out_s[4]["chaser_state"])
        ended += int(np.sum(out_n[2] | out_n[3]))
    assert ended >= 3  # the runs went through autoresets


def test_a_residual_env_pickles_mid_episode_and_flies_on_the_same():
    env = gym.make(EASY, action="residual")
    env.reset(seed=1)
    for _ in range(3):
        env.step(np.array([0.1, -0.1], dtype=np.float32))
    copy = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a, b = env.step(np.zeros(2)), copy.step(np.zeros(2))
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[4]["chaser_state"], b[4]["chaser_state"])


def test_the_residual_mode_passes_the_env_checkers():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(DEFAULT, action="residual")
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)


# --- validation ---------------------------------------------------------------------------------


def test_an_unknown_action_mode_names_the_option_and_the_choices():
    with pytest.raises(ValueError, match=r"action='residue'.*'continuous', 'discrete', 'residual'"):
        EnvConfig(action="residue")


def test_the_residual_mode_refuses_navigation_errors():
    with pytest.raises(ValueError, match=r"action='residual'.*navigation errors"):
        EnvConfig(action="residual", nav_sigma_position=1.0)
    EnvConfig(action="residual", thrust_sigma_magnitude=0.05)  # thrust errors are fine


def test_in_a_swarm_the_base_law_flies_each_chaser_to_its_own_targets():
    """With several chasers per field each row's base command steers toward that chaser's own
    current goal (the targets assigned to the others read as taken): at the first step every
    chaser's command points at its assigned target, and zero corrections complete the Easy
    swarm's missions (each chaser its own target, no collision, no teammate contact)."""
    pytest.importorskip("pettingzoo")
    from debris_gym import swarm

    env = swarm.make("DebrisGym/Swarm2D-Easy-v0", action="residual")
    for seed in range(8):
        env.reset(seed=seed)
        batch = env.core.shell.batch
        commands = batch.base_commands()
        m, f = batch.missions, batch.field_arrays
        for i in range(batch.num):
            own = np.flatnonzero(m.assigned[i])
            assert own.size == 1  # Easy: two chasers, two targets, one each
            toward = f.centers[i // 2, own[0]] - m.state[i, :2]
            assert commands[i] @ toward > 0.5 * np.linalg.norm(commands[i]) * np.linalg.norm(toward)
        while env.agents:
            _, _, _, _, info = env.step({a: np.zeros(2, dtype=np.float32) for a in env.agents})
        last = next(iter(info.values()))
        assert last["team_success"] and last["team_captures"] == 2
        assert not any(i["collision"] or i["teammate_collision"] for i in info.values())


def test_the_base_law_agent_flies_the_continuous_env_only():
    with pytest.raises(ValueError, match=r"needs action='continuous'"):
        make_agent("base-law", gym.make(EASY, action="residual"))
    with pytest.raises(ValueError, match="navigation errors"):
        make_agent("base-law", gym.make(EASY, nav_sigma_position=1.0))


def test_base_commands_refuses_rows_out_of_range():
    env = gym.make(EASY)
    env.reset(seed=0)
    batch = env.unwrapped.batch
    with pytest.raises(ValueError, match=r"rows must be indices in \[0, 0\]"):
        base_law.base_commands(batch.base_law, batch.missions, batch.field_arrays, [1])


def test_a_policy_trained_in_the_residual_mode_is_flown_in_it(tmp_path):
    """evaluate.py makes a learned agent's env with the options its run trained with: for a
    residual run that includes the action mode (its actions alone are no thrust command)."""
    import agents

    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text(f"env_id: {EASY}\nenv_kwargs: {{action: residual}}\n")
    assert agents.observation_options(f"ppo:{run / 'model.zip'}", EASY)["action"] == "residual"
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "config.yaml").write_text(f"env_id: {EASY}\nenv_kwargs: {{}}\n")
    assert "action" not in agents.observation_options(f"ppo:{plain / 'model.zip'}", EASY)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    x=st.floats(-400.0, 400.0),
    y=st.floats(-400.0, 400.0),
    vx=st.floats(-2.0, 2.0),
    vy=st.floats(-2.0, 2.0),
    action=st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
    model=st.sampled_from(["ball", "box"]),
)
def test_any_state_gets_a_feasible_command_and_the_sum_is_what_flies(x, y, vx, vy, action, model):
    """Wherever the chaser is and however it moves, the law's command is finite and inside the
    thrust model's set, and a residual step applies the thrust of clip(base + action)."""
    target = np.array([200.0, 150.0, 0.1, -2 * N * 200.0])
    if math.hypot(x - 200.0, y - 150.0) < TARGET_RADIUS + CHASER_RADIUS + 1.0:
        return  # in contact with the target: not a state a reset accepts
    chaser = np.array([x, y, vx, vy])
    base, env = command_at(target, chaser, moving=True, thrust_model=model, action="residual")
    assert np.all(np.isfinite(base))
    if model == "ball":
        assert np.linalg.norm(base) <= 1.0 + 1e-12
    else:
        assert np.all(np.abs(base) <= 1.0)
    command = np.clip(base + np.asarray(action), -1.0, 1.0)
    *_, info = env.step(np.asarray(action))
    scale = max(1.0, float(np.linalg.norm(command))) if model == "ball" else 1.0
    np.testing.assert_allclose(info["applied_accel"], MAX_ACCEL * command / scale, rtol=1e-12)
