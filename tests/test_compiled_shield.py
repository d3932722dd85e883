"""The compiled safety shield (``shield=True``): the same decisions as the Python shield, the
option's validation, the intervention counts and penalty, and nothing changed with it off.

Agreement is checked decision by decision: a Python :class:`SafetyShield` (default tunables)
and the compiled kernel (through the env's :class:`LoopShield`) are given the same command in
the same state; both must agree on whether to intervene and give the very same action (the
float32 action the Python shield returns, compared as float64 to :data:`ACTION_TOLERANCE`,
and bit for bit in at least 95 % of the decisions: the two compute the same sums in another
order, which can move the last bits of a component). The states come
from missions started beside a random body and flown partly straight at the nearest body, so
that a large share of the decisions are interventions; the share is asserted.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import debris_gym.swarm
from agents.experiments.training.config import TrainConfig
from agents.experiments.training.models import make_eval_env, make_train_env
from agents.policies.shield import SafetyShield, ShieldParams
from debris_gym import shield_model
from debris_gym.config import MAX_WEIGHT, EnvConfig
from debris_gym.envs.common import discrete_action_table
from debris_gym.envs.loop_shield import LoopShield
from debris_gym.envs.shell_info import INFO_KEYS
from tests.helpers import flies_old_ids

ROOT = Path(__file__).resolve().parents[1]
ID_2D = "DebrisGym/Rendezvous2D-v2"
ID_3D = "DebrisGym/Rendezvous3D-v2"
ACTION_TOLERANCE = 1e-9
"""Largest difference of a normalised action component between the two shields (a billionth
of the thrust limit: the round-off of a command built from a few products)."""


def _start_beside_a_body(env, rng: np.random.Generator, seed: int) -> None:
    """Reset ``env`` with seed ``seed`` and its chaser 2–30 m from a random body's surface,
    moving toward it at 0.2–2 m/s (redrawn until the start is clear of every body)."""
    env.reset(seed=seed)
    base = env.unwrapped
    d = base.dim
    states = base.body_states
    radii = np.array([b.radius for b in base.scenario.bodies])
    for _ in range(200):
        b = int(rng.integers(len(radii)))
        direction = rng.normal(size=d)
        direction /= np.linalg.norm(direction)
        gap = radii[b] + base.config.chaser_radius + rng.uniform(2.0, 30.0)
        position = states[b, :d] + gap * direction
        velocity = states[b, d:] - rng.uniform(0.2, 2.0) * direction
        try:
            env.reset(seed=seed, options={"chaser_state": np.concatenate([position, velocity])})
            return
        except ValueError:
            continue
    raise AssertionError("no clear start found")


def _command(base, rng: np.random.Generator) -> np.ndarray:
    """Full thrust straight at the nearest body (70 %) or a uniform random command."""
    d = base.dim
    if rng.random() < 0.7:
        state = base.chaser_state
        bodies = base.body_states
        radii = np.array([b.radius for b in base.scenario.bodies])
        gaps = np.linalg.norm(bodies[:, :d] - state[:d], axis=1) - radii
        toward = bodies[int(np.argmin(gaps)), :d] - state[:d]
        return (toward / np.linalg.norm(toward)).astype(np.float32)
    return rng.uniform(-1.0, 1.0, d).astype(np.float32)


def _compare(env_id: str, seeds: range, steps: int, **kwargs) -> tuple[int, int]:
    """Fly missions of ``env_id`` with the compiled shield's actions, checking every decision
    against the Python shield's; returns (decisions, interventions)."""
    env = gym.make(env_id, **kwargs)
    base = env.unwrapped
    python = SafetyShield(env)
    rng = np.random.default_rng(1234)
    decisions = interventions = exact = 0
    discrete = base.config.action == "discrete"
    table = discrete_action_table(base.dim, base.config.fine_thrust)
    for seed in seeds:
        _start_beside_a_body(env, rng, seed)
        compiled = LoopShield(base.config, 1)
        for _ in range(steps):
            if discrete:
                action = int(rng.integers(base.action_space.n))
                command = table[action][None]  # what the shell is given
            else:
                action = _command(base, rng)
                command = action[None].astype(float)
            decision = python.decide(action)
            out = compiled.filter(base.batch, command, np.ones(1, dtype=bool))[0].copy()
            assert bool(compiled.intervened[0]) == decision.intervened, (seed, decisions)
            if discrete:
                expected = table[int(decision.action)]
            else:
                expected = np.asarray(decision.action, dtype=float)
            # round-off: the Python shield's products go through BLAS in another order
            np.testing.assert_allclose(out, expected, rtol=0.0, atol=ACTION_TOLERANCE)
            exact += bool(np.array_equal(out, expected))
            decisions += 1
            interventions += decision.intervened
            flown = int(decision.action) if discrete else out.astype(np.float32)
            _, _, terminated, truncated, _ = env.step(flown)
            if terminated or truncated:
                break
    env.close()
    counts = f"{decisions} decisions, {interventions} interventions, {exact} bit for bit"
    print(f"\n{env_id} {kwargs}: {counts}")
    assert exact >= 0.95 * decisions  # nearly all bit for bit
    return decisions, interventions


