"""With the v2 defaults the return ranks a success above every other way to end a mission.

The claim (docs/environments.md, "Rewards"): on every v2 rung, for every learner discount whose
effective horizon 1 / (1 − γ) is at least the time limit (1 000 steps, γ ≥ 0.999), the
discounted return of a successful mission exceeds that of each strategy below flown on the same
field. The strategies are scripted here, most of them on top of the APF-MPC planner's flight
(so they reach the targets the way a learner that has half-learned the task would):

=========================  =====================================================================
rush-capture               straight at the nearest target at up to 3 m/s, braking at 30 % of
                           full thrust into a hold 2.5 m off its surface; after the capture, coast
rush-capture-crash         ... after the capture, thrust into the captured target
partial-hold               fly the mission, but break every hold one step end short of a capture
hover                      fly to the first target, then station-keep 10 m off its capture zone
timed budget burn-out      wait at the dock, then burn the whole Δv budget — the best of six
                           start times (the moving targets make the remaining tour shorter at
                           some times: the potential moves)
idle                       coast from the dock to the time limit
crash                      full thrust into the nearest debris
flee                       full thrust radially out of the world
potential farming          thrust toward the nearest target and away again, 10 steps each,
                           at 30 % thrust, to the end (of the time limit or of the budget)
=========================  =====================================================================

Each strategy must also end the way it aims to on some field (a capture before a crash, a
budget spent, ...), so that the comparison is the one named. On the Easy rungs the first capture
completes the mission, so the two rush strategies are the success itself there and are left out.
"""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest

import agents
import debris_gym  # noqa: F401  (registers the IDs)
from tests.helpers import discounted, fly_policy

GAMMAS = (0.999, 0.9995, 1.0)
"""The discounts the claim covers: effective horizon 1 / (1 − γ) ≥ the 1 000-step limit."""
RUNGS = (
    "DebrisGym/Rendezvous2D-v2",
    "DebrisGym/Rendezvous2D-Easy-v2",
    "DebrisGym/Rendezvous2D-Medium-v2",
    "DebrisGym/Rendezvous3D-v2",
    "DebrisGym/Rendezvous3D-Easy-v2",
    "DebrisGym/Rendezvous3D-Medium-v2",
)
FIELDS_PER_RUNG = 2
BURN_STARTS = (0, 150, 300, 450, 600, 750)
"""Steps waited at the dock before the budget burn-out (the burn takes 200 steps)."""

Policy = Callable[[gym.Env, np.ndarray, dict, bool], np.ndarray]


def dim_of(env: gym.Env) -> int:
    return env.unwrapped.dim


def thrust(direction: np.ndarray, level: float = 1.0) -> np.ndarray:
    norm = float(np.linalg.norm(direction))
    if norm == 0.0:
        return np.zeros_like(direction, dtype=np.float32)
    return (level * direction / norm).astype(np.float32)


def relative_to(env: gym.Env, body: int) -> tuple[np.ndarray, np.ndarray]:
    """The body's position and velocity minus the chaser's (m, m/s)."""
    base, d = env.unwrapped, dim_of(env)
    state, other = base.chaser_state, base.body_states[body]
    return other[:d] - state[:d], other[d:] - state[d:]


def nearest(env: gym.Env, first: int, last: int | None = None) -> int:
    """The index of the body nearest the chaser among ``first … last − 1``."""
    base, d = env.unwrapped, dim_of(env)
    bodies = base.body_states[first:last, :d]
    return first + int(np.argmin(np.linalg.norm(bodies - base.chaser_state[:d], axis=1)))


class Planned:
    """The APF-MPC planner's flight, handed to ``after`` once ``switch(info)`` is true (from
    then on ``after`` flies; it may hand back by returning None)."""

    def __init__(self, planner, switch=None, after=None):
        self.planner, self.switch, self.after = planner, switch, after
        self.switched = False

    def __call__(self, env, obs, info, first):
        if first:
            self.switched = False
        if self.switch is not None and not self.switched and self.switch(env, info):
            self.switched = True
        if self.switched:
            action = self.after(env, info)
            if action is not None:
                return action
            self.switched = False
        return self.planner.predict(obs, episode_start=np.array([first]))[0]


