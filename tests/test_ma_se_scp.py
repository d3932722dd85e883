"""Tests of the "ma-se-scp" team (agents.policies.ma_se_scp) and its place in the swarm
evaluation: the teammate spheres in closed form, a re-plan per decision, bad parameters, and
the team name and connectivity lines of the report."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from agents.experiments.swarm_evaluation.report import exploration_lines
from agents.experiments.swarm_evaluation.teams import make_team, parse_teams
from agents.planners.spherical_expansion import SphereChain
from agents.policies.ma_se_scp import MASESCPTeam, TeammateSpheres
from agents.policies.se_scp import SESCPAgent
from agents.policies.team import start_episode
from debris_gym import swarm


class _Field:
    dim, n_bodies = 2, 1

    def signed_distance(self, points):
        pts = np.asarray(points, float).reshape(-1, 2)
        return np.linalg.norm(pts - [100.0, 0.0], axis=1, keepdims=True) - 10.0


def test_teammate_spheres_add_one_closed_form_column_per_teammate():
    mates = np.array([[0.0, 0.0], [30.0, 40.0]])
    spheres = TeammateSpheres(_Field(), mates, np.array([5.0, 12.0]))
    points = np.array([[0.0, 10.0], [60.0, 80.0], [100.0, 20.0]])
    out = spheres.signed_distance(points)
    assert spheres.n_bodies == 3 and out.shape == (3, 3)
    for p, row in zip(points, out, strict=True):
        assert row[0] == pytest.approx(np.hypot(p[0] - 100.0, p[1]) - 10.0)
        assert row[1] == pytest.approx(np.hypot(*p) - 5.0)
        assert row[2] == pytest.approx(np.hypot(p[0] - 30.0, p[1] - 40.0) - 12.0)


def _env(**kwargs):
    return swarm.make("DebrisGym/Swarm2D-Easy-v0", debris_motion="frozen", **kwargs)


def test_every_flying_chaser_replans_at_every_decision_and_the_pair_stays_apart():
    env = _env(return_to_dock=True)
    team = MASESCPTeam(env)
    observations, _, _ = start_episode(env, team, 0)
    decisions = dict.fromkeys(team.agents, 0)
    for _ in range(12):
        actions = team.predict({a: observations[a] for a in env.agents})
        for agent, action in actions.items():
            assert np.all(np.abs(action) <= 1.0)
            decisions[agent] += 1
        observations, *_ = env.step(actions)
    assert min(decisions.values()) == 12  # both chasers have a target (the balanced rule)
    for agent, member in zip(team.agents, team.members, strict=True):
        assert member.stats["plans"] == decisions[agent]
    r_col = 2.0 * env.core.config.chaser_radius
    assert float(env.core.min_separation()[0]) > r_col
    # the chasers' goals are their starts (dock slots): nothing to explore
    assert team.last_exploration is None
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [({"replan_every": 0}, "replan_every"), ({"r_max": -1.0}, "r_max"),
     ({"rule": "fastest"}, "rule"), ({"seed": -1}, "seed"), ({"local_bias": 2.0}, "local_bias"),
     ({"flight_pool": -1}, "flight_pool"), ({"flight_pool": 1.5}, "flight_pool"),
     ({"detour": 0.9}, "detour"), ({"detour": math.inf}, "detour")],
)  # fmt: skip
def test_bad_team_parameters_raise_naming_them(kwargs, name):
    env = _env()
    with pytest.raises(ValueError, match=name):
        MASESCPTeam(env, **kwargs)
    env.close()


def test_a_swarm_without_given_assignments_is_refused():
    env = swarm.make("DebrisGym/Swarm2D-v0", debris_motion="frozen", assignment="free")
    with pytest.raises(ValueError, match="assignment='given'"):
        MASESCPTeam(env)
    env.close()


def test_the_evaluation_names_and_builds_the_team():
    specs = parse_teams("ma-se-scp,ma-se-scp@greedy,team-zero")
    assert [s.label for s in specs] == [
        "ma-se-scp@balanced",
        "ma-se-scp@greedy",
        "team-zero@balanced",
    ]
    with pytest.raises(ValueError, match="rule"):
        parse_teams("ma-se-scp@fastest")
    env = _env()
    team = make_team(specs[1], env)
    assert isinstance(team, MASESCPTeam) and team.rule == "greedy"
    env.close()


def test_the_report_states_both_connectivity_figures_beside_the_paper():
    entry = {"exploration": {
        "episodes": 2, "agents": 6, "r_col": 2.0, "r_max": 10.0,
        "iterations_shared_mean": 31.5, "iterations_shared_max": 40, "connected_shared": 2,
        "runs_shared": 2, "nodes_shared_mean": 180.0,
        "iterations_alone_mean": 300.0, "iterations_alone_max": 300, "connected_alone": 0,
        "runs_alone": 2, "nodes_alone_mean": 250.0,
    }}  # fmt: skip
    (line,) = exploration_lines({"ma-se-scp@optimal": entry, "team-zero@balanced": {}})
    assert "with sharing 31.5" in line and "without 300" in line
    assert "connected in 0/2" in line and "N = 48: 25" in line


def test_a_moving_field_falls_back_to_the_bodies_alone_with_their_own_margins(monkeypatch):
    """When no chain clears the teammates in a moving field, the "se-scp" chain among the
    bodies alone is flown: its margins are one per body (not the teammate-extended ones)."""
    env = swarm.make("DebrisGym/Swarm2D-Easy-v0")
    team = MASESCPTeam(env)
    observations, _, _ = start_episode(env, team, 0)
    calls = []
    original = SESCPAgent.sphere_chain

    def failing_with_teammates(self, start, goal, geometry, margins, *rest):
        calls.append((geometry.n_bodies, len(margins)))
        if isinstance(geometry, TeammateSpheres):
            d = len(start)
            return SphereChain(False, np.zeros(0, int), np.zeros((0, d)), np.zeros(0), np.inf), 2
        return original(self, start, goal, geometry, margins, *rest)

    monkeypatch.setattr(SESCPAgent, "sphere_chain", failing_with_teammates)
    team.predict({a: observations[a] for a in env.agents})
    assert len(calls) == 4  # two chasers, each: with teammates, then alone
    assert all(bodies == margins for bodies, margins in calls)
    assert [m.stats["teammate_fallbacks"] for m in team.members] == [1, 1]
    env.close()


def _chain_is_free(chain, geometry, margins, mates, teammate_radius):
    """Every sphere of ``chain`` clear of the bodies (closed-form signed distances less the
    margins) and of the teammates' spheres, and every two consecutive spheres overlapping."""
    gaps = geometry.signed_distance(chain.centers) - margins[None]
    assert np.all(gaps.min(axis=1) >= chain.radii - 1e-6)
    if len(mates):
        apart = np.linalg.norm(chain.centers[:, None] - mates[None], axis=-1) - teammate_radius
        # the first sphere is the chaser's own position, the last its slot: they may be given
        # a floor radius inside a teammate's sphere, the others are free of them
        assert np.all(apart[1:-1].min(axis=1) >= chain.radii[1:-1] - 1e-6)
    steps = np.linalg.norm(np.diff(chain.centers, axis=0), axis=1)
    assert np.all(steps < chain.radii[:-1] + chain.radii[1:])


