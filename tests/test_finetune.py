"""RL fine-tuning of an imitation policy (train.py --init, the ``init`` config section,
agents.experiments.training.anchored / finetune): the critic warm-up, the anchor and its
schedule, the files evaluate.py flies, the refusals, and resume."""

from __future__ import annotations

import contextlib
import pickle
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

import torch

import agents
from agents.experiments.config_files import CONFIG_DIR, ConfigError, load_config_file
from agents.experiments.imitation.config import ImitationConfig
from agents.experiments.imitation.run import imitate
from agents.experiments.training.anchored import (
    AnchoredPPO,
    anchor_coef_at,
    value_parameter_names,
)
from agents.experiments.training.config import TrainConfig
from agents.experiments.training.finetune import REFERENCE_MODEL
from agents.experiments.training.run import TrainOptions, resolve_config, train
from tests.helpers import flies_old_ids, load_script

pytestmark = [
    flies_old_ids,  # the init and its recipe fly v1 on purpose
    pytest.mark.usefixtures("one_torch_thread"),
]

ENV_ID = "DebrisGym/Rendezvous2D-v1"  # the init and its recipe (the v2 fine-tunes widen it)
RECIPE = CONFIG_DIR / "rendezvous2d_finetune.yaml"
INIT_OPTIONS = {"obs_goal": True, "obs_targets": 1, "obs_other_targets": True}
TINY_IMITATION = {
    "env_id": ENV_ID,  # an init without the hold element: widened for v2
    "env_kwargs": INIT_OPTIONS,
    "bc_episodes": 2,
    "dagger_rounds": 0,
    "epochs": 2,
    "workers": 1,
    "max_episode_steps": 25,
    "net_arch": (16, 16),
}
# 2 envs x 32 steps = 64 env steps per update; no periodic evaluation or checkpoint; a constant
# learning rate (the recipe's decays to 0 at the end of the run, so its last update is a no-op)
TINY = [
    "algo_kwargs.learning_rate=0.0003",
    "algo_kwargs.n_steps=32",
    "algo_kwargs.batch_size=32",
    "eval.freq=0",
    "checkpoint.freq=0",
    "env_kwargs.max_episode_steps=40",
    "env_kwargs.n_obstacles=5",
]


@pytest.fixture(scope="module")
def init_run(tmp_path_factory) -> Path:
    """A tiny imitate() run (behaviour cloning of APF-MPC, a 16 x 16 MLP): the init to fine-tune."""
    out = tmp_path_factory.mktemp("init") / "dagger"
    imitate(ImitationConfig(**TINY_IMITATION), out, log=lambda _: None, progress=False)
    return out


def finetune(init: Path, out: Path, steps: int, *sets: str, **options) -> Path:
    """A tiny fine-tune run of the checked-in recipe from ``init`` into ``out``."""
    result = train(
        TrainOptions(
            out=out, config=RECIPE, init=init, overrides=[*TINY, *sets], timesteps=steps,
            n_envs=2, seed=5, progress=False, argv=["test"], **options,
        )
    )  # fmt: skip
    assert result.status == "completed"
    return out


