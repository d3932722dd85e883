"""The compiled mission step (both envs run it) against an independent reference.

``tests/reference_env.py`` is the rules of docs/environments.md written one env at a time in
numpy, with pymunk's segment queries for the swept collision check and the lidar, and the
observation layout written out by hand. The env and the reference fly the same fields (the
env draws them, the reference is handed them) with the same actions; observation names,
observations, rewards, terminations and infos must agree.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.config import EnvConfig
from debris_gym.envs import DebrisFieldEnv
from debris_gym.gap_order import sort_by_gap
from debris_gym.generators import FieldSpec, random_field
from debris_gym.goal import DOCK_GOAL, NO_GOAL, current_goal
from debris_gym.mission_batch import MissionBatch, Physics
from debris_gym.observation import observation_names
from debris_gym.scenario import Body
from tests.helpers import assert_same, assert_same_step, flies_old_ids, simple_scenario
from tests.reference_env import ReferenceDebrisFieldEnv, reference_observation_names

# some tests fly the free-space simple_scenario in envs with the default LEO orbit on purpose;
# the reference is flown against the frozen-world IDs (v0) too
pytestmark = [
    pytest.mark.filterwarnings("ignore:the pinned scenario's physics differ"),
    flies_old_ids,
]

INFO_KEYS = ["chaser_state", "time", "delta_v", "targets_captured", "min_clearance", "collision"]
INFO_KEYS += ["out_of_bounds", "is_success", "captured", "n_targets", "budget_spent", "hold"]

HORIZON = {"DebrisGym/PaperField2D-v0": 2000}


def pd_action(env, obs: np.ndarray, rng: np.random.Generator, noise: float) -> np.ndarray:
    """Fly at the current goal (target slot 0, or the dock once all are captured) and brake:
    a PD law on the observation, plus noise. It captures, collides and succeeds."""
    names = env.unwrapped.observation_names()
    axes = "xyz"[: env.unwrapped.dim]
    goal = "target0_rel_pos" if obs[names.index("target0_captured")] < 0.5 else "dock_rel_pos"
    rel = np.array([obs[names.index(f"{goal}_{a}")] for a in axes])
    vel = np.array([obs[names.index(f"chaser_vel_{a}")] for a in axes])
    action = 2.0 * rel - 4.0 * vel + rng.normal(0.0, noise, len(axes))
    return np.clip(action, -1.0, 1.0).astype(np.float32)


def fly_both(
    env_id: str, episodes: int, scale: float, seed: int, pd: bool = False, **kwargs
) -> dict[str, int]:
    """Fly ``episodes`` episodes in both with the same actions (random ones of size ``scale``,
    or with ``pd`` :func:`pd_action` with noise ``scale``); returns how they ended (counts of
    ``success``, ``collision``, ``out_of_bounds``, ``budget`` and ``truncated`` episodes), the
    ``captures`` and the ``steps`` compared."""
    env = gym.make(env_id, **kwargs)
    spec = gym.spec(env_id)
    config = {**spec.kwargs, **{k: v for k, v in kwargs.items() if k != "max_episode_steps"}}
    horizon = HORIZON.get(env_id, spec.max_episode_steps)
    ref = gym.wrappers.TimeLimit(
        ReferenceDebrisFieldEnv(horizon=horizon, **config),
        kwargs.get("max_episode_steps", spec.max_episode_steps),
    )
    assert env.unwrapped.observation_names() == ref.unwrapped.observation_names()
    rng = np.random.default_rng(seed)
    ended = dict.fromkeys(
        ("success", "collision", "out_of_bounds", "budget", "truncated", "captures", "steps"), 0
    )
    for episode in range(episodes):
        obs, info = env.reset(seed=seed + episode)
        obs_r, info_r = ref.reset(seed=seed + episode, options={"scenario": env.unwrapped.scenario})
        assert_same(obs, obs_r, "reset obs")
        done = False
        step = 0
        while not done:
            if pd:
                action = pd_action(env, obs, rng, scale)
            elif env.unwrapped.config.action == "discrete":
                action = int(rng.integers(env.action_space.n)) if rng.uniform() < 0.3 else 0
            else:
                action = (rng.uniform(-1, 1, env.unwrapped.dim) * scale).astype(np.float32)
            out = env.step(action)
            assert_same_step(out, ref.step(action), INFO_KEYS, f"episode {episode} step {step}")
            done = out[2] or out[3]
            obs = out[0]
            step += 1
        info = out[4]
        ended["captures"] += info["targets_captured"]
        ended["steps"] += step
        if not out[2]:
            ended["truncated"] += 1
        elif info["is_success"]:
            ended["success"] += 1
        else:
            kind = next((k for k in ("collision", "out_of_bounds") if info[k]), "budget")
            ended[kind] += 1
    return ended


@pytest.mark.parametrize(
    "env_id, kwargs, scale",
    [
        ("DebrisGym/Rendezvous2D-v0", {"max_episode_steps": 150}, 0.4),
        ("DebrisGym/Rendezvous2D-v0", {"observation": "lidar", "lidar_rays": 16}, 0.4),
        ("DebrisGym/Rendezvous2D-v0", {"action": "discrete", "max_episode_steps": 120}, 1.0),
        (
            "DebrisGym/Rendezvous2D-v0",
            {"target_order": "queued", "thrust_model": "box", "delta_v_budget": 15.0},
            0.6,
        ),
        ("DebrisGym/Rendezvous2D-v0", {"shaping_terminal": "hold", "n_obstacles": 60}, 0.4),
        ("DebrisGym/Rendezvous2D-v0", {"return_to_dock": False, "obs_obstacles": 2}, 0.4),
        ("DebrisGym/Rendezvous3D-v0", {"max_episode_steps": 150}, 0.4),
        ("DebrisGym/Rendezvous3D-v0", {"observation": "lidar", "lidar_rays": 12}, 0.4),
        # small random burns in the paper's open 20 m world: every flight reaches the time limit
        ("DebrisGym/PaperField2D-v0", {"max_episode_steps": 150}, 0.2),
    ],
)
def test_env_equals_the_reference_on_random_flights(env_id, kwargs, scale):
    ended = fly_both(env_id, episodes=6, scale=scale, seed=7, **kwargs)
    # the comparison covered whole flights, and the steps that end them: a terminal step (where
    # the shaping correction and the end flags are compared) or, in the paper's world, the
    # truncation at the time limit (150 steps each)
    assert ended["steps"] >= 6 * 10, ended
    if env_id == "DebrisGym/PaperField2D-v0":
        assert ended["truncated"] == 6 and ended["steps"] == 6 * 150, ended
    else:
        terminal = ended["success"] + ended["collision"] + ended["out_of_bounds"] + ended["budget"]
        assert terminal >= 1, ended


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("DebrisGym/Rendezvous2D-v0", {}),
        ("DebrisGym/Rendezvous2D-v0", {"target_order": "queued", "shaping_terminal": "hold"}),
        ("DebrisGym/Rendezvous3D-v0", {}),
    ],
)
def test_env_equals_the_reference_on_missions_that_capture(env_id, kwargs):
    ended = fly_both(env_id, episodes=8, scale=0.1, seed=0, pd=True, **kwargs)
    assert ended["captures"] >= 5 and ended["success"] >= 1 and ended["collision"] >= 1, ended


def fly_by_hand(env, ref, options: dict, burns: list) -> dict:
    """Fly ``burns`` from the pinned ``options`` in both, comparing every step; returns the
    env's last info (the flight stops at termination)."""
    assert_same(env.reset(options=options)[0], ref.reset(options=options)[0], "reset")
    start = options["chaser_state"]
    for k, burn in enumerate(burns):
        action = np.array(burn, dtype=np.float32)
        out = env.step(action)
        assert_same_step(out, ref.step(action), INFO_KEYS, f"{start} step {k}")
        if out[2]:
            break
    return out[4]