@pytest.mark.parametrize("seed", range(4))
def test_the_exploration_connects_six_chasers_on_the_reconfigure_dock_lattice(seed):
    """The Reconfigure IDs' dock slots are 12 m apart = 2 (r_col + r_max) with the team's
    cruise: uniform samples in the 1 000 m field alone left a start stranded within 300
    iterations; with the local samples every graph connects, the slots go by the graphs'
    path costs, and every chaser's chain to its slot keeps clear of the bodies and of the
    other chasers' spheres."""
    env = swarm.make("DebrisGym/Reconfigure3D-v0")
    team = MASESCPTeam(env, measure_alone=False)
    start_episode(env, team, seed)
    team.predict({})  # the episode starts: the prepared graphs are taken over
    record = team.last_exploration
    assert record is not None and record.connected_shared
    assert record.r_max == pytest.approx(4.0) and record.iterations_shared < 300
    graphs = team.graphs
    assert graphs is not None and graphs.assigned is not None
    view = team.views[0]
    cfg = view.config
    margins = np.full(view.geometry.n_bodies, cfg.chaser_radius + 0.002 * view.scenario.size)
    # an arrived chaser stands still: r_col and the bodies' keep-out
    assert graphs.params.parked_radius == pytest.approx(2.0 + 0.002 * view.scenario.size)
    for k in range(env.core.chasers):
        chain, _ = graphs.chain_to(k, int(graphs.assigned[k]))
        assert chain.success
        mates = np.delete(graphs.positions, k, axis=0)
        _chain_is_free(chain, view.geometry, margins, mates, graphs.params.teammate_radius)
    env.close()