def ppo(path: Path):
    from stable_baselines3 import PPO

    return PPO.load(str(path), device="cpu", custom_objects={"learning_rate": 0.0,
                    "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0})  # fmt: skip


def held_observations(run: Path, n: int = 64) -> np.ndarray:
    """Raw observations of the init's env (reset states and a few coasting steps)."""
    env = gym.make(ENV_ID, **INIT_OPTIONS)
    out = []
    for seed in range(n // 4):
        obs, _ = env.reset(seed=700 + seed)
        for _ in range(4):
            out.append(obs)
            obs, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    env.close()
    return np.asarray(out, dtype=np.float32)


def normalised(run_model: Path, raw: np.ndarray) -> np.ndarray:
    """``raw`` normalised by hand with the statistics saved beside ``run_model``."""
    with open(run_model.parent / "vecnormalize.pkl", "rb") as fh:
        stats = pickle.load(fh)
    scaled = (raw - stats.obs_rms.mean) / np.sqrt(stats.obs_rms.var + stats.epsilon)
    return np.clip(scaled, -stats.clip_obs, stats.clip_obs).astype(np.float32)


def mean_actions(model, obs: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return model.policy.get_distribution(torch.as_tensor(obs)).mode().numpy()


# --- the critic warm-up -------------------------------------------------------------------------


def test_warmup_changes_only_the_value_function(init_run, tmp_path):
    """Every update inside the warm-up trains the value head; every policy parameter (actor
    layers, action head, log_std) stays bit-identical to the init's."""
    out = finetune(init_run, tmp_path / "ft", 256, "init.critic_warmup=256")
    before = ppo(init_run / "model.zip").policy.state_dict()
    after = ppo(out / "model.zip").policy.state_dict()
    value = set(value_parameter_names(ppo(out / "model.zip").policy))
    assert value and "log_std" not in value and any("action_net" in k for k in before)
    assert before.keys() == after.keys()
    for name in before:
        if name in value:
            assert not torch.equal(before[name], after[name]), f"{name} did not learn"
        else:
            assert torch.equal(before[name], after[name]), f"{name} changed in the warm-up"


def test_after_the_warmup_the_policy_learns(init_run, tmp_path):
    """The same run one update past the warm-up moves the policy (so the test above can fail)."""
    out = finetune(init_run, tmp_path / "ft", 320, "init.critic_warmup=256")
    before = ppo(init_run / "model.zip").policy.state_dict()
    after = ppo(out / "model.zip").policy.state_dict()
    assert not torch.equal(before["action_net.weight"], after["action_net.weight"])


# --- the anchor ---------------------------------------------------------------------------------


def test_a_large_anchor_keeps_the_policy_near_its_init(init_run, tmp_path):
    """Same run, same seed, a high learning rate: with anchor 100 the mean actions on held
    observations stay close to the init's; with anchor 0 they move several times farther."""
    raw = held_observations(init_run)
    obs = normalised(init_run / "model.zip", raw)
    start = mean_actions(ppo(init_run / "model.zip"), obs)
    moved = {}
    for coef in (100.0, 0.0):
        out = finetune(
            init_run, tmp_path / f"ft{coef:g}", 640,
            "algo_kwargs.learning_rate=0.003", "algo_kwargs.target_kl=null",
            "algo_kwargs.n_epochs=10", f"init.anchor_coef={coef}", "init.anchor_decay=1000000",
            "init.critic_warmup=0",
        )  # fmt: skip
        after = mean_actions(ppo(out / "model.zip"), obs)
        moved[coef] = float(np.mean(np.sum((after - start) ** 2, axis=1)))
    assert moved[0.0] > 1e-3, moved  # PPO alone does move it
    assert moved[100.0] < 0.25 * moved[0.0], moved


@pytest.mark.parametrize(
    "t, expected",
    [(0, 2.0), (100, 2.0), (164, 1.68), (200, 1.5), (300, 1.0), (499, 0.005), (500, 0.0),
     (10_000, 0.0)],
)  # fmt: skip
def test_anchor_schedule_by_hand(t, expected):
    """Warm-up 100 steps, anchor 2, decay over 400 steps: 2 until step 100, then linear to 0
    at step 500."""
    assert anchor_coef_at(t, 100, 2.0, 400) == pytest.approx(expected, abs=1e-12)


def test_anchor_schedule_edges():
    assert anchor_coef_at(10, 0, 1.0, 0) == 0.0  # no decay window: no anchor after the warm-up
    assert anchor_coef_at(0, 0, 1.0, 0) == 1.0
    assert anchor_coef_at(50, 0, 0.0, 100) == 0.0


def test_anchor_coef_and_loss_reach_tensorboard(init_run, tmp_path):
    """``train/anchor_coef`` at each logged step is the schedule at the update before it (SB3
    writes an update's values with the next rollout); ``train/anchor_loss`` is there, > 0 once
    the policy has moved."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = finetune(
        init_run, tmp_path / "ft", 640,
        "init.critic_warmup=128", "init.anchor_coef=3.0", "init.anchor_decay=384",
    )  # fmt: skip
    (run,) = (out / "tb").iterdir()
    events = EventAccumulator(str(run))
    events.Reload()
    coef = [(e.step, e.value) for e in events.Scalars("train/anchor_coef")]
    assert len(coef) >= 5
    for step, value in coef:
        assert value == pytest.approx(anchor_coef_at(step - 64, 128, 3.0, 384), rel=1e-6)
    losses = [e.value for e in events.Scalars("train/anchor_loss")]
    assert losses[0] == 0.0 and max(losses) > 0.0
    warm = [(e.step, e.value) for e in events.Scalars("train/critic_warmup")]
    assert all(v == float(s - 64 <= 128) for s, v in warm)


# --- what evaluate.py flies ---------------------------------------------------------------------


def test_the_model_flies_in_evaluate_py_as_trained(init_run, tmp_path):
    """The run takes the init's observation options and frozen statistics; load_agent (what
    evaluate.py uses) gives the same actions as the model on observations normalised by hand
    with the init's statistics; evaluate.py flies it."""
    out = finetune(init_run, tmp_path / "ft", 192, "init.critic_warmup=0",
                   "init.anchor_decay=1000")  # fmt: skip
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert {k: config["env_kwargs"][k] for k in INIT_OPTIONS} == INIT_OPTIONS
    assert config["init"]["path"] == str(init_run.resolve())
    assert agents.observation_options(f"ppo:{out / 'model.zip'}", ENV_ID) == INIT_OPTIONS

    with open(out / "vecnormalize.pkl", "rb") as fh:
        saved = pickle.load(fh)
    with open(init_run / "vecnormalize.pkl", "rb") as fh:
        init_stats = pickle.load(fh)
    assert type(saved).__name__ == "VecNormalize" and not saved.training
    assert np.array_equal(saved.obs_rms.mean, init_stats.obs_rms.mean)  # frozen, bit for bit
    assert np.array_equal(saved.obs_rms.var, init_stats.obs_rms.var)

    raw = held_observations(init_run, 16)
    env = gym.make(ENV_ID, **INIT_OPTIONS)
    agent = agents.load_agent(f"ppo:{out / 'model.zip'}", env)
    model = ppo(out / "model.zip")
    by_hand = np.clip(mean_actions(model, normalised(init_run / "model.zip", raw)), -1, 1)
    np.testing.assert_allclose(agent.predict(raw)[0], by_hand, rtol=0, atol=1e-6)
    env.close()

    evaluate = load_script("evaluate.py")
    args = ["--agents", f"ppo={out / 'model.zip'}", "--episodes", "1", "--max-steps", "20",
            "--no-progress", "--plots", "0", "--out", str(tmp_path / "eval")]  # fmt: skip
    assert evaluate.main(args) == 0
    assert (out / REFERENCE_MODEL).is_file()  # the reference, itself a policy evaluate.py flies
    assert agents.observation_options(f"ppo:{out / REFERENCE_MODEL}", ENV_ID) == INIT_OPTIONS


def test_the_training_env_normalises_with_the_init_statistics(init_run):
    """The fine-tune's training env: observations = the init's statistics applied to the raw
    ones, unchanged however many steps it takes (frozen); rewards scaled by a learned std."""
    from agents.experiments.training.models import make_train_env

    config, _ = resolve_config(TrainOptions(config=RECIPE, init=init_run, overrides=TINY, n_envs=2))
    venv = make_train_env(config, seed=0)
    mean0 = venv.obs_rms.mean.copy()
    obs = venv.reset()
    np.testing.assert_array_equal(obs, normalised(init_run / "model.zip", venv.get_original_obs()))
    count = venv.ret_rms.count
    for _ in range(5):
        obs, *_ = venv.step(np.zeros((2, *venv.action_space.shape), dtype=np.float32))
    np.testing.assert_array_equal(venv.obs_rms.mean, mean0)
    np.testing.assert_array_equal(obs, normalised(init_run / "model.zip", venv.get_original_obs()))
    assert venv.ret_rms.count > count
    venv.close()


# --- refusals -----------------------------------------------------------------------------------


def resolve(init, *sets: str) -> None:
    resolve_config(TrainOptions(config=RECIPE, init=init, overrides=[*TINY, *sets], n_envs=2))


def test_bad_init_directories_are_refused(init_run, tmp_path):
    with pytest.raises(ConfigError, match=r"'init.path' names .*not a directory"):
        resolve(tmp_path / "nowhere")
    partial = tmp_path / "partial"
    shutil.copytree(init_run, partial)
    (partial / "vecnormalize.pkl").unlink()
    with pytest.raises(ConfigError, match=r"'init.path' .* has no vecnormalize.pkl"):
        resolve(partial)
    (partial / "vecnormalize.pkl").write_bytes(b"not a pickle")
    with pytest.raises(ConfigError, match=r"'init.path' .*unusable statistics"):
        resolve(partial)
    shutil.copy(init_run / "vecnormalize.pkl", partial / "vecnormalize.pkl")
    (partial / "model.zip").write_bytes(b"junk")
    with pytest.raises(ConfigError, match=r"'init.path' .*model.zip is not an SB3 model"):
        resolve(partial)
    with pytest.raises(ConfigError, match="--init must name a run directory"):
        resolve(" ")


def test_mismatched_options_are_refused(init_run):
    with pytest.raises(ConfigError, match=r"'env_kwargs.obs_goal' is False .*obs_goal=True"):
        resolve(init_run, "env_kwargs.obs_goal=false")  # removes elements
    with pytest.raises(ConfigError, match=r"'env_kwargs.obs_obstacles' is 4 .*obs_obstacles=8"):
        resolve(init_run, "env_kwargs.obs_obstacles=4")  # the init left it at the default
    with pytest.raises(ConfigError, match=r"'env_kwargs.obs_other_targets' is False"):
        resolve(init_run, "env_kwargs.obs_other_targets=false")  # same names, other meaning
    resolve(init_run, "env_kwargs.obs_obstacles=8")  # the default, spelled out: the same
    with pytest.raises(ConfigError, match=r"'normalize.epsilon' is 1e-08 .*set normalize.epsilon"):
        resolve(init_run, "normalize.epsilon=1e-8")
    with pytest.raises(ConfigError, match=r"'policy_kwargs.net_arch' is \[32, 32\]"):
        resolve(init_run, "policy_kwargs.net_arch=[32, 32]")


@pytest.mark.parametrize(
    "change, match",
    [
        ({"critic_warmup": -1}, r"'init.critic_warmup' must be >= 0"),
        ({"critic_warmup": 1.5}, r"'init.critic_warmup' must be an integer"),
        ({"anchor_coef": -0.5}, r"'init.anchor_coef' must be >= 0"),
        ({"anchor_coef": "lots"}, r"'init.anchor_coef' must be a number"),
        ({"anchor_decay": 0}, r"'init.anchor_decay' must be >= 1 env step"),
        ({"anchor_dacay": 5}, r"'init.anchor_dacay' is unknown \(did you mean 'anchor_decay'"),
        ({"path": None}, r"'init.path' is required with init.critic_warmup"),
        ({"path": ""}, r"'init.path' must name a run directory"),
    ],
)
def test_bad_init_values_are_refused_naming_the_key(change, match):
    data, _ = load_config_file(RECIPE)
    data["init"] = {**data["init"], "path": "/somewhere", **change}
    with pytest.raises(ConfigError, match=match):
        TrainConfig.from_dict(data, "test")


def test_init_needs_ppo_and_normalised_observations():
    data, _ = load_config_file(RECIPE)
    data["init"]["path"] = "/somewhere"
    with pytest.raises(ConfigError, match=r"'init.path' fine-tuning .* needs algo ppo"):
        TrainConfig.from_dict({**data, "algo": "sac", "algo_kwargs": {}}, "test")
    with pytest.raises(ConfigError, match=r"'normalize.enabled' and normalize.norm_obs must be"):
        TrainConfig.from_dict({**data, "normalize": {"enabled": False}}, "test")


def test_the_checked_in_recipe_needs_an_init():
    data, _ = load_config_file(RECIPE)
    with pytest.raises(ConfigError, match=r"'init.path' is required .*train.py --init DIR"):
        TrainConfig.from_dict(data, str(RECIPE))
    config = TrainConfig.from_dict({**data, "init": {**data["init"], "path": "/x"}}, "test")
    assert config.init.critic_warmup == 300_000 and config.init.anchor_coef == 1.0


def test_init_and_resume_do_not_mix(tmp_path):
    with pytest.raises(ValueError, match="--init cannot be combined with --resume"):
        train(TrainOptions(resume=tmp_path, init=tmp_path))


# --- widening to an observation with more elements -------------------------------------------

V2_ID = "DebrisGym/Rendezvous2D-v2"
WIDEN = ["env_id=DebrisGym/Rendezvous2D-v2", "env_kwargs.obs_hold=true"]
"""The v2 env, whose observation adds the hold's progress (target0_hold) to the init's."""


def wide_and_narrow_observations(n: int = 64) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw observations of the v2 env with the hold observed (hold values set at random, as a
    policy may meet any), the same without the new element, and the columns of the init's."""
    env = gym.make(V2_ID, **INIT_OPTIONS)
    names = env.unwrapped.observation_names()
    new = [i for i, name in enumerate(names) if name.endswith("_hold")]
    columns = np.array([i for i in range(len(names)) if i not in new])
    rng = np.random.default_rng(3)
    wide = []
    for seed in range(n // 4):
        obs, _ = env.reset(seed=700 + seed)
        for _ in range(4):
            wide.append(obs)
            obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    env.close()
    raw = np.asarray(wide, dtype=np.float32)
    raw[:, new] = rng.uniform(0.0, 1.0, (len(raw), len(new)))
    assert new == [names.index("target0_hold")]
    return raw, raw[:, columns], columns


def test_a_wider_observation_starts_from_the_init_policy(init_run, tmp_path):
    """A fine-tune on the v2 env (the init saw no hold element) widens the init: inside the
    warm-up its policy and value function give, bit for bit on a batch, what the init's give on
    the init's observation, whatever the hold element holds; the first layers have zero weights
    for it, its statistics are mean 0 / variance 1, the init's are unchanged; evaluate.py's
    loader flies it on the v2 env."""
    out = finetune(init_run, tmp_path / "ft", 128, *WIDEN, "init.critic_warmup=256")
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env_id"] == V2_ID and config["env_kwargs"]["obs_hold"] is True
    raw, narrow, columns = wide_and_narrow_observations()
    init, model = ppo(init_run / "model.zip"), ppo(out / "model.zip")
    assert model.observation_space.shape == (len(columns) + 1,)

    with open(out / "vecnormalize.pkl", "rb") as fh:
        stats = pickle.load(fh)
    with open(init_run / "vecnormalize.pkl", "rb") as fh:
        init_stats = pickle.load(fh)
    (new,) = sorted(set(range(len(columns) + 1)) - set(columns.tolist()))
    assert (stats.obs_rms.mean[new], stats.obs_rms.var[new]) == (0.0, 1.0)
    np.testing.assert_array_equal(stats.obs_rms.mean[columns], init_stats.obs_rms.mean)
    np.testing.assert_array_equal(stats.obs_rms.var[columns], init_stats.obs_rms.var)

    obs, init_obs = normalised(out / "model.zip", raw), normalised(init_run / "model.zip", narrow)
    np.testing.assert_array_equal(obs[:, columns], init_obs)
    assert np.ptp(obs[:, new]) > 0.5  # the hold element varies: the equalities below mean it
    for name in ("mlp_extractor.policy_net.0.weight", "mlp_extractor.value_net.0.weight"):
        assert torch.count_nonzero(model.policy.state_dict()[name][:, new]) == 0
    assert np.array_equal(mean_actions(model, obs), mean_actions(init, init_obs))
    with torch.no_grad():
        values = model.policy.predict_values(torch.as_tensor(obs))
        init_values = init.policy.predict_values(torch.as_tensor(init_obs))
    assert not torch.equal(values, init_values)  # the warm-up trained the critic
    assert torch.equal(model.policy.log_std, init.policy.log_std)

    env = gym.make(V2_ID, **INIT_OPTIONS)
    agent = agents.load_agent(f"ppo:{out / 'model.zip'}", env)
    np.testing.assert_allclose(
        agent.predict(raw)[0], np.clip(mean_actions(init, init_obs), -1, 1), rtol=0, atol=0
    )
    env.close()
    assert agents.observation_options(f"ppo:{out / 'model.zip'}", V2_ID)["obs_hold"] is True


def test_the_widened_reference_anchors_and_survives_a_resume(init_run, tmp_path):
    """The anchor's μ₀ on the wide observation is the init's on the narrow one (the anchor loss
    is 0 before the policy moves), in the fresh run and after a resume."""
    out = finetune(init_run, tmp_path / "ft", 64, *WIDEN, "init.critic_warmup=128",
                   "init.anchor_coef=1.0", "init.anchor_decay=1000")  # fmt: skip
    raw, narrow, _ = wide_and_narrow_observations(16)
    obs, init_obs = normalised(out / "model.zip", raw), normalised(init_run / "model.zip", narrow)
    expected = mean_actions(ppo(init_run / "model.zip"), init_obs)
    with models_that_learn() as captured:
        result = train(TrainOptions(resume=out, timesteps=64, progress=False, argv=["test"]))
    assert result.status == "completed"
    reference = captured["model"].reference_policy
    with torch.no_grad():
        mu0 = reference.get_distribution(torch.as_tensor(obs)).mode().numpy()
    assert np.array_equal(mu0, expected)


@contextlib.contextmanager
def models_that_learn():
    """Within the block, ``captured["model"]`` is the last AnchoredPPO model that learned."""
    captured: dict = {}
    original = AnchoredPPO.learn

    def spy(self, *args, **kwargs):
        captured["model"] = self
        return original(self, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(AnchoredPPO, "learn", spy)
        yield captured


def tiny_lidar_init(out: Path, rays: int) -> Path:
    """An untrained PPO policy with statistics and config, observing ``rays`` lidar rays."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from debris_gym.integrations.sb3 import NativeVecEnv

    options = {"observation": "lidar", "lidar_rays": rays}
    venv = VecNormalize(NativeVecEnv(ENV_ID, 1, **options), clip_obs=10.0, epsilon=0.01)
    out.mkdir()
    PPO("MlpPolicy", venv, n_steps=8, batch_size=8, device="cpu").save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    (out / "config.yaml").write_text(yaml.safe_dump({"env_id": ENV_ID, "env_kwargs": options}))
    venv.close()
    return out


def test_a_widening_whose_shared_names_mean_other_values_is_refused(tmp_path):
    """8 → 16 lidar rays keeps the names lidar0..lidar7 but points rays 1..7 elsewhere: the
    values are compared on a test mission and the widening refused, naming the elements; the
    same rays, spelled out, are accepted."""
    init = tiny_lidar_init(tmp_path / "lidar8", 8)
    with pytest.raises(ConfigError, match=r"elements (lidar[1-7](, )?)+ take other values"):
        resolve(init, "env_kwargs.lidar_rays=16")
    resolve(init, "env_kwargs.lidar_rays=8")


def test_another_dimension_is_not_a_widening(init_run):
    """The 3D observation holds every 2D element name (x, y among x, y, z) but is not the 2D
    one widened by an option: refused."""
    with pytest.raises(ConfigError, match=r"observation space \(\d+ elements.*differs"):
        resolve(init_run, "env_id=DebrisGym/Rendezvous3D-v1")


# --- resume -------------------------------------------------------------------------------------


def test_resume_continues_with_the_reference_restored(init_run, tmp_path):
    """A resumed fine-tune continues from its model with the same anchor settings and μ₀ from
    the run's copy of the init (then, with that copy gone, from init.path; with neither, a clear
    error)."""
    out = finetune(init_run, tmp_path / "ft", 128, "init.critic_warmup=64",
                   "init.anchor_coef=2.0", "init.anchor_decay=500")  # fmt: skip
    init_state = ppo(init_run / "model.zip").policy.state_dict()

    with models_that_learn() as captured:
        result = train(TrainOptions(resume=out, timesteps=128, progress=False, argv=["test"]))
        assert result.status == "completed" and result.num_timesteps == 256
        model = captured["model"]
        assert (model.critic_warmup, model.anchor_coef, model.anchor_decay) == (64, 2.0, 500)
        reference = model.reference_policy.state_dict()
        assert all(torch.equal(reference[k], init_state[k]) for k in init_state)

        (out / REFERENCE_MODEL).unlink()
        result = train(TrainOptions(resume=out, timesteps=64, progress=False, argv=["test"]))
        assert result.num_timesteps == 320
        reference = captured["model"].reference_policy.state_dict()
        assert all(torch.equal(reference[k], init_state[k]) for k in init_state)

    moved = tmp_path / "moved"
    init_run.rename(moved)
    try:
        with pytest.raises(FileNotFoundError, match="the anchor's reference is gone"):
            train(TrainOptions(resume=out, timesteps=64, progress=False, argv=["test"]))
    finally:
        moved.rename(init_run)


def test_a_single_agent_policy_is_widened_to_a_swarm(init_run, tmp_path):
    """A fine-tune on a swarm ID from a single-agent run: one SB3 env per chaser, the init
    widened to the hold and teammates blocks (zero policy weights for them, so every chaser
    starts flying as the init flies alone)."""
    from debris_gym.swarm import make as make_swarm

    out = tmp_path / "ft_swarm"
    result = train(
        TrainOptions(
            out=out, config=RECIPE, init=init_run, timesteps=128, n_envs=2, seed=5,
            progress=False, argv=["test"],
            overrides=[*TINY, "env_id=DebrisGym/Swarm2D-Easy-v0", "init.critic_warmup=256",
                       "env_kwargs.obs_hold=true"],
        )
    )  # fmt: skip
    assert result.status == "completed"
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env_id"] == "DebrisGym/Swarm2D-Easy-v0"
    model, init = ppo(out / "model.zip"), ppo(init_run / "model.zip")
    env = make_swarm("DebrisGym/Swarm2D-Easy-v0", **INIT_OPTIONS, obs_hold=True)
    names = env.observation_names()
    assert names[-1] == "teammate0_flying" and model.observation_space.shape == (len(names),)
    new = [k for k, name in enumerate(names) if name.startswith("teammate") or "hold" in name]
    weights = model.policy.state_dict()
    # inside the warm-up the policy is the init's; the critic has begun to read the teammates
    assert torch.count_nonzero(weights["mlp_extractor.policy_net.0.weight"][:, new]) == 0
    assert torch.count_nonzero(weights["mlp_extractor.value_net.0.weight"][:, new[1:]]) > 0
    assert model.observation_space.shape[0] == init.observation_space.shape[0] + len(new)
