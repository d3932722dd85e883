"""train.py, agents.experiments.training and agents.policies.learned: tiny runs of every algorithm,
resume, Ctrl-C, config validation, and learned agents behind the shared predict() interface.

The script runs of the off-policy algorithms, the Ctrl-C run and the cut-log resume are marked
``slow``; the default run keeps a script run of PPO, its resume, and in-process runs of the others.
"""

from __future__ import annotations

import csv
import json
import os
import pickle
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

import agents
from agents.experiments.config_files import CONFIG_DIR, apply_overrides, load_config_file
from agents.experiments.training.checkpoints import (
    find_latest_checkpoint,
    interrupts_deferred,
    model_timesteps,
)
from agents.experiments.training.config import (
    OFF_POLICY,
    TrainConfig,
    available_configs,
    default_config_path,
)
from agents.experiments.training.run import TrainOptions, train
from agents.policies.learned_agent import LearnedAgent
from agents.policies.model_files import sidecar_path
from debris_gym.files import save_atomic
from debris_gym.swarm import SWARM_SPECS
from tests.helpers import flies_old_ids, fly_policy, load_script

ROOT = Path(__file__).resolve().parents[1]
TRAIN = ROOT / "train.py"
EVALUATE = ROOT / "evaluate.py"
ENV_ID = "DebrisGym/Rendezvous2D-v2"

TINY = [
    "--no-progress", "--n-envs", "2", "--timesteps", "256",
    "--set", "eval.freq=128", "--set", "eval.n_episodes=2", "--set", "eval.n_envs=2",
    "--set", "checkpoint.freq=128", "--set", "env_kwargs.max_episode_steps=40",
    "--set", "env_kwargs.n_obstacles=5",
]  # fmt: skip
OFF_POLICY_SETS = ["buffer_size=2000", "learning_starts=32", "batch_size=32", "gradient_steps=1"]
ALGO_SETS = {
    "ppo": ["n_steps=32", "batch_size=32", "n_epochs=1"],
    "sac": OFF_POLICY_SETS,
    "td3": OFF_POLICY_SETS,
    "dqn": [*OFF_POLICY_SETS, "target_update_interval=64"],
}
SUBPROCESS_ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def tiny_args(algo: str) -> list[str]:
    args = ["--algo", algo, *TINY]
    for item in ALGO_SETS[algo]:
        args += ["--set", f"algo_kwargs.{item}"]
    return args


def run_train(args: list[str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(TRAIN), *args],
        cwd=ROOT, capture_output=True, text=True, timeout=timeout, env=SUBPROCESS_ENV,
    )  # fmt: skip


def run_env(run: Path, **kwargs):
    """The env a policy of ``run`` flies: the default env with the run's observation options."""
    from agents import observation_options

    return gym.make(ENV_ID, **{**observation_options(f"ppo:{run / 'model.zip'}", ENV_ID), **kwargs})


@pytest.fixture(scope="module")
def train_cli():
    return load_script("train.py")


@pytest.fixture(scope="module")
def evaluate_cli():
    return load_script("evaluate.py")


_SCRIPT_RUNS: dict[str, Path] = {}
_LIBRARY_RUNS: dict[str, Path] = {}


@pytest.fixture(scope="module")
def trained_by_script(tmp_path_factory):
    """algo → run directory of a tiny ``python train.py`` run (once per module and worker)."""

    def get(algo: str) -> Path:
        if algo not in _SCRIPT_RUNS:
            out = tmp_path_factory.mktemp(f"script_{algo}") / "run"
            proc = run_train([*tiny_args(algo), "--out", str(out), "--seed", "3"])
            assert proc.returncode == 0, proc.stdout + proc.stderr
            _SCRIPT_RUNS[algo] = out
        return _SCRIPT_RUNS[algo]

    return get


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """algo → run directory of a tiny in-process :func:`train` run."""

    def get(algo: str) -> Path:
        if algo not in _LIBRARY_RUNS:
            out = tmp_path_factory.mktemp(f"lib_{algo}") / "run"
            args = tiny_args(algo)
            overrides = [args[i + 1] for i, a in enumerate(args) if a == "--set"]
            result = train(
                TrainOptions(
                    out=out, algo=algo, overrides=overrides, timesteps=256, n_envs=2, seed=3,
                    progress=False, argv=["test"],
                )
            )  # fmt: skip
            assert result.status == "completed"
            _LIBRARY_RUNS[algo] = out
        return _LIBRARY_RUNS[algo]

    return get


# --- train.py end to end ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "algo",
    ["ppo", *(pytest.param(a, marks=pytest.mark.slow) for a in ("sac", "td3", "dqn"))],
)
def test_train_writes_a_run_that_evaluate_py_flies(
    algo, trained_by_script, evaluate_cli, tmp_path, capsys
):
    out = trained_by_script(algo)
    for name in ("model.zip", "config.yaml", "learning_curve.png", "train_log.json",
                 "evaluations.npz", "best_model.zip", "train_episodes.csv"):  # fmt: skip
        assert (out / name).is_file(), name
    assert (out / "vecnormalize.pkl").is_file()  # every checked-in config normalises obs
    assert (out / "learning_curve.png").read_bytes().startswith(b"\x89PNG")
    assert model_timesteps(out / "model.zip") >= 256
    checkpoints = list((out / "checkpoints").glob("rl_model_*_steps.zip"))
    assert checkpoints
    for ckpt in checkpoints:  # each with its VecNormalize stats beside it, no scratch files
        assert sidecar_path(ckpt, "vecnormalize").is_file(), ckpt
    latest = max(checkpoints, key=model_timesteps)
    buffer = sidecar_path(latest, "replay_buffer").is_file()
    assert buffer == (algo in OFF_POLICY)  # small buffers go with the latest checkpoint
    assert (out / "best_model_vecnormalize.pkl").is_file()
    assert not list(out.rglob(".*tmp*"))

    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["algo"] == algo and config["env_id"] == ENV_ID and config["version"] >= 1
    assert config["run"]["seed"] == 3 and "train.py" in config["run"]["command"]
    assert config["run"]["versions"]["debris_gym"]
    assert (config["env_kwargs"].get("action") == "discrete") == (algo == "dqn")
    log = json.loads((out / "train_log.json").read_text())
    assert log["status"] == "completed" and log["env_steps_per_s"] > 0
    with np.load(out / "evaluations.npz") as data:
        assert data["timesteps"][-1] == model_timesteps(out / "model.zip")
        assert data["results"].shape[1] == 2 and "successes" in data

    args = [
        "--agents", f"{algo}={out / 'model.zip'}", "--episodes", "2", "--max-steps", "20",
        "--no-progress", "--plots", "0", "--out", str(tmp_path / "eval"),
    ]  # fmt: skip
    if algo == "ppo":  # the documented command, as a subprocess
        proc = subprocess.run(
            [sys.executable, str(EVALUATE), *args],
            cwd=ROOT, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        stdout = proc.stdout
    else:  # the same script in-process (saves a torch import per algorithm)
        assert evaluate_cli.main(args) == 0
        stdout = capsys.readouterr().out
    assert f"| {algo} |" in stdout
    summary = json.loads((tmp_path / "eval" / "summary.json").read_text())
    assert summary["agents"][algo]["decision_ms_p50"] > 0


@pytest.mark.parametrize("algo", ["sac", "td3", "dqn"])
def test_off_policy_runs_keep_their_replay_buffer_and_statistics(algo, trained):
    out = trained(algo)
    assert model_timesteps(out / "model.zip") >= 256
    assert (out / "vecnormalize.pkl").is_file() and (out / "replay_buffer.pkl").is_file()
    checkpoints = sorted((out / "checkpoints").glob("rl_model_*_steps.zip"), key=model_timesteps)
    assert checkpoints and all(sidecar_path(c, "vecnormalize").is_file() for c in checkpoints)
    buffers = [c for c in checkpoints if sidecar_path(c, "replay_buffer").is_file()]
    assert buffers == checkpoints[-1:]  # only the latest checkpoint keeps its buffer
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["algo"] == algo and config["run"]["seed"] == 3


def test_resume_adds_timesteps(trained_by_script, train_cli, tmp_path, capsys):
    out = tmp_path / "run"
    shutil.copytree(trained_by_script("ppo"), out)
    before = model_timesteps(out / "model.zip")
    for argv, message in (
        (["--resume", str(out)], "pass --timesteps N to train N more"),  # budget reached
        (["--resume", str(out), "--seed", "1"], "--seed cannot be combined with --resume"),
        (["--out", str(out)], "already holds a run"),
    ):
        with pytest.raises(SystemExit) as exc:
            train_cli.main(argv)
        assert exc.value.code == 2 and message in capsys.readouterr().err

    proc = run_train(["--resume", str(out), "--timesteps", "128", "--no-progress"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    after = model_timesteps(out / "model.zip")
    assert after >= before + 128
    log = json.loads((out / "train_log.json").read_text())
    assert [s["start_timesteps"] for s in log["segments"]] == [0, before]
    assert log["segments"][1]["env_seed"] != log["segments"][0]["env_seed"]
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert len(config["run"]["resumes"]) == 1 and config["timesteps"] == after
    with np.load(out / "evaluations.npz") as data:  # the earlier evaluations are kept
        steps = list(data["timesteps"])
    assert steps == sorted(steps) and steps[0] < before < steps[-1] == after


@pytest.mark.slow
def test_resume_survives_an_evaluation_log_cut_short(trained_by_script, tmp_path):
    """Regression: a run stopped mid-evaluation left evaluations.npz with fewer ``successes``
    than ``timesteps``, and ``--resume`` failed with an IndexError."""
    out = tmp_path / "run"
    shutil.copytree(trained_by_script("ppo"), out)
    with np.load(out / "evaluations.npz", allow_pickle=True) as data:
        arrays = {k: data[k] for k in data.files}
    assert len(arrays["timesteps"]) >= 2
    arrays["successes"] = arrays["successes"][:-1]
    np.savez(out / "evaluations.npz", **arrays)
    before = model_timesteps(out / "model.zip")
    proc = run_train(["--resume", str(out), "--timesteps", "128", "--no-progress"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    with np.load(out / "evaluations.npz", allow_pickle=True) as data:
        lengths = {k: len(data[k]) for k in data.files}
        steps = list(data["timesteps"])
    assert len(set(lengths.values())) == 1, lengths  # every array has every evaluation
    assert steps[-1] >= before + 128
    assert not list(out.glob(".evaluations*"))  # no scratch or temporary files left


@pytest.mark.slow
def test_ctrl_c_leaves_a_checkpoint_that_resumes(tmp_path):
    out = tmp_path / "run"
    args = [a if a != "256" else "10000000" for a in tiny_args("ppo")]  # far too long to finish
    with open(tmp_path / "stdout", "w") as so, open(tmp_path / "stderr", "w") as se:
        proc = subprocess.Popen(
            [sys.executable, str(TRAIN), *args, "--out", str(out)],
            cwd=ROOT, stdout=so, stderr=se, env=SUBPROCESS_ENV,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 60
            while not (out / "train_episodes.csv").exists():  # created when learning starts
                assert proc.poll() is None, (tmp_path / "stderr").read_text()
                assert time.monotonic() < deadline, "training did not start"
                time.sleep(0.1)
            time.sleep(1.0)
            proc.send_signal(signal.SIGINT)
            code = proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    stderr = (tmp_path / "stderr").read_text()
    assert code == 130, stderr
    assert f"--resume {out}" in stderr
    interrupted = out / "checkpoints" / "interrupted.zip"
    assert (
        interrupted.is_file() and (out / "checkpoints" / "interrupted_vecnormalize.pkl").is_file()
    )
    assert not (out / "model.zip").exists()
    steps = model_timesteps(interrupted)
    assert steps > 0 and find_latest_checkpoint(out) == interrupted
    log = json.loads((out / "train_log.json").read_text())
    assert log["status"] == "interrupted"

    proc2 = run_train(["--resume", str(out), "--timesteps", "64", "--no-progress"])
    assert proc2.returncode == 0, proc2.stdout + proc2.stderr
    assert model_timesteps(out / "model.zip") >= steps + 64


def test_ctrl_c_during_a_save_waits_for_the_whole_file(tmp_path):
    """Regression: a Ctrl-C that hit EvalCallback's best-model save inside torch's zip writer
    came out as a RuntimeError ("unexpected pos"), so train.py exited 1 without its interrupt
    checkpoint, leaving a cut best_model.zip. Saves during learning now hold the interrupt until
    the file is whole, then raise it."""
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", "CartPole-v1", n_steps=64, batch_size=64, device="cpu")
    path = tmp_path / "best_model.zip"
    reached = []

    def save(tmp: str) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # arrives mid-save: handled at the next bytecode
        model.save(tmp)
        reached.append(True)

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # xdist may change it
    try:
        with pytest.raises(KeyboardInterrupt), interrupts_deferred():
            save_atomic(path, save)
        # under an ignoring handler (the final save) the block runs as it is and raises nothing
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with interrupts_deferred():
            save_atomic(tmp_path / "final.zip", save)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert reached == [True, True]
    assert PPO.load(path, device="cpu").num_timesteps == model.num_timesteps
    assert not list(tmp_path.glob(".*tmp*"))  # no scratch files left behind


# --- config validation --------------------------------------------------------------------------


def base_config(algo: str = "ppo") -> dict:
    data, _ = load_config_file(default_config_path(ENV_ID, algo))
    return data


def test_checked_in_configs_are_valid():
    names = available_configs()
    for required in ("rendezvous2d_ppo", "rendezvous2d_sac", "rendezvous2d_td3",
                     "rendezvous2d_dqn", "rendezvous3d_ppo", "paperfield2d_ppo"):  # fmt: skip
        assert required in names
    for name in names:
        path = CONFIG_DIR / f"{name}.yaml"
        data, _ = load_config_file(path)
        config = TrainConfig.from_dict(data, str(path))
        assert default_config_path(config.env_id, config.algo) == path
        assert config.version >= 1
        if config.algo == "ppo":
            assert config.normalize.enabled
            # the env's options as the run makes them: its ID's, then the recipe's
            spec = SWARM_SPECS[config.env_id] if config.env_id in SWARM_SPECS else None
            own = spec["kwargs"] if spec else gym.spec(config.env_id).kwargs
            env_options = {**own, **config.env_kwargs}
            if env_options.get("shaping_terminal", "zero") == "zero":
                # policy-invariant shaping: gamma equals the env's shaping_gamma (0.99 default)
                assert config.gamma == env_options.get("shaping_gamma", 0.99)


@pytest.mark.parametrize(
    "change, match",
    [
        (
            {"algo_kwargs": {"n_step": 64}},
            r"'algo_kwargs.n_step' is unknown \(did you mean 'n_steps'",
        ),
        ({"normalise": {}}, r"'normalise' is unknown \(did you mean 'normalize'"),
        ({"eval": {"n_episodes": 0}}, r"'eval.n_episodes' must be >= 1"),
        ({"n_envs": "many"}, r"'n_envs' must be an integer"),
        ({"env_kwargs": {"n_obstacle": 3}}, r"'env_kwargs' is invalid: unknown config key"),
        ({"algo_kwargs": {"seed": 1}}, r"'algo_kwargs.seed' is not set here; use train.py --seed"),
        ({"policy_kwargs": {"activation_fn": "sigmoidish"}}, r"activation_fn' must be one of"),
        ({"algo": "a2c"}, r"'algo' must be one of ppo, sac, td3, dqn"),
        ({"checkpoint": {"replay_buffer": "sometimes"}}, r"'checkpoint.replay_buffer'"),
        ({"normalize": {"epsilon": 0.0}}, r"'normalize.epsilon' must be > 0"),
    ],
)
def test_config_errors_name_the_key(change, match):
    data = base_config()
    for key, value in change.items():
        data[key] = {**data[key], **value} if isinstance(value, dict) and key in data else value
    with pytest.raises(ValueError, match=match):
        TrainConfig.from_dict(data, "test.yaml")


def test_config_algorithm_must_fit_the_action_space():
    data = base_config("dqn")
    data["env_kwargs"] = {}
    with pytest.raises(ValueError, match=r"env_kwargs.action' must be 'discrete' for dqn"):
        TrainConfig.from_dict(data, "dqn.yaml")


def test_overrides_and_numbers():
    data = apply_overrides(
        base_config(),
        ["algo_kwargs.learning_rate=3e-4", "normalize.enabled=false", "env_kwargs.dim=3"],
    )
    config = TrainConfig.from_dict(data)
    assert config.algo_kwargs["learning_rate"] == 3e-4  # YAML reads "3e-4" as a string
    assert config.normalize.enabled is False and config.env_kwargs["dim"] == 3
    with pytest.raises(ValueError, match="KEY=VALUE"):
        apply_overrides({}, ["novalue"])


def test_sidecar_names():
    assert sidecar_path("d/model.zip", "vecnormalize") == Path("d/vecnormalize.pkl")
    assert sidecar_path("d/best_model.zip", "vecnormalize") == Path("d/best_model_vecnormalize.pkl")
    assert sidecar_path("d/rl_model_1024_steps.zip", "replay_buffer") == Path(
        "d/rl_model_replay_buffer_1024_steps.pkl"
    )


# --- load_agent ---------------------------------------------------------------------------------


def test_load_agent_applies_frozen_vecnormalize_stats(trained):
    out = trained("ppo")
    env = run_env(out)
    agent = agents.load_agent(f"ppo:{out / 'model.zip'}", env)
    assert isinstance(agent, LearnedAgent) and agent.obs_normalizer is not None
    with open(out / "vecnormalize.pkl", "rb") as fh:
        stats = pickle.load(fh)
    mean, var = stats.obs_rms.mean.copy(), stats.obs_rms.var.copy()
    obs, _ = env.reset(seed=0)
    expected = np.clip((obs - mean) / np.sqrt(var + stats.epsilon), -stats.clip_obs, stats.clip_obs)
    np.testing.assert_allclose(agent.normalize(obs), expected, rtol=1e-5, atol=1e-6)
    action, state = agent.predict(obs)
    model_action, _ = agent.model.predict(expected.astype(np.float32), deterministic=True)
    np.testing.assert_allclose(action, model_action, rtol=1e-5, atol=1e-6)
    assert state is None
    for _ in range(5):
        agent.predict(env.step(action)[0])
    np.testing.assert_array_equal(agent.obs_normalizer.obs_rms.mean, mean)  # never updated
    # the same model without its statistics is refused (the run's config says it normalised)
    bare = out.parent / "bare"
    bare.mkdir(exist_ok=True)
    shutil.copy(out / "model.zip", bare / "model.zip")
    shutil.copy(out / "config.yaml", bare / "config.yaml")
    with pytest.raises(FileNotFoundError, match=r"vecnormalize\.pkl"):
        agents.load_agent(f"ppo={bare / 'model.zip'}", env)
    env.close()


def test_load_agent_single_and_batch_shapes(trained):
    out = trained("ppo")
    env = run_env(out)
    agent = agents.load_agent(f"ppo={out / 'model.zip'}", env)  # '=' as evaluate.py writes it
    obs = np.stack([env.reset(seed=s)[0] for s in range(3)])
    single, _ = agent.predict(obs[0])
    batch, _ = agent.predict(obs, episode_start=np.ones(3, dtype=bool))
    assert single.shape == (2,) and batch.shape == (3, 2)
    np.testing.assert_allclose(batch[0], single, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="neither"):
        agent.predict(np.zeros(5, dtype=np.float32))
    env.close()


@flies_old_ids
def test_load_agent_checks_spaces(trained):
    model = trained("ppo") / "model.zip"
    for kwargs, match in (({"obs_obstacles": 4}, "observes"), ({"action": "discrete"}, "acts in")):
        env = run_env(model.parent, **kwargs)
        with pytest.raises(ValueError, match=match):
            agents.load_agent(f"ppo:{model}", env)
        env.close()
    env3 = gym.make("DebrisGym/Rendezvous3D-v0")
    with pytest.raises(ValueError, match="observes"):
        agents.load_agent(f"ppo:{model}", env3)
    env3.close()


def test_load_agent_errors(trained, tmp_path):
    env = run_env(trained("ppo"))
    with pytest.raises(ValueError, match="unknown learning algorithm 'a2c'"):
        agents.load_agent("a2c:model.zip", env)
    with pytest.raises(ValueError, match="ALGO:PATH"):
        agents.load_agent("model.zip", env)
    with pytest.raises(FileNotFoundError, match="not found"):
        agents.load_agent(f"ppo:{tmp_path / 'missing.zip'}", env)
    with pytest.raises(ValueError, match="another algorithm"):
        agents.load_agent(f"sac:{trained('ppo') / 'model.zip'}", env)
    paper = gym.make("DebrisGym/PaperField2D-v0")
    with pytest.raises(ValueError, match="no pretrained policy for DebrisGym/PaperField2D-v0"):
        agents.load_agent("pretrained", paper)
    paper.close()
    env.close()


@flies_old_ids
def test_the_shipped_pretrained_policy_flies_its_env():
    """agents/pretrained/rendezvous2d_dagger.zip loads with its statistics and the observation
    options of its run, and refuses the default env with an error naming them."""
    from agents import observation_options

    v0 = "DebrisGym/Rendezvous2D-v0"  # the shipped policy flies the frozen world it learned
    options = observation_options("pretrained", v0)
    assert options == {"obs_targets": 1, "obs_goal": True, "obs_other_targets": True}
    env = gym.make(v0, **options)
    agent = agents.load_agent("pretrained", env)
    assert agent.algo == "ppo" and agent.obs_normalizer is not None
    obs, _ = env.reset(seed=10_000_000)
    for _ in range(20):
        action, _ = agent.predict(obs)
        assert env.action_space.contains(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    env.close()
    default = gym.make(v0)
    with pytest.raises(ValueError, match=re.escape("trained with env options {'obs_targets': 1")):
        agents.load_agent("pretrained", default)
    default.close()
    medium = "DebrisGym/Rendezvous2D-Medium-v1"
    with pytest.raises(ValueError, match=f"no pretrained policy for {medium}"):
        agents.load_agent("pretrained", gym.make(medium))


@flies_old_ids
def _fly_pretrained(env_id: str, seed: int, **options: Any) -> dict[str, Any]:
    """One episode of the ``pretrained`` agent on ``env_id`` made with ``options``, from reset
    seed ``seed`` to its end (the ID's time limit at the latest): the last info."""
    env = gym.make(env_id, **options)
    agent = agents.load_agent("pretrained", env)
    _, info = fly_policy(env, seed, lambda env, obs, info, first: agent.predict(obs)[0])
    env.close()
    return info


def test_the_pretrained_easy_policy_is_the_one_made_for_the_easy_rung():
    """`pretrained` picks the policy made for the env being evaluated: on the Easy rung the
    recipe's PPO policy (no observation options: the registered env as it is), which captures
    its target on a held-out mission; the v0 IDs keep the DAgger policy."""
    from agents import observation_options
    from agents.policies.learned import pretrained_path

    easy = "DebrisGym/Rendezvous2D-Easy-v1"
    assert pretrained_path(easy)[1].name == "rendezvous2d-easy_ppo.zip"
    assert pretrained_path("DebrisGym/Rendezvous2D-v0")[1].name == "rendezvous2d_dagger.zip"
    assert observation_options("pretrained", easy) == {}
    info = _fly_pretrained(easy, 20_000_000)
    assert info["is_success"] and not info["collision"]


@flies_old_ids
@pytest.mark.parametrize(
    "env_id, name",
    [
        ("DebrisGym/Rendezvous2D-v1", "rendezvous2d_finetuned.zip"),
        ("DebrisGym/Rendezvous3D-v1", "rendezvous3d_finetuned.zip"),
    ],
)
def test_the_pretrained_v1_policies_are_the_fine_tuned_ones(env_id, name):
    """On the v1 IDs `pretrained` is the RL-fine-tuned policy (imitation of APF-MPC, then PPO
    from the reward): it flies with its run's observation options and completes a held-out
    mission of the default difficulty (seed outside every training and evaluation range)."""
    from agents import observation_options
    from agents.policies.learned import pretrained_path

    assert pretrained_path(env_id)[1].name == name
    options = observation_options("pretrained", env_id)
    assert options == {"obs_targets": 1, "obs_goal": True, "obs_other_targets": True}
    info = _fly_pretrained(env_id, 20_000_001, **options)
    assert info["is_success"] and info["targets_captured"] == 3 and not info["collision"]


def test_dqn_policy_flies_discrete_and_continuous_envs(trained):
    model = trained("dqn") / "model.zip"
    discrete = gym.make(ENV_ID, action="discrete")
    obs, _ = discrete.reset(seed=0)
    action, _ = agents.load_agent(f"dqn:{model}", discrete).predict(obs)
    assert discrete.action_space.contains(action)
    continuous = gym.make(ENV_ID)
    agent = agents.load_agent(f"dqn:{model}", continuous)
    obs2, _ = continuous.reset(seed=0)
    thrust, _ = agent.predict(obs2)
    from debris_gym.envs.common import discrete_action_table

    table = discrete_action_table(2, continuous.unwrapped.config.fine_thrust)
    np.testing.assert_array_equal(thrust, table[int(action)])
    assert continuous.action_space.contains(thrust)
    discrete.close()
    continuous.close()


def test_curriculum_switches_the_training_env(train_cli, tmp_path, capsys):
    """Stages run with their missions until their step count, then the final task."""
    out = tmp_path / "run"
    stages = "[{until: 128, mission: {n_targets: 1, return_to_dock: false}}]"
    argv = [*tiny_args("ppo"), "--out", str(out), "--set", f"curriculum={stages}"]
    argv += ["--set", "eval.freq=0"]
    assert train_cli.main(argv) == 0
    printed = capsys.readouterr().out
    assert "curriculum: stage 0 (until 128) from step 0: mission {'n_targets': 1" in printed
    assert "curriculum: stage 1 (the final task) from step 128" in printed
    with open(out / "train_episodes.csv") as fh:
        rows = list(csv.DictReader(fh))
    early = [int(r["targets_captured"]) for r in rows if int(r["timesteps"]) <= 128]
    assert all(c <= 1 for c in early)  # one target in stage 0
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["curriculum"] == [
        {"until": 128, "mission": {"n_targets": 1, "return_to_dock": False}}
    ]


@pytest.mark.parametrize(
    "stages, message",
    [
        ("[{until: 0}]", "curriculum[0].until"),
        ("[{until: 500}, {until: 400}]", "must be > 500"),
        ("[{until: 10, mission: {obs_targets: 2}}]", "may change only n_targets"),
        ("[{until: 10, mission: {n_targets: 0}}]", "curriculum[0].mission"),
        ("[{until: 10, env_kwargs: {shaping_gamma: 0.9}}]", "curriculum[0].env_kwargs"),
        ("[{until: 10, mission: {}, env_kwargs: {}}]", "not both"),
        ("[{until: 10, envkwargs: {}}]", "curriculum[0].envkwargs"),
    ],
)
def test_bad_curricula_are_refused(stages, message):
    data, _ = load_config_file(default_config_path(ENV_ID, "ppo"))
    data = apply_overrides(data, [f"curriculum={stages}"])
    with pytest.raises(ValueError, match=re.escape(message)):
        TrainConfig.from_dict(data, "test")


def test_a_policy_trained_with_other_observation_options_flies_beside_the_baselines(
    train_cli, evaluate_cli, tmp_path, capsys
):
    """evaluate.py gives a learned agent the observation options of its run (here obs_goal),
    on the same fields as the baselines."""
    out = tmp_path / "run"
    argv = [*tiny_args("ppo"), "--out", str(out), "--set", "env_kwargs.obs_goal=false"]
    argv += ["--set", "env_kwargs.obs_targets=2"]  # neither the default env's nor the recipe's
    assert train_cli.main([*argv, "--set", "eval.freq=0"]) == 0
    capsys.readouterr()
    args = [
        "--agents", f"zero,ppo={out / 'model.zip'}", "--episodes", "2", "--max-steps", "10",
        "--no-progress", "--plots", "0", "--out", str(tmp_path / "eval"),
    ]  # fmt: skip
    assert evaluate_cli.main(args) == 0
    stdout = capsys.readouterr().out
    assert "| ppo |" in stdout and "| zero |" in stdout
    from agents import observation_options

    options = {"obs_goal": False, "obs_targets": 2, "obs_hold": True}  # obs_hold: the v2 ID's
    assert observation_options(f"ppo:{out / 'model.zip'}", ENV_ID) == options
    env = gym.make(ENV_ID)  # the default env does not fit the model; the error names the options
    with pytest.raises(ValueError, match=r"trained with env options \{.*'obs_targets': 2"):
        agents.load_agent(f"ppo:{out / 'model.zip'}", env)


def test_training_you_can_watch_captures_and_success_in_tensorboard(train_cli, tmp_path, capsys):
    """TensorBoard gets rollout/success_rate, rollout/targets_captured and the held-out
    evaluation's eval/success_rate and eval/targets_captured; the console's evaluation line
    names the captures. The logged captures equal the episode log's own mean."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = tmp_path / "run"
    assert train_cli.main([*tiny_args("ppo"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"eval @ [\d,]+ steps: .*success \d+%, targets captured [\d.]+ per", printed)
    events = EventAccumulator(str(next((out / "tb").iterdir())))
    events.Reload()
    tags = set(events.Tags()["scalars"])
    wanted = {"rollout/success_rate", "rollout/targets_captured", "eval/success_rate"}
    assert wanted | {"eval/targets_captured"} <= tags
    with open(out / "train_episodes.csv") as fh:
        rows = list(csv.DictReader(fh))
    last = events.Scalars("rollout/targets_captured")[-1]
    seen = [int(r["targets_captured"]) for r in rows if int(r["timesteps"]) <= last.step]
    assert last.value == pytest.approx(np.mean(seen[-100:]))


def test_a_resumed_runs_progress_bar_counts_the_runs_steps_as_its_log_does():
    """Regression: on --resume the bar counted the segment from 0 while the log counted the
    run's steps; it now starts at the checkpoint's count and ends at the run's target."""
    from types import SimpleNamespace

    from agents.experiments.training.callbacks import RunProgressBar

    bar = RunProgressBar()
    bar.model = SimpleNamespace(num_timesteps=4096)
    bar.locals = {"total_timesteps": 6144}  # SB3's total on a resume: done + to add
    bar._on_training_start()
    try:
        assert (bar.pbar.n, bar.pbar.total) == (4096, 6144)
    finally:
        bar.pbar.close()
