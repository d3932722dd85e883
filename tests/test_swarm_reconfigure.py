"""The reconfiguration missions: every chaser to its own formation slot around a body."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test

from debris_gym import swarm
from debris_gym.swarm.formation import (
    checked_slot_assignment,
    formation_slots,
    nearest_slots,
    outer_radius,
)

R2D, R3D = "DebrisGym/Reconfigure2D-v0", "DebrisGym/Reconfigure3D-v0"


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 256),
    core=st.floats(0.5, 50.0),
    spacing=st.floats(1.0, 40.0),
    dim=st.sampled_from([2, 3]),
)
def test_formation_slots_keep_their_spacing_outside_the_core(n, core, spacing, dim):
    slots = formation_slots(n, core, spacing, dim)
    assert slots.shape == (n, dim)
    if n > 1:
        assert pdist(slots).min() >= spacing * (1.0 - 1e-9)
    assert np.linalg.norm(slots, axis=1).min() >= core + spacing * (1.0 - 1e-9)


def test_formation_shells_fill_inside_out():
    # 2D: the first ring at core + spacing = 17 m holds floor(pi / asin(6 / 17)) = 8 slots
    slots = formation_slots(9, 5.0, 12.0, 2)
    radii = np.linalg.norm(slots, axis=1)
    np.testing.assert_allclose(radii[:8], 17.0)
    np.testing.assert_allclose(radii[8], 29.0)
    assert outer_radius(slots, 5.0, 1.0) == pytest.approx(35.0)


@pytest.mark.parametrize(
    ("args", "match"),
    [((0, 5.0, 12.0, 2), "n=0"), ((3, 5.0, 12.0, 4), "dim=4"), ((3, -1.0, 12.0, 2), "core"),
     ((3, 5.0, float("nan"), 3), "spacing")],
)  # fmt: skip
def test_bad_formation_arguments_are_named(args, match):
    with pytest.raises(ValueError, match=match):
        formation_slots(*args)


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 6), seed=st.integers(0, 2**31 - 1), dim=st.sampled_from([2, 3]))
def test_the_nearest_slots_are_the_brute_force_optimum(k, seed, dim):
    rng = np.random.default_rng(seed)
    starts, slots = rng.normal(size=(k, dim)) * 50, rng.normal(size=(k, dim)) * 50
    order = nearest_slots(starts, slots)
    assert sorted(order.tolist()) == list(range(k))
    cost = np.linalg.norm(starts - slots[order], axis=1).sum()
    best = min(
        np.linalg.norm(starts - slots[list(p)], axis=1).sum()
        for p in itertools.permutations(range(k))
    )
    assert cost == pytest.approx(best, rel=1e-12, abs=1e-9)


@pytest.mark.parametrize("value", [[2, 0, 1], [[2], [0], [1]], np.eye(3, dtype=bool)[[2, 0, 1]]])
def test_a_slot_assignment_reads_in_every_form(value):
    np.testing.assert_array_equal(checked_slot_assignment(value, 3), [2, 0, 1])


@pytest.mark.parametrize(
    "value", [[0, 0, 1], [0, 1], [0, 1, 3], [0.0, 1.0, 2.0], "abc", [[0, 1], [2], []],
              np.ones((3, 3), dtype=bool)],
)  # fmt: skip
def test_a_bad_slot_assignment_is_refused(value):
    with pytest.raises(ValueError, match="assignment"):
        checked_slot_assignment(value, 3)


@pytest.mark.parametrize(
    ("options", "match"),
    [({"assignment": "free"}, "assignment='free'"), ({"n_targets": 3}, "n_targets=3"),
     ({"slot_spacing": 5.0}, "slot_spacing=5.0"), ({"formation_core": 0.0}, "formation_core"),
     ({"mission": "orbit"}, "mission='orbit'"),
     ({"n_chasers": 256, "slot_spacing": 60.0}, "n_chasers=256"),
     ({"scenario": "paper"}, "scenario='paper'")],
)  # fmt: skip
def test_bad_reconfiguration_options_are_named(options, match):
    with pytest.raises(ValueError, match=match):
        swarm.make(R2D, **options).reset(seed=0)


def _field(env):
    core = env.core
    return core, core.shell.batch_in_use


@pytest.mark.parametrize("env_id", [R2D, R3D])
def test_a_reset_starts_every_chaser_at_its_dock_slot_bound_for_a_clear_formation(env_id):
    env = swarm.make(env_id)
    env.reset(seed=3)
    core, batch = _field(env)
    k, d = core.chasers, env.config.dim
    m, field = batch.missions, batch.field
    starts = swarm.dock_slots(k, core.swarm.dock_spacing, d)
    np.testing.assert_allclose(m.state[:k, :d], starts)
    np.testing.assert_array_equal(m.state[:k, d:], 0.0)
    centre = field.centers[0, 0]
    assert field.radii[0, 0] == core.swarm.formation_core
    slots = centre + core.formation
    order = nearest_slots(starts, slots)
    np.testing.assert_allclose(batch.dock[:k], slots[order])
    assert not m.assigned[:k].any() and m.captured[:k].all()  # the body is nobody's target
    # every slot's zone is clear of every other body (bounding balls), and inside the bounds
    reach = env.config.capture_radius + env.config.chaser_radius
    gaps = np.linalg.norm(batch.dock[:k, None] - field.centers[0, None, 1:], axis=2)
    assert (gaps - field.radii[0, None, 1:]).min() > reach
    assert np.abs(batch.dock[:k]).max() < env.config.field_size / 2.0 - reach
    assert np.all(field.velocities[0] == 0.0)  # frozen debris, as in the paper


def test_every_reset_starts_the_chasers_at_their_dock_slots_again():
    env = swarm.make(R2D)
    for seed in (0, 0, 1):
        env.reset(seed=seed)
        core, batch = _field(env)
        np.testing.assert_allclose(
            batch.missions.state[:6, :2], swarm.dock_slots(6, core.swarm.dock_spacing, 2)
        )
        assert np.linalg.norm(batch.dock[:6], axis=1).min() > 100.0
        _, _, terms, _, _ = env.step({a: np.zeros(2) for a in env.agents})
        assert not any(terms.values())


def test_the_moving_option_moves_the_debris():
    env = swarm.make(R2D, debris_motion="bounded")
    env.reset(seed=0)
    _, batch = _field(env)
    assert np.abs(batch.field.velocities[0]).max() > 0.0


def _at_slots(env, seed: int) -> np.ndarray:
    """Initial states: every chaser at rest at the slot of the identity assignment."""
    env.reset(seed=seed)
    core, batch = _field(env)
    d = env.config.dim
    states = np.zeros((core.chasers, 2 * d))
    states[:, :d] = batch.field.centers[0, 0] + core.formation
    return states


def test_chasers_held_at_their_slots_succeed_as_a_team():
    env = swarm.make(R2D)
    states = _at_slots(env, seed=5)
    env.reset(seed=5, options={"chaser_state": states, "assignment": list(range(6))})
    _, rewards, terms, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert all(terms.values()) and env.agents == []
    for agent, info in infos.items():
        assert info["is_success"] and info["team_success"], agent
        assert info["reward_terms"]["success"] == env.config.reward_success
        assert rewards[agent] > 0.9 * env.config.reward_success


def test_a_chaser_at_another_slot_does_not_succeed():
    env = swarm.make(R2D)
    states = _at_slots(env, seed=5)
    env.reset(seed=5, options={"chaser_state": states, "assignment": [1, 0, 2, 3, 4, 5]})
    _, _, terms, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert not terms["chaser_0"] and not terms["chaser_1"]
    assert terms["chaser_2"] and not infos["chaser_2"]["team_success"]


def test_an_arrived_chaser_stays_a_body_its_teammates_can_hit():
    env = swarm.make(R2D)
    states = _at_slots(env, seed=7)
    slot0 = states[0, :2].copy()
    # chaser 1 at rest 3 m from slot 0 (1 m more than the 2 m at which chasers touch), on the
    # side away from the core
    outward = slot0 - _field(env)[1].field.centers[0, 0]
    outward /= np.linalg.norm(outward)
    states[1, :2] = slot0 + 3.0 * outward
    env.reset(seed=7, options={"chaser_state": states, "assignment": list(range(6))})
    _, _, terms, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert terms["chaser_0"] and infos["chaser_0"]["is_success"]
    assert not terms["chaser_1"]
    # full thrust at the held chaser: 0.5 · 0.05 m/s² · (10 s)² = 2.5 m of the 3 m in a step
    actions = {a: np.zeros(2) for a in env.agents}
    actions["chaser_1"] = -outward.astype(np.float32)
    _, _, terms, _, infos = env.step(actions)
    assert terms["chaser_1"]
    assert infos["chaser_1"]["collision"] and infos["chaser_1"]["teammate_collision"]
    assert infos["chaser_1"]["separation"] < 2.0
    m = env.core.shell.batch_in_use.missions
    assert m.success[0] and not m.collision[0]  # the held chaser keeps its success


def test_a_given_slot_assignment_is_flown():
    env = swarm.make(R3D)
    env.reset(seed=2, options={"assignment": [5, 4, 3, 2, 1, 0]})
    core, batch = _field(env)
    np.testing.assert_allclose(
        batch.dock[:6], batch.field.centers[0, 0] + core.formation[[5, 4, 3, 2, 1, 0]]
    )
    with pytest.raises(ValueError, match="permutation"):
        env.reset(seed=2, options={"assignment": [0, 0, 1, 2, 3, 4]})


def test_forty_eight_chasers_fit_the_3d_field():
    env = swarm.make(R3D, n_chasers=48)
    env.reset(seed=0)
    core, batch = _field(env)
    assert len(env.agents) == 48
    assert pdist(batch.dock[:48]).min() >= core.swarm.spacing(env.config) - 1e-9


def test_pettingzoo_parallel_api_reconfigure():
    parallel_api_test(swarm.make(R2D), num_cycles=100)


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 6), seed=st.integers(0, 2**31 - 1))
def test_the_slot_rules_are_the_brute_force_optima(k, seed):
    from agents.planners.team_assignment import TeamField, slot_assignment

    rng = np.random.default_rng(seed)
    starts = rng.integers(-5, 5, size=(k, 2)) * 10.0  # ties happen: the rules must break them
    slots = rng.integers(-5, 5, size=(k, 2)) * 10.0
    field = TeamField(starts, slots, np.zeros(k), False, one_each=True)
    legs = np.linalg.norm(starts[:, None] - slots[None], axis=2)
    perms = [list(p) for p in itertools.permutations(range(k))]
    totals = [legs[np.arange(k), p].sum() for p in perms]
    longest = [legs[np.arange(k), p].max() for p in perms]
    best_total, least_longest = min(totals), min(longest)
    for rule in ("balanced", "optimal"):
        assert slot_assignment(rule, field).cost == pytest.approx(best_total, abs=1e-9)
    minmax = slot_assignment("minmax", field)
    assert minmax.longest == pytest.approx(least_longest, abs=1e-9)
    ties = [t for t, m in zip(totals, longest) if m <= least_longest + 1e-9]
    assert minmax.cost == pytest.approx(min(ties), abs=1e-9)
    greedy = slot_assignment("greedy", field)
    assert greedy.table.sum(axis=0).tolist() == [1] * k  # a matching
    assert greedy.table.sum(axis=1).tolist() == [1] * k
    assert greedy.cost >= best_total - 1e-9


def test_a_team_of_singles_flies_a_reconfiguration():
    from agents.policies.team import TeamOfSingles, start_episode

    env = swarm.make(R2D, n_chasers=3)
    team = TeamOfSingles(env, "zero", rule="minmax")
    _, _, chosen = start_episode(env, team, seed=4)
    core, batch = _field(env)
    slots = batch.field.centers[0, 0] + core.formation
    order = np.argmax(chosen.table, axis=1)
    np.testing.assert_allclose(batch.dock[:3], slots[order])
    starts = batch.missions.state[:3, :2]
    assert chosen.longest == pytest.approx(np.linalg.norm(starts - slots[order], axis=1).max())


@pytest.mark.parametrize(
    ("name", "env_id", "count", "chasers"),
    [("swarm-2d-v0", "DebrisGym/Swarm2D-v0", 50, 3),
     ("reconfigure-3d-v0", "DebrisGym/Reconfigure3D-v0", 20, 48)],
)  # fmt: skip
def test_a_swarm_suite_mission_replays_the_field_its_seed_draws(name, env_id, count, chasers):
    from debris_gym import suites

    suite = suites.load_suite(name)
    assert suite.env_id == env_id and len(suite) == count
    env = swarm.make(env_id, **suite.env_kwargs)
    assert env.core.chasers == chasers
    for mission in (suite.missions[0], suite.missions[-1]):
        env.reset(seed=mission.seed)
        batch = env.core.shell.batch_in_use
        drawn = (batch.field.centers.copy(), batch.field.radii.copy(), batch.dock.copy())
        env.reset(seed=mission.seed, options={"scenario": mission.scenario})
        for before, after in zip(drawn, (batch.field.centers, batch.field.radii, batch.dock)):
            np.testing.assert_allclose(after, before, atol=1e-9)
