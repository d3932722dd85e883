"""The set encoder of the body slots (agents.policies.set_encoder) and the recurrent policy
(sb3-contrib's RecurrentPPO): layouts read from real observation names, permutation invariance,
config validation, and tiny training runs that evaluate.py flies."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401
from agents.experiments.config_files import CONFIG_DIR, load_config_file
from agents.experiments.training.config import TrainConfig
from agents.experiments.training.run import TrainOptions, train
from agents.policies.set_encoder import SlotSetExtractor, slot_layout

torch = pytest.importorskip("torch")

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
EXPERIMENTS = CONFIG_DIR / "experiments"


def _layout(env_id: str = EASY, **kwargs):
    env = gym.make(env_id, **kwargs)
    names = env.unwrapped.observation_names()
    space = env.observation_space
    env.close()
    return names, space, slot_layout(names)


def test_layout_of_the_moving_field_groups_each_slot_with_its_velocity_block():
    names, _, (context, slots) = _layout()
    assert sorted(slots) == ["obstacle", "target"]
    assert len(slots["obstacle"]) == 8 and len(slots["target"]) == 3
    for k, row in enumerate(slots["obstacle"]):
        features = [names[i] for i in row]
        assert all(f.startswith(f"obstacle{k}_") for f in features)
        # the velocities sit in a block after all the slots, and still belong to their slot
        assert f"obstacle{k}_rel_vel_x" in features and f"obstacle{k}_gap" in features
        assert [f.split("_", 1)[1] for f in features] == [
            names[i].split("_", 1)[1] for i in slots["obstacle"][0]
        ]
    assert [names[i] for i in context] == [
        "chaser_pos_x", "chaser_pos_y", "chaser_vel_x", "chaser_vel_y",
        "dock_rel_pos_x", "dock_rel_pos_y", "delta_v_remaining", "time_remaining",
    ]  # fmt: skip
    used = sorted(context + [i for rows in slots.values() for row in rows for i in row])
    assert used == list(range(len(names)))


def test_layout_errors():
    with pytest.raises(ValueError, match="no body slots"):
        slot_layout(["chaser_pos_x", "time_remaining"])
    with pytest.raises(ValueError, match="obstacle slot 1 has features"):
        slot_layout(["obstacle0_gap", "obstacle0_radius", "obstacle1_gap"])


def _extractor(seed: int = 0, **kwargs):
    _, space, (context, slots) = _layout(**kwargs)
    torch.manual_seed(seed)
    return SlotSetExtractor(space, context, slots, embed_dim=8, hidden_dim=16), slots, space


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_features_do_not_depend_on_the_order_of_the_slots(seed):
    extractor, slots, space = _extractor()
    rng = np.random.default_rng(seed)
    obs = rng.uniform(-1, 1, size=(3, space.shape[0])).astype(np.float32)
    shuffled = obs.copy()
    for rows in slots.values():  # move whole slots, velocity block included
        order = rng.permutation(len(rows))
        for dst, src in enumerate(order):
            shuffled[:, rows[dst]] = obs[:, rows[src]]
    with torch.no_grad():
        a = extractor(torch.as_tensor(obs))
        b = extractor(torch.as_tensor(shuffled))
    torch.testing.assert_close(a, b)
    # ... and they do depend on what is in the slots: changing one obstacle changes them
    changed = obs.copy()
    changed[:, slots["obstacle"][2]] += 0.5
    with torch.no_grad():
        assert not torch.allclose(a, extractor(torch.as_tensor(changed)))


def test_extractor_size_and_bad_layouts():
    extractor, slots, _ = _extractor()
    assert extractor.features_dim == 8 + 2 * 8 * len(slots)
    _, space, (context, slots) = _layout()
    with pytest.raises(ValueError, match="exactly once"):
        SlotSetExtractor(space, context[:-1], slots)
    with pytest.raises(ValueError, match="embed_dim and hidden_dim must be >= 1"):
        SlotSetExtractor(space, context, slots, embed_dim=0)


@pytest.mark.parametrize(
    "encoder, match",
    [
        ({"kind": "deepsets"}, r"'encoder.kind' must be one of flat, set"),
        ({"kind": "set", "embed_dim": 0}, r"'encoder.embed_dim' must be >= 1"),
        ({"kind": "set", "width": 3}, r"'encoder.width' is unknown"),
    ],
)
def test_encoder_config_errors_name_the_key(encoder, match):
    data, _ = load_config_file(CONFIG_DIR / "rendezvous2d-easy_ppo.yaml")
    with pytest.raises(ValueError, match=match):
        TrainConfig.from_dict({**data, "encoder": encoder}, "test")


def test_experiment_configs_are_valid():
    paths = sorted(EXPERIMENTS.glob("*.yaml"))
    assert paths
    for path in paths:
        data, _ = load_config_file(path)
        TrainConfig.from_dict(data, str(path))


TINY = [
    "n_envs=2", "eval.freq=128", "eval.n_episodes=2", "eval.n_envs=2", "checkpoint.freq=0",
    "env_kwargs.max_episode_steps=40", "algo_kwargs.n_steps=32", "algo_kwargs.batch_size=32",
    "algo_kwargs.n_epochs=1",
]  # fmt: skip


def _tiny_run(config: Path, out: Path) -> Path:
    result = train(
        TrainOptions(
            out=out, config=config, env_id=EASY, overrides=TINY, timesteps=128, n_envs=2,
            seed=1, progress=False, argv=["test"],
        )
    )  # fmt: skip
    assert result.status == "completed"
    return out / "model.zip"


def _evaluate(spec: str, out: Path) -> dict:
    from tests.helpers import load_script

    evaluate = load_script("evaluate.py")
    args = ["--env", EASY, "--agents", spec, "--episodes", "2", "--max-steps", "15",
            "--no-progress", "--plots", "0", "--out", str(out)]  # fmt: skip
    assert evaluate.main(args) == 0
    return json.loads((out / "summary.json").read_text())


def test_a_set_encoder_run_is_saved_and_flown_by_evaluate(tmp_path):
    model = _tiny_run(EXPERIMENTS / "rendezvous2d-easy_ppo_set.yaml", tmp_path / "run")
    from stable_baselines3 import PPO

    loaded = PPO.load(model, device="cpu")
    assert isinstance(loaded.policy.features_extractor, SlotSetExtractor)
    summary = _evaluate(f"ppo={model}", tmp_path / "eval")
    assert summary["agents"]["ppo"]["decision_ms_p50"] > 0


def test_a_recurrent_run_carries_its_lstm_state_through_an_episode(tmp_path):
    pytest.importorskip("sb3_contrib")
    from agents import load_agent

    model = _tiny_run(CONFIG_DIR / "rendezvous2d-easy_recurrent_ppo.yaml", tmp_path / "run")
    env = gym.make(EASY)
    agent = load_agent(f"recurrent_ppo={model}", env)
    obs, _ = env.reset(seed=4)
    first, state = agent.predict(obs, None, np.array([True]))
    assert state is not None  # the LSTM's (hidden, cell) states
    again, state2 = agent.predict(obs, state, np.array([False]))
    fresh, _ = agent.predict(obs, None, np.array([True]))
    np.testing.assert_array_equal(first, fresh)  # a new episode starts from a zero state
    assert not all(np.array_equal(a, b) for a, b in zip(state[0], state2[0]))
    summary = _evaluate(f"recurrent_ppo={model}", tmp_path / "eval")
    assert summary["agents"]["recurrent_ppo"]["decision_ms_p50"] > 0


def test_recurrent_ppo_without_sb3_contrib_is_a_clear_error(monkeypatch):
    import sys

    from agents.experiments.config_files import ConfigError
    from agents.policies.model_files import algo_class

    monkeypatch.setitem(sys.modules, "sb3_contrib", None)  # import fails
    with pytest.raises(ValueError, match="pip install sb3-contrib"):
        algo_class("recurrent_ppo")
    data, _ = load_config_file(CONFIG_DIR / "rendezvous2d-easy_recurrent_ppo.yaml")
    with pytest.raises(ConfigError, match=r"config key 'algo' .*pip install sb3-contrib"):
        TrainConfig.from_dict(data, "recipe")
