"""agents.experiments.imitation and imitate.py: the expert's goal rule, the numpy actor, the fit,
the config checks, a tiny run in-process and (slow) one through imitate.py and evaluate.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("stable_baselines3")

import agents
from agents.experiments.imitation.config import ImitationConfig, load_imitation_config
from agents.experiments.imitation.fitting import (
    export_actor,
    fit,
    make_model,
    set_observation_stats,
)
from agents.experiments.imitation.run import RUN_FILES, imitate, run_config_yaml
from agents.experiments.run_directory import RunDirectoryLock
from agents.experiments.training.config import available_configs
from agents.planners.mission import MissionPlan
from debris_gym.envs import DebrisFieldEnv
from tests.helpers import flies_old_ids, load_script

pytestmark = pytest.mark.usefixtures("one_torch_thread")

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "DebrisGym/Rendezvous2D-v2"
TINY = {
    "bc_episodes": 2,
    "dagger_rounds": 1,
    "dagger_episodes": 1,
    "epochs": 2,
    "refit_epochs": 1,
    "workers": 1,
    "max_episode_steps": 25,
    "net_arch": (16, 16),
}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_nearest_ordering_names_the_envs_own_goal(seed):
    """MissionPlan(ordering="nearest") picks the target the env's obs_goal shows, wherever the
    chaser is and whichever targets are captured (the env's observation is the reference)."""
    env = DebrisFieldEnv(obs_goal=True)
    names = env.observation_names()
    env.reset(seed=seed)
    scen = env.scenario
    plan = MissionPlan(scen, env.config, "nearest")
    half = 0.5 * scen.size
    rng = np.random.default_rng(seed)
    checked = 0
    for _ in range(40):
        # near a target: farther goals are clipped in the observation (|x| / (L/10) <= 10)
        centre = plan.centres[rng.integers(len(plan.centres))]
        pos = np.clip(centre + rng.uniform(-150.0, 150.0, 2), -0.95 * half, 0.95 * half)
        try:
            obs, _ = env.reset(options={"scenario": scen, "chaser_state": [*pos, 0.0, 0.0]})
        except ValueError:  # inside a body
            continue
        shown = np.array([obs[names.index("goal_rel_pos_x")], obs[names.index("goal_rel_pos_y")]])
        goal = plan.current_goal(env.captured, pos)
        assert goal.kind == "target"
        np.testing.assert_allclose(shown * half / 10.0, goal.centre - pos, rtol=1e-5, atol=1e-3)
        checked += 1
    assert checked >= 30


def test_nearest_ordering_follows_captures_then_the_dock():
    env = DebrisFieldEnv()
    env.reset(seed=3)
    plan = MissionPlan(env.scenario, env.config, "nearest")
    centres = plan.centres
    pos = centres[0] + np.array([plan.stand_off(0), 0.0])
    goals = plan.goals(np.array([False, False, False]), pos)
    assert [g.kind for g in goals] == ["target"] * 3 + ["dock"]
    assert goals[0].index == 0  # the chaser sits at target 0's approach point
    captured = np.array([True, False, False])
    gaps = [np.linalg.norm(centres[i] - pos) - plan.radii[i] for i in (1, 2)]
    assert plan.current_goal(captured, pos).index == (1, 2)[int(np.argmin(gaps))]
    assert plan.current_goal(np.ones(3, bool), pos).kind == "dock"


def test_unknown_ordering_is_refused_by_name():
    env = DebrisFieldEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="ordering must be one of shortest, polygon, nearest"):
        MissionPlan(env.scenario, env.config, "closest")


@flies_old_ids
def test_apf_mpc_with_the_envs_goal_completes_a_mission():
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    expert = agents.make_agent("apf-mpc", env, ordering="nearest")
    obs, info = env.reset(seed=11)
    done = False
    while not done:
        action, _ = expert.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    assert info["is_success"], info


def _tiny_model(**kwargs):
    config = ImitationConfig(**{**TINY, **kwargs})
    model, venv = make_model(config)
    return config, model, venv