class Rush:
    """Straight for a hold point 2.5 m off the nearest target's surface (on the chaser's side):
    the relative velocity steered to √(2·a·d) toward it (d its distance, a 30 % of full thrust;
    at most 3 m/s, and at most 30 % of d per step), which brakes into the hold; once a target is
    captured, ``after`` flies."""

    def __init__(self, n_targets: int, chaser_radius: float, after):
        self.n_targets, self.chaser_radius, self.after = n_targets, chaser_radius, after
        self.target = None

    def __call__(self, env, obs, info, first):
        if first:
            self.target = nearest(env, 0, self.n_targets)
        if info["targets_captured"] >= 1:
            return self.after(env, info)
        rel, rel_v = relative_to(env, self.target)
        base = env.unwrapped
        stand_off = base.scenario.targets[self.target].radius + self.chaser_radius + 2.5
        to_hold = rel - stand_off * rel / np.linalg.norm(rel)  # chaser → hold point
        d = float(np.linalg.norm(to_hold))
        max_accel, dt = base.config.max_accel, base.config.dt
        speed = min(3.0, float(np.sqrt(2.0 * 0.3 * max_accel * d)), 0.3 * d / dt)
        wanted = speed * to_hold / d if d > 0.0 else np.zeros_like(to_hold)
        accel = (wanted - (-rel_v)) / dt  # chaser velocity relative to the target is −rel_v
        return np.clip(accel / max_accel, -1.0, 1.0).astype(np.float32)


def coast(env, info):
    return np.zeros(dim_of(env), dtype=np.float32)


def into_captured_target(env, info):
    j = int(np.flatnonzero(info["captured"])[0])
    rel, _ = relative_to(env, j)
    return thrust(rel)


class BreakHolds:
    """Thrust away from the held target for one step whenever a hold is one step end short of
    a capture; the planner flies otherwise."""

    def __init__(self, planner, hold_steps: int):
        self.planned = Planned(planner)
        self.hold_steps = hold_steps

    def __call__(self, env, obs, info, first):
        if not first and info["hold"].max() >= self.hold_steps - 1:
            rel, _ = relative_to(env, int(np.argmax(info["hold"])))
            return thrust(-rel)  # 0.5 m/s away: over capture_speed, off the hold
        return self.planned(env, obs, info, first)


class Hover:
    """Fly with the planner until 10 m beyond the capture zone of the nearest target, then
    station-keep there relative to it (a PD law on the relative state)."""

    def __init__(self, planner, n_targets: int, reach: float):
        self.planner, self.n_targets, self.reach = planner, n_targets, reach
        self.hover = None

    def __call__(self, env, obs, info, first):
        if first:
            self.hover = None
        if self.hover is None:
            j = nearest(env, 0, self.n_targets)
            rel, _ = relative_to(env, j)
            radius = env.unwrapped.scenario.targets[j].radius
            if np.linalg.norm(rel) - radius <= self.reach + 10.0:
                self.hover = (j, rel.copy())
            else:
                return self.planner.predict(obs, episode_start=np.array([first]))[0]
        j, rel0 = self.hover
        rel, rel_v = relative_to(env, j)
        max_accel = env.unwrapped.config.max_accel
        accel = 0.002 * (rel - rel0) + 0.1 * rel_v  # back toward rel0, relative velocity nulled
        return np.clip(accel / max_accel, -1.0, 1.0).astype(np.float32)


def burn_after(start: int) -> Policy:
    """Coast ``start`` steps, then full thrust +x, −x, −x, +x, … until the budget is spent:
    the velocity swings about zero, so the chaser burns it hovering near the dock."""

    def policy(env, obs, info, first):
        k = round(info["time"] / env.unwrapped.config.dt)
        burn = np.zeros(dim_of(env), dtype=np.float32)
        if k >= start:
            burn[0] = 1.0 if (k - start) % 4 in (0, 3) else -1.0
        return burn

    return policy