def test_the_kernel_defaults_are_the_python_shields_defaults():
    params = ShieldParams()
    assert params.horizon_steps == shield_model.HORIZON_STEPS
    assert params.substeps == shield_model.SUBSTEPS
    assert params.target_margin == shield_model.TARGET_MARGIN
    assert params.directions == shield_model.DIRECTIONS
    assert params.levels == shield_model.LEVELS
    assert params.fallback_bodies == shield_model.FALLBACK_BODIES
    assert params.margin is None  # the chaser's radius: what ShieldModel.margin holds


@pytest.mark.parametrize("env_id", [ID_2D, ID_3D])
def test_the_compiled_shield_makes_the_python_shields_decisions(env_id):
    decisions, interventions = _compare(env_id, range(30), 10)
    assert decisions >= 150
    assert interventions >= 0.25 * decisions  # a substantial share are interventions


@pytest.mark.parametrize(
    "kwargs",
    [{"thrust_model": "box"}, {"action": "discrete"}],
    ids=["box-thrust", "discrete"],
)
def test_the_compiled_shield_agrees_for_box_thrust_and_discrete_actions(kwargs):
    decisions, interventions = _compare(ID_2D, range(6), 20, **kwargs)
    assert decisions >= 60
    assert interventions >= 0.1 * decisions


@flies_old_ids
def test_the_compiled_shield_agrees_in_a_frozen_field():
    decisions, interventions = _compare("DebrisGym/Rendezvous2D-v0", range(6), 20)
    assert decisions >= 60
    assert interventions >= 0.1 * decisions


# --- the option --------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.text()))
def test_shield_penalty_is_checked(value):
    ok = (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and 0.0 <= value <= MAX_WEIGHT
    )
    if ok:
        assert EnvConfig(shield=True, shield_penalty=value).shield_penalty == float(value)
    else:
        with pytest.raises(ValueError, match="shield_penalty"):
            EnvConfig(shield=True, shield_penalty=value)


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.integers(), st.floats(), st.text(), st.none()))
def test_shield_must_be_a_flag(value):
    with pytest.raises(ValueError, match="shield"):
        EnvConfig(shield=value)


def test_a_penalty_without_the_shield_is_refused():
    with pytest.raises(ValueError, match=r"shield_penalty.*shield=True"):
        EnvConfig(shield_penalty=0.5)


def test_a_swarm_refuses_the_shield():
    with pytest.raises(ValueError, match="shield=True is for one chaser"):
        debris_gym.swarm.make("DebrisGym/Swarm2D-v0", shield=True).reset(seed=0)


# --- counts, penalty, NaN, shield off --------------------------------------------------------


