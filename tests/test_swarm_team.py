"""Teams on the swarm IDs: a single-agent baseline flying one chaser through its view acts as on a
single env holding the same field and chaser state; the assignment rules against brute force;
evaluate.py on a swarm ID end to end."""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("pettingzoo")

from agents import make_agent
from agents.control.mpc import MPCParams
from agents.experiments.swarm_evaluation import SwarmEvaluateOptions, run_swarm_evaluation
from agents.experiments.swarm_evaluation.report import episode_columns
from agents.experiments.swarm_evaluation.teams import DEFAULT_TEAMS, make_team, parse_teams
from agents.planners.team_assignment import (
    ASSIGNMENT_RULES,
    TeamField,
    assign,
    assignment_cost,
    greedy_assignment,
    minmax_assignment,
    optimal_assignment,
    tour_costs,
)
from agents.policies.base import field_view, unwrap
from agents.policies.chaser_view import ChaserView
from agents.policies.shield import ShieldParams
from agents.policies.team import TeamOfSingles, start_episode, team_field
from debris_gym import swarm
from debris_gym.envs import DebrisFieldEnv
from debris_gym.swarm.config import split_options
from tests.helpers import load_script

SWARM = "DebrisGym/Swarm2D-v0"
SMALL = {"n_targets": 2, "n_obstacles": 3}


def _single_env_like(options: dict) -> DebrisFieldEnv:
    """A single env with the world options of the swarm ``SWARM`` made with ``options``."""
    env_options, _ = split_options({**swarm.SWARM_SPECS[SWARM]["kwargs"], **options})
    env_options.pop("obs_teammates")
    return DebrisFieldEnv(**env_options)


# --- the per-chaser view ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["apf-mpc", "apf"])
def test_a_baseline_flying_one_chaser_acts_as_on_a_single_env_with_that_field_and_state(name):
    """The view is the single env's field and chaser (the MPC's teammates left out: it keeps
    clear of them otherwise, tests/test_team_bodies.py)."""
    options = {**SMALL, "n_chasers": 2}
    team = swarm.make(SWARM, **options)
    observations, _ = team.reset(seed=4)
    view = ChaserView(team.core, 1)
    params = {"mpc": MPCParams(teammates_per_step=0)} if name == "apf-mpc" else {}
    on_view = make_agent(name, view, **params)
    single = _single_env_like(options)
    obs, _ = single.reset(options={"scenario": view.scenario, "chaser_state": view.chaser_state})
    on_single = make_agent(name, single)
    assert view.scenario is not None and view.scenario.dock == (5.0, 0.0)  # its own slot
    flown = 0
    for step in range(40):
        if "chaser_1" not in team.agents:
            break
        a_view = on_view.predict(observations["chaser_1"])[0]
        a_single = on_single.predict(obs)[0]
        assert np.array_equal(a_view, a_single), step
        actions = {a: np.zeros(2, np.float32) for a in team.agents}
        actions["chaser_1"] = a_view
        observations, _, _, _, infos = team.step(actions)
        obs, _, terminated, _, info = single.step(a_single)
        assert np.array_equal(view.chaser_state, single.chaser_state), step
        assert np.array_equal(view.captured, single.captured), step
        assert view.elapsed == single.elapsed
        flown += 1
        if terminated:
            break
    assert flown >= 10
    assert np.linalg.norm(view.chaser_state[:2] - np.array([5.0, 0.0])) > 1.0  # it flew


def test_with_given_targets_a_view_marks_the_other_chasers_targets_as_done():
    team = swarm.make(SWARM, n_targets=4, n_obstacles=3, assignment="given")
    team.reset(seed=1, options={"assignment": [[0], [1, 3], [2]]})
    views = [ChaserView(team.core, k) for k in range(3)]
    assert views[1].captured.tolist() == [True, False, True, False]
    assert views[1].assigned.tolist() == [False, True, False, True]
    assert views[0].captured.tolist() == [False, True, True, True]
    scenario = views[2].scenario
    assert scenario is not None and len(scenario.targets) == 4  # the others' stay bodies
    assert views[2].scenario is scenario  # one object per field: an agent plans once


