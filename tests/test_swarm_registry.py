"""The swarm IDs in PettingZoo's own registry (PettingZoo 1.27 and later has one): made through
``pettingzoo.make`` they are the envs of ``debris_gym.swarm.make``, seed for seed."""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

import pettingzoo
from pettingzoo import AECEnv, ParallelEnv

from debris_gym import swarm
from debris_gym.swarm.parallel import SwarmParallelEnv

HAS_REGISTRY = callable(getattr(pettingzoo, "register", None))
needs_registry = pytest.mark.skipif(
    not HAS_REGISTRY, reason=f"PettingZoo {pettingzoo.__version__} has no registry"
)
SMALL = {"n_chasers": 2, "n_targets": 2, "n_obstacles": 3}


def test_an_installed_registry_holds_every_swarm_id_once_imported():
    """Fails on a PettingZoo with a registry that the swarm IDs are missing from; on one
    without a registry, registering is a no-op."""
    if not HAS_REGISTRY:
        assert swarm.register_with_pettingzoo() == []
        return
    for env_id in swarm.SWARM_SPECS:
        assert pettingzoo.spec("parallel", env_id).id == env_id
        assert pettingzoo.spec("aec", env_id).id == env_id


@needs_registry
@pytest.mark.parametrize("env_id", list(swarm.SWARM_SPECS))
def test_pettingzoo_make_gives_the_same_env_as_swarm_make(env_id):
    options = {k: v for k, v in SMALL.items() if "Reconfigure" not in env_id or k != "n_targets"}
    ours = swarm.make(env_id, **options)
    theirs = pettingzoo.make("parallel", env_id, **options)
    assert isinstance(theirs, SwarmParallelEnv) and isinstance(theirs, ParallelEnv)
    assert theirs.possible_agents == ours.possible_agents
    assert (
        theirs.max_episode_steps
        == ours.max_episode_steps
        == (swarm.SWARM_SPECS[env_id]["max_episode_steps"])
    )
    obs_a, _ = ours.reset(seed=11)
    obs_b, _ = theirs.reset(seed=11)
    for agent in ours.possible_agents:
        np.testing.assert_array_equal(obs_a[agent], obs_b[agent])
    actions = {a: ours.action_space(a).sample() for a in ours.agents}
    step_a = ours.step(actions)
    step_b = theirs.step(actions)
    for agent in ours.possible_agents:
        np.testing.assert_array_equal(step_a[0][agent], step_b[0][agent])
        assert step_a[1][agent] == step_b[1][agent]


@needs_registry
def test_the_aec_view_and_the_time_limit_come_through_pettingzoo_make():
    env = pettingzoo.make("aec", "DebrisGym/Swarm2D-Easy-v0", max_cycles=3)
    assert isinstance(env, AECEnv)
    env.reset(seed=0)
    steps = 0
    for _ in env.agent_iter():
        _, _, terminated, truncated, _ = env.last()
        env.step(None if terminated or truncated else np.zeros(2, dtype=np.float32))
        steps += 1
    assert steps == 3 * 2 + 2  # three cycles of two chasers, then each chaser's final step
    parallel = pettingzoo.make("parallel", "DebrisGym/Swarm2D-Easy-v0", max_episode_steps=4)
    assert parallel.max_episode_steps == 4
    # an unversioned ID is its newest version, as in gymnasium
    assert pettingzoo.spec("parallel", "DebrisGym/Swarm3D").id == "DebrisGym/Swarm3D-v0"


@needs_registry
def test_registering_again_changes_nothing_and_warns_nothing():
    before = dict(pettingzoo.parallel_registry)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert swarm.register_with_pettingzoo() == []
    assert pettingzoo.parallel_registry == before


def test_registering_needs_a_registry_and_fills_both():
    """Against stand-ins of the module: one without a registry (PettingZoo before 1.27), one
    with."""
    assert swarm.register_with_pettingzoo(types.SimpleNamespace(__version__="1.24.3")) == []
    calls: list[tuple[str, str]] = []
    stub = types.SimpleNamespace(
        parallel_registry={}, aec_registry={"DebrisGym/Swarm3D-v0": object()}
    )
    stub.register = lambda kind, env_id, entry_point: calls.append((kind, env_id))
    registered = swarm.register_with_pettingzoo(stub)
    assert registered == sorted(swarm.SWARM_SPECS)
    assert sorted(calls) == sorted(
        [("parallel", e) for e in swarm.SWARM_SPECS]
        + [("aec", e) for e in swarm.SWARM_SPECS if e != "DebrisGym/Swarm3D-v0"]
    )