def _vector(n: int, **kwargs):
    return gym.make_vec(ID_2D, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def _rollout(env, actions: np.ndarray) -> list[tuple]:
    out = [env.reset(seed=7)]
    for a in actions:
        out.append(env.step(a))
    return out


def test_interventions_are_counted_per_episode_and_penalised():
    n, steps, penalty = 16, 120, 0.25
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1.0, 1.0, (steps, n, 2)).astype(np.float32)
    free = _rollout(_vector(n, shield=True), actions)
    paid = _rollout(_vector(n, shield=True, shield_penalty=penalty), actions)
    counts = np.zeros(n, dtype=np.int64)
    ended = np.zeros(n, dtype=bool)
    total = 0
    for t in range(1, steps + 1):
        _, r0, term, trunc, info0 = free[t]
        _, r1, _, _, info1 = paid[t]
        hit = info1["shield_intervened"]
        np.testing.assert_array_equal(hit, info0["shield_intervened"])  # same decisions
        counts = np.where(ended, 0, counts) + hit  # next-step autoreset: a new episode
        np.testing.assert_array_equal(info1["shield_interventions"], counts)
        np.testing.assert_array_equal(r1, r0 - penalty * hit)
        np.testing.assert_array_equal(info1["reward_terms"]["shield"], -penalty * hit)
        assert not np.any(hit & ended)  # a restarting row's action is not flown
        total += int(hit.sum())
        ended = term | trunc
    assert total > 0


def test_the_single_env_counts_interventions_and_its_terms_sum_to_the_reward():
    env = gym.make(ID_2D, shield=True, shield_penalty=1.0)
    _, info = env.reset(seed=0)
    assert info["shield_interventions"] == 0 and info["shield_intervened"] is False
    assert info["reward_terms"]["shield"] == 0.0
    rng = np.random.default_rng(0)
    count = 0
    for _ in range(60):
        _, reward, terminated, truncated, info = env.step(_command(env.unwrapped, rng))
        count += info["shield_intervened"]
        assert info["shield_interventions"] == count
        assert info["reward_terms"]["shield"] == -1.0 * info["shield_intervened"]
        assert math.isclose(reward, sum(info["reward_terms"].values()), abs_tol=1e-12)
        if terminated or truncated:
            break
    assert count > 0


def test_the_single_env_is_the_vector_envs_row():
    single = gym.make(ID_2D, shield=True)
    vector = _vector(1, shield=True)
    obs_s, _ = single.reset(seed=11)
    obs_v, _ = vector.reset(seed=11)
    rng = np.random.default_rng(5)
    for _ in range(50):
        a = rng.uniform(-1.0, 1.0, 2).astype(np.float32)
        obs_s, r_s, term_s, _, info_s = single.step(a)
        obs_v, r_v, term_v, _, info_v = vector.step(a[None])
        np.testing.assert_array_equal(obs_s, obs_v[0])
        assert r_s == r_v[0] and info_s["shield_intervened"] == info_v["shield_intervened"][0]
        if term_s:
            break


def test_a_shielded_env_pickles_mid_episode():
    env = gym.make(ID_2D, shield=True, shield_penalty=0.5)
    env.reset(seed=3)
    rng = np.random.default_rng(8)
    for _ in range(5):
        env.step(_command(env.unwrapped, rng))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(20):
        action = _command(env.unwrapped, rng)
        a, b = env.step(action), clone.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1] and a[4]["shield_interventions"] == b[4]["shield_interventions"]


def test_the_filtered_actions_are_finite_for_any_finite_command():
    env = _vector(8, shield=True)
    env.reset(seed=2)
    shield = env.unwrapped.shell._shield
    rng = np.random.default_rng(9)
    for scale in (1e-300, 1.0, 1e6, 1e300):
        actions = scale * rng.uniform(-1.0, 1.0, (8, 2))
        obs, reward, _, _, _ = env.step(actions)
        assert np.all(np.isfinite(shield._out))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
        assert np.all(np.abs(env.unwrapped.batch.missions.accel) <= 0.05 + 1e-12)
    with pytest.raises(ValueError, match="action"):
        env.step(np.full((8, 2), np.nan))