@pytest.mark.parametrize(("pool", "expect_growth"), [(0, False), (None, True), (10**6, True)])
def test_in_flight_every_chaser_grows_the_graphs_until_the_pool_is_full(pool, expect_growth):
    """At the first decisions after the exploration every chain to a slot exists (no chaser
    is stranded): below ``flight_pool`` (or without one: the paper) every flying chaser draws
    a sample; past it only stranded chasers would, so the pool stays as explored."""
    env = swarm.make("DebrisGym/Reconfigure3D-v0")
    team = MASESCPTeam(env, measure_alone=False, flight_pool=pool)
    observations, _, _ = start_episode(env, team, 0)
    team.predict({a: observations[a] for a in env.agents})
    graphs = team.graphs
    assert graphs is not None and not graphs.stranded.any()
    explored = graphs.n_nodes
    observations, *_ = env.step(team.predict({a: observations[a] for a in env.agents}))
    grown = graphs.n_nodes - explored
    if expect_growth:
        assert 0 < grown <= env.core.chasers
    else:
        assert grown == 0 and not graphs.stranded.any()
    env.close()


@pytest.mark.parametrize("expansion", [True, False])
def test_a_chaser_its_graph_strands_grows_its_own_chain_among_the_teammates(monkeypatch, expansion):
    """When the shared graph holds no chain from chaser 0 to its slot, it plans with a
    spherical expansion from its position among the bodies and its teammates' spheres (the
    chain checked against the closed-form signed distances), or holds when that is off."""
    env = swarm.make("DebrisGym/Reconfigure3D-v0")
    team = MASESCPTeam(env, measure_alone=False, stranded_expansion=expansion, detour=None)
    observations, _, _ = start_episode(env, team, 1)
    team.predict({})  # the prepared graphs are taken over
    graphs = team.graphs
    assert graphs is not None
    original_chain_to = type(graphs).chain_to

    def strand_chaser_zero(self, agent, goal, floor=None):
        chain, nodes = original_chain_to(self, agent, goal, floor)
        if agent != 0:
            return chain, nodes
        self.stranded[agent] = True
        d = self.dim
        return SphereChain(False, np.zeros(0, int), np.zeros((0, d)), np.zeros(0), np.inf), nodes

    grown = []
    original_sphere_chain = SESCPAgent.sphere_chain

    def recording(self, start, goal, geometry, margins, *rest):
        chain, nodes = original_sphere_chain(self, start, goal, geometry, margins, *rest)
        grown.append((self.team.members.index(self), chain, geometry, margins))
        return chain, nodes

    monkeypatch.setattr(type(graphs), "chain_to", strand_chaser_zero)
    monkeypatch.setattr(SESCPAgent, "sphere_chain", recording)
    team.predict({a: observations[a] for a in env.agents})
    zero = team.members[0]
    others = team.members[1:]
    assert all("own_expansions" not in m.stats and "holds" not in m.stats for m in others)
    if not expansion:
        assert zero.stats.get("holds") == 1 and "own_expansions" not in zero.stats
        assert grown == []
        env.close()
        return
    assert zero.stats["own_expansions"] == 1 and "holds" not in zero.stats
    ((who, chain, spheres, margins),) = grown
    assert who == 0 and chain.success and len(chain.radii) >= 2
    mates = np.delete(team.positions(), 0, axis=0)
    assert isinstance(spheres, TeammateSpheres) and np.allclose(spheres.centers, mates)
    view = team.views[0]
    body_margins = margins[: view.geometry.n_bodies]
    _chain_is_free(chain, view.geometry, body_margins, mates, graphs.params.teammate_radius)
    slot = graphs.centers[graphs.goal_nodes[graphs.assigned[0]]]
    assert np.allclose(chain.centers[-1], slot)
    assert np.allclose(chain.centers[0], view.chaser_state[:3])
    env.close()


