"""agents.policies.learned: a model's VecNormalize statistics are restored or their absence is
refused / warned about, damaged statistics give a clear error, and loading a policy never imports
the training code (nor does ``import agents`` import torch)."""

from __future__ import annotations

import json
import os
import pickle
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import agents
import debris_gym  # noqa: F401  (registers the IDs)
from tests.helpers import flies_old_ids, load_script

# learned policies of the frozen-world default field (v0)
pytestmark = flies_old_ids

ENV_ID = "DebrisGym/Rendezvous2D-v0"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory) -> Path:
    """A run directory with an untrained tiny PPO model, its VecNormalize statistics (moved
    away from the initial ones) and a config.yaml saying the run normalised observations."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    out = tmp_path_factory.mktemp("run")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV_ID)]), norm_reward=False)
    venv.reset()
    for _ in range(20):  # statistics that differ from the initial mean 0 / variance 1
        venv.step(np.array([venv.action_space.sample()]))
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]})
    model.save(out / "model.zip")
    venv.save(out / "vecnormalize.pkl")
    venv.close()
    (out / "config.yaml").write_text("normalize:\n  enabled: true\n  norm_obs: true\n")
    return out


def _copy_model(run: Path, dest: Path, config: str | None) -> Path:
    dest.mkdir()
    shutil.copy(run / "model.zip", dest / "model.zip")
    if config is not None:
        (dest / "config.yaml").write_text(config)
    return dest / "model.zip"


def test_a_model_with_its_statistics_normalises_observations(saved_run):
    env = gym.make(ENV_ID)
    agent = agents.load_agent(f"ppo:{saved_run / 'model.zip'}", env)
    with open(saved_run / "vecnormalize.pkl", "rb") as fh:
        stats = pickle.load(fh)
    obs, _ = env.reset(seed=0)
    want = np.clip(
        (obs - stats.obs_rms.mean) / np.sqrt(stats.obs_rms.var + stats.epsilon),
        -stats.clip_obs,
        stats.clip_obs,
    )
    np.testing.assert_allclose(agent.normalize(obs), want, rtol=1e-5, atol=1e-6)
    assert not np.allclose(agent.normalize(obs), obs)  # the statistics really act
    env.close()


def test_missing_statistics_of_a_normalised_run_are_refused(saved_run, tmp_path):
    model = _copy_model(saved_run, tmp_path / "bare", "normalize:\n  enabled: true\n")
    env = gym.make(ENV_ID)
    with pytest.raises(FileNotFoundError) as err:
        agents.load_agent(f"ppo:{model}", env)
    message = str(err.value)
    assert str(tmp_path / "bare" / "vecnormalize.pkl") in message and "copy" in message
    env.close()


def test_missing_statistics_of_an_unknown_run_are_warned_about(saved_run, tmp_path):
    model = _copy_model(saved_run, tmp_path / "alone", None)
    env = gym.make(ENV_ID)
    with pytest.warns(UserWarning, match="raw observations") as record:
        agent = agents.load_agent(f"ppo:{model}", env)
    assert str(tmp_path / "alone" / "vecnormalize.pkl") in str(record[0].message)
    assert agent.obs_normalizer is None
    env.close()


def test_a_run_without_normalisation_loads_silently(saved_run, tmp_path):
    model = _copy_model(saved_run, tmp_path / "raw", "normalize:\n  enabled: false\n")
    env = gym.make(ENV_ID)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        agent = agents.load_agent(f"ppo:{model}", env)
    assert agent.obs_normalizer is None
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(agent.normalize(obs), obs)
    env.close()


@pytest.mark.parametrize("damage", ["empty", "truncated", "garbage", "wrong_object"])
def test_damaged_statistics_give_an_error_naming_the_file(saved_run, tmp_path, damage):
    model = _copy_model(saved_run, tmp_path / damage, "normalize:\n  enabled: true\n")
    stats = model.with_name("vecnormalize.pkl")
    good = (saved_run / "vecnormalize.pkl").read_bytes()
    content = {
        "empty": b"",
        "truncated": good[: len(good) // 2],
        "garbage": b"this is not a pickle at all",
        "wrong_object": pickle.dumps({"obs_rms": None}),
    }[damage]
    stats.write_bytes(content)
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match="VecNormalize statistics") as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(stats) in str(err.value)
    env.close()


def test_statistics_with_corrupt_numbers_give_an_error_naming_the_file(saved_run, tmp_path):
    model = _copy_model(saved_run, tmp_path / "nan", "normalize:\n  enabled: true\n")
    stats = model.with_name("vecnormalize.pkl")
    with open(saved_run / "vecnormalize.pkl", "rb") as fh:
        normalizer = pickle.load(fh)
    # what VecNormalize.__getstate__ drops (and unpickling does not restore)
    normalizer.venv, normalizer.class_attributes, normalizer.returns = None, {}, None
    normalizer.obs_rms.mean[0] = np.nan
    stats.write_bytes(pickle.dumps(normalizer))
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match="corrupt VecNormalize statistics") as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(stats) in str(err.value)
    del normalizer.obs_rms  # a VecNormalize object without its statistics
    stats.write_bytes(pickle.dumps(normalizer))
    with pytest.raises(ValueError, match="incomplete VecNormalize statistics"):
        agents.load_agent(f"ppo:{model}", env)
    env.close()


@pytest.mark.parametrize("damage", ["empty", "truncated"])
def test_a_damaged_model_file_gives_an_error_naming_it(saved_run, tmp_path, damage):
    dest = tmp_path / damage
    dest.mkdir()
    good = (saved_run / "model.zip").read_bytes()
    model = dest / "model.zip"
    model.write_bytes(b"" if damage == "empty" else good[: len(good) // 2])
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match="not a model file") as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(model) in str(err.value)
    env.close()


@pytest.mark.parametrize(
    "config", ["normalize: [unclosed\n", "- just\n- a list\n", "normalize: true\n"]
)
def test_a_damaged_run_config_gives_an_error_naming_it(saved_run, tmp_path, config):
    model = _copy_model(saved_run, tmp_path / "cfg", config)
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError) as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(tmp_path / "cfg" / "config.yaml") in str(err.value)
    env.close()


def test_evaluate_py_shows_and_keeps_the_raw_observation_warning(saved_run, tmp_path, capsys):
    model = _copy_model(saved_run, tmp_path / "bare", None)
    cli = load_script("evaluate.py")
    out = tmp_path / "eval"
    argv = [
        "--agents", f"zero,ppo={model}", "--episodes", "1", "--max-steps", "5", "--plots", "0",
        "--no-progress", "--out", str(out), "--env", ENV_ID,
    ]  # fmt: skip
    assert cli.main(argv) == 0
    captured = capsys.readouterr()
    assert "note: agent 'ppo'" in captured.err and "raw observations" in captured.err
    assert captured.err.count("raw observations") == 1  # noted once, not again per episode
    summary = json.loads((out / "summary.json").read_text())
    assert "raw observations" in summary["warnings"]["ppo"]
    assert "Warning — ppo" in (out / "summary.md").read_text()


def _run(code: str) -> str:
    result = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_import_agents_imports_neither_torch_nor_training_code():
    out = _run(
        """
        import sys
        import agents
        heavy = ("torch", "stable_baselines3", "agents.experiments", "agents.training")
        print(sorted(m for m in heavy if m in sys.modules))
        try:
            agents.load_agent("ppo:/nonexistent/model.zip", None)
        except FileNotFoundError:
            pass
        print(sorted(m for m in heavy if m in sys.modules))
        """
    )
    assert out.split("\n")[:2] == ["[]", "[]"]


def test_loading_and_running_a_policy_never_imports_training_code(saved_run):
    out = _run(
        f"""
        import sys
        import gymnasium as gym
        import debris_gym
        import agents.policies.learned
        print(sorted(m for m in sys.modules if m.startswith(("agents.experiments",
                                                              "agents.training", "torch"))))
        import agents
        env = gym.make("{ENV_ID}")
        agent = agents.load_agent("ppo:{saved_run / "model.zip"}", env)
        obs, _ = env.reset(seed=0)
        agent.predict(obs)
        print("torch" in sys.modules)
        print(sorted(m for m in sys.modules if m.startswith(("agents.experiments",
                                                              "agents.training"))))
        """
    )
    assert out.split("\n")[:3] == ["[]", "True", "[]"]


# --- what a model directory may run, and what it must say ---------------------------------


class _RunsCode:
    """Unpickling this calls os.mkdir: what a hostile statistics file could do."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (os.mkdir, (self.path,))