def idle(env, obs, info, first):
    return np.zeros(dim_of(env), dtype=np.float32)


def crash(env, obs, info, first):
    j = nearest(env, len(env.unwrapped.scenario.targets))
    return thrust(relative_to(env, j)[0])


def flee(env, obs, info, first):
    away = np.zeros(dim_of(env), dtype=np.float32)
    away[0] = 1.0  # radially out, the nearest way off the map from the dock
    return away


def farm(env, obs, info, first):
    k = round(info["time"] / env.unwrapped.config.dt)
    rel, _ = relative_to(env, nearest(env, 0, len(env.unwrapped.scenario.targets)))
    return thrust(rel if (k // 10) % 2 == 0 else -rel, 0.3)


def strategies(env: gym.Env, planner) -> dict[str, tuple[Policy, Callable[[dict], bool]]]:
    """Each strategy with the ending it aims at (checked to happen on some field)."""
    cfg = env.unwrapped.config
    hold_steps = env.unwrapped.shell.batch_in_use.rules.hold_steps
    captured_one = lambda info: info["targets_captured"] >= 1  # noqa: E731
    one_goal = cfg.n_targets == 1 and not cfg.return_to_dock
    rush = {
        "rush-capture": (
            Rush(len(env.unwrapped.scenario.targets), cfg.chaser_radius, coast),
            lambda info: captured_one(info) and not info["is_success"],
        ),
        "rush-capture-crash": (
            Rush(len(env.unwrapped.scenario.targets), cfg.chaser_radius, into_captured_target),
            lambda info: captured_one(info) and info["collision"],
        ),
    }
    return {
        **({} if one_goal else rush),
        "partial-hold": (
            BreakHolds(planner, hold_steps),
            lambda info: info["targets_captured"] == 0 and not info["collision"],
        ),
        "hover": (
            Hover(planner, len(env.unwrapped.scenario.targets), cfg.capture_radius),
            lambda info: info["targets_captured"] == 0 and not info["collision"],
        ),
        "idle": (idle, lambda info: not info["collision"] and info["targets_captured"] == 0),
        "crash": (crash, lambda info: info["collision"]),
        "flee": (flee, lambda info: info["out_of_bounds"]),
        "potential farming": (farm, lambda info: not info["is_success"]),
        **{
            f"budget burn-out after {start} steps": (
                burn_after(start),
                lambda info: info["budget_spent"],
            )
            for start in BURN_STARTS
        },
    }


@pytest.mark.parametrize("env_id", RUNGS)
def test_success_outranks_every_other_strategy(env_id):
    env = gym.make(env_id)
    planner = agents.make_agent("apf-mpc", env)
    env.reset(seed=0)
    tried = strategies(env, planner)
    hits = dict.fromkeys(tried, 0)  # fields where each strategy ended as it aims to
    compared = 0
    for seed in range(12):
        if compared == FIELDS_PER_RUNG:
            break
        good_rewards, good_info = fly_policy(
            env, seed, lambda e, o, i, first: planner.predict(o, episode_start=np.array([first]))[0]
        )
        if not good_info["is_success"]:
            continue
        compared += 1
        for name, (policy, aimed) in tried.items():
            rewards, info = fly_policy(env, seed, policy)
            assert not info["is_success"], (env_id, seed, name)
            hits[name] += bool(aimed(info))
            for gamma in GAMMAS:
                good, bad = discounted(good_rewards, gamma), discounted(rewards, gamma)
                assert good > bad, (env_id, seed, name, gamma, good, bad)
    assert compared == FIELDS_PER_RUNG, f"APF-MPC completed only {compared} fields of {env_id}"
    missed = [name for name, count in hits.items() if count == 0]
    assert not missed, f"{env_id}: never ended as aimed: {missed}"