def test_the_field_view_protocol_accepts_a_chaser_view_and_unwrap_stays_strict():
    team = swarm.make(SWARM, **SMALL)
    view = ChaserView(team.core, 0)
    assert field_view(view) is view  # no field yet: still a view
    with pytest.raises(TypeError, match="expected a DebrisGym env"):
        unwrap(view)
    with pytest.raises(TypeError, match="lacks config, dim"):
        field_view(object())
    with pytest.raises(ValueError, match=r"chaser=3 is out of range; allowed: \[0, 2\]"):
        ChaserView(team.core, 3)


# --- assignment rules ----------------------------------------------------------------------------


def _tour_brute(field: TeamField, chaser: int, targets: tuple[int, ...]) -> float:
    if not targets:
        return 0.0
    dock, c, r = field.docks[chaser], field.centers, field.radii

    def leg(p, q, rp, rq):
        return max(math.dist(p, q) - rp - rq, 0.0)

    best = math.inf
    for order in itertools.permutations(targets):
        total = leg(dock, c[order[0]], 0.0, r[order[0]])
        for a, b in itertools.pairwise(order):
            total += leg(c[a], c[b], r[a], r[b])
        if field.return_to_dock:
            total += leg(c[order[-1]], dock, r[order[-1]], 0.0)
        best = min(best, total)
    return best


@st.composite
def team_fields(draw):
    k = draw(st.integers(1, 3))
    t = draw(st.integers(0, 5))
    coord = st.floats(-500.0, 500.0, allow_nan=False)
    docks = np.array([[draw(coord), draw(coord)] for _ in range(k)])
    centers = np.array([[draw(coord), draw(coord)] for _ in range(t)]).reshape(t, 2)
    radii = np.array([draw(st.floats(0.0, 30.0)) for _ in range(t)])
    return TeamField(docks, centers, radii, draw(st.booleans()))


@settings(max_examples=60, deadline=None)
@given(team_fields())
def test_each_rule_is_judged_by_tours_equal_to_brute_force_and_the_exact_rules_are_optimal(field):
    k, t = field.n_chasers, field.n_targets
    tours = tour_costs(field)
    for c in range(k):
        for mask in range(1 << t):
            members = tuple(j for j in range(t) if mask >> j & 1)
            assert tours[c, mask] == pytest.approx(_tour_brute(field, c, members), abs=1e-6)
    partitions = []
    for owners in itertools.product(range(k), repeat=t):
        per = [
            _tour_brute(field, c, tuple(j for j in range(t) if owners[j] == c)) for c in range(k)
        ]
        partitions.append((sum(per), max(per, default=0.0)))
    best_total = min(p[0] for p in partitions)
    least_longest = min(p[1] for p in partitions)
    assert optimal_assignment(field).cost == pytest.approx(best_total, abs=1e-6)
    minmax = minmax_assignment(field)
    assert minmax.longest == pytest.approx(least_longest, abs=1e-6)
    for rule in ASSIGNMENT_RULES:
        chosen = assign(rule, field)
        assert chosen.table.shape == (k, t) and np.all(chosen.table.sum(axis=0) == 1)
        cost, per = assignment_cost(chosen.table, field)
        assert chosen.cost == pytest.approx(cost) and np.allclose(chosen.tours, per)
        assert chosen.cost >= best_total - 1e-6
        assert chosen.longest >= least_longest - 1e-6
    balanced = assign("balanced", field).table
    assert balanced.sum(axis=1).max(initial=0) <= math.ceil(t / k)


