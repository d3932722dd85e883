"""The safety shield from outside: judged by the env's own collision flag and by the textbook
closed-form CW motion, never by the shield's own prediction.

Fields are pinned (``reset(options={"scenario": ...})``); the moving one puts a body on a CW
orbit, built by back-propagating the closed form (tests.helpers.cw_closed_form, typed in for the
tests) from the moment it crosses the chaser's position.
"""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401  (registers the IDs)
from agents import make_agent
from agents.policies.shield import SafetyShield, ShieldParams
from agents.policies.shielded import ShieldedAgent, ShieldWrapper
from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Body, Scenario
from tests.helpers import (
    LEO_MEAN_MOTION,
    MOVING_WORLD,
    cw_closed_form,
    flies_old_ids,
    simple_scenario,
)

N = LEO_MEAN_MOTION


def wall_ahead(dim: int, size: float = 4000.0) -> Scenario:
    """Free space; one debris body 150 m along +y from the dock, a target far behind."""
    half = size / 2

    def at(y: float) -> tuple[float, ...]:
        return (0.0, y, 0.0)[:dim]

    return Scenario(
        dim=dim, bounds=((-half, half),) * dim, dock=(0.0,) * dim,
        targets=(Body(at(-600.0), 5.0, (0.0,) * dim),),
        obstacles=(Body(at(150.0), 20.0, (0.0,) * dim),),
        mean_motion=0.0, dt=10.0, max_accel=0.05,
    )  # fmt: skip


def free_env(dim: int = 2, **kwargs) -> DebrisFieldEnv:
    return DebrisFieldEnv(dim=dim, mean_motion=0.0, **kwargs)


def full_thrust_plus_y(env: DebrisFieldEnv):
    """The command 'full thrust along +y' in the env's action mode."""
    if env.config.action == "discrete":
        return 3  # coast, +x, -x, +y, ...
    a = np.zeros(env.dim, dtype=np.float32)
    a[1] = 1.0
    return a


def fly(env, command, shield: SafetyShield | None, steps: int) -> tuple[list[dict], int]:
    """Fly ``command`` every step (through ``shield`` if given); the infos and interventions."""
    infos, interventions = [], 0
    for _ in range(steps):
        action = command(env) if callable(command) else command
        if shield is not None:
            action, intervened = shield.filter(action)
            interventions += intervened
        *_, terminated, truncated, info = env.step(action)
        infos.append(info)
        if terminated or truncated:
            break
    return infos, interventions


MODES = [
    (2, "ball", "continuous"),
    (2, "box", "continuous"),
    (3, "ball", "continuous"),
    (3, "box", "continuous"),
    (2, "ball", "discrete"),
    (3, "ball", "discrete"),
]


@pytest.mark.parametrize(("dim", "thrust_model", "action"), MODES)
def test_full_thrust_at_debris_collides_and_the_shielded_same_policy_does_not(
    dim, thrust_model, action
):
    env = free_env(dim, thrust_model=thrust_model, action=action)
    env.reset(seed=0, options={"scenario": wall_ahead(dim)})
    infos, _ = fly(env, full_thrust_plus_y, None, 25)
    assert infos[-1]["collision"]

    env.reset(seed=0, options={"scenario": wall_ahead(dim)})
    infos, interventions = fly(env, full_thrust_plus_y, SafetyShield(env), 25)
    assert len(infos) == 25  # neither a collision nor anything else ended it
    assert not any(info["collision"] for info in infos)
    margin = env.config.chaser_radius  # the default margin
    assert min(info["min_clearance"] for info in infos) >= margin - 1e-6
    assert interventions > 0


def test_a_safe_action_passes_through_unchanged():
    env = free_env()
    env.reset(seed=0, options={"scenario": wall_ahead(2)})
    shield = SafetyShield(env)
    for command in (np.array([0.3, -0.2], dtype=np.float32), np.array([1e6, 3.0])):
        original = command.copy()
        safe, intervened = shield.filter(command)
        assert safe is command and not intervened
        assert np.array_equal(command, original) and command.dtype == original.dtype


def test_a_coasting_agent_in_free_space_is_never_touched():
    env = free_env()
    obs, _ = env.reset(seed=0, options={"scenario": simple_scenario()})
    agent = ShieldedAgent(make_agent("zero", env), env)
    for k in range(60):
        action, _ = agent.predict(obs, episode_start=np.array([k == 0]))
        obs, *_ = env.step(action)
    assert agent.stats.decisions == 60
    assert agent.stats.interventions == 0 and agent.stats.size_max == 0.0