def test_numpy_actor_matches_the_saved_sb3_policy(tmp_path):
    """export_actor's numpy forward pass = what load_agent's PPO model answers (the reference)."""
    config, model, venv = _tiny_model()
    rng = np.random.default_rng(0)
    data = rng.normal(size=(500, venv.observation_space.shape[0])).astype(np.float32) * 3.0
    set_observation_stats(venv, data)
    actor = export_actor(model, venv, config.activation_fn)
    model.save(tmp_path / "model.zip")
    venv.save(str(tmp_path / "vecnormalize.pkl"))
    (tmp_path / "config.yaml").write_text(run_config_yaml(config))
    env = gym.make(ENV_ID, **config.env_kwargs)
    learned = agents.load_agent(f"ppo:{tmp_path / 'model.zip'}", env)
    obs = data[:50] * 4.0  # some beyond the clip range
    expected, _ = learned.predict(obs, deterministic=True)
    np.testing.assert_allclose(actor(obs), expected, atol=1e-5)


def test_fit_learns_a_known_map():
    """The fit regresses onto a hand-made expert, action = clip(0.4·(x0, x1)), among ~60 inputs
    that do not matter: held-out RMS error under a fifth of the zero policy's (~0.39)."""
    config, model, venv = _tiny_model(net_arch=(64, 64), learning_rate=3e-3, batch_size=256)
    rng = np.random.default_rng(1)
    obs = rng.normal(size=(8000, venv.observation_space.shape[0])).astype(np.float32)
    target = np.clip(0.4 * obs[:, :2], -1, 1).astype(np.float32)
    set_observation_stats(venv, obs)
    losses = fit(model, venv, obs, target, 40, config, rng)
    assert losses[-1] < 0.1 * losses[0]
    actor = export_actor(model, venv, config.activation_fn)
    test = rng.normal(size=(500, obs.shape[1])).astype(np.float32)
    truth = np.clip(0.4 * test[:, :2], -1, 1)
    rms = float(np.sqrt(np.mean((actor(test) - truth) ** 2)))
    assert rms < 0.2 * float(np.sqrt(np.mean(truth**2)))


def test_config_errors_name_the_key():
    with pytest.raises(
        ValueError, match=r"unknown key 'dagger_round' \(did you mean 'dagger_rounds'"
    ):
        ImitationConfig.from_dict({"dagger_round": 3})
    with pytest.raises(ValueError, match=r"dagger_beta=1.5 is out of range; allowed: \[0, 1\]"):
        ImitationConfig.from_dict({"dagger_beta": 1.5})
    with pytest.raises(ValueError, match="n_obstacles"):
        ImitationConfig.from_dict({"env_kwargs": {"n_obstacles": -1}})
    with pytest.raises(ValueError, match="action"):
        ImitationConfig.from_dict({"env_kwargs": {"action": "discrete"}})
    with pytest.raises(ValueError, match="activation_fn"):
        ImitationConfig.from_dict({"activation_fn": "swish"})


@settings(max_examples=40, deadline=None)
@given(
    key=st.sampled_from(["bc_episodes", "dagger_episodes", "epochs", "refit_epochs", "batch_size"]),
    value=st.integers(max_value=0),
)
def test_counts_below_one_are_refused(key, value):
    with pytest.raises(ValueError, match=rf"{key}={value} is out of range; allowed: >= 1"):
        ImitationConfig(**{key: value})


@settings(max_examples=20, deadline=None)
@given(st.floats(allow_nan=True, allow_infinity=True).filter(lambda x: not 0 <= x <= 1))
def test_beta_outside_the_unit_interval_is_refused(beta):
    with pytest.raises(ValueError, match="dagger_beta"):
        ImitationConfig(dagger_beta=beta)


