"""Missions that start part-way (``reset(options={"start": ...})``), the start bank and the
leg sampler.

Truths: a recorded rollout of the env itself (a start taken from it must reproduce the
observation it saw at that step, in a field drawn from another seed), the closed-form CW motion
of the bodies (:meth:`Scenario.body_states`), hand-computed PLR probabilities.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401
from agents import make_agent
from agents.experiments.starts import LegSampler, SamplerParams, fly_and_record
from agents.experiments.starts.bank import BankEntry
from debris_gym.envs.starts import EpisodeEnds
from debris_gym.goal import DOCK_GOAL
from debris_gym.mission_starts import MissionStart
from debris_gym.start_bank import StartBank, world_options
from tests.helpers import flies_old_ids

ENV_2D = "DebrisGym/Rendezvous2D-v2"
WORLD_2D = world_options(gym.make(ENV_2D).unwrapped.config)


def fly_recording(env, agent, seed):
    """Fly ``agent`` on seed ``seed``: the observation after every step, and the bank entries
    of the flight."""
    obs, _ = env.reset(seed=seed)
    seen = [obs]
    word = env.unwrapped.field_word
    order: list[int] = []
    entries = []
    for step in range(1, 2000):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        seen.append(obs)
        new = [int(j) for j in np.flatnonzero(info["captured"]) if int(j) not in order]
        order += sorted(new)
        if new and not (terminated or truncated):
            entries.append(
                BankEntry(0, word, step, info["chaser_state"].copy(), tuple(order), info["delta_v"])
            )
        if terminated or truncated:
            return seen, entries, info
    raise AssertionError("the mission did not end")


@pytest.fixture(scope="module")
def apf_mpc_flight():
    env = gym.make(ENV_2D)
    agent = make_agent("apf-mpc", env)
    seen, entries, info = fly_recording(env, agent, seed=5)
    env.close()
    return seen, entries, info


def test_a_start_from_a_recorded_flight_reproduces_its_observation_in_another_seeds_env(
    apf_mpc_flight,
):
    """Every capture of an APF-MPC flight, restarted from its bank entry in an env reset with
    another seed: the observation equals the flight's at that step, element for element."""
    seen, entries, info = apf_mpc_flight
    assert info["is_success"] and len(entries) == 3  # legs 1, 2 and the return
    env = gym.make(ENV_2D)
    for entry in entries:
        start = {
            "captured": list(entry.order), "step": entry.step, "delta_v": entry.delta_v,
            "chaser_state": entry.state, "field_word": entry.word,
        }  # fmt: skip
        obs, info = env.reset(seed=123, options={"start": start})
        np.testing.assert_array_equal(obs, seen[entry.step])
        assert info["targets_captured"] == len(entry.order)
        assert info["delta_v"] == entry.delta_v
        assert info["time"] == pytest.approx(entry.step * env.unwrapped.config.dt, rel=1e-12)
    env.close()


def test_the_fly_and_record_command_banks_the_same_entries(apf_mpc_flight):
    _, entries, _ = apf_mpc_flight
    env = gym.make(ENV_2D)
    found = fly_and_record(env, make_agent("apf-mpc", env), seed=5, episode=0)
    assert [(e.step, e.order, e.word) for e in found] == [
        (e.step, e.order, e.word) for e in entries
    ]
    for a, b in zip(found, entries):
        np.testing.assert_array_equal(a.state, b.state)


@pytest.mark.parametrize("env_id", [ENV_2D, "DebrisGym/Rendezvous3D-v2"])
def test_bodies_start_where_closed_form_cw_motion_puts_them(env_id):
    """With ``step`` k the bodies are where the closed-form CW solution of the field as drawn
    (``env.scenario`` at t = 0) puts them at k·dt, and the mission clock reads k·dt."""
    env = gym.make(env_id)
    k = 137
    env.reset(seed=9, options={"start": {"step": k}})
    u = env.unwrapped
    t = k * u.config.dt
    expected = u.scenario.body_states(t)
    np.testing.assert_allclose(u.body_states, expected, rtol=1e-9, atol=1e-7)
    assert u.elapsed == pytest.approx(t, rel=1e-12)
    # the chaser at rest at its dock, nothing captured
    np.testing.assert_array_equal(u.chaser_state, np.zeros(2 * u.dim))
    assert not u.captured.any()