def crossing_body(t_meet: float, speed: float) -> Body:
    """A body (radius 5 m) whose CW path runs through the origin at ``t_meet`` (s), moving
    along-track at ``speed`` (m/s) there: back-propagated with the closed form."""
    state0 = cw_closed_form(np.array([0.0, 0.0, 0.0, speed]), -t_meet)
    return Body(position=tuple(state0[:2]), radius=5.0, velocity=tuple(state0[2:]))


def moving_field(body: Body) -> Scenario:
    far = Body((300.0, -300.0), 5.0, (0.0, -2 * N * 300.0))  # a target on a closed orbit
    # its orbit reaches past the bounds late in an episode: flown anyway, on purpose
    return Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0), targets=(far,),
        obstacles=(body,), mean_motion=N, dt=10.0, max_accel=0.05, motion="cwh",
        motion_faults="warn",
    )  # fmt: skip


@pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")
def test_the_shield_dodges_a_body_on_its_predicted_orbit():
    t_meet = 150.0
    body = crossing_body(t_meet, speed=0.6)
    start = np.array([*body.position, *body.velocity])
    # the body is far at first: only its predicted motion shows the threat
    assert np.linalg.norm(start[:2]) > 60.0

    env = DebrisFieldEnv(dim=2, **MOVING_WORLD)
    env.reset(seed=0, options={"scenario": moving_field(body)})
    infos, _ = fly(env, np.zeros(2, dtype=np.float32), None, 40)
    assert infos[-1]["collision"]  # the chaser at rest at the dock (a CW equilibrium) is hit

    env.reset(seed=0, options={"scenario": moving_field(body)})
    shield = SafetyShield(env)
    first_intervention = None
    infos = []
    for k in range(40):
        action, intervened = shield.filter(np.zeros(2, dtype=np.float32))
        if intervened and first_intervention is None:
            first_intervention = k
        *_, terminated, _, info = env.step(action)
        infos.append(info)
        assert not terminated
    assert not any(info["collision"] for info in infos)
    # it acted while the body was still clear of the margin, closing in: the present
    # positions alone would not have called for it (true distance from the closed form)
    assert first_intervention is not None
    body_then = cw_closed_form(start, first_intervention * 10.0)
    chaser_then = infos[first_intervention - 1]["chaser_state"] if first_intervention else 0.0
    reach = body.radius + 2 * env.config.chaser_radius  # radius + chaser + default margin
    assert np.linalg.norm(body_then[:2] - np.asarray(chaser_then)[:2]) > reach + 2.0
    # the same body frozen where it was then: nothing to fear, nothing done
    frozen = Body(tuple(body_then[:2]), body.radius, (0.0, 0.0))
    still = Scenario(
        dim=2, bounds=((-500.0, 500.0),) * 2, dock=(0.0, 0.0),
        targets=(Body((300.0, -300.0), 5.0, (0.0, 0.0)),), obstacles=(frozen,),
        mean_motion=N, dt=10.0, max_accel=0.05,
    )  # fmt: skip
    env = DebrisFieldEnv(dim=2, mean_motion=N)
    env.reset(seed=0, options={"scenario": still, "chaser_state": np.zeros(4)})
    assert not SafetyShield(env).filter(np.zeros(2, dtype=np.float32))[1]
    # and the body really passed where the chaser would have been
    assert np.linalg.norm(cw_closed_form(start, t_meet)[:2]) < 1e-6


@flies_old_ids
@pytest.mark.parametrize(
    ("env_id", "seed"),
    [
        ("DebrisGym/Rendezvous2D-v2", 0),
        ("DebrisGym/Rendezvous2D-v2", 1),
        ("DebrisGym/Rendezvous2D-v2", 2),
        ("DebrisGym/Rendezvous3D-v2", 0),
        ("DebrisGym/Rendezvous2D-v0", 0),
        # a 20-unit world with a 0.1-unit chaser: the default margin scales with it
        ("DebrisGym/PaperField2D-v0", 0),
    ],
)
def test_apf_mpc_still_captures_every_target_with_the_shield_on(env_id, seed):
    env = gym.make(env_id)
    agent = ShieldedAgent(make_agent("apf-mpc", env), env)
    obs, _ = env.reset(seed=seed)
    done, first = False, True
    while not done:
        action, _ = agent.predict(obs, episode_start=np.array([first]))
        first = False
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    assert info["is_success"] and not info["collision"]
    assert info["targets_captured"] == info["n_targets"]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_actions_are_refused_naming_the_action(bad):
    env = free_env()
    env.reset(seed=0, options={"scenario": wall_ahead(2)})
    with pytest.raises(ValueError, match="action must be finite"):
        SafetyShield(env).filter(np.array([0.0, bad]))