def test_checked_in_recipe_loads():
    """The recipe loads; train.py does not list it among its own configs (regression: its
    config test read every YAML in agents/configs as a training config)."""
    assert "rendezvous2d_imitation" not in available_configs()
    config = load_imitation_config(ENV_ID)
    assert config.expert == "apf-mpc" and config.expert_kwargs["ordering"] == "nearest"
    assert config.env_kwargs["obs_goal"] is True
    three_d = load_imitation_config("DebrisGym/Rendezvous3D-v2")  # the 3D policy's start
    assert three_d.env_id == "DebrisGym/Rendezvous3D-v2" and three_d.expert == "apf-mpc"
    with pytest.raises(FileNotFoundError, match="no imitation config"):
        load_imitation_config("DebrisGym/PaperField2D-v0")


def test_tiny_run_in_process_writes_a_policy_that_loads(tmp_path):
    """The library call behind imitate.py: a loadable model, its statistics and its logs."""
    config = ImitationConfig(**TINY)
    lines = []
    log = imitate(config, tmp_path / "run", log=lines.append, progress=False, command="test")
    assert [r["round"] for r in log["rounds"]] == [0, 1]
    assert lines[0].startswith("round 0 (apf-mpc flew 2 episodes)")
    assert log["rounds"][1]["dataset"] > log["rounds"][0]["dataset"] > 0
    for name in ("model.zip", "vecnormalize.pkl", "config.yaml", "imitation_log.json",
                 "imitation_curve.png"):  # fmt: skip
        assert (tmp_path / "run" / name).is_file(), name
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert sorted(manifest["files"]) == sorted(RUN_FILES)  # committed as one set
    env = gym.make(ENV_ID, **config.env_kwargs)
    policy = agents.load_agent(f"ppo:{tmp_path / 'run' / 'model.zip'}", env)
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(policy.predict(obs)[0])
    env.close()
    with pytest.raises(FileExistsError, match="already holds a run"):
        imitate(config, tmp_path / "run", log=lines.append, progress=False)


@pytest.mark.slow
def test_tiny_run_end_to_end(tmp_path):
    """imitate.py writes a loadable model; evaluate.py flies it; a second run refuses the dir."""
    out = tmp_path / "run"
    sets = []
    for key, value in TINY.items():
        text = json.dumps(list(value)) if isinstance(value, tuple) else str(value)
        sets += ["--set", f"{key}={text}"]
    cmd = [sys.executable, str(ROOT / "imitate.py"), "--out", str(out), "--no-progress", *sets]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "round 0 (apf-mpc flew 2 episodes)" in done.stdout
    assert "round 1 (policy flew 1 episodes)" in done.stdout
    for name in ("model.zip", "vecnormalize.pkl", "config.yaml", "imitation_log.json",
                 "imitation_curve.png"):  # fmt: skip
        assert (out / name).is_file(), name
    run = yaml.safe_load((out / "config.yaml").read_text())["run"]
    assert run["command"].startswith("python imitate.py --out") and run["wall_s"] > 0
    log = json.loads((out / "imitation_log.json").read_text())
    assert [r["round"] for r in log["rounds"]] == [0, 1]
    assert log["rounds"][0]["episodes"] == 2 and log["rounds"][1]["dataset"] > 0
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 2 and "already holds a run" in again.stderr
    evaluated = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), "--agents", f"ppo={out / 'model.zip'}",
         "--episodes", "1", "--out", str(tmp_path / "eval"), "--max-steps", "20", "--plots", "0",
         "--no-progress"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert evaluated.returncode == 0, evaluated.stderr


def test_expert_settings_are_checked_up_front():
    with pytest.raises(ValueError, match="unknown agent 'apf-mcp'"):
        ImitationConfig.from_dict({"expert": "apf-mcp"})
    with pytest.raises(ValueError, match="cruise_speed must be > 0"):
        ImitationConfig.from_dict({"expert_kwargs": {"reference": {"cruise_speed": -1}}})
    with pytest.raises(ValueError, match="expert_kwargs"):
        ImitationConfig.from_dict({"expert_kwargs": {"horizon": 3}})


