"""The swarm envs: one chaser is the single-agent mission bit for bit, chaser–chaser contacts
against the closed-form CW solution, shared captures, relabelling, bad input, and PettingZoo's
own API tests."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("pettingzoo")

from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    state_test,
)

from debris_gym import swarm
from debris_gym.swarm.assignment import balanced_assignment
from debris_gym.swarm.config import dock_slots
from tests.helpers import cw_closed_form

EASY = "DebrisGym/Swarm2D-Easy-v0"


def fly_both(single_id: str, swarm_id: str, seed: int, steps: int, **options) -> int:
    """Fly the single-agent ID and a one-chaser swarm with the same seed and random actions;
    every observation, reward, flag and info value must be equal. Returns the steps flown."""
    single = gym.make(single_id)
    team = swarm.make(swarm_id, n_chasers=1, **options)
    obs1, info1 = single.reset(seed=seed)
    obs2, info2 = team.reset(seed=seed)
    assert np.array_equal(obs1, obs2["chaser_0"])
    rng = np.random.default_rng(seed)
    dim = single.unwrapped.dim
    for step in range(steps):
        action = rng.uniform(-1.0, 1.0, dim).astype(np.float32)
        if step % 3 == 0:  # gentle steps too: slow approaches, holds
            action *= 0.05
        obs1, r1, term1, trunc1, info1 = single.step(action)
        obs2, r2, term2, trunc2, info2 = team.step({"chaser_0": action})
        assert np.array_equal(obs1, obs2["chaser_0"]), step
        assert r1 == r2["chaser_0"], step
        assert term1 == term2["chaser_0"] and trunc1 == trunc2["chaser_0"], step
        for key, value in info1.items():
            np.testing.assert_array_equal(
                np.asarray(value if key != "reward_terms" else list(value.values())),
                np.asarray(
                    info2["chaser_0"][key]
                    if key != "reward_terms"
                    else list(info2["chaser_0"][key].values())
                ),
                err_msg=f"{key} at step {step}",
            )
        if term1 or trunc1:
            assert team.agents == []
            return step + 1
    return steps


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_chaser_is_the_single_agent_mission_bit_for_bit_2d(seed):
    """A swarm of one (the field loop of the compiled step) flies the v2 mission exactly as the
    single env (the row loop): observations, rewards, flags and infos equal."""
    fly_both(
        "DebrisGym/Rendezvous2D-v2", "DebrisGym/Swarm2D-v0", seed, 300, n_targets=3,
        shaping_potential="tour",
    )  # fmt: skip


def test_one_chaser_is_the_single_agent_mission_bit_for_bit_3d():
    fly_both(
        "DebrisGym/Rendezvous3D-v2", "DebrisGym/Swarm3D-v0", 5, 200, n_targets=3,
        shaping_potential="tour",
    )  # fmt: skip


def two_chasers(
    rel_state: np.ndarray, dt_steps: int = 1, **options
) -> tuple[dict, swarm.SwarmParallelEnv]:
    """Chaser 0 at rest at the dock (it stays there: the origin is an equilibrium), chaser 1
    at ``rel_state``; both coast ``dt_steps`` steps; the last step's infos."""
    env = swarm.make(EASY, **options)
    d = env.config.dim
    states = np.zeros((2, 2 * d))
    states[1] = rel_state
    env.reset(seed=7, options={"chaser_state": states})
    infos: dict = {}
    for _ in range(dt_steps):
        if not env.agents:
            break
        _, _, _, _, infos = env.step({a: np.zeros(d, dtype=np.float32) for a in env.agents})
    return infos, env


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    x=st.floats(-20.0, 20.0), y=st.floats(-20.0, 20.0),
    vx=st.floats(-2.0, 2.0), vy=st.floats(-2.0, 2.0),
)  # fmt: skip
def test_chaser_contacts_against_the_closed_form(x, y, vx, vy):
    """Two coasting chasers collide in a step iff the closed-form CW solution, sampled densely,
    brings their centres within r_col (2 m: the chasers touch); cases within 5 cm of the
    boundary are left out (the swept check follows chords between sub-steps)."""
    state = np.array([x, y, vx, vy])
    if np.hypot(x, y) <= 3.0:
        return
    env = swarm.make(EASY)
    n, dt = env.config.n, env.config.dt
    times = np.linspace(0.0, dt, 2001)
    closest = min(np.hypot(*cw_closed_form(state, t, n)[:2]) for t in times)
    if abs(closest - 2.0) < 0.05:
        return
    infos, _ = two_chasers(state)
    assert infos["chaser_1"]["teammate_collision"] == (closest < 2.0)
    assert infos["chaser_0"]["teammate_collision"] == (closest < 2.0)  # both collide
    assert infos["chaser_1"]["separation"] == pytest.approx(closest, abs=0.05)