def test_env_equals_the_reference_on_captures_and_success():
    """Hand-made flights through captures, a fast touch, two crashes and a completed mission;
    each flight ends as its comment says (else the comparison would not cover that case)."""
    targets = (
        Body(position=(0.0, 100.0), radius=5.0, velocity=(0.0, 0.0)),
        Body(position=(60.0, 0.0), radius=4.0, velocity=(0.0, 0.0)),
    )
    polygon = ((10.0, 0.0), (0.0, 10.0), (-10.0, 0.0), (0.0, -10.0))
    obstacles = (
        Body(position=(-80.0, 0.0), radius=10.0, vertices=polygon),
        Body(position=(0.0, -70.0), radius=6.0),
    )
    scen = simple_scenario(targets=targets, obstacles=obstacles)
    coast = (0.0, 0.0)
    for kwargs in ({}, {"target_order": "queued"}, {"delta_v_budget": None}):
        env = DebrisFieldEnv(n_targets=2, n_obstacles=2, **kwargs)
        ref = ReferenceDebrisFieldEnv(n_targets=2, n_obstacles=2, **kwargs)
        queued = kwargs.get("target_order") == "queued"

        def fly(start, burns, env=env, ref=ref):
            return fly_by_hand(env, ref, {"scenario": scen, "chaser_state": start}, burns)

        info = fly([0.0, 80.0, 0.0, 0.3], [coast] * 12)  # drift into target 0's capture zone
        assert info["captured"].tolist() == [True, False] and not info["collision"], info
        info = fly([0.0, 80.0, 0.0, 2.0], [coast] * 6)  # too fast: a collision
        assert info["collision"] and info["targets_captured"] == 0, info
        # brake beside target 1: captured, unless the queue asks for target 0 first
        info = fly([40.0, 0.0, 0.4, 0.0], [coast] * 8 + [(-0.3, 0.0)] * 4)
        assert info["captured"].tolist() == [False, not queued] and not info["collision"], info
        info = fly([-60.0, 0.0, -1.0, 0.0], [coast] * 5)  # into the polygon
        assert info["collision"], info
        info = fly([0.0, -50.0, 0.0, -2.0], [coast] * 5)  # into the circle
        assert info["collision"], info
    # one target, no return: drifting into its capture zone completes the mission
    env = DebrisFieldEnv(n_targets=1, n_obstacles=2, return_to_dock=False)
    ref = ReferenceDebrisFieldEnv(n_targets=1, n_obstacles=2, return_to_dock=False)
    alone = simple_scenario(targets=targets[:1], obstacles=obstacles)
    options = {"scenario": alone, "chaser_state": [0.0, 80.0, 0.0, 0.3]}
    info = fly_by_hand(env, ref, options, [coast] * 20)
    assert info["is_success"] and info["targets_captured"] == 1 and not info["collision"], info


@settings(max_examples=200, deadline=None)
@given(
    gaps=st.lists(st.sampled_from([-3.0, 0.0, 0.5, 2.0, 2.0 + 1e-12, 7.0, np.inf]), min_size=1,
                  max_size=25),
    first=st.integers(0, 3),
    data=st.data(),
)  # fmt: skip
def test_the_obstacle_order_is_by_gap_then_index_from_any_start(gaps, first, data):
    """The step re-sorts last step's order (sort_by_gap): from whatever permutation it starts,
    the result is the (gap, index) order, ties (drawn often here) by index."""
    gaps = np.array(gaps)
    first = min(first, len(gaps) - 1)
    bodies = list(range(first, len(gaps)))
    start = np.array(data.draw(st.permutations(bodies)), dtype=np.int64)
    sort_by_gap(gaps, start)
    assert start.tolist() == sorted(bodies, key=lambda b: (gaps[b], b))


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"dim": 3, "obs_targets": 2, "obs_obstacles": 3},
        {"observation": "lidar", "lidar_rays": 7},
        {"obs_goal": True},
        {"dim": 3, "observation": "lidar", "obs_goal": True},
    ],
)
def test_observation_names_are_the_documented_layout(kwargs):
    """The names generated from the table of slots equal the layout written out by hand."""
    cfg = EnvConfig.from_kwargs(**kwargs)
    assert observation_names(cfg) == reference_observation_names(cfg)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"observation": "lidar"},
        {"obs_goal": True, "obs_other_targets": True},
        {"obs_obstacles": 30, "obs_targets": 5},  # more slots than bodies: empty slots
        {"dim": 3},
    ],
)
def test_every_observation_element_is_written(kwargs):
    """The envs hand out observations in arrays they do not clear first: the compiled
    observation must write every element of every block (checked on buffers full of NaN)."""
    cfg = EnvConfig.from_kwargs(n_targets=3, n_obstacles=20, **kwargs)
    spec = FieldSpec(dim=cfg.dim, n_targets=3, n_obstacles=20)
    physics = dict(mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel)
    fields = [
        random_field(np.random.default_rng(k), spec, capture_radius=5.0, **physics)
        for k in range(5)
    ]
    batch = MissionBatch(
        cfg, 5, 3, len(fields[0].bodies), physics=Physics(**physics), max_episode_steps=40,
        polygon_start=0,
    )  # fmt: skip
    for k, scen in enumerate(fields):
        batch.field.load(k, scen)
        batch.set_world(np.array([k]), scen.dock, scen.low, scen.high, scen.size / 2.0)
    batch.begin(np.arange(5))
    size = len(observation_names(cfg))
    rng = np.random.default_rng(0)
    live = np.ones(5, dtype=bool)
    for _ in range(30):
        batch.step(rng.uniform(-0.5, 0.5, (5, cfg.dim)), live)
        out = batch.observe(np.full((5, size), np.nan, dtype=np.float32), 40)
        assert not np.isnan(out).any()


def test_current_goal_follows_the_rule_on_a_hand_computed_case():
    """Gaps from the chaser's centre (chaser radius 2 m): targets 0 … 2 at 30, 12, 12 m, then
    two obstacles (not read)."""
    gaps = np.array([[30.0, 12.0, 12.0, 1.0, 0.5]])
    none = np.zeros(3, dtype=bool)
    # any order: the smallest gap, the lowest index among equals; the surface gap is 12 − 2
    assert current_goal(0, gaps, none[None], False, True, 2.0) == (1, 10.0, 3)
    assert current_goal(0, gaps, none[None], False, False, 2.0) == (1, 10.0, 2)
    # queued: the first uncaptured target whatever its gap
    assert current_goal(0, gaps, none[None], True, True, 2.0) == (0, 28.0, 3)
    first_done = np.array([True, False, False])
    assert current_goal(0, gaps, first_done[None], True, False, 2.0) == (1, 10.0, 1)
    assert current_goal(0, gaps, np.array([False, True, True])[None], False, True, 2.0) == (
        0,
        28.0,
        1,
    )
    # row i of a batch: the rule reads that row only
    two = np.vstack([gaps, [[1.0, 50.0, 3.0, 0.0, 0.0]]])
    flags = np.array([[False, False, False], [False, False, True]])
    assert current_goal(1, two, flags, False, True, 2.0) == (0, -1.0, 2)
    # all captured: the dock if a return is required, else nothing
    done = np.ones(3, dtype=bool)
    assert current_goal(0, gaps, done[None], False, True, 2.0) == (DOCK_GOAL, 0.0, 0)
    assert current_goal(0, gaps, done[None], True, False, 2.0) == (NO_GOAL, 0.0, 0)


def test_the_env_reports_its_current_goal():
    """Target 0 of the simple field is 100 m along-track (radius 5, chaser radius 2): from
    (0, 40) the surface gap is 100 − 5 − 40 − 2 = 53 m; after the capture the dock, 92 m away."""
    env = DebrisFieldEnv(mean_motion=0.0, delta_v_budget=None, chaser_radius=2.0)
    env.reset(options={"scenario": simple_scenario(), "chaser_state": [0.0, 40.0, 0.0, 0.0]})
    assert env.current_goal == (0, pytest.approx(53.0), 1)
    env.reset(options={"scenario": simple_scenario(), "chaser_state": [0.0, 92.0, 0.0, 0.0]})
    env.step(np.zeros(2, dtype=np.float32))
    assert env.captured.all()
    assert env.current_goal == (DOCK_GOAL, pytest.approx(92.0), 0)


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("DebrisGym/Rendezvous2D-v1", {}),
        ("DebrisGym/Rendezvous3D-v2", {}),
        ("DebrisGym/Rendezvous2D-v2", {"action": "residual"}),
        ("DebrisGym/Rendezvous2D-v2", {"shield": True, "shield_penalty": 0.5}),
    ],
)
def test_step_observe_equals_a_step_then_an_observation(env_id, kwargs):
    """The single env's one compiled call for a step and its observation gives the same
    missions, outputs and observation as two calls (the vector env's way), step after step."""
    single = gym.make(env_id, **kwargs).unwrapped
    twin = gym.make(env_id, **kwargs).unwrapped
    single.reset(seed=3)
    twin.reset(seed=3)
    rng = np.random.default_rng(0)
    buffer = np.empty((1, single.observation_space.shape[0]), dtype=np.float32)
    for _ in range(60):
        action = rng.uniform(-1, 1, (1, single.dim))
        one = single.shell.step(action, observe_into=buffer)
        two = twin.shell.step(action)
        observed = twin.shell.observe()
        np.testing.assert_array_equal(buffer, observed)
        np.testing.assert_array_equal(one.reward, two.reward)
        np.testing.assert_array_equal(one.terms, two.terms)
        np.testing.assert_array_equal(single.batch.missions.state, twin.batch.missions.state)
        if one.terminated[0] or one.truncated[0]:
            break


def test_observe_into_is_refused_with_an_autoreset():
    from debris_gym.envs.shell import Autoreset, MissionShell

    shell = MissionShell(EnvConfig(), 2, autoreset=Autoreset.NEXT_STEP)
    shell.reset()
    with pytest.raises(ValueError, match="observe_into"):
        shell.step(np.zeros((2, 2)), observe_into=np.empty((2, 10), dtype=np.float32))
    shell.close()
