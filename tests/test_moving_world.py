"""The moving world (v1 rules) from outside: bodies on CW motion, solid bodies, honest capture.

Truth here is independent of the library: the textbook closed-form CW solution typed into
``tests.helpers.cw_closed_form`` ([Curtis14] eq. 7.53; [Vallado13] §6.8), dense sampling of it
for first contacts, and plain trigonometry for turning polygons. The envs fly pinned
``motion="cwh"`` scenarios with the moving-world options (what the v1 IDs register).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from debris_gym.envs import DebrisFieldEnv
from debris_gym.envs.vector import DebrisFieldVectorEnv
from debris_gym.scenario import Body, Scenario
from tests.helpers import (
    LEO_MEAN_MOTION,
    MOVING_DT,
    MOVING_WORLD,
    cw_closed_form,
    flies_old_ids,
    moving_scenario,
)

pytestmark = pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")

N = LEO_MEAN_MOTION
DT = MOVING_DT
MOVING = MOVING_WORLD
cw = cw_closed_form


def drift_free(x0: float, y0: float, vx0: float, dim: int = 2, z0: float = 0.0) -> tuple:
    """A body state on a closed relative orbit (ẏ₀ = −2n x₀)."""
    if dim == 2:
        return (x0, y0), (vx0, -2 * N * x0)
    return (x0, y0, z0), (vx0, -2 * N * x0, 0.1)


def field(dim: int) -> Scenario:
    """Bodies on assorted closed and drifting orbits, away from the dock for 20 minutes."""
    bodies = []
    for k, (x, y) in enumerate([(150, 200), (-120, 260), (200, -220), (-180, -240), (60, 330)]):
        pos, vel = drift_free(x, y, 0.05 * (-1) ** k, dim)
        if k == 4:  # a drifting one
            vel = (vel[0], vel[1] + 0.02, *vel[2:])
        bodies.append(Body(position=pos, radius=5.0 + k, velocity=vel))
    if dim == 2:
        square = ((4.0, 0.0), (0.0, 4.0), (-4.0, 0.0), (0.0, -4.0))
        pos, vel = drift_free(-250.0, 60.0, 0.02)
        bodies.append(Body(pos, 4.0, vel, square, spin=0.01))
    return moving_scenario(bodies[:2], bodies[2:], dim)


@pytest.mark.parametrize("dim", [2, 3])
def test_bodies_follow_the_closed_form_over_an_episode(dim):
    scen = field(dim)
    env = DebrisFieldEnv(dim=dim, **MOVING)
    env.reset(seed=0, options={"scenario": scen})
    starts = [np.array([*b.position, *b.velocity]) for b in scen.bodies]
    worst = 0.0
    for k in range(1, 121):
        *_, info = env.step(np.zeros(dim))
        t = k * DT
        assert info["time"] == pytest.approx(t)
        states = env.body_states
        for b, s0 in enumerate(starts):
            worst = max(worst, float(np.abs(states[b] - cw(s0, t)).max()))
    assert worst < 1e-6
    # the vector env moves them the same way
    venv = DebrisFieldVectorEnv(3, dim=dim, **MOVING)
    venv.reset(seed=0, options={"scenario": scen})
    for _ in range(120):
        venv.step(np.zeros((3, dim)))
    f = venv.batch.field
    for b, s0 in enumerate(starts):
        truth = cw(s0, 120 * DT)
        for i in range(3):
            np.testing.assert_allclose(f.centers[i, b], truth[:dim], atol=1e-6)
            np.testing.assert_allclose(f.velocities[i, b], truth[dim:], atol=1e-9)


def test_a_polygon_keeps_its_inertial_attitude_plus_its_spin():
    scen = field(2)
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(seed=0, options={"scenario": scen})
    b = len(scen.bodies) - 1
    body = scen.bodies[b]
    for _ in range(50):
        env.step(np.zeros(2))
    t = 50 * DT
    angle = (body.spin - N) * t  # inertially fixed turns at −n in LVLH, plus the tumble
    centre = cw(np.array([*body.position, *body.velocity]), t)[:2]
    c, s = math.cos(angle), math.sin(angle)
    corner = centre + np.array([4.0 * c, 4.0 * s])  # vertex (4, 0) turned by the angle
    outward = (corner - centre) / 4.0
    # points just outside / inside that corner: the env's gap changes sign there
    # just outside the corner the gap is the distance to it; just inside, the depth behind
    # the two edges that meet there at 45 degrees to the corner's direction
    for offset, expected in ((0.5, 0.5), (-0.5, -0.5 / math.sqrt(2))):
        gap = env.geometry.signed_distance(corner + offset * outward)[b]
        assert gap == pytest.approx(expected, abs=1e-9)


def crossing_body(t_meet: float, speed: float, miss: float, dim: int = 2) -> Body:
    """A body whose CW path passes ``miss`` m (centre distance) from the origin at t_meet,
    moving at ``speed`` m/s along-track there."""
    state_meet = np.zeros(2 * dim)
    state_meet[0] = miss  # radial offset at the meeting time
    state_meet[dim + 1] = speed
    # back-propagate with the closed form (CW is time-reversible: t → −t)
    state0 = cw(state_meet, -t_meet)
    return Body(position=tuple(state0[:dim]), radius=5.0, velocity=tuple(state0[dim:]))


def first_contact(body: Body, reach: float, horizon: float, dim: int = 2) -> float | None:
    """First time (s) the body's centre comes within ``reach`` of the origin (dense samples)."""
    s0 = np.array([*body.position, *body.velocity])
    for t in np.arange(0.0, horizon, 0.01):
        if np.linalg.norm(cw(s0, t)[:dim]) <= reach:
            return float(t)
    return None