def test_the_flight_script_reports_every_step_it_is_asked_for(capsys):
    """docs/swarm_flight.py: a line per ``--every`` steps with the distance to the slots, then
    the outcome line."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "docs" / "swarm_flight.py"
    spec = importlib.util.spec_from_file_location("swarm_flight", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--env", "DebrisGym/Reconfigure2D-v0", "--chasers", "3", "--seed", "0",
                 "--steps", "4", "--every", "2"])  # fmt: skip
    lines = capsys.readouterr().out.splitlines()
    steps = [line for line in lines if line.startswith("step ")]
    assert [line.split(":")[0] for line in steps] == ["step 2", "step 4"]
    assert all("to slot mean" in line for line in steps)
    assert lines[-1].startswith("team success False, reconfigured 0/3, steps 4")
    with pytest.raises(SystemExit):
        module.main(["--every", "0"])


@pytest.mark.parametrize("detour", [1.0, None])
def test_a_chaser_whose_graph_chain_detours_also_grows_its_own_and_flies_the_cheaper(
    monkeypatch, detour
):
    """With ``detour`` the chasers whose graph chain costs more than ``detour`` times the
    straight distance to the slot plus 4 (r_col + r_max) (computed here from the graphs) grow
    a chain of their own among their teammates' spheres; the cheaper one is flown and it keeps
    clear of the bodies and the teammates. Without it nobody does."""
    env = swarm.make("DebrisGym/Reconfigure3D-v0")
    team = MASESCPTeam(env, measure_alone=False, detour=detour)
    observations, _, _ = start_episode(env, team, 0)
    team.predict({})
    graphs = team.graphs
    assert graphs is not None and graphs.assigned is not None
    rho = graphs.params.teammate_radius
    detouring = set()
    for k in range(env.core.chasers):
        chain, _ = graphs.chain_to(k, int(graphs.assigned[k]))
        slot = graphs.centers[graphs.goal_nodes[graphs.assigned[k]]]
        straight = float(np.linalg.norm(slot - graphs.positions[k]))
        if chain.success and chain.cost > 1.0 * straight + 4.0 * rho:
            detouring.add(k)
    assert detouring  # the dock lattice's chains leave by the exits the exploration found
    grown = {}
    original = SESCPAgent.sphere_chain

    def recording(self, start, goal, geometry, margins, *rest):
        chain, nodes = original(self, start, goal, geometry, margins, *rest)
        grown[self.team.members.index(self)] = (chain, geometry, margins)
        return chain, nodes

    monkeypatch.setattr(SESCPAgent, "sphere_chain", recording)
    team.predict({a: observations[a] for a in env.agents})
    if detour is None:
        assert grown == {} and all("detours" not in m.stats for m in team.members)
        env.close()
        return
    assert set(grown) == detouring
    view = team.views[0]
    for k, (chain, _, margins) in grown.items():
        member = team.members[k]
        assert member.stats["detours"] == 1
        if chain.success:
            mates = np.delete(team.positions(), k, axis=0)
            body_margins = margins[: view.geometry.n_bodies]
            _chain_is_free(chain, view.geometry, body_margins, mates, rho)
    env.close()


STRAGGLERS = Path(__file__).parent / "data" / "reconfigure3d_48_seed3_stragglers.npy"


def _fly_stragglers(steps: int, **team_kwargs) -> tuple[bool, float, float]:
    """The 48-chaser reconfiguration of seed 3 restarted where, without thinned chains, two
    chasers stood still 26 m and 14 m short of their slots among 46 parked teammates.

    Returns:
        team success, min inter-chaser separation (m) and r_col (m).
    """
    env = swarm.make("DebrisGym/Reconfigure3D-v0", n_chasers=48, assignment="given")
    team = MASESCPTeam(env, measure_alone=False, **team_kwargs)
    env.reset(seed=3)
    chosen = team.choose_assignment()
    states = np.load(STRAGGLERS)
    observations, _ = env.reset(
        seed=3, options={"assignment": chosen.targets(), "chaser_state": states}
    )
    for _ in range(steps):
        if not env.agents:
            break
        observations, *_ = env.step(team.predict({a: observations[a] for a in env.agents}))
    r_col = 2.0 * env.core.config.chaser_radius
    return bool(env.core.team_success()[0]), float(env.core.min_separation()[0]), r_col


def test_two_stragglers_among_parked_teammates_reach_their_slots():
    # 46 chasers start inside their slots' capture radius and end at once; chasers 0 and 25
    # each have a free straight line to their slot but a chain of 8 and 14 spheres
    success, separation, r_col = _fly_stragglers(60)
    assert success
    assert separation >= r_col
