"""The teammates as moving bodies of an MPC team member: their predicted tracks, the keep-out
half-spaces around them, what a chaser's view reports of them, and a team that keeps apart
where teammate-blind members collide."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("pettingzoo")

from agents import make_agent
from agents.control.mpc import MPCParams
from agents.planners.teammates import MovingSpheres, predict_tracks, sphere_halfspaces
from agents.policies.chaser_view import ChaserView
from agents.policies.shield import ShieldParams
from agents.policies.team import TeamOfSingles, start_episode
from debris_gym import swarm
from debris_gym.dynamics import discretize
from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Body, Scenario

EASY, R2D = "DebrisGym/Swarm2D-Easy-v0", "DebrisGym/Reconfigure2D-v0"
N_LEO, DT = 1.1314e-3, 10.0


def _fly(model, x: np.ndarray, controls: np.ndarray) -> np.ndarray:
    """States (len(controls) + 1, 2·dim) from ``x`` under ``controls`` (m/s², one per step)."""
    out = [x]
    for u in controls:
        x = model.ad @ x + model.bd @ u
        out.append(x)
    return np.array(out)


# --- predicted tracks -----------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    dim=st.sampled_from([2, 3]),
    lag=st.integers(0, 6),
    plan_steps=st.integers(6, 12),
    deviation=st.floats(0.0, 5.0),
)
def test_a_teammate_flying_the_rest_of_its_plan_is_predicted_exactly(
    seed, dim, lag, plan_steps, deviation
):
    """Planned at t_p from x_p, then pushed off by a deviation, it flies the rest of its planned
    thrust and then coasts: the prediction from its state now is that flight, step for step."""
    rng = np.random.default_rng(seed)
    model = discretize(N_LEO, DT, dim)
    controls = rng.uniform(-0.05, 0.05, size=(plan_steps, dim))
    x_plan = np.concatenate([rng.uniform(-200, 200, dim), rng.uniform(-1, 1, dim)])
    plan = _fly(model, x_plan, controls)
    x_now = plan[lag] + deviation * rng.normal(size=2 * dim)
    steps = 10
    rest = np.zeros((steps, dim))
    rest[: max(plan_steps - lag, 0)] = controls[lag:][:steps]
    truth = _fly(model, x_now, rest)[:, :dim]
    tracks = predict_tracks(
        x_now[None], [plan], np.array([lag]), np.array([False]), model.ad, steps
    )
    np.testing.assert_allclose(tracks[0], truth, rtol=0, atol=1e-8)


def test_a_teammate_without_a_plan_coasts_and_a_held_one_stands_still():
    model = discretize(N_LEO, DT, 2)
    states = np.array([[30.0, -10.0, 0.1, 0.2], [5.0, 7.0, 0.3, -0.1]])
    tracks = predict_tracks(
        states, [None, np.zeros((4, 4))], np.zeros(2), np.array([False, True]), model.ad, 5
    )
    coast = _fly(model, states[0], np.zeros((5, 2)))[:, :2]
    np.testing.assert_allclose(tracks[0], coast, rtol=0, atol=1e-12)
    assert np.all(tracks[1] == states[1, :2])  # held: not moved by its plan nor by CW motion


# --- keep-out half-spaces -------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), count=st.integers(1, 4), spheres=st.integers(1, 6))
def test_every_point_of_a_teammates_half_space_keeps_its_distance_now_and_one_step_on(
    seed, count, spheres
):
    rng = np.random.default_rng(seed)
    steps = 3
    tracks = rng.uniform(-20, 20, size=(spheres, steps + 1, 2))
    radii = rng.uniform(0.5, 3.0, spheres)
    keep = rng.uniform(0.0, 3.0, spheres)
    points = rng.uniform(-30, 30, size=(steps + 1, 2))
    normals, offsets, carried = sphere_halfspaces(points, MovingSpheres(tracks, radii), keep, count)
    assert np.isfinite(offsets).sum(axis=1).tolist() == [min(count, spheres)] * (steps + 1)
    probes = rng.uniform(-40, 40, size=(4000, 2))
    centre_dist = np.linalg.norm(points[:, None, :] - tracks.transpose(1, 0, 2), axis=2)
    chosen = np.sort(centre_dist - radii - keep, axis=1)[:, : min(count, spheres)]
    for k in range(steps + 1):
        for m in np.flatnonzero(np.isfinite(offsets[k])):
            inside = probes[probes @ normals[k, m] >= offsets[k, m]]
            gaps = np.linalg.norm(inside[:, None] - tracks[:, k][None], axis=2) - radii - keep
            # the half-space keeps clear of the sphere it was taken from (one of the nearest)
            assert np.any(np.all(gaps >= -1e-9, axis=0)), (k, m)
            if k < steps:  # carried one step on with that sphere: clear of it there too
                moved = probes[probes @ normals[k, m] >= carried[k, m]]
                later = np.linalg.norm(moved[:, None] - tracks[:, k + 1][None], axis=2)
                assert np.any(np.all(later - radii - keep >= -1e-9, axis=0)), (k, m)
        taken = normals[k, np.isfinite(offsets[k])]
        dist_taken = np.sort(
            (points[k] @ taken.T) - offsets[k][np.isfinite(offsets[k])]
        )  # n·p̂ − b = |p̂ − c| − r − keep for a sphere's supporting half-space
        np.testing.assert_allclose(dist_taken, chosen[k], atol=1e-9)  # the nearest ones


# --- the view's teammates -------------------------------------------------------------------------


def _field(env):
    return env.core, env.core.shell.batch_in_use


def test_a_view_reports_flying_and_held_teammates_as_spheres_of_the_collision_distance():
    env = swarm.make(R2D, n_chasers=3, r_col=3.0)
    env.reset(seed=5)
    core, batch = _field(env)
    slots = batch.field.centers[0, 0] + core.formation
    states = np.zeros((3, 4))
    states[0, :2] = slots[0]  # held at its slot after the first step
    states[1, :2] = slots[1] + np.array([40.0, 0.0])
    states[2, :2] = slots[2] + np.array([0.0, 60.0])
    env.reset(seed=5, options={"chaser_state": states, "assignment": [0, 1, 2]})
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert env.agents == ["chaser_1", "chaser_2"]  # chaser 0 arrived and is held
    view = ChaserView(env.core, 1)
    mates = view.teammates(5)
    assert mates.count == 2
    np.testing.assert_allclose(mates.radii, 3.0 - env.config.chaser_radius)
    held, flying = mates.tracks
    assert np.all(held == batch.missions.state[0, :2])  # where it ended, at every step
    assert np.linalg.norm(held[0] - slots[0]) < env.config.capture_radius
    now = batch.missions.state[2]
    coast = _fly(discretize(env.config.n, env.config.dt, 2), now, np.zeros((5, 2)))
    np.testing.assert_allclose(flying, coast[:, :2], rtol=0, atol=1e-9)  # no plan: it coasts


def test_a_capture_missions_chaser_that_ended_is_no_teammate():
    env = swarm.make(EASY)
    env.reset(seed=3)
    env.core.flying[0] = False  # as after a collision: it left the field
    assert ChaserView(env.core, 1).teammates(4).count == 0
    assert ChaserView(env.core, 0).teammates(4).count == 1


def test_a_member_predicts_a_teammate_that_decided_before_it_where_that_one_goes_next():
    env = swarm.make(EASY)
    team = TeamOfSingles(env, "apf-mpc")
    observations, _, _ = start_episode(env, team, seed=2)
    d = env.config.dim
    checked = 0
    for _ in range(15):
        if len(env.agents) < 2:
            break
        actions = team.predict(observations)
        predicted = team.views[1].teammates(3).tracks[0]  # chaser 0 decided first
        observations, *_ = env.step(actions)
        now = env.core.shell.batch_in_use.missions.state[0, :d]
        if team.plans.get(0) is not None:
            # one step on, the plan is what it flew (to the float32 rounding of its action)
            assert np.linalg.norm(predicted[1] - now) < 1e-3
            checked += 1
    assert checked >= 10


# --- teams ----------------------------------------------------------------------------------------


def _head_on(env) -> dict:
    """A pinned field where the two chasers' targets lie each behind the other chaser: 80 m
    apart on the V-bar, at rest, they must pass each other."""
    cfg = env.config
    targets = (Body((0.0, 120.0), 5.0, (0.0, 0.0)), Body((0.0, -120.0), 5.0, (0.0, 0.0)))
    scenario = Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0), targets=targets,
        mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel, motion="cwh",
    )  # fmt: skip
    states = np.zeros((2, 4))
    states[0, 1], states[1, 1] = -40.0, 40.0
    return {"scenario": scenario, "chaser_state": states, "assignment": [[0], [1]]}


@pytest.mark.parametrize("teammates", [3, 0])
def test_chasers_flying_head_on_keep_apart_only_when_their_mpc_sees_the_teammates(teammates):
    env = swarm.make(EASY)
    team = TeamOfSingles(env, "apf-mpc", mpc=MPCParams(teammates_per_step=teammates))
    observations, _ = env.reset(seed=0, options=_head_on(env))
    r_col = float(env.core.shell.batch_in_use.rules.chaser_separation)
    while env.agents:
        observations, _, _, _, infos = env.step(team.predict(observations))
    separation = float(env.core.min_separation()[0])
    collided = env.core.shell.batch_in_use.missions.collision[:2]
    if teammates:
        assert separation > r_col and not collided.any()
        assert env.core.team_success()[0]
    else:  # blind to each other, they fly straight into each other
        assert separation <= r_col and collided.all()


@pytest.mark.parametrize("teammates", [3, 0])
def test_a_reconfiguring_team_leaves_its_lattice_without_contact_only_when_seeing_teammates(
    teammates,
):
    """Six chasers start 5 m apart (2 m collide) and head out together."""
    env = swarm.make(R2D)
    team = TeamOfSingles(env, "apf-mpc", mpc=MPCParams(teammates_per_step=teammates))
    observations, _, _ = start_episode(env, team, seed=3)
    while env.agents:
        observations, *_ = env.step(team.predict(observations))
    m = env.core.shell.batch_in_use.missions
    if teammates:
        assert env.core.team_success()[0] and not m.collision[:6].any()
        assert env.core.min_separation()[0] > env.core.shell.batch_in_use.rules.chaser_separation
    else:
        assert m.collision[:6].any()


@pytest.mark.parametrize("shielded", [True, False])
def test_a_pair_aware_shield_keeps_teammate_blind_chasers_apart_head_on(shielded):
    env = swarm.make(EASY)
    blind = MPCParams(teammates_per_step=0)
    shield = ShieldParams() if shielded else None
    team = TeamOfSingles(env, "apf-mpc", shield=shield, mpc=blind)
    observations, _ = env.reset(seed=0, options=_head_on(env))
    while env.agents:
        observations, *_ = env.step(team.predict(observations))
    r_col = float(env.core.shell.batch_in_use.rules.chaser_separation)
    collided = env.core.shell.batch_in_use.missions.collision[:2]
    if shielded:
        assert env.core.min_separation()[0] > r_col and not collided.any()
        assert all(stats.interventions >= 1 for stats in team.shield_stats)
    else:
        assert collided.all() and team.shield_stats == []


def test_a_single_env_agent_has_no_teammates_and_its_mpc_no_teammate_rows():
    env = DebrisFieldEnv()
    env.reset(seed=0)
    agent = make_agent("apf-mpc", env)
    agent.predict(env.observation_space.sample())
    assert agent.tracker.T == 0 and agent.planned_states() is None


def test_bad_teammate_parameters_are_named():
    with pytest.raises(ValueError, match="teammates_per_step must be an integer >= 0"):
        MPCParams(teammates_per_step=-1)
    with pytest.raises(ValueError, match=r"tracks must be \(J, S \+ 1, dim\)"):
        MovingSpheres(np.zeros((2, 3)), np.zeros(2))
    with pytest.raises(ValueError, match="radii must be 2 finite values"):
        MovingSpheres(np.zeros((2, 3, 2)), np.array([1.0, -1.0]))