def test_bad_discrete_actions_and_shapes_are_refused():
    env = free_env(action="discrete")
    env.reset(seed=0, options={"scenario": wall_ahead(2)})
    with pytest.raises(ValueError, match="outside"):
        SafetyShield(env).filter(99)
    env = free_env()
    env.reset(seed=0, options={"scenario": wall_ahead(2)})
    with pytest.raises(ValueError, match="shape"):
        SafetyShield(env).filter(np.zeros(3))


def test_a_shield_before_reset_says_so():
    with pytest.raises(RuntimeError, match="reset"):
        SafetyShield(free_env()).filter(np.zeros(2))


RANGES = {
    "horizon_steps": (1, 200, True),
    "substeps": (1, 64, True),
    "margin": (0.0, 1e6, False),
    "target_margin": (0.0, 1e6, False),
    "directions": (4, 512, True),
    "levels": (1, 16, True),
    "fallback_bodies": (0, 32, True),
}


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(sorted(RANGES)),
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(-(10**6), 10**6),
        st.booleans(),
        st.none(),
        st.text(max_size=3),
    ),
)
def test_shield_params_out_of_range_are_refused_naming_the_parameter(name, value):
    low, high, integer = RANGES[name]
    kind_ok = (
        isinstance(value, int) and not isinstance(value, bool)
        if integer
        else isinstance(value, (int, float)) and not isinstance(value, bool)
    )
    valid = kind_ok and math.isfinite(value) and low <= value <= high
    if name == "margin" and value is None:
        valid = True
    if valid:
        assert getattr(ShieldParams(**{name: value}), name) == value
    else:
        with pytest.raises(ValueError, match=rf"{name} must be .* in \[{low}, {high}\]"):
            ShieldParams(**{name: value})


def test_a_shielded_agent_refuses_a_batch():
    env = free_env()
    obs, _ = env.reset(seed=0, options={"scenario": wall_ahead(2)})
    agent = ShieldedAgent(make_agent("zero", env), env)
    with pytest.raises(ValueError, match="one observation"):
        agent.predict(np.stack([obs, obs]))
    action, _ = agent.predict(obs[None])  # a batch of one is answered as a batch
    assert np.shape(action) == (1, 2)


def test_the_wrapper_reports_the_counters_in_info():
    env = ShieldWrapper(free_env())
    _, info = env.reset(seed=0, options={"scenario": wall_ahead(2)})
    assert info["shield_interventions"] == 0 and info["shield_decisions"] == 0
    count = 0
    for _ in range(25):
        *_, terminated, _, info = env.step(np.array([0.0, 1.0], dtype=np.float32))
        count += info["shield_intervened"]
        assert not info["collision"] and not terminated
    assert info["shield_interventions"] == count > 0 and info["shield_decisions"] == 25
    assert 0.0 < info["shield_size_mean"] <= info["shield_size_max"] <= 2.0
    _, info = env.reset(seed=0, options={"scenario": wall_ahead(2)})
    assert info["shield_interventions"] == 0


def test_sb3_trains_a_few_steps_behind_the_shield():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    def make() -> gym.Env:
        return ShieldWrapper(gym.make("DebrisGym/Rendezvous2D-v2", max_episode_steps=20))

    venv = DummyVecEnv([make])
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(64)
    shielded = venv.envs[0]
    assert isinstance(shielded, ShieldWrapper)
    assert shielded.stats.decisions > 0


class ChargeNearestDebris:
    """Full thrust straight at the nearest debris body, every step: a policy that crashes."""

    def __init__(self, env) -> None:
        self.env = env.unwrapped

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        base = self.env
        d = base.dim
        debris = base.body_states[len(base.scenario.targets) :, :d]
        offset = debris - base.chaser_state[:d]
        nearest = offset[np.argmin(np.linalg.norm(offset, axis=1))]
        return (nearest / np.linalg.norm(nearest)).astype(np.float32), state