def test_a_start_without_a_chaser_state_holds_beside_the_last_capture():
    env = gym.make(ENV_2D)
    obs, info = env.reset(seed=2, options={"start": {"captured": [2, 0], "step": 60}})
    u = env.unwrapped
    cfg = u.config
    bodies = u.body_states
    target = bodies[0]  # the last of the captured, in order
    state = info["chaser_state"]
    gap = np.linalg.norm(state[:2] - target[:2]) - u.scenario.targets[0].radius
    assert gap == pytest.approx(cfg.chaser_radius + 0.5 * cfg.capture_radius, rel=1e-9)
    np.testing.assert_allclose(state[2:], target[2:], rtol=0, atol=1e-12)
    # on the side facing the dock (the origin)
    assert np.linalg.norm(state[:2]) < np.linalg.norm(target[:2])
    np.testing.assert_array_equal(info["captured"], [True, False, True])
    assert info["targets_captured"] == 2


def test_a_late_single_env_mission_is_truncated_by_its_own_clock():
    """TimeLimit counts from the reset; a mission started k steps in is truncated when the
    mission clock reaches the limit."""
    env = gym.make("DebrisGym/Rendezvous2D-Easy-v2")
    limit = env.spec.max_episode_steps
    env.reset(seed=0, options={"start": {"step": limit - 3}})
    flags = []
    for _ in range(3):
        _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
        flags.append((terminated, truncated))
    assert flags == [(False, False), (False, False), (False, True)]


def test_a_late_vector_mission_is_truncated_by_its_clock_and_restarts_at_the_dock():
    env = gym.make_vec(ENV_2D, num_envs=2, vectorization_mode="vector_entry_point")
    limit = env.unwrapped.shell.max_episode_steps
    env.reset(seed=0, options={"start": [{"step": limit - 2}, None]})
    zero = np.zeros((2, 2), np.float32)
    _, _, _, truncated, _ = env.step(zero)
    assert not truncated.any()
    _, _, _, truncated, _ = env.step(zero)
    assert truncated.tolist() == [True, False]
    _, _, _, _, info = env.step(zero)  # next-step autoreset: a usual start
    assert info["time"][0] == 0.0


def test_spent_delta_v_counts_against_the_budget():
    env = gym.make(ENV_2D)
    budget = env.unwrapped.config.delta_v_budget
    env.reset(seed=1, options={"start": {"delta_v": budget - 1e-3}})
    _, _, terminated, _, info = env.step(np.ones(2, np.float32))
    assert terminated and info["budget_spent"]
    assert info["delta_v"] == pytest.approx(budget)


def test_a_start_on_every_target_captured_has_the_dock_as_its_goal():
    env = gym.make(ENV_2D)
    _, info = env.reset(seed=4, options={"start": {"captured": [0, 1, 2], "step": 10}})
    assert info["targets_captured"] == 3
    assert env.unwrapped.current_goal.index == DOCK_GOAL
    _, info = env.reset(seed=4, options={"start": {"captured": [0, 2], "step": 10}})
    assert env.unwrapped.current_goal.index == 1


# --- input checks -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "start, match",
    [
        ({"captured": [0, 0]}, "names a target twice"),
        ({"captured": [3]}, r"captured'\]\[0\]=3 is out of range"),
        ({"captured": "01"}, "must be a list of target indices"),
        ({"step": -1}, r"step'\]=-1 is out of range"),
        ({"step": 1.5}, "must be an integer"),
        ({"delta_v": float("nan")}, "delta_v"),
        ({"delta_v": -0.1}, "out of range"),
        ({"beside": 1, "captured": [0]}, "must be one of the captured targets"),
        ({"captured": [0], "beside": 0, "chaser_state": [0, 0, 0, 0]}, "not both"),
        ({"chaser_state": [0, 0, np.inf, 0]}, "finite"),
        ({"chaser_state": [0, 0, 0]}, "4 finite numbers"),
        ({"field_word": -1}, "field_word"),
        ({"speed": 1}, "unknown key"),
        ("dock", "must be a dict"),
    ],
)
def test_a_bad_start_is_refused_naming_the_key_and_changes_nothing(start, match):
    env = gym.make(ENV_2D)
    obs, _ = env.reset(seed=0)
    next_obs = env.step(np.full(2, 0.1, np.float32))[0]
    with pytest.raises(ValueError, match=match):
        env.reset(seed=7, options={"start": start})
    again = gym.make(ENV_2D)
    again.reset(seed=0)
    np.testing.assert_array_equal(next_obs, again.step(np.full(2, 0.1, np.float32))[0])
    # the refused reset left the env stepping on as before
    np.testing.assert_array_equal(
        env.step(np.zeros(2, np.float32))[0], again.step(np.zeros(2, np.float32))[0]
    )