def test_greedy_takes_turns_from_each_tour_end():
    # chaser 0 at x = 0, chaser 1 at x = 100; targets (points) along x
    field = TeamField(
        np.array([[0.0, 0.0], [100.0, 0.0]]),
        np.array([[10.0, 0.0], [20.0, 0.0], [90.0, 0.0], [55.0, 0.0]]),
        np.zeros(4),
    )
    # 0 takes 10 (nearest its slot), 1 takes 90, 0 takes 20 (nearest 10), 1 takes 55
    assert greedy_assignment(field).targets() == [[0, 1], [2, 3]]
    # the sum of tours is least with one chaser flying everything (a slot 100 m away is no help)
    assert optimal_assignment(field).cost <= greedy_assignment(field).cost


def test_assignment_rules_refuse_what_they_cannot_do():
    field = TeamField(np.zeros((3, 2)), np.zeros((13, 2)), np.zeros(13))
    with pytest.raises(ValueError, match="at most 12 targets"):
        tour_costs(field)
    with pytest.raises(ValueError, match="unknown assignment rule 'nearest'"):
        assign("nearest", TeamField(np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1)))
    with pytest.raises(ValueError, match="centers must have shape"):
        TeamField(np.zeros((2, 2)), np.zeros((3, 3)), np.zeros(3))


# --- teams ---------------------------------------------------------------------------------------


def test_a_team_starts_each_episode_on_the_seeded_field_with_its_assignment():
    env = swarm.make(SWARM, n_targets=4, n_obstacles=3, assignment="given")
    once = swarm.make(SWARM, n_targets=4, n_obstacles=3, assignment="given")
    once.reset(seed=7)
    team = TeamOfSingles(env, "zero", "minmax")
    _, infos, chosen = start_episode(env, team, 7)
    assert team.views[0].scenario == ChaserView(once.core, 0).scenario  # the seed's field
    assert chosen.rule == "minmax"
    for k, agent in enumerate(env.possible_agents):
        assert infos[agent]["assigned"].tolist() == chosen.table[k].tolist()
    assert chosen.cost == pytest.approx(assign("minmax", team_field(team.views)).cost)
    size = env.core.observation_space.shape
    actions = team.predict({a: np.zeros(size, np.float32) for a in env.agents})
    assert set(actions) == set(env.agents)
    with pytest.raises(ValueError, match="seed must be an integer"):
        start_episode(env, team, None)  # type: ignore[arg-type]


def test_a_team_answers_for_the_chasers_still_flying():
    env = swarm.make(SWARM, n_targets=4, n_obstacles=3, assignment="given")
    team = TeamOfSingles(env, "zero", "optimal")
    observations, _, chosen = start_episode(env, team, 7)
    assert chosen.targets() == [[0, 1, 2, 3], [], []]  # the chasers without targets end at once
    observations, *_ = env.step(team.predict(observations))
    assert sorted(observations) == ["chaser_0", "chaser_1", "chaser_2"]
    assert env.agents == ["chaser_0"]
    assert list(team.predict(observations)) == ["chaser_0"]
    with pytest.raises(ValueError, match="unknown agents"):
        team.predict({"chaser_9": observations["chaser_0"]})


def test_a_team_needs_given_assignments_and_a_known_rule_and_member():
    with pytest.raises(ValueError, match="assignment='given'"):
        TeamOfSingles(swarm.make(SWARM, **SMALL), "zero")
    env = swarm.make(SWARM, assignment="given", **SMALL)
    with pytest.raises(ValueError, match="unknown assignment rule 'best'"):
        TeamOfSingles(env, "zero", "best")
    with pytest.raises(ValueError, match="unknown team member 'nope'"):
        TeamOfSingles(env, "nope")
    with pytest.raises(ValueError, match="the model observes Box"):
        TeamOfSingles(env, "pretrained")  # made without the policy's observation options


def test_a_pretrained_team_flies_the_direct_thrust_v2_policy():
    """The single-agent v2 IDs' `pretrained` is a residual policy (its base law flies one
    chaser per field, so a swarm refuses the mode); a team's `pretrained` member is the
    shipped v2 policy that commands the thrust itself, and the swarm made for it flies."""
    from agents.policies.learned import PRETRAINED_DIR, pretrained_path
    from agents.policies.team import member_spec, team_options

    assert pretrained_path("DebrisGym/Rendezvous2D-v2")[1].name == "rendezvous2d_v2_residual.zip"
    for dim in (2, 3):
        spec = member_spec("pretrained", dim)
        assert spec == f"ppo:{PRETRAINED_DIR / f'rendezvous{dim}d_v2.zip'}"
        assert "action" not in team_options("pretrained", dim)
    assert member_spec("ppo:runs/a/model.zip", 2) == "ppo:runs/a/model.zip"
    env = swarm.make(SWARM, **SMALL, **team_options("pretrained", 2))
    team = TeamOfSingles(env, "pretrained")
    observations, _, _ = start_episode(env, team, 5)
    actions = team.predict(observations)
    assert sorted(actions) == sorted(env.agents)
    assert all(np.all(np.isfinite(a)) and a.shape == (2,) for a in actions.values())


def test_team_names_parse_with_the_balanced_rule_by_default():
    specs = parse_teams("team-apf-mpc@optimal, team-zero")
    assert [(s.label, s.agent, s.rule) for s in specs] == [
        ("team-apf-mpc@optimal", "apf-mpc", "optimal"),
        ("team-zero@balanced", "zero", "balanced"),
    ]
    assert [s.label for s in parse_teams(None)] == list(DEFAULT_TEAMS)
    for bad, message in (
        ("apf-mpc", "swarm IDs fly teams"),
        ("team-apf-mpc@best", "unknown assignment rule 'best'"),
        ("team-nope", "unknown team member 'nope'"),
        ("team-zero,team-zero@balanced", "named twice"),
    ):
        with pytest.raises(ValueError, match=message):
            parse_teams(bad)


# --- evaluate.py ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def evaluate():
    return load_script("evaluate.py", "evaluate_swarm_script")


def test_evaluate_py_flies_teams_on_a_swarm_id_and_writes_the_tables(evaluate, tmp_path, capsys):
    out = tmp_path / "eval"
    status = evaluate.main([
        "--env", SWARM, "--env-kwargs", '{"n_targets": 2, "n_obstacles": 2}', "--max-steps",
        "25", "--episodes", "2", "--seed", "3", "--no-progress", "--out", str(out), "--agents",
        "team-zero,team-apf-mpc@optimal,team-pretrained@greedy",
    ])  # fmt: skip
    assert status == 0
    text = capsys.readouterr().out
    assert "team-apf-mpc@optimal" in text and "Assignment rules on the same fields" in text
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(out / "episodes.csv", newline="") as fh:
        assert next(csv.reader(fh)) == episode_columns(3)
    assert [(r["agent"], r["seed"]) for r in rows] == [
        (team, seed)
        for team in ("team-zero@balanced", "team-apf-mpc@optimal", "team-pretrained@greedy")
        for seed in ("3", "4")
    ]
    for episode in ("0", "1"):  # every team on the same field
        assert len({r["field"] for r in rows if r["episode"] == episode}) == 1
    for r in rows:
        assert int(r["steps"]) <= 25
        assert r["assignment"] == r["agent"].rpartition("@")[2]
        outcomes = [r[f"chaser{k}_outcome"] for k in range(3)]
        assert int(r["chasers_succeeded"]) == outcomes.count("success")
        collided = [o for o in outcomes if o.endswith("collision")]
        assert int(r["collisions"]) == len(collided)
        assert r["clean_success"] == str(r["team_success"] == "True" and not collided)
        assert float(r["assignment_gap"]) >= -1e-9
    optimal = [r for r in rows if r["assignment"] == "optimal"]
    assert all(float(r["assignment_gap"]) == 0.0 for r in optimal)
    with open(out / "assignments.csv", newline="") as fh:
        gaps = list(csv.DictReader(fh))
    assert [(g["episode"], g["rule"]) for g in gaps] == [
        (e, rule) for e in ("0", "1") for rule in ASSIGNMENT_RULES
    ]
    assert {p.name for p in out.iterdir()} >= {"summary.json", "summary.md", "manifest.json"}
    # the default --plots (3): each team's two episodes drawn, every chaser's path on them
    plots = sorted(p.name for p in out.glob("trajectories_ep*.png"))
    assert len(plots) == 6 and sum(name.startswith("trajectories_ep1_") for name in plots) == 3


def test_evaluate_py_flies_a_swarm_suite(evaluate, tmp_path, capsys):
    out = tmp_path / "suite"
    argv = ["--suite", "swarm-2d-v0", "--episodes", "2", "--agents", "team-zero",
            "--max-steps", "5", "--plots", "0", "--no-progress", "--out", str(out)]  # fmt: skip
    assert evaluate.main(argv) == 0
    assert "suite swarm-2d-v0" in capsys.readouterr().out
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["seed"] for r in rows] == ["906000000", "906000001"]
    for extra, flag in (
        (["--env-kwargs", '{"n_chasers": 2}'], "--env-kwargs"),
        (["--seed", "3"], "--seed"),
        (["--episodes", "51"], "--episodes"),
        (["--env", "DebrisGym/Swarm3D-v0"], "--env"),
    ):
        with pytest.raises(SystemExit):
            evaluate.main(["--suite", "swarm-2d-v0", "--out", str(tmp_path / "x"), *extra])
        assert f"argument {flag}" in capsys.readouterr().err


def test_evaluate_py_draws_and_records_swarm_episodes(evaluate, tmp_path):
    pytest.importorskip("moviepy", reason="--video needs moviepy: pip install -e '.[video]'")
    from moviepy import VideoFileClip

    out = tmp_path / "eval"
    status = evaluate.main([
        "--env", SWARM, "--env-kwargs", '{"n_targets": 2, "n_obstacles": 2}', "--max-steps",
        "12", "--episodes", "2", "--no-progress", "--out", str(out), "--agents", "team-zero",
        "--plots", "1", "--video", "1",
    ])  # fmt: skip
    assert status == 0
    plots = [p.name for p in out.glob("trajectories_ep*.png")]
    assert len(plots) == 1 and plots[0].startswith("trajectories_ep0_team-zero_balanced")
    videos = list((out / "videos").glob("*/episode-*.mp4"))
    assert [v.name for v in videos] == ["episode-0.mp4"]
    with VideoFileClip(str(videos[0])) as clip:
        frames = sum(1 for _ in clip.iter_frames())
    assert 12 <= frames <= 13  # the reset frame and one per step (moviepy may drop the last)


def _rows(out) -> list[dict[str, str]]:
    with open(out / "episodes.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_a_shielded_swarm_evaluation_flies_every_team_behind_its_shields(tmp_path):
    """Two chasers, short episodes: the shields act (the shielded flights differ from the
    unshielded ones exactly where they replaced commands), and the tables say so."""
    teams = "team-pretrained@minmax,team-zero"
    common = {
        "env": SWARM, "agents": teams, "episodes": 2, "max_steps": 30, "progress": False,
        "plots": 0, "env_kwargs": {"n_chasers": 2, "n_targets": 2, "n_obstacles": 3},
    }  # fmt: skip
    options = SwarmEvaluateOptions.from_arguments({**common, "shield": True})
    assert options.shield
    text = run_swarm_evaluation(dataclasses.replace(options, out=tmp_path / "on"))
    run_swarm_evaluation(SwarmEvaluateOptions(**common, out=tmp_path / "off"))
    on, off = _rows(tmp_path / "on"), _rows(tmp_path / "off")
    assert "**Shielded**" in text and "Safety shield: commands replaced" in text
    assert [(r["agent"], r["seed"]) for r in on] == [(r["agent"], r["seed"]) for r in off]
    for shielded, plain in zip(on, off, strict=True):
        replaced = int(shielded["shield_interventions"])
        per_chaser = [int(shielded[f"chaser{k}_shield_interventions"]) for k in range(2)]
        assert replaced == sum(per_chaser)
        assert int(plain["shield_interventions"]) == 0
        for column in ("team_success", "clean_success", "team_captures", "collisions",
                       "teammate_collisions", "min_separation", "chaser0_outcome"):  # fmt: skip
            assert shielded[column] != ""
        flown = [shielded[f"chaser{k}_delta_v"] for k in range(2)]
        unshielded = [plain[f"chaser{k}_delta_v"] for k in range(2)]
        # a shield that replaced nothing changed nothing; a replaced command is flown
        # (the teammates may then react too: they see each other)
        assert (flown != unshielded) == (replaced > 0), shielded["agent"]
        assert replaced == 0 or any(
            flown[k] != unshielded[k] for k in range(2) if per_chaser[k] > 0
        )
        if replaced:
            assert 0.0 < float(shielded["shield_size_mean"]) <= float(shielded["shield_size_max"])
    learned = [r for r in on if r["agent"] == "team-pretrained@minmax"]
    assert sum(int(r["shield_interventions"]) for r in learned) > 0
    with open(tmp_path / "on" / "summary.json") as fh:
        summary = json.load(fh)
    assert summary["shield"] == ShieldParams().to_dict()
    entry = summary["teams"]["team-pretrained@minmax"]
    assert entry["shield_interventions_mean"] > 0 and 0 < entry["shield_intervention_share"] <= 1
    with open(tmp_path / "off" / "summary.json") as fh:
        assert json.load(fh)["shield"] is None


@pytest.mark.parametrize("name", ["team-apf-mpc@balanced", "ma-se-scp"])
def test_every_kind_of_team_takes_the_shield(name):
    env = swarm.make(SWARM, n_chasers=2, n_targets=2, n_obstacles=3, assignment="given")
    team = make_team(parse_teams(name)[0], env, ShieldParams())
    assert make_team(parse_teams(name)[0], env).shield_stats == []
    observations, _, _ = start_episode(env, team, seed=1)
    for _ in range(3):
        observations, *_ = env.step(team.predict(observations))
    assert [s.decisions for s in team.shield_stats] == [3, 3]
    observations, _, _ = start_episode(env, team, seed=2)  # a new episode counts afresh
    team.predict(observations)
    assert [s.decisions for s in team.shield_stats] == [1, 1]


@pytest.mark.parametrize(
    ("extra", "flag"),
    [
        (["--backend", "ray"], "--backend"),
        (["--resume", "somewhere"], "--resume"),
        (["--agents", "apf-mpc"], "--agents"),
        (["--env-kwargs", '{"assignment": "free"}'], "--env-kwargs"),
        (["--env-kwargs", '{"n_chasers": 0}'], "--env-kwargs"),
    ],
)
def test_evaluate_py_refuses_what_does_not_apply_to_swarm_ids(
    evaluate, tmp_path, capsys, extra, flag
):
    with pytest.raises(SystemExit) as exc:
        evaluate.main(["--env", SWARM, "--out", str(tmp_path / "x"), "--no-progress", *extra])
    assert exc.value.code == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "x" / "episodes.csv").exists()


def test_evaluate_py_flies_teams_of_other_rules_on_one_reconfiguration_field(
    evaluate, tmp_path, capsys
):
    """The rules give the chasers other slots (each view's dock), on the same field."""
    out = tmp_path / "eval"
    status = evaluate.main([
        "--env", "DebrisGym/Reconfigure2D-v0", "--max-steps", "3", "--episodes", "1",
        "--no-progress", "--out", str(out), "--agents", "team-zero@balanced,team-zero@minmax",
    ])  # fmt: skip
    assert status == 0, capsys.readouterr().err
    with open(out / "episodes.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and rows[0]["field"] == rows[1]["field"]
    assert rows[0]["assignment_targets"] != rows[1]["assignment_targets"]