def test_evaluate_with_the_shield_counts_interventions_in_every_output(tmp_path):
    from agents.experiments.evaluation import evaluate_agents, summarize, summary_markdown
    from agents.experiments.evaluation.report import episodes_csv

    def run(shield):
        return evaluate_agents(
            "DebrisGym/Rendezvous2D-v2", {"charge": ChargeNearestDebris}, episodes=2, seed=2,
            progress=False, max_episode_steps=60, shield=shield,
        )  # fmt: skip

    plain = run(None)
    assert all(r.collision for r in plain.records)
    assert all(r.shield_interventions == 0 for r in plain.records)
    assert "Shielded" not in summary_markdown(summarize(plain))

    shielded = run(ShieldParams())
    assert not any(r.collision for r in shielded.records)
    counts = [r.shield_interventions for r in shielded.records]
    assert all(c > 0 for c in counts)
    summary = summarize(shielded)
    entry = summary["agents"]["charge"]
    assert summary["shield"] == ShieldParams().to_dict()
    assert entry["shield_interventions_mean"] == pytest.approx(np.mean(counts))
    assert 0.0 < entry["shield_size_mean"] <= entry["shield_size_max"] <= 2.0
    text = summary_markdown(summary)
    assert text.splitlines()[0].count("**Shielded**") == 1
    assert "| charge | " + f"{np.mean(counts):.3g}" in text
    rows = episodes_csv(shielded.records).splitlines()
    header = rows[0].split(",")
    column = header.index("shield_interventions")
    assert [int(row.split(",")[column]) for row in rows[1:]] == counts


def test_evaluate_py_takes_the_shield_flag(tmp_path):
    from tests.helpers import load_script

    cli = load_script("evaluate.py")
    out = tmp_path / "out"
    argv = ["--agents", "zero", "--episodes", "1", "--max-steps", "5", "--plots", "0"]
    assert cli.main([*argv, "--shield", "--no-progress", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["shield"]["horizon_steps"] == ShieldParams().horizon_steps
    assert summary["agents"]["zero"]["shield_interventions_mean"] == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["evaluation"]["shield"] is True


class FixedCommand:
    """An agent of the residual mode that asks for ``command`` (normalised thrust) every step:
    its correction is ``command`` minus the base law's command now."""

    episode_independent = True

    def __init__(self, env: DebrisFieldEnv, command: np.ndarray) -> None:
        self.env, self.command = env, np.asarray(command, dtype=float)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        base = self.env.batch.base_commands(np.zeros(1, dtype=np.int64))[0]
        return self.command - base, state


@pytest.mark.parametrize("dim", [2, 3])
def test_in_the_residual_mode_the_shield_judges_and_flies_the_whole_command(dim):
    """With ``action="residual"`` the shield judges base + correction (the command flown), and
    a replaced command is flown exactly: full thrust at a body, asked for as a correction,
    collides unshielded and is stopped behind the shield."""
    env = free_env(dim, action="residual")
    command = np.zeros(dim)
    command[1] = 1.0
    env.reset(seed=0, options={"scenario": wall_ahead(dim)})
    agent = FixedCommand(env, command)
    infos, _ = fly(env, lambda e: agent.predict(None)[0], None, 25)
    assert infos[-1]["collision"]

    obs, _ = env.reset(seed=0, options={"scenario": wall_ahead(dim)})
    shielded = ShieldedAgent(agent, env)
    judged: list[tuple[np.ndarray, np.ndarray]] = []
    decide = shielded.shield.decide

    def recording(action):
        decision = decide(action)
        judged.append((np.array(action, dtype=float), np.array(decision.action, dtype=float)))
        return decision

    shielded.shield.decide = recording  # type: ignore[method-assign]
    infos = []
    for _ in range(25):
        base = env.batch.base_commands(np.zeros(1, dtype=np.int64))[0]
        correction, _ = shielded.predict(obs)
        np.testing.assert_allclose(judged[-1][0], np.clip(base + command - base, -1, 1))
        np.testing.assert_allclose(np.clip(base + correction, -1, 1), judged[-1][1], atol=1e-12)
        obs, _, terminated, truncated, info = env.step(correction)
        infos.append(info)
        if terminated or truncated:
            break
    assert len(infos) == 25 and not any(info["collision"] for info in infos)
    assert shielded.stats.interventions > 0


def test_the_wrapper_filters_the_whole_command_in_the_residual_mode():
    """ShieldWrapper on a residual env: a correction asking for full thrust at a body is
    replaced, and the episode is flown without a collision."""
    env = ShieldWrapper(free_env(2, action="residual"))
    env.reset(seed=0, options={"scenario": wall_ahead(2)})
    agent = FixedCommand(env.unwrapped, np.array([0.0, 1.0]))
    infos = []
    for _ in range(25):
        *_, terminated, truncated, info = env.step(agent.predict(None)[0])
        infos.append(info)
        if terminated or truncated:
            break
    assert not any(info["collision"] for info in infos)
    assert infos[-1]["shield_interventions"] > 0
    assert any(info["shield_intervened"] for info in infos)