def test_a_chaser_inside_a_body_at_the_starts_step_is_refused():
    env = gym.make(ENV_2D)
    env.reset(seed=3)
    scenario = env.unwrapped.scenario
    k = 40
    inside = scenario.body_states(k * env.unwrapped.config.dt)[5].copy()  # a debris' centre
    with pytest.raises(ValueError, match="cannot start there"):
        env.reset(seed=3, options={"start": {"step": k, "chaser_state": inside}})


def test_start_and_chaser_state_options_together_are_refused():
    env = gym.make(ENV_2D)
    with pytest.raises(ValueError, match="not both"):
        env.reset(seed=0, options={"start": {}, "chaser_state": np.zeros(4)})


@flies_old_ids
def test_a_field_word_needs_a_moving_random_field():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    env.reset(seed=0)
    assert env.unwrapped.field_word is None
    with pytest.raises(ValueError, match="moving random field"):
        env.reset(seed=0, options={"start": {"field_word": 5}})


def test_a_step_is_refused_where_the_truth_model_moves_the_bodies():
    env = gym.make("DebrisGym/Rendezvous2D-Uncertain-v2")
    with pytest.raises(ValueError, match="truth_model"):
        env.reset(seed=0, options={"start": {"step": 3}})


@settings(max_examples=30, deadline=None)
@given(step=st.integers(-5, 2000), delta_v=st.floats(-1.0, 100.0) | st.just(math.nan))
def test_the_step_and_delta_v_ranges_hold_for_any_value(step, delta_v):
    """hypothesis: an out-of-range value is refused naming it, an in-range one starts."""
    env = _ENV_FOR_HYPOTHESIS
    limit = env.spec.max_episode_steps
    budget = env.unwrapped.config.delta_v_budget
    ok = 0 <= step < limit and 0.0 <= delta_v < budget
    if ok:
        _, info = env.reset(seed=0, options={"start": {"step": step, "delta_v": delta_v}})
        assert info["delta_v"] == delta_v
    else:
        with pytest.raises(ValueError, match=r"step|delta_v"):
            env.reset(seed=0, options={"start": {"step": step, "delta_v": delta_v}})


_ENV_FOR_HYPOTHESIS = gym.make("DebrisGym/Rendezvous2D-Easy-v2")


# --- the bank -----------------------------------------------------------------------------------


def test_a_bank_saves_and_loads_unchanged_and_refuses_another_env(tmp_path, apf_mpc_flight):
    _, entries, _ = apf_mpc_flight
    world = world_options(gym.make(ENV_2D).unwrapped.config)
    bank = StartBank(
        env_id=ENV_2D, env_kwargs={}, world=world, source="apf-mpc",
        words=np.array([e.word for e in entries], dtype=np.uint64),
        steps=np.array([e.step for e in entries]), states=np.array([e.state for e in entries]),
        captured=np.array([[*e.order, *[-1] * (3 - len(e.order))] for e in entries]),
        delta_v=np.array([e.delta_v for e in entries]), episodes=np.zeros(len(entries), int),
    )  # fmt: skip
    path = tmp_path / "bank.npz"
    bank.save(path)
    loaded = StartBank.load(path)
    assert loaded.env_id == ENV_2D and loaded.source == "apf-mpc"
    for name in ("words", "steps", "states", "captured", "delta_v"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(bank, name))
    assert loaded.legs.tolist() == [1, 2, 3]
    assert loaded.start(1).captured == entries[1].order
    assert loaded.world == world
    loaded.check_config(gym.make(ENV_2D, obs_goal=True, reward_delta_v=0.3).unwrapped.config)
    with pytest.raises(ValueError, match="n_obstacles=5"):
        loaded.check_config(gym.make(ENV_2D, n_obstacles=5).unwrapped.config)
    (tmp_path / "junk.npz").write_bytes(b"not a bank")
    with pytest.raises(ValueError, match="is not a start bank"):
        StartBank.load(tmp_path / "junk.npz")


# --- the leg sampler ------------------------------------------------------------------------------


def tiny_bank(legs: list[int], n_targets: int = 3) -> StartBank:
    s = len(legs)
    captured = np.full((s, n_targets), -1)
    for k, leg in enumerate(legs):
        captured[k, :leg] = np.arange(leg)
    return StartBank(
        ENV_2D, {}, WORLD_2D, "test", np.arange(s, dtype=np.uint64), np.arange(s), np.zeros((s, 4)),
        captured, np.zeros(s), np.arange(s),
    )  # fmt: skip