def test_statistics_that_would_run_code_are_refused_before_it_runs(saved_run, tmp_path):
    """Regression: vecnormalize.pkl was unpickled before its type was checked, so a pickle that
    calls a function ran it."""
    model = _copy_model(saved_run, tmp_path / "hostile", "normalize:\n  enabled: true\n")
    marker = tmp_path / "it_ran"
    model.with_name("vecnormalize.pkl").write_bytes(pickle.dumps(_RunsCode(str(marker))))
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match=r"references (posix|os)\.mkdir") as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(model.with_name("vecnormalize.pkl")) in str(err.value)
    assert not marker.exists()
    env.close()


@pytest.mark.parametrize("key", ["env_kwargs", "normalize"])
def test_a_damaged_config_entry_is_refused_although_the_statistics_exist(saved_run, tmp_path, key):
    """Regression: with the statistics beside the model, a damaged env_kwargs or normalize in
    config.yaml was swallowed."""
    config = {"env_kwargs": "env_kwargs: 5\nnormalize: {enabled: true}\n",
              "normalize": "normalize: [1, 2]\n"}[key]  # fmt: skip
    model = _copy_model(saved_run, tmp_path / key, config)
    shutil.copy(saved_run / "vecnormalize.pkl", model.with_name("vecnormalize.pkl"))
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match=f"'{key}' must be a mapping") as err:
        agents.load_agent(f"ppo:{model}", env)
    assert str(model.with_name("config.yaml")) in str(err.value)
    with pytest.raises(ValueError, match=f"'{key}' must be a mapping"):
        agents.observation_options(f"ppo:{model}", ENV_ID)
    env.close()


def _evaluate_once(model: Path, out: Path) -> dict[str, Any]:
    """evaluate.py in this process: one 3-step episode of ``ppo=model`` on ENV_ID into ``out``;
    its summary.json."""
    argv = [
        "--agents", f"ppo={model}", "--episodes", "1", "--max-steps", "3", "--plots", "0",
        "--no-progress", "--workers", "1", "--out", str(out), "--env", ENV_ID,
    ]  # fmt: skip
    assert load_script("evaluate.py").main(argv) == 0
    return json.loads((out / "summary.json").read_text())


def test_a_model_flown_on_another_env_is_named_in_a_warning_the_summary_keeps(
    saved_run, tmp_path, capsys
):
    """Regression: an Easy-rung model flown on another env gave its (poor) numbers without a
    word, although its config.yaml records the env it was trained on."""
    config = "env_id: DebrisGym/Rendezvous2D-Easy-v1\nnormalize: {enabled: true}\n"
    model = _copy_model(saved_run, tmp_path / "easy", config)
    shutil.copy(saved_run / "vecnormalize.pkl", model.with_name("vecnormalize.pkl"))
    env = gym.make(ENV_ID)
    with pytest.warns(UserWarning, match="trained on DebrisGym/Rendezvous2D-Easy-v1 but is flown"):
        agents.load_agent(f"ppo:{model}", env)
    env.close()
    summary = _evaluate_once(model, tmp_path / "eval")
    assert f"is flown on {ENV_ID}" in summary["warnings"]["ppo"]
    assert "--env DebrisGym/Rendezvous2D-Easy-v1" in (tmp_path / "eval" / "summary.md").read_text()


def _checkpoint(saved_run: Path, path: Path, timesteps: int) -> None:
    """A copy of the saved model as ``path``, claiming ``timesteps``, with its statistics."""
    from stable_baselines3 import PPO

    from agents.policies.model_files import sidecar_path

    model = PPO.load(saved_run / "model.zip")
    model.num_timesteps = timesteps
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)
    shutil.copy(saved_run / "vecnormalize.pkl", sidecar_path(path, "vecnormalize"))


def test_a_run_directory_flies_its_model_else_its_newest_checkpoint(saved_run, tmp_path):
    """Regression: after Ctrl-C there is no model.zip, and `ppo=runs/ppo` said "model file
    'runs/ppo' not found" although the directory held checkpoints."""
    run = tmp_path / "run"
    _checkpoint(saved_run, run / "checkpoints" / "interrupted.zip", 6000)
    _checkpoint(saved_run, run / "checkpoints" / "rl_model_4096_steps.zip", 4096)
    (run / "config.yaml").write_text("normalize: {enabled: true}\n")
    env = gym.make(ENV_ID)
    with pytest.warns(UserWarning) as record:
        agent = agents.load_agent(f"ppo:{run}", env)
    assert agent.path == run / "checkpoints" / "interrupted.zip"
    assert any(
        "has no model.zip" in str(w.message) and "checkpoints/interrupted.zip (6000 timesteps)"
        in str(w.message) for w in record
    )  # fmt: skip
    assert agent.obs_normalizer is not None  # the checkpoint's own statistics

    with pytest.raises(FileNotFoundError) as err:
        agents.load_agent(f"ppo:{run / 'model.zip'}", env)
    message = str(err.value)
    assert "checkpoints/interrupted.zip (6000 timesteps)" in message
    assert "checkpoints/rl_model_4096_steps.zip (4096 timesteps)" in message

    shutil.copy(saved_run / "model.zip", run / "model.zip")
    shutil.copy(saved_run / "vecnormalize.pkl", run / "vecnormalize.pkl")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        assert agents.load_agent(f"ppo:{run}", env).path == run / "model.zip"

    empty = tmp_path / "empty"
    (empty / "tb").mkdir(parents=True)
    (empty / "config.yaml").write_text("normalize: {enabled: true}\n")
    with pytest.raises(FileNotFoundError, match=r"holds no model .*it has: config.yaml, tb/"):
        agents.load_agent(f"ppo:{empty}", env)
    env.close()


def test_evaluate_py_takes_a_run_directory(saved_run, tmp_path):
    run = tmp_path / "run"
    _checkpoint(saved_run, run / "checkpoints" / "interrupted.zip", 6000)
    (run / "config.yaml").write_text("normalize: {enabled: true}\n")
    summary = _evaluate_once(run, tmp_path / "eval")
    assert "checkpoints/interrupted.zip" in summary["warnings"]["ppo"]
