"""Hyper-parameter sweeps: the recipe's ``sweep:`` section is validated with
the rest of the config, and a tiny Ray Tune sweep trains each trial into its own run directory
and exports the best model where evaluate.py loads it. The Tune test runs only where Ray is
installed."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
import yaml

from agents.experiments.config_files import load_config_file
from agents.experiments.training.config import TrainConfig, default_config_path
from agents.experiments.training.sweep_config import SweepParam

EASY = "DebrisGym/Rendezvous2D-Easy-v2"
HAS_RAY = importlib.util.find_spec("ray") is not None


def _recipe(sweep):
    data, _ = load_config_file(default_config_path(EASY, "ppo"))
    data["sweep"] = sweep
    return data


def test_the_easy_recipe_carries_a_search_space_that_round_trips():
    config = TrainConfig.from_dict(load_config_file(default_config_path(EASY, "ppo"))[0], "easy")
    sweep = config.sweep
    assert sweep is not None and sweep.num_samples == 4 and sweep.metric == "success_rate"
    assert sweep.params["algo_kwargs.learning_rate"] == SweepParam("loguniform", [1e-4, 1e-3])
    assert TrainConfig.from_dict(config.to_dict(), "again").sweep == sweep
    assert TrainConfig.from_dict(_recipe(None), "plain").sweep is None


@pytest.mark.parametrize(
    "sweep, message",
    [
        ({"params": {}}, "'sweep.params' must name at least one config key"),
        ({"num_samples": 0, "params": {"algo_kwargs.n_epochs": {"choice": [3]}}},
         "'sweep.num_samples' must be >= 1, got 0"),
        ({"metric": "reward", "params": {"algo_kwargs.n_epochs": {"choice": [3]}}},
         "'sweep.metric' must be one of success_rate, mean_reward, got 'reward'"),
        ({"params": {"algo_kwargs.learning_rate": {"loguniform": [0.0, 1e-3]}}},
         "'sweep.params.algo_kwargs.learning_rate.loguniform' needs low > 0"),
        ({"params": {"algo_kwargs.n_epochs": {"randint": [5, 5]}}}, "needs low < high"),
        ({"params": {"algo_kwargs.n_epochs": {"normal": [5, 1]}}},
         "has unknown distribution 'normal'"),
        ({"params": {"algo_kwargs.gamma": {"uniform": [0.9, 1.5]}}},
         "'sweep.params.algo_kwargs.gamma' can draw 1.5, which the recipe refuses: config key "
         "'algo_kwargs.gamma' must be a number in [0, 1]"),
        ({"params": {"algo_kwargs.gama": {"choice": [0.99]}}},
         "'algo_kwargs.gama' is unknown (did you mean 'gamma'?)"),
        ({"params": {"env_id": {"choice": ["DebrisGym/Rendezvous2D-v2"]}}}, "cannot be swept"),
        ({"params": {"algo_kwargs.n_epochs": {"choice": [3]}}, "sede": 1},
         "'sweep.sede' is unknown (did you mean 'seed'?)"),
    ],
)  # fmt: skip
def test_a_bad_search_space_is_refused_naming_the_key(sweep, message):
    with pytest.raises(ValueError, match=r"easy\.yaml: config key") as exc:
        TrainConfig.from_dict(_recipe(sweep), "easy.yaml")
    assert message in str(exc.value)


def test_a_sweep_needs_a_search_space_and_an_evaluation(tmp_path):
    from agents.experiments.distributed.sweep import SweepOptions, run_sweep

    plain = tmp_path / "plain.yaml"
    plain.write_text(yaml.safe_dump(_recipe(None)))
    with pytest.raises(ValueError, match="has no 'sweep:' section"):
        run_sweep(SweepOptions(out=tmp_path / "s", config=plain))
    with pytest.raises(ValueError, match=r"eval\.freq must be > 0"):
        run_sweep(SweepOptions(out=tmp_path / "s", env_id=EASY, overrides=["eval.freq=0"]))
    with pytest.raises(ValueError, match="workers must be an integer >= 1, got 0"):
        run_sweep(SweepOptions(out=tmp_path / "s", env_id=EASY, workers=0))
    assert not (tmp_path / "s").exists()


@pytest.mark.skipif(not HAS_RAY, reason="needs ray (pip install 'debris-gym[distributed]')")
def test_a_tiny_tune_sweep_trains_each_trial_and_exports_the_best(tmp_path):
    import agents
    from agents.experiments.distributed.sweep import SweepOptions, run_sweep
    from agents.experiments.evaluation.runner import make_env

    out = tmp_path / "sweep"
    tiny = ["eval.n_episodes=2", "eval.n_envs=2", "algo_kwargs.batch_size=32",
            "algo_kwargs.n_steps=32", "checkpoint.freq=64"]  # fmt: skip
    result = run_sweep(
        SweepOptions(
            out=out, env_id=EASY, overrides=tiny, samples=2, timesteps=128, n_envs=2, workers=2
        )
    )
    assert len(result.trials) == 2 and all(t.error is None for t in result.trials)
    rates = [(t.metrics["success_rate"], t.metrics["mean_reward"]) for t in result.trials]
    assert (result.best.metrics["success_rate"], result.best.metrics["mean_reward"]) == max(rates)
    drawn = set()
    for trial in result.trials:
        run = out / "trials" / trial.trial_id
        assert str(run) == trial.run_dir
        for name in ("model.zip", "vecnormalize.pkl", "config.yaml", "evaluations.npz"):
            assert (run / name).is_file(), name
        assert list((run / "checkpoints").glob("*.zip"))
        config = yaml.safe_load((run / "config.yaml").read_text())
        assert config["sweep"] is None and config["timesteps"] == 128
        lr = config["algo_kwargs"]["learning_rate"]
        assert lr == trial.params["algo_kwargs.learning_rate"] and 1e-4 <= lr <= 1e-3
        drawn.add(lr)
        with np.load(run / "evaluations.npz") as log:
            assert float(np.mean(log["results"][-1])) == trial.metrics["mean_reward"]
    assert len(drawn) == 2  # two trials, two draws
    best = out / "best"
    exported = sorted(p.name for p in best.iterdir())
    assert exported == ["config.yaml", "model.zip", "vecnormalize.pkl"]
    best_run = out / "trials" / result.best.trial_id
    assert (best / "model.zip").read_bytes() == (best_run / "model.zip").read_bytes()
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["best"]["trial_id"] == result.best.trial_id and len(summary["trials"]) == 2
    env = make_env(EASY)
    try:
        policy = agents.load_agent(f"ppo:{best / 'model.zip'}", env)
        obs, _ = env.reset(seed=0)
        action, _ = policy.predict(obs)
        assert env.action_space.contains(action)
    finally:
        env.close()