def test_a_teammate_collision_ends_both_and_is_penalised():
    infos, env = two_chasers(np.array([4.0, 0.0, -0.5, 0.0]))
    for agent in ("chaser_0", "chaser_1"):
        assert infos[agent]["collision"] and infos[agent]["teammate_collision"]
        assert infos[agent]["reward_terms"]["collision"] == -env.config.reward_collision
    assert env.agents == []
    assert infos["chaser_0"]["min_separation"] < 2.0


def beside_target_0(env, seed: int, options: dict | None = None) -> np.ndarray:
    """(2, 2·dim) initial states: chaser 0 at the dock, chaser 1 parked 2 m off target 0's
    surface (2D), moving with it, in the field of ``env.reset(seed=seed, options=options)``."""
    env.reset(seed=seed, options=options)
    field, d = env.core.shell.batch_in_use.field, env.config.dim
    gap = field.radii[0, 0] + env.config.chaser_radius + 2.0
    states = np.zeros((2, 2 * d))
    states[1, :d] = field.centers[0, 0] + np.array([gap, 0.0])
    states[1, d:] = field.velocities[0, 0]
    return states


def test_a_target_captured_by_one_chaser_is_captured_for_all():
    """Park chaser 1 beside target 0, still relative to it: it holds and captures; the capture
    shows in every chaser's captured flags, the bonus only in the holder's reward."""
    env = swarm.make(EASY, return_to_dock=False, assignment="free")
    states = beside_target_0(env, seed=11)
    d = env.config.dim
    env.reset(seed=11, options={"chaser_state": states})
    bonus = 0.0
    for _ in range(6):
        _, rewards, _, _, infos = env.step({a: np.zeros(d, np.float32) for a in env.agents})
        bonus += infos["chaser_1"]["reward_terms"]["capture"]
        assert infos["chaser_0"]["reward_terms"]["capture"] == 0.0
        if infos["chaser_1"]["captured"][0]:
            break
    assert infos["chaser_1"]["captured"][0] and infos["chaser_0"]["captured"][0]
    assert bonus == env.config.reward_capture
    assert infos["chaser_0"]["team_captures"] >= 1


def test_relabelling_the_chasers_permutes_the_outputs():
    """Chasers swapped (initial states and actions swapped) give the swapped outputs (no
    return: the dock slots, which go by agent index, then play no part)."""
    d = 2
    states = np.zeros((3, 2 * d))
    states[0, :2], states[1, :2], states[2, :2] = (0.0, 0.0), (10.0, 0.0), (0.0, -12.0)
    perm = [2, 0, 1]
    rng = np.random.default_rng(3)
    actions = rng.uniform(-0.3, 0.3, (40, 3, d)).astype(np.float32)
    runs = []
    for order in (list(range(3)), perm):
        env = swarm.make("DebrisGym/Swarm2D-v0", dock_spacing=6.0, return_to_dock=False)
        obs, _ = env.reset(seed=21, options={"chaser_state": states[order]})
        trace = [obs]
        for a in actions:
            if not env.agents:
                break
            act = {f"chaser_{j}": a[order][j] for j in range(3) if f"chaser_{j}" in env.agents}
            trace.append(env.step(act))
        runs.append(trace)
    (first, *steps_a), (first_b, *steps_b) = runs
    for j in range(3):
        assert np.array_equal(first[f"chaser_{j}"][:4], first_b[f"chaser_{perm.index(j)}"][:4])
    for out_a, out_b in zip(steps_a, steps_b):
        obs_a, rew_a = out_a[0], out_a[1]
        obs_b, rew_b = out_b[0], out_b[1]
        for j in range(3):
            name_a, name_b = f"chaser_{j}", f"chaser_{perm.index(j)}"
            if name_a in obs_a:
                assert np.array_equal(obs_a[name_a][:4], obs_b[name_b][:4])
                assert np.array_equal(obs_a[name_a][-14:], obs_b[name_b][-14:])  # teammates
                assert rew_a[name_a] == rew_b[name_b]


def test_dock_slots_are_apart_and_start_at_the_dock():
    for k in (1, 2, 7, 48, 256):
        slots = dock_slots(k, 5.0, 3)
        assert slots.shape == (k, 3) and np.all(slots[0] == 0.0) and np.all(slots[:, 2] == 0.0)
        gaps = np.linalg.norm(slots[:, None] - slots[None], axis=-1) + np.eye(k) * 1e9
        assert gaps.min() >= 5.0 - 1e-9


@pytest.mark.parametrize(
    "options, match",
    [
        ({"n_chasers": 0}, r"n_chasers=0 is out of range; allowed: \[1, 256\]"),
        ({"n_chasers": 257}, r"n_chasers=257"),
        ({"r_col": 1.0}, r"r_col=1.0 m is out of range"),
        ({"dock_spacing": 2.0}, r"dock_spacing=2.0 m is out of range"),
        ({"reward_team": -1.0}, r"reward_team=-1.0"),
        ({"obs_teammates": 5}, r"obs_teammates=5 is out of range for 2 chasers"),
        ({"n_chasers": 256, "dock_spacing": 9.0}, r"beyond its clear zone"),
    ],
)
def test_bad_options_name_the_key_and_range(options, match):
    with pytest.raises(ValueError, match=match):
        swarm.make(EASY, **options)


def test_bad_actions_are_refused():
    env = swarm.make(EASY)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no action for"):
        env.step({"chaser_0": np.zeros(2, np.float32)})
    with pytest.raises(ValueError, match="finite"):
        env.step({"chaser_0": np.array([np.nan, 0.0]), "chaser_1": np.zeros(2)})
    with pytest.raises(ValueError, match="not flying"):
        env.step({"chaser_0": np.zeros(2), "chaser_1": np.zeros(2), "chaser_9": np.zeros(2)})
    with pytest.raises(ValueError, match="unknown swarm ID"):
        swarm.make("DebrisGym/Swarm9D-v0")
    with pytest.raises(ValueError, match="obs_teammates=1 is a swarm option"):
        gym.make("DebrisGym/Rendezvous2D-v2", obs_teammates=1)


def test_pettingzoo_parallel_api():
    parallel_api_test(swarm.make(EASY), num_cycles=300)


def test_pettingzoo_parallel_seed():
    parallel_seed_test(lambda: swarm.make(EASY), num_cycles=100)


def test_pettingzoo_aec_api():
    api_test(swarm.env(n_chasers=2, n_targets=2, n_obstacles=5), num_cycles=100)


class _GentleEasy:
    """The Easy rung as a module for PettingZoo's max_cycles_test, with a thrust too weak to
    reach anything within the test's few cycles (it flies random actions and needs every chaser
    alive until the time limit): 0.001 m/s² moves a chaser at most 0.5 · 0.001 · (40 s)² =
    0.8 m in 4 steps, and the chasers start 5 m apart, 3 m more than their contact distance."""

    @staticmethod
    def parallel_env(**options):
        return swarm.make(EASY, max_accel=0.001, **options)

    @staticmethod
    def env(**options):
        from pettingzoo.utils.conversions import parallel_to_aec

        return parallel_to_aec(_GentleEasy.parallel_env(**options))


def test_pettingzoo_max_cycles():
    max_cycles_test(_GentleEasy)
    assert swarm.make(EASY, max_cycles=7).max_episode_steps == 7
    with pytest.raises(ValueError, match="max_cycles or max_episode_steps"):
        swarm.make(EASY, max_cycles=7, max_episode_steps=8)


def test_pettingzoo_state():
    state_test(swarm.env(), swarm.parallel_env(), num_cycles=20)


@pytest.mark.filterwarnings("ignore::debris_gym.envs.rendering.NoDisplayWarning")
def test_pettingzoo_render():
    render_test(lambda render_mode=None: swarm.env(render_mode=render_mode))


def test_a_frame_shows_every_chaser_with_its_path():
    # dock slots 30 m apart: about 14 pixels on the 480-pixel panel of a 1 km field
    env = swarm.make("DebrisGym/Swarm2D-v0", render_mode="rgb_array", dock_spacing=30.0)
    env.reset(seed=0)
    for _ in range(4):
        env.step({a: np.array([0.0, 0.2]) for a in env.agents})  # gently along-track
    assert len(env.agents) == 3
    trails = env.trails
    assert [len(t) for t in trails] == [5, 5, 5]
    np.testing.assert_allclose(trails[1][0, :2], [30.0, 0.0])  # each path from its own slot
    frame = env.render()
    assert frame.shape[2] == 3 and frame.dtype == np.uint8
    chaser = np.array([0x1F, 0x5F, 0xD0])  # the chaser marker colour
    ys, xs = np.nonzero(np.all(np.abs(frame.astype(int) - chaser) <= 8, axis=2))
    assert len(xs) > 0
    # the markers apart: their pixels span more than one marker's width (about 9 pixels)
    assert max(xs.max() - xs.min(), ys.max() - ys.min()) > 12
    with pytest.raises(ValueError, match="render_mode='ansi'"):
        swarm.make(EASY, render_mode="ansi")