def far_target() -> Body:
    return Body(position=(300.0, -300.0), radius=5.0, velocity=(0.0, -2 * N * 300.0))


@pytest.mark.parametrize("t_meet", [95.0, 233.0])
def test_a_body_crossing_a_chaser_at_rest_collides_at_the_right_step(t_meet):
    body = crossing_body(t_meet, speed=0.6, miss=0.0)
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": moving_scenario([far_target()], [body])})
    contact = first_contact(body, 5.0 + env.config.chaser_radius, 400.0)
    expected_step = math.ceil(contact / DT)
    steps = 0
    terminated = False
    while not terminated and steps < 40:
        *_, terminated, _, info = env.step(np.zeros(2))
        steps += 1
    assert info["collision"] and steps == expected_step


def test_a_body_that_misses_by_a_margin_does_not_collide():
    reach = 5.0 + 1.0
    body = crossing_body(150.0, speed=0.6, miss=reach + 0.5)
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": moving_scenario([far_target()], [body])})
    for _ in range(40):
        *_, terminated, _, info = env.step(np.zeros(2))
        assert not terminated
    assert not info["collision"]
    assert info["min_clearance"] == pytest.approx(0.5, abs=0.05)


def target_beside(gap: float, rel_v=(0.0, 0.0)) -> tuple[Scenario, np.ndarray]:
    """A target on a closed orbit and a chaser ``gap`` m from its surface along-track, with
    velocity ``rel_v`` relative to it (along-track offsets are CW equilibria)."""
    pos, vel = drift_free(200.0, 150.0, 0.1)
    target = Body(position=pos, radius=5.0, velocity=vel)
    offset = 5.0 + 1.0 + gap  # centre to centre
    chaser = np.array([pos[0], pos[1] + offset, vel[0] + rel_v[0], vel[1] + rel_v[1]])
    return moving_scenario([target], []), chaser


def test_coasting_beside_a_moving_target_captures_it_after_the_hold():
    scen, chaser = target_beside(3.0)
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": scen, "chaser_state": chaser})
    hold_steps = 1 + math.ceil(30.0 / DT)  # step ends spanning 30 s
    for k in range(1, hold_steps + 1):
        *_, info = env.step(np.zeros(2))
        assert info["targets_captured"] == (1 if k == hold_steps else 0), k
    assert not info["collision"]


def test_no_capture_when_the_speed_relative_to_the_target_is_too_high():
    scen, chaser = target_beside(3.0, rel_v=(0.0, 0.25))  # drifting away at 0.25 m/s
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": scen, "chaser_state": chaser})
    for _ in range(6):
        *_, info = env.step(np.zeros(2))
    assert info["targets_captured"] == 0


@pytest.mark.parametrize("speed", [0.05, 0.45])
def test_a_slow_pass_into_a_target_is_a_collision(speed):
    scen, chaser = target_beside(2.0, rel_v=(0.0, -speed))  # toward the target's centre
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": scen, "chaser_state": chaser})
    for _ in range(int(20 / speed / DT) + 2):
        *_, terminated, _, info = env.step(np.zeros(2))
        if terminated:
            break
    assert info["collision"]


def test_a_hard_impact_braked_within_the_step_is_a_collision():
    scen, chaser = target_beside(2.0, rel_v=(0.0, -0.9))
    env = DebrisFieldEnv(dim=2, **MOVING)
    env.reset(options={"scenario": scen, "chaser_state": chaser})
    # full thrust away from the target: the step ends slow and outside, the path went in
    *_, terminated, _, info = env.step(np.array([0.0, 1.0]))
    assert terminated and info["collision"]


def test_the_vector_env_flies_a_moving_field_like_the_single_env():
    scen = field(2)
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1, 1, (60, 2))
    env = DebrisFieldEnv(dim=2, **MOVING)
    venv = DebrisFieldVectorEnv(2, dim=2, **MOVING)
    obs, _ = env.reset(seed=1, options={"scenario": scen})
    vobs, _ = venv.reset(seed=1, options={"scenario": scen})
    np.testing.assert_array_equal(vobs[0], obs)
    for a in actions:
        obs, r, term, _, info = env.step(a)
        vobs, vr, vterm, _, vinfo = venv.step(np.stack([a, a]))
        np.testing.assert_array_equal(vobs[0], obs)
        assert vr[0] == r and vterm[0] == term
        assert vinfo["task_score"][0] == info["task_score"]
        if term:
            break


def test_a_pinned_field_must_move_as_the_env_does():
    env = DebrisFieldEnv(dim=2, mean_motion=N)  # a frozen-world env
    with pytest.raises(ValueError, match="debris_motion"):
        env.reset(options={"scenario": field(2)})


@flies_old_ids
@pytest.mark.parametrize("env_id", ["DebrisGym/Rendezvous3D-v0", "DebrisGym/Rendezvous3D-v2"])
def test_the_3d_vector_env_lists_its_fields(env_id):
    """Regression: ``scenarios[i]`` of a 3D vector env raised IndexError (no polygon slots)."""
    import gymnasium as gym

    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    env = gym.make(env_id)
    env.reset(seed=6)  # sub-env 1 was seeded with 5 + 1
    assert venv.unwrapped.scenarios[1] == env.unwrapped.scenario


@pytest.mark.parametrize("env_id", ["DebrisGym/Rendezvous2D-v2", "DebrisGym/Rendezvous3D-v2"])
def test_the_vector_env_gives_the_drawn_field_after_its_bodies_moved(env_id):
    import gymnasium as gym

    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=11)
    for _ in range(20):
        venv.step(np.zeros((2, venv.unwrapped.dim)))
    env = gym.make(env_id)
    env.reset(seed=11)
    assert venv.unwrapped.scenarios[0] == env.unwrapped.scenario
    assert env.unwrapped.scenario.motion == "cwh"