def test_with_the_shield_off_nothing_changes():
    n, steps = 16, 80
    actions = np.random.default_rng(4).uniform(-1.0, 1.0, (steps, n, 2)).astype(np.float32)
    plain = _rollout(_vector(n), actions)
    off = _rollout(_vector(n, shield=False), actions)
    on = _rollout(_vector(n, shield=True), actions)
    touched = np.zeros(n, dtype=bool)  # rows that have met an intervention
    for t, (a, b, c) in enumerate(zip(plain, off, on)):
        for x, y in zip(a[:-1], b[:-1]):
            np.testing.assert_array_equal(x, y)
        assert set(a[-1]) == set(b[-1]) >= set(INFO_KEYS)
        assert not b[-1]["shield_intervened"].any() and not b[-1]["shield_interventions"].any()
        if t:
            touched |= c[-1]["shield_intervened"]
            clean = ~touched
            np.testing.assert_array_equal(a[0][clean], c[0][clean])  # observations
            np.testing.assert_array_equal(a[1][clean], c[1][clean])  # rewards
    assert touched.any() and (~touched).any()  # both kinds of rows were compared


# --- the training recipe -----------------------------------------------------------------------


def test_the_shield_recipe_trains_shielded_and_evaluates_unshielded():
    recipe = ROOT / "agents" / "configs" / "experiments" / "rendezvous2d_v2_shield_ppo.yaml"
    data = yaml.safe_load(recipe.read_text())
    data.update(n_envs=2, eval={"freq": 1000, "n_episodes": 2, "n_envs": 2})
    config = TrainConfig.from_dict(data, source=str(recipe))
    assert config.env_kwargs["shield"] is True and config.env_kwargs["shield_penalty"] > 0
    train, evaluation = make_train_env(config, seed=0), make_eval_env(config)
    try:
        assert train.unwrapped.venv.config.shield is True
        assert train.unwrapped.venv.config.shield_penalty == config.env_kwargs["shield_penalty"]
        assert evaluation.unwrapped.venv.config.shield is False
    finally:
        train.close()
        evaluation.close()


def test_a_part_way_start_counts_its_interventions_from_zero():
    env = gym.make(ID_2D, shield=True)
    rng = np.random.default_rng(6)
    _start_beside_a_body(env, rng, 4)
    count = 0
    for _ in range(10):
        _, _, terminated, truncated, info = env.step(_command(env.unwrapped, rng))
        count = info["shield_interventions"]
        if terminated or truncated:
            break
    assert count > 0
    _, info = env.reset(seed=5, options={"start": {"step": 60}})
    assert info["shield_interventions"] == 0 and info["shield_intervened"] is False
    _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert info["shield_interventions"] == int(info["shield_intervened"])


def test_in_the_residual_mode_the_shield_filters_the_whole_command():
    """With ``action="residual"`` the compiled shield judges the command flown (the base law's
    plus the correction, clipped): step for step, a residual env flies exactly what a
    continuous env with the shield flies when given that whole command, interventions and
    penalties included."""
    rng = np.random.default_rng(7)
    residual = gym.make(ID_2D, shield=True, shield_penalty=0.5, action="residual")
    direct = gym.make(ID_2D, shield=True, shield_penalty=0.5)
    first = np.zeros(1, dtype=np.int64)
    interventions = 0
    for seed in range(4):
        _start_beside_a_body(residual, np.random.default_rng(seed), seed)
        _start_beside_a_body(direct, np.random.default_rng(seed), seed)
        for _ in range(15):
            wanted = _command(residual.unwrapped, rng).astype(float)
            base = residual.unwrapped.batch.base_commands(first)[0]
            correction = wanted - base
            whole = np.clip(base + correction, -1.0, 1.0)
            one = residual.step(correction)
            two = direct.step(whole)
            np.testing.assert_array_equal(one[0], two[0])
            assert one[1] == two[1] and one[2:4] == two[2:4]
            assert one[4]["shield_intervened"] == two[4]["shield_intervened"]
            interventions += one[4]["shield_intervened"]
            if one[2] or one[3]:
                break
    assert interventions > 0
