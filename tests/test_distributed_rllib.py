"""The registered envs under RLlib's new API stack: PPO built on a DebrisGym
ID named "debris_gym:DebrisGym/...", its env made on a separate env-runner process through the
native vector env, trains one iteration. Runs only where RLlib is installed."""

from __future__ import annotations

import math

import pytest

from agents.experiments.distributed.rllib import rllib_env_id


def test_ids_get_the_module_prefix_that_registers_them_on_any_worker():
    assert rllib_env_id("DebrisGym/Rendezvous2D-v2") == "debris_gym:DebrisGym/Rendezvous2D-v2"
    assert rllib_env_id("debris_gym:DebrisGym/Rendezvous3D-v2") == (
        "debris_gym:DebrisGym/Rendezvous3D-v2"
    )
    with pytest.raises(ValueError, match="must be a DebrisGym ID"):
        rllib_env_id("CartPole-v1")


def test_ppo_trains_one_iteration_on_an_env_runner_with_the_native_vector_env():
    pytest.importorskip("ray.rllib")
    import ray

    from agents.experiments.distributed.rllib import ppo_config, train_ppo

    with pytest.raises(ValueError, match="num_envs_per_env_runner must be an integer >= 1"):
        ppo_config(num_envs_per_env_runner=0)
    config = ppo_config(
        "DebrisGym/Rendezvous2D-Easy-v2",
        num_env_runners=1,
        num_envs_per_env_runner=4,
        train_batch_size=400,
        minibatch_size=100,
        num_epochs=1,
        hidden=(32, 32),
    )
    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    try:
        algo = config.build_algo()
        try:
            env_ids = algo.env_runner_group.foreach_env_runner(
                lambda runner: type(runner.env.unwrapped).__name__, local_env_runner=False
            )
            assert env_ids == ["DebrisFieldVectorEnv"]  # made on the remote runner, natively
        finally:
            algo.stop()
        (summary,) = train_ppo(config, 1)
    finally:
        ray.shutdown()
    assert summary.env_steps >= 400
    assert summary.episodes >= 1 and math.isfinite(summary.episode_return_mean)
    assert math.isfinite(summary.policy_loss) and math.isfinite(summary.vf_loss)
    assert math.isnan(summary.team_success)  # a single chaser: no team to report


def test_multi_agent_ppo_trains_one_iteration_on_a_swarm():
    pytest.importorskip("ray.rllib")
    pytest.importorskip("pettingzoo")
    from agents.experiments.distributed.rllib import swarm_ppo_config, train_ppo

    with pytest.raises(ValueError, match="must be a swarm ID"):
        swarm_ppo_config("DebrisGym/Rendezvous2D-v2")
    config = swarm_ppo_config(
        "DebrisGym/Swarm2D-Easy-v0", train_batch_size=400, minibatch_size=100, num_epochs=1,
        hidden=(32, 32),
    )  # fmt: skip
    import ray

    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    try:
        (summary,) = train_ppo(config, 1)
    finally:
        ray.shutdown()
    assert summary.env_steps >= 400
    assert summary.episodes >= 1 and 0.0 <= summary.team_success <= 1.0
    assert math.isfinite(summary.policy_loss) and math.isfinite(summary.vf_loss)