@pytest.mark.slow
def test_ctrl_c_stops_the_run_and_its_workers(tmp_path):
    """SIGINT during a DAgger round: exit status 130, no model written, the rollout workers
    stopped (regression: SIGINT ignored by a background parent; workers printed tracebacks)."""
    import signal
    import time

    out = tmp_path / "run"
    sets = ["bc_episodes=2", "max_episode_steps=25", "dagger_episodes=400", "workers=2"]
    cmd = [sys.executable, str(ROOT / "imitate.py"), "--out", str(out), "--no-progress"]
    for item in sets:
        cmd += ["--set", item]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("round 0"), line
        time.sleep(1.0)  # inside round 1's rollouts
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted; nothing saved" in err
    assert "Traceback" not in err
    assert not (out / "model.zip").exists()


# --- bad options are usage errors before any work; one run per directory --------------------


def load_imitate_cli():
    return load_script("imitate.py")


def imitate_refused(argv: list[str], capsys) -> str:
    """The usage error of ``imitate.py argv`` (exit status 2, no traceback)."""
    with pytest.raises(SystemExit) as exc:
        load_imitate_cli().main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("kind", ["under a file", "empty"])
def test_bad_out_directories_are_usage_errors(kind, tmp_path, capsys, monkeypatch):
    """Regression: ``imitate.py --out afile/x`` ended in a NotADirectoryError traceback and
    ``--out ""`` ran the whole recipe into the current directory."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    out = str(tmp_path / "afile" / "x") if kind == "under a file" else ""
    err = imitate_refused(["--out", out], capsys)
    assert "argument --out" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_a_busy_directory_is_refused_and_left_alone(tmp_path, capsys):
    """Regression: two runs on one --out could both run; the lock refuses the second at once."""
    out = tmp_path / "run"
    out.mkdir()
    with RunDirectoryLock(out):  # stands in for a run in progress
        err = imitate_refused(["--out", str(out), *tiny_sets()], capsys)
        assert sorted(p.name for p in out.iterdir()) == [".lock"]  # the holder's only
    assert f"in use by another run (process {os.getpid()})" in err


def tiny_sets() -> list[str]:
    sets = []
    for key, value in TINY.items():
        text = json.dumps(list(value)) if isinstance(value, tuple) else str(value)
        sets += ["--set", f"{key}={text}"]
    return sets


@pytest.mark.parametrize(
    "setting, message",
    [
        ("net_arch=5", "net_arch=5 is out of range; allowed: a non-empty list of at most 16"),
        ("net_arch=[1e9]", "net_arch"),
        ("net_arch=[abc]", "net_arch"),
        ("max_episode_steps=2.5", "max_episode_steps must be an integer >= 1, got 2.5"),
        ("learning_rate=abc", "learning_rate must be a number in (0, inf), got 'abc'"),
        ("dagger_beta=nan", "dagger_beta"),
        ("weight_decay=abc", "weight_decay"),
        ("bc_episodes=2.0", "bc_episodes must be an integer >= 1, got 2.0"),
        ("workers=100", "workers=100 is out of range; allowed: [1, 64]"),
        ("seed=100000000000000000000", "is out of range; allowed: [0, 2147483647]"),
    ],
)
def test_bad_settings_are_usage_errors_naming_the_key(setting, message, tmp_path, capsys):
    """Regression: ``--set net_arch=5`` and ``--set max_episode_steps=2.5`` ended in TypeError
    tracebacks; others in numpy's messages naming no key."""
    out = tmp_path / "run"
    assert message in imitate_refused(["--out", str(out), "--set", setting], capsys)
    assert not out.exists()


def test_a_failed_run_leaves_no_partial_set(tmp_path, monkeypatch):
    """The run's files are staged and committed together: a failure while writing them leaves
    none of them (and the directory can be used again)."""
    import agents.experiments.imitation.run as run_module

    def fail(run_log, path):
        raise OSError("disk full")

    monkeypatch.setattr(run_module, "plot_rounds", fail)
    with pytest.raises(OSError, match="disk full"):
        imitate(ImitationConfig(**TINY), tmp_path / "run", log=lambda line: None, progress=False)
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == []
