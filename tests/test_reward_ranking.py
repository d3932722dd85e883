"""With the default v1 weights, the return ranks outcomes the way the task does.

For every learner discount γ in {0.9, 0.95, 0.99, 0.995, 0.999, 1}, on seeded default fields, the
discounted return of every successful APF-MPC mission must exceed that of doing nothing until
the time limit, flying into the nearest debris, leaving the bounds, and spending the Δv budget
on the same field. The failing behaviours are simple scripted policies written here.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import agents
import debris_gym  # noqa: F401  (registers the IDs)
from tests.helpers import discounted, flies_old_ids, fly_policy

pytestmark = flies_old_ids  # the v1 weights on purpose

GAMMAS = (0.9, 0.95, 0.99, 0.995, 0.999, 1.0)
ENV_ID = "DebrisGym/Rendezvous2D-v1"


def idle(env, obs, info, first):
    return np.zeros(env.unwrapped.dim, dtype=np.float32)


def toward_nearest_debris(env, obs, info, first):
    base = env.unwrapped
    chaser = info["chaser_state"][: base.dim]
    bodies = base.body_states[len(base.scenario.targets) :, : base.dim]
    rel = bodies[np.argmin(np.linalg.norm(bodies - chaser, axis=1))] - chaser
    return (rel / np.linalg.norm(rel)).astype(np.float32)


def flee(env, obs, info, first):
    away = np.zeros(env.unwrapped.dim, dtype=np.float32)
    away[0] = 1.0  # radially out, the nearest way off the map from the dock
    return away


def spend_budget(env, obs, info, first):
    """Full thrust +x, −x, −x, +x, … : the velocity swings about zero, so the chaser burns its
    whole budget hovering near the dock."""
    burn = np.zeros(env.unwrapped.dim, dtype=np.float32)
    burn[0] = 1.0 if round(info["time"] / env.unwrapped.scenario.dt) % 4 in (0, 3) else -1.0
    return burn


FAILURES = {
    "idle": (idle, lambda info: not info["collision"] and info["targets_captured"] == 0),
    "crash": (toward_nearest_debris, lambda info: info["collision"]),
    "flee": (flee, lambda info: info["out_of_bounds"]),
    "budget": (spend_budget, lambda info: info["delta_v"] >= 100.0 - 1e-9),
}
"""Each scripted failure and the outcome it aims at (a flight off the map may meet a body on
the way: it is compared all the same, as the crash it became)."""


def test_success_outranks_idling_crashing_fleeing_and_burning_for_every_discount():
    env = gym.make(ENV_ID)
    planner = agents.make_agent("apf-mpc", env)
    compared = 0
    hits = dict.fromkeys(FAILURES, 0)  # fields where each failure ended as it aimed to
    for seed in range(40):
        if compared >= 10:
            break
        rewards, info = fly_policy(
            env, seed, lambda e, o, i, first: planner.predict(o, episode_start=np.array([first]))[0]
        )
        if not info["is_success"]:
            continue
        failures = {}
        for name, (policy, happened) in FAILURES.items():
            fail_rewards, fail_info = fly_policy(env, seed, policy)
            assert not fail_info["is_success"], (name, seed)
            hits[name] += happened(fail_info)
            failures[name] = fail_rewards
        for gamma in GAMMAS:
            good = discounted(rewards, gamma)
            for name, fail_rewards in failures.items():
                bad = discounted(fail_rewards, gamma)
                assert good > bad, (seed, gamma, name, good, bad)
        compared += 1
    assert compared >= 10
    assert all(count >= compared // 2 for count in hits.values()), hits