def test_plr_probabilities_follow_rank_prioritisation_and_staleness():
    """By hand: legs 1, 2, 3 with failure rates 0.9, 0.1, 0.5 rank 1, 3, 2; with β = 0.5 the
    scores are 1, 1/9, 1/4; with no draws yet the staleness term is uniform."""
    sampler = LegSampler(tiny_bank([1, 2, 3]), 4, 3, SamplerParams(temperature=0.5, staleness=0.2))
    sampler.failure[:] = [0.0, 0.9, 0.1, 0.5]
    scores = np.array([1.0, 1 / 9, 1 / 4])
    expected = 0.8 * scores / scores.sum() + 0.2 / 3
    np.testing.assert_allclose(sampler.probabilities()[1:], expected, rtol=1e-12)
    assert sampler.probabilities()[0] == 0.0


def test_an_ended_mission_updates_the_legs_it_flew():
    """Started on leg 1, ended with 2 captured and no success: leg 1 flown, leg 2 failed."""
    params = SamplerParams(usual=0.0, smoothing=0.5)
    sampler = LegSampler(tiny_bank([1]), 1, 3, params)
    starts = sampler(np.array([0]), None)
    assert starts[0] is not None and starts[0].leg == 1
    sampler(np.array([0]), EpisodeEnds(np.array([2]), np.array([False])))
    np.testing.assert_allclose(sampler.failure, [0.5, 0.25, 0.75, 0.5])
    assert sampler.flown.tolist() == [0, 1, 1, 0]
    # a success flies every leg from its start to the return
    sampler(np.array([0]), EpisodeEnds(np.array([3]), np.array([True])))
    assert sampler.flown.tolist() == [0, 2, 2, 1]
    assert sampler.failure[3] == pytest.approx(0.25)


def test_usual_one_never_starts_part_way_and_the_draws_follow_the_seed():
    always = LegSampler(tiny_bank([1, 2]), 8, 3, SamplerParams(usual=1.0))
    assert always(np.arange(8), None) == [None] * 8
    a = LegSampler(tiny_bank([1, 2, 3]), 50, 3, SamplerParams(usual=0.2, seed=4))
    b = LegSampler(tiny_bank([1, 2, 3]), 50, 3, SamplerParams(usual=0.2, seed=4))
    assert a(np.arange(50), None) == b(np.arange(50), None)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"usual": 1.5}, "usual"), ({"temperature": 0.0}, "temperature"),
     ({"smoothing": 0.0}, "smoothing"), ({"staleness": -0.1}, "staleness")],
)  # fmt: skip
def test_bad_sampler_params_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SamplerParams(**kwargs)


def test_a_vector_env_restarts_missions_where_the_sampler_says():
    bank = tiny_bank([1, 2, 3])
    env = gym.make_vec(
        "DebrisGym/Rendezvous2D-v2", num_envs=4, vectorization_mode="vector_entry_point"
    )
    real = []
    probe = gym.make(ENV_2D)
    # a real bank: states at each target, recorded by the env itself (beside placement)
    for leg in (1, 2, 3):
        probe.reset(seed=leg, options={"start": {"captured": list(range(leg)), "step": 20}})
        real.append(
            MissionStart(tuple(range(leg)), 20, 0.0, probe.unwrapped.chaser_state,
                         field_word=probe.unwrapped.field_word)
        )  # fmt: skip
    bank = StartBank(
        ENV_2D, {}, WORLD_2D, "test", np.array([s.field_word for s in real], dtype=np.uint64),
        np.full(3, 20), np.array([s.chaser_state for s in real]),
        np.array([[*s.captured, *[-1] * (3 - s.leg)] for s in real]), np.zeros(3), np.arange(3),
    )  # fmt: skip
    sampler = LegSampler(bank, 4, 3, SamplerParams(usual=0.0))
    env.unwrapped.shell.start_sampler = sampler
    _, info = env.reset(seed=0)
    assert (info["targets_captured"] >= 1).all()
    assert math.isclose(float(info["time"][0]), 20 * probe.unwrapped.config.dt)
    rng = np.random.default_rng(0)
    for _ in range(300):
        env.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
    assert sampler.flown[1:].sum() > 4  # missions ended and were scored
    assert sampler.started[1:].sum() > 4 and sampler.started[0] == 0


# --- training with a bank -----------------------------------------------------------------------


