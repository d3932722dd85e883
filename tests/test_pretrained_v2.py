"""The shipped v2 policies and the observation a learned policy is flown with across versions:
`pretrained` on a v2 ID is the policy fine-tuned for the v2 rules (it observes the hold's
progress), and a policy of a v1 ID flies a v2 ID without the element it never saw."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")


import agents
from agents.policies.learned import PRETRAINED_DIR, PRETRAINED_POLICIES, pretrained_path
from tests.helpers import flies_old_ids

pytestmark = pytest.mark.usefixtures("one_torch_thread")

V1_OPTIONS = {"obs_targets": 1, "obs_goal": True, "obs_other_targets": True}
V2_OPTIONS = {**V1_OPTIONS, "obs_hold": True}


def fly(env: gym.Env, agent, seed: int) -> dict:
    obs, info = env.reset(seed=seed)
    for _ in range(1000):
        obs, _, terminated, truncated, info = env.step(agent.predict(obs)[0])
        if terminated or truncated:
            break
    return info


@pytest.mark.parametrize(
    "env_id, name",
    [
        ("DebrisGym/Rendezvous2D-v2", "rendezvous2d_v2_residual.zip"),
        ("DebrisGym/Rendezvous3D-v2", "rendezvous3d_v2_residual.zip"),
    ],
)
def test_the_pretrained_v2_policies_are_residual_ones(env_id, name):
    """On the v2 IDs `pretrained` is the residual policy: its files ship, it is flown in the
    residual mode with the v2 ID's observation (the hold's progress among it), and it
    completes a held-out mission of the default difficulty (a seed outside every training,
    evaluation and suite range) under the hold rule."""
    assert pretrained_path(env_id)[1].name == name
    stem = name.removesuffix(".zip")
    assert (PRETRAINED_DIR / f"{stem}_vecnormalize.pkl").is_file()
    assert (PRETRAINED_DIR / f"{stem}.yaml").is_file()
    options = agents.observation_options("pretrained", env_id)
    assert options == {"obs_hold": True, "action": "residual"}  # the v2 ID's own observation
    env = gym.make(env_id, **options)
    agent = agents.load_agent("pretrained", env)
    info = fly(env, agent, 20_000_001)
    assert info["is_success"] and info["targets_captured"] == 3 and not info["collision"]
    env.close()


@pytest.mark.parametrize(
    "env_id, name, expected",
    [
        # the 2D policy also observes the goal's near field (obs_near: DAgger, then fine-tuned)
        ("DebrisGym/Rendezvous2D-v2", "rendezvous2d_v2.zip", {**V2_OPTIONS, "obs_near": True}),
        ("DebrisGym/Rendezvous3D-v2", "rendezvous3d_v2.zip", V2_OPTIONS),
    ],
)
def test_the_direct_thrust_v2_policies_still_fly_their_ids(env_id, name, expected):
    """The DAgger + PPO v2 policies (the swarm's `pretrained`) stay shipped: named by file
    they are flown with their own observation options and complete a held-out mission."""
    spec = f"ppo:{PRETRAINED_DIR / name}"
    stem = name.removesuffix(".zip")
    assert (PRETRAINED_DIR / f"{stem}_vecnormalize.pkl").is_file()
    options = agents.observation_options(spec, env_id)
    assert options == expected
    env = gym.make(env_id, **options)
    info = fly(env, agents.load_agent(spec, env), 20_000_001)
    assert info["is_success"] and info["targets_captured"] == 3 and not info["collision"]
    env.close()


def test_the_v1_entries_stay():
    assert PRETRAINED_POLICIES["DebrisGym/Rendezvous2D-v1"][1] == "rendezvous2d_finetuned.zip"
    assert PRETRAINED_POLICIES["DebrisGym/Rendezvous3D-v1"][1] == "rendezvous3d_finetuned.zip"


def test_a_v1_policy_flies_a_v2_id_without_the_hold_element():
    """The v1 policy was trained on an env whose registration leaves obs_hold off; the v2 ID
    turns it on: flown there it gets obs_hold False (its own observation) and loads."""
    v1_policy = f"ppo:{PRETRAINED_DIR / 'rendezvous2d_finetuned.zip'}"
    on_v2 = agents.observation_options(v1_policy, "DebrisGym/Rendezvous2D-v2")
    assert on_v2 == {**V1_OPTIONS, "obs_hold": False}
    assert agents.observation_options(v1_policy, "DebrisGym/Rendezvous2D-v1") == V1_OPTIONS
    env = gym.make("DebrisGym/Rendezvous2D-v2", **on_v2)
    agent = agents.load_agent(v1_policy, env)
    assert agent.observation_space.shape == env.observation_space.shape
    env.close()


def test_a_v2_policy_keeps_its_hold_element_on_another_id():
    """The other way round: the v2 policy's observation options carry obs_hold True (set by its
    config, and by its env's registration) whatever ID it is flown on."""
    v2_policy = f"ppo:{PRETRAINED_DIR / 'rendezvous2d_v2.zip'}"
    for env_id in ("DebrisGym/Rendezvous2D-v1", "DebrisGym/Rendezvous2D-v2"):
        assert agents.observation_options(v2_policy, env_id) == {**V2_OPTIONS, "obs_near": True}


@pytest.mark.parametrize("dim", ["2d", "3d"])
def test_the_v2_recipes_start_from_the_shipped_v1_policies(dim, tmp_path):
    """The recipe that made each v2 policy resolves with the v1 policy's files as its init run
    (as docs/training.md assembles it): the v1 observation options are taken, obs_hold widens
    them, and the init run is accepted (spaces, statistics, the shared elements' values)."""
    import shutil

    from agents.experiments.config_files import CONFIG_DIR
    from agents.experiments.training.run import TrainOptions, resolve_config

    init = tmp_path / f"v1_{dim}"
    init.mkdir()
    stem = PRETRAINED_DIR / f"rendezvous{dim}_finetuned"
    shutil.copy(stem.with_suffix(".zip"), init / "model.zip")
    shutil.copy(f"{stem}_vecnormalize.pkl", init / "vecnormalize.pkl")
    shutil.copy(stem.with_suffix(".yaml"), init / "config.yaml")
    recipe = CONFIG_DIR / f"rendezvous{dim}_v2_finetune.yaml"
    config, _ = resolve_config(TrainOptions(config=recipe, init=init, n_envs=2))
    assert config.env_id == f"DebrisGym/Rendezvous{dim.upper()}-v2"
    assert {k: config.env_kwargs[k] for k in V2_OPTIONS} == V2_OPTIONS
    assert config.init.path == str(init.resolve())


@flies_old_ids
def test_a_v2_policy_fine_tuned_on_a_v1_id_keeps_its_hold_element(tmp_path):
    """The other way round: the v2 policy observed the hold because its env's registration
    turns obs_hold on (its config need not say so); fine-tuned on the v1 ID, whose default is
    off, the run takes the init's value instead of refusing the v1 ID's default."""
    import shutil

    import yaml

    from agents.experiments.config_files import CONFIG_DIR
    from agents.experiments.training.run import TrainOptions, resolve_config

    init = tmp_path / "v2_2d"
    init.mkdir()
    stem = PRETRAINED_DIR / "rendezvous2d_v2"
    shutil.copy(stem.with_suffix(".zip"), init / "model.zip")
    shutil.copy(f"{stem}_vecnormalize.pkl", init / "vecnormalize.pkl")
    data = yaml.safe_load(stem.with_suffix(".yaml").read_text())
    del data["env_kwargs"]["obs_hold"]  # left to DebrisGym/Rendezvous2D-v2's registration
    (init / "config.yaml").write_text(yaml.safe_dump(data))
    recipe = CONFIG_DIR / "rendezvous2d_finetune.yaml"  # the v1 recipe: DebrisGym/Rendezvous2D-v1
    config, _ = resolve_config(TrainOptions(config=recipe, init=init, n_envs=2))
    assert config.env_id == "DebrisGym/Rendezvous2D-v1"
    assert {k: config.env_kwargs[k] for k in V2_OPTIONS} == V2_OPTIONS


def test_the_residual_policy_is_flown_in_its_mode_and_refused_outside_it():
    """The shipped residual policy: evaluate.py's options for it name the residual mode, it
    loads and acts in an env made with them, and an env without the mode is refused (the same
    Box of actions would be flown as whole thrusts)."""
    from agents import load_agent
    from agents.policies.learned import observation_options

    spec = f"ppo:{PRETRAINED_DIR / 'rendezvous2d_v2_residual.zip'}"
    options = observation_options(spec, "DebrisGym/Rendezvous2D-v2")
    assert options.get("action") == "residual"
    env = gym.make("DebrisGym/Rendezvous2D-v2", **options)
    obs, _ = env.reset(seed=0)
    action, _ = load_agent(spec, env).predict(obs)
    assert action.shape == (2,) and np.all(np.isfinite(action))
    with pytest.raises(ValueError, match="action='residual'"):
        load_agent(spec, gym.make("DebrisGym/Rendezvous2D-v2"))