def test_state_is_every_observation_in_agent_order():
    env = swarm.make("DebrisGym/Swarm2D-v0")
    obs, _ = env.reset(seed=4)
    state = env.state()
    assert env.state_space.contains(state)
    assert np.array_equal(state, np.concatenate([obs[a] for a in env.possible_agents]))


def brute_force_cost(gaps: np.ndarray) -> float:
    """The least total gap of any assignment of every target to one chaser, each chaser at most
    ⌈T / K⌉ targets: every map from targets to chasers, enumerated."""
    k, t = gaps.shape
    places = -(-t // k)
    best = np.inf
    for owners in itertools.product(range(k), repeat=t):
        if max(owners.count(c) for c in range(k)) <= places:
            best = min(best, sum(gaps[c, j] for j, c in enumerate(owners)))
    return float(best)


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 4), t=st.integers(1, 6), seed=st.integers(0, 2**32 - 1),
)  # fmt: skip
def test_the_balanced_assignment_is_the_brute_force_optimum(k, t, seed):
    rng = np.random.default_rng(seed)
    docks, centers = rng.uniform(-50, 50, (k, 2)), rng.uniform(-400, 400, (t, 2))
    radii = rng.uniform(3, 10, t)
    out = balanced_assignment(docks, centers, radii)
    assert out.shape == (k, t) and np.all(out.sum(axis=0) == 1)
    assert out.sum(axis=1).max() <= -(-t // k)
    gaps = np.linalg.norm(docks[:, None] - centers[None], axis=-1) - radii
    assert gaps[out].sum() == pytest.approx(brute_force_cost(gaps), rel=1e-12, abs=1e-9)


@pytest.mark.parametrize(
    "value, match",
    [
        ([[0], [0]], "target 0 to 2 chasers"),
        ([[0], []], "target 1 to 0 chasers"),
        ([[0, 5], [1]], r"assignment\[0\] holds 5"),
        ([[0, 1]], "must be 2 lists"),
        (np.ones((2, 3), dtype=bool), r"shape \(2, 2\)"),
    ],
)
def test_a_bad_assignment_names_what_is_wrong(value, match):
    env = swarm.make(EASY, assignment="given")
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options={"assignment": value})


def test_a_given_target_is_its_chasers_alone():
    """With assignment="given" a chaser holding beside another chaser's target captures
    nothing; beside its own it captures it, for the team; the team succeeds only when every
    target is captured."""
    env = swarm.make(EASY, assignment="given", return_to_dock=False)
    states = beside_target_0(env, seed=11, options={"assignment": [[1], [0]]})
    d = env.config.dim
    for owner, captures in ((0, False), (1, True)):
        env.reset(
            seed=11,
            options={
                "chaser_state": states,
                "assignment": [[1], [0]] if owner == 1 else [[0], [1]],
            },
        )
        infos: dict = {}
        for _ in range(6):  # the last info of each chaser (one that succeeds leaves)
            infos.update(env.step({a: np.zeros(d, np.float32) for a in env.agents})[4])
        assert infos["chaser_1"]["assigned"][0] == captures
        assert infos["chaser_1"]["is_success"] == captures  # its one target: its whole task
        assert bool(infos["chaser_1"]["captured"][0]) == captures
        assert bool(infos["chaser_0"]["captured"][0]) == captures  # the team's flags
        assert not infos["chaser_1"]["team_success"]  # target 1 is still out there


def test_a_reset_without_assignment_uses_the_balanced_rule():
    env = swarm.make("DebrisGym/Swarm2D-v0", assignment="given")
    env.reset(seed=3)
    batch = env.core.shell.batch_in_use
    expected = balanced_assignment(batch.dock, batch.field.centers[0, :6], batch.field.radii[0, :6])
    assert np.array_equal(batch.missions.assigned, expected)
    assert expected.sum(axis=1).tolist() == [2, 2, 2]
    with pytest.raises(ValueError, match="needs an env made with assignment='given'"):
        swarm.make(EASY, assignment="free").reset(seed=0, options={"assignment": [[0], [1]]})