def test_train_py_trains_with_a_start_bank_and_logs_the_legs(tmp_path):
    """A tiny run whose missions start from a bank: it completes, its training env carries the
    sampler, and start_legs.json records the legs it started."""
    import json

    from agents.experiments.training.resolve import TrainOptions
    from agents.experiments.training.run import train

    bank_path = tmp_path / "bank.npz"
    env = gym.make("DebrisGym/Rendezvous2D-v2")
    entries = []
    for seed in range(3):
        env.reset(seed=seed, options={"start": {"captured": [0], "step": 30}})
        entries.append((env.unwrapped.field_word, env.unwrapped.chaser_state))
    StartBank(
        "DebrisGym/Rendezvous2D-v2", {}, WORLD_2D, "test",
        np.array([w for w, _ in entries], dtype=np.uint64), np.full(3, 30),
        np.array([s for _, s in entries]), np.array([[0, -1, -1]] * 3), np.zeros(3),
        np.arange(3),
    ).save(bank_path)  # fmt: skip
    sets = [
        "eval.freq=0", "checkpoint.freq=0", "algo_kwargs.n_steps=32",
        "algo_kwargs.batch_size=32", "algo_kwargs.n_epochs=1", "policy_kwargs.net_arch=[16]",
        "curriculum=[]", f"starts.bank={bank_path}", "starts.usual=0.0",
    ]  # fmt: skip
    out = tmp_path / "run"
    result = train(
        TrainOptions(
            out=out, env_id="DebrisGym/Rendezvous2D-v2", overrides=sets, timesteps=512,
            n_envs=4, seed=0, progress=False, argv=["test"],
        )
    )  # fmt: skip
    assert result.status == "completed"
    legs = json.loads((out / "start_legs.json").read_text())
    assert legs["started"][1] >= 4 and legs["started"][0] == 0


def test_a_start_bank_with_a_curriculum_or_another_env_is_refused(tmp_path):
    from agents.experiments.config_files import ConfigError
    from agents.experiments.training.config import TrainConfig
    from agents.experiments.training.models import make_train_env

    base = {"version": 1, "env_id": "DebrisGym/Rendezvous2D-v2", "algo": "ppo",
            "timesteps": 64, "n_envs": 2}  # fmt: skip
    with pytest.raises(ValueError, match=r"starts\.bank"):
        TrainConfig.from_dict(
            {**base, "starts": {"bank": "x.npz"},
             "curriculum": [{"until": 10, "mission": {"n_targets": 1}}]}
        )  # fmt: skip
    with pytest.raises(ValueError, match=r"starts\.usual"):
        TrainConfig.from_dict({**base, "starts": {"usual": "half"}})
    path = tmp_path / "bank.npz"
    tiny_bank([1]).save(path)
    config = TrainConfig.from_dict({**base, "env_kwargs": {"n_obstacles": 5},
                                    "starts": {"bank": str(path)}})  # fmt: skip
    with pytest.raises(ConfigError, match="recorded in"):
        make_train_env(config, seed=0)


def test_a_bank_refuses_the_seeds_of_an_evaluation_suite():
    from agents.experiments.starts import build_start_bank
    from debris_gym.suites import suite_seeds

    seed = min(suite_seeds("standard-2d-v2"))
    with pytest.raises(ValueError, match="evaluation suite"):
        build_start_bank(ENV_2D, missions=3, seed=seed - 1, progress=False)


def test_the_field_word_of_an_autoreset_row_names_its_field():
    """Rows restarted by the vector env (fields drawn ahead and loaded in place): each row's
    field_word, given to a single env, flies that row's field."""
    env = gym.make_vec(ENV_2D, num_envs=8, vectorization_mode="vector_entry_point")
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    restarted = np.zeros(8, dtype=bool)
    for _ in range(200):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, (8, 2)).astype(np.float32))
        restarted |= terminated | truncated
    assert restarted.sum() >= 2
    shell = env.unwrapped.shell
    single = gym.make(ENV_2D)
    for i in np.flatnonzero(restarted)[:3].tolist():
        env.step(np.zeros((8, 2), np.float32))  # let a pending next-step autoreset happen
        word = shell.field_word(i)
        single.reset(seed=0, options={"start": {"field_word": word}})
        np.testing.assert_array_equal(
            single.unwrapped.scenario.body_states(0.0), shell.scenario(i).body_states(0.0)
        )


@pytest.mark.parametrize(
    "kwargs", [{"shield": True, "shield_penalty": 0.1}, {"action": "residual"}]
)
def test_the_shipped_bank_fits_an_env_that_differs_only_in_the_learners_options(kwargs):
    """The shield filters the learner's commands and the residual mode adds a base law to them:
    the world is the recording env's, so the shipped bank (recorded before the shield options
    existed) fits; a change of the world is still refused."""
    from pathlib import Path

    import agents

    bank = StartBank.load(Path(agents.__file__).parent / "data" / "rendezvous2d-v2_apf-mpc.npz")
    bank.check_config(gym.make(ENV_2D, **kwargs).unwrapped.config)
    with pytest.raises(ValueError, match="n_obstacles=5"):
        bank.check_config(gym.make(ENV_2D, n_obstacles=5, **kwargs).unwrapped.config)
