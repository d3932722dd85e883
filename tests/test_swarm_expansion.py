"""Tests of the multi-agent spherical expansion (agents.planners.swarm_expansion) against truths
computed here: straight-line distances, a hand-computed shortest-path bound through a gap in a
wall of circles, sphere clearances in closed form, and brute-force assignments."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import dijkstra

from agents.planners.spherical_expansion import ExpansionParams
from agents.planners.swarm_expansion import SwarmGraphs, SwarmParams
from agents.planners.swarm_exploration import compare_sharing, explore
from agents.planners.team_assignment import assign_goals


class Spheres:
    """A field of circles / spheres, the clearance in closed form: |p − c| − r."""

    def __init__(self, centers, radii, dim: int = 2) -> None:
        self.centers = np.asarray(centers, float).reshape(-1, dim)
        self.radii = np.asarray(radii, float).reshape(-1)
        self.dim = dim
        self.n_bodies = len(self.radii)

    def signed_distance(self, points):
        pts = np.asarray(points, float).reshape(-1, self.dim)
        return np.linalg.norm(pts[:, None] - self.centers[None], axis=-1) - self.radii[None]


def _segment_gap(a, b, c) -> float:
    """Distance (m) from point c to the segment a–b."""
    ab = b - a
    t = np.clip(np.dot(c - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(a + t * ab - c))


def _params(**kwargs) -> SwarmParams:
    expansion = {"goal_bias": 0.0, "max_nodes": 5000, "narrow_cost": 0.0, "min_overlap": 0.5}
    expansion.update(kwargs.pop("expansion", {}))
    return SwarmParams(
        **{"r_col": 2.0, "r_max": 8.0, **kwargs}, expansion=ExpansionParams(**expansion)
    )


BOX = (np.array([-100.0, -100.0]), np.array([100.0, 100.0]))


# --- graphs and paths against independent truth ----------------------------------------------


@pytest.mark.parametrize("seed", range(4))
def test_an_empty_box_path_costs_at_least_the_straight_line_and_at_most_a_third_more(seed):
    """Edge costs are centre distances (``narrow_cost`` 0), so a path can never be shorter
    than the straight line (triangle inequality); the chain of steered spheres in free space
    zigzags by little: the bound 4/3 leaves room (the largest ratio over 30 seeds was 1.10)."""
    field = Spheres(np.zeros((0, 2)), np.zeros(0))
    starts = np.array([[-90.0, -90.0], [-90.0, -60.0], [-60.0, -90.0]])
    goals = np.array([[90.0, 90.0], [90.0, 60.0], [60.0, 90.0]])
    found = explore(
        field, starts, goals, np.zeros(0), np.random.default_rng(seed), _params(),
        low=BOX[0], high=BOX[1],
    )  # fmt: skip
    assert found.connected
    straight = np.linalg.norm(starts[:, None] - goals[None], axis=-1)
    assert np.all(found.costs >= straight - 1e-9)
    assert np.all(found.costs <= 4.0 / 3.0 * straight)


def _wall(gap_center: float, gap_half: float):
    """Circles of radius 12 m every 20 m on the line x = 0 (they overlap), none whose centre
    lies within ``gap_half`` of ``gap_center``."""
    ys = np.arange(-100.0, 100.1, 20.0)
    ys = ys[np.abs(ys - gap_center) >= gap_half]
    return Spheres(np.c_[np.zeros_like(ys), ys], np.full(len(ys), 12.0)), ys


def _bound_through_gaps(start, goal, ys, reach: float) -> float:
    """The least length of any curve from ``start`` (x < 0) to ``goal`` (x > 0) that crosses
    x = 0 at a point farther than ``reach`` from every circle centre (the free part of the
    line): the crossing height y minimises |start − (0, y)| + |(0, y) − goal|, a convex
    function of y, over each free interval: the straight crossing clamped to the interval."""
    lo, hi = BOX[0][1], BOX[1][1]
    blocked = sorted((y - reach, y + reach) for y in ys)
    free, edge = [], lo
    for a, b in blocked:
        if a > edge:
            free.append((edge, min(a, hi)))
        edge = max(edge, b)
    if edge < hi:
        free.append((edge, hi))
    # the straight line's crossing height
    t = -start[0] / (goal[0] - start[0])
    y_star = start[1] + t * (goal[1] - start[1])
    best = math.inf
    for a, b in free:
        p = np.array([0.0, float(np.clip(y_star, a, b))])
        best = min(best, float(np.linalg.norm(start - p) + np.linalg.norm(p - goal)))
    return best


@pytest.mark.parametrize("seed", range(3))
def test_a_path_through_a_wall_of_circles_is_no_shorter_than_the_route_through_its_gap(seed):
    margin = 2.0
    field, ys = _wall(gap_center=50.0, gap_half=25.0)
    starts = np.array([[-80.0, -80.0], [-80.0, -40.0]])
    goals = np.array([[80.0, -80.0], [80.0, -40.0]])
    margins = np.full(field.n_bodies, margin)
    found = explore(
        field, starts, goals, margins, np.random.default_rng(seed), _params(max_iterations=600),
        low=BOX[0], high=BOX[1],
    )  # fmt: skip
    assert found.connected
    for i, j in itertools.product(range(2), range(2)):
        bound = _bound_through_gaps(starts[i], goals[j], ys, 12.0 + margin)
        assert found.costs[i, j] >= bound - 1e-6
        # the straight line is blocked, so the bound is a real detour
        assert bound > np.linalg.norm(starts[i] - goals[j]) + 1.0
    chain, _ = found.graphs.chain_to(0, 0)
    assert chain.success
    for a, b in itertools.pairwise(chain.centers):
        for c in field.centers:
            assert _segment_gap(a, b, c) >= 12.0 + margin - 1e-6


def test_every_node_radius_is_the_body_clearance_cut_by_the_teammates_spheres():
    field = Spheres([[0.0, 0.0], [40.0, -50.0]], [20.0, 10.0])
    starts = np.array([[-70.0, -70.0], [-40.0, -70.0], [-70.0, -40.0]])
    goals = np.array([[70.0, 70.0], [40.0, 70.0], [70.0, 40.0]])
    margins = np.array([1.5, 3.0])
    p = _params()
    graphs = SwarmGraphs(field, starts, goals, margins, p, low=BOX[0], high=BOX[1])
    rng = np.random.default_rng(1)
    for _ in range(20):
        graphs.iterate(rng)
    pts = graphs.centers
    walls = np.minimum(pts - BOX[0], BOX[1] - pts).min(axis=1)
    bodies = np.linalg.norm(pts[:, None] - field.centers[None], axis=-1) - field.radii - margins
    clearance = np.minimum(bodies.min(axis=1), walls)
    for i in range(3):
        others = np.delete(starts, i, axis=0)
        mates = np.linalg.norm(pts[:, None] - others[None], axis=-1).min(axis=1)
        truth = np.minimum(clearance, mates - (p.r_col + p.r_max))
        np.testing.assert_allclose(graphs.radii(i), truth, atol=1e-9)
        # a node the agent drew itself is at least min_radius clear in its own graph
        own = np.flatnonzero(graphs.known(i))[5:]  # past the goals and the start
        assert np.all(graphs.radii(i, own) >= p.expansion.min_radius - 1e-9)


def test_a_chain_keeps_out_of_the_teammates_spheres():
    field = Spheres(np.zeros((0, 2)), np.zeros(0))
    starts = np.array([[-80.0, 0.0], [0.0, 0.0], [0.0, 60.0]])
    goals = np.array([[80.0, 0.0], [0.0, -80.0], [-60.0, 80.0]])
    p = _params(r_max=20.0)
    found = explore(field, starts, goals, np.zeros(0), np.random.default_rng(3), p,
                    low=BOX[0], high=BOX[1])  # fmt: skip
    assert found.connected
    chain, _ = found.graphs.chain_to(0, 0)  # right through agent 1's position
    assert chain.success
    for a, b in itertools.pairwise(chain.centers):
        for other in starts[1:]:
            assert _segment_gap(a, b, other) >= p.r_col + p.r_max - 1e-6


_EXPLORED: dict[int, SwarmGraphs] = {}


def _explored_field(seed: int) -> SwarmGraphs:
    """Four agents explored to connection among five circles (cached per seed)."""
    if seed not in _EXPLORED:
        field = Spheres([[0.0, 0.0], [50.0, 40.0], [-45.0, 50.0], [40.0, -50.0], [-50.0, -40.0]],
                        [25.0, 15.0, 15.0, 12.0, 12.0])  # fmt: skip
        starts = np.array([[-85.0, -85.0], [85.0, -85.0], [-85.0, 85.0], [85.0, 85.0]])
        goals = starts[::-1] * 0.9
        p = _params(r_max=4.0, expansion={"narrow_cost": 2.0})
        found = explore(field, starts, goals, np.full(5, 2.0), np.random.default_rng(seed), p,
                        low=BOX[0], high=BOX[1])  # fmt: skip
        for _ in range(40):  # a denser pool than the first connection gives
            found.graphs.iterate(np.random.default_rng(seed + 1))
        _EXPLORED[seed] = found.graphs
    return _EXPLORED[seed]


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2),
    agent=st.integers(0, 3),
    goal=st.integers(0, 3),
    moves=st.lists(st.floats(-60.0, 60.0), min_size=8, max_size=8),
)
def test_the_chain_to_a_goal_is_the_least_chain_of_the_whole_graph(seed, agent, goal, moves):
    """:meth:`SwarmGraphs.chain_to` searches an ellipsoid around the agent and its goal first;
    its chain must cost what Dijkstra finds in the agent's whole graph (no region), for agents
    moved anywhere (their spheres cutting the pool), and fail exactly when that does."""
    graphs = _explored_field(seed)
    starts = graphs.centers[graphs.start_nodes]
    graphs.move(np.clip(starts + np.reshape(moves, (4, 2)), -95.0, 95.0))
    chain, _ = graphs.chain_to(agent, goal)
    floor = graphs.params.expansion.min_radius
    target = int(graphs.goal_nodes[goal])
    whole = graphs.graph(agent, {target: floor}, graphs.positions[agent], floor)
    dist = dijkstra(whole.adjacency, indices=whole.n_nodes - 1)
    assert chain.success == bool(np.isfinite(dist[target]))
    if chain.success:
        assert chain.cost == pytest.approx(dist[target], rel=1e-9)


def test_an_agent_that_has_arrived_is_a_sphere_of_the_parked_radius():
    """r_max is the distance an agent travels per step: a parked agent's sphere is
    ``parked_radius``, the flying ones' r_col + r_max, both cut to ``min_radius`` short of a
    teammate already closer (closed form here), and a node's radius is its gap to them."""
    field = Spheres(np.zeros((0, 2)), np.zeros(0))
    starts = np.array([[0.0, 0.0], [30.0, 0.0], [0.0, 30.0], [0.0, 5.0]])
    goals = np.array([[80.0, 80.0], [-80.0, 80.0], [80.0, -80.0], [-80.0, -80.0]])
    p = _params(r_max=4.0, parked_radius=3.0)  # r_col 2: flying spheres 6 m
    graphs = SwarmGraphs(field, starts, goals, np.zeros(0), p, low=BOX[0], high=BOX[1])
    assert graphs.teammate_radii(0).tolist() == [0.0, 6.0, 6.0, 4.0]  # 5 m away, less 1 m
    graphs.move(starts, parked=np.array([False, True, False, True]))
    assert graphs.teammate_radii(0).tolist() == [0.0, 3.0, 6.0, 3.0]
    point = np.array([[15.0, 0.0]])
    gap = min(15.0 - 3.0, math.hypot(15.0, 30.0) - 6.0, math.hypot(15.0, 5.0) - 3.0)
    assert graphs._teammate_gap(0, point)[0] == pytest.approx(gap)
    with pytest.raises(ValueError, match="parked"):
        graphs.move(starts, parked=np.ones(3, dtype=bool))


def test_nodes_are_shared_one_iteration_later_and_only_when_sharing():
    field = Spheres(np.zeros((0, 2)), np.zeros(0))
    starts = np.array([[-80.0, -80.0], [80.0, -80.0]])
    goals = np.array([[-80.0, 80.0], [80.0, 80.0]])
    for share in (True, False):
        graphs = SwarmGraphs(field, starts, goals, np.zeros(0), _params(share_nodes=share),
                             low=BOX[0], high=BOX[1])  # fmt: skip
        rng = np.random.default_rng(0)
        graphs.iterate(rng)
        first = np.arange(4, graphs.n_nodes)  # after 2 goals and 2 starts
        assert graphs.nodes_per_agent().tolist() == [4, 4]  # own start, both goals, own node
        graphs.iterate(rng)
        for i in range(2):
            other = first[graphs.owners[first] != i]
            assert graphs.known(i)[other].all() == share


def test_node_sharing_needs_fewer_iterations_than_exploring_alone():
    """Mean over 20 seeds of the iterations until every graph connects its start to every
    goal, 4 agents: with sharing each agent gains 3 nodes per iteration instead of 1, so it
    should connect in well under the iterations alone; the assertion asks only for at most
    3/4 of them (the censored runs alone, stopped at the cap, count as the cap: that can only
    lower the mean alone)."""
    field = Spheres([[0.0, 0.0], [50.0, 40.0], [-45.0, 50.0]], [30.0, 15.0, 15.0])
    starts = np.array([[-85.0, -85.0], [-45.0, -85.0], [-85.0, -45.0], [-45.0, -45.0]])
    angles = np.linspace(0.0, 2.0 * math.pi, 4, endpoint=False) + 0.4
    goals = 40.0 * np.c_[np.cos(angles), np.sin(angles)]
    p = _params(max_iterations=200, expansion={"narrow_cost": 2.0})
    shared, alone = [], []
    for seed in range(20):
        both = compare_sharing(field, starts, goals, np.full(3, 2.0), seed, p,
                               low=BOX[0], high=BOX[1])  # fmt: skip
        assert both.shared.connected
        shared.append(both.shared.iterations)
        alone.append(both.alone.iterations)
    assert np.mean(shared) <= 0.75 * np.mean(alone)


def _tight_lattice_case():
    """Seven 3D agents on a planar hexagonal lattice of pitch 2 (r_col + r_max) = 12 m (the
    Reconfigure IDs' dock pitch) in a 1 000 m box, their goals on a ring 400 m away: each start's
    free sphere is 6 m, so no other agent places a node within 6 m of it."""
    ring = np.r_[[[0.0, 0.0, 0.0]], [[12 * math.cos(a), 12 * math.sin(a), 0.0]
                                     for a in np.arange(6) * math.pi / 3]]  # fmt: skip
    starts = ring - [400.0, 0.0, 0.0]
    angles = np.arange(7) * 2 * math.pi / 7
    goals = np.c_[40 * np.cos(angles), 40 * np.sin(angles), np.zeros(7)]
    field = Spheres([[0.0, 0.0, 0.0], [-200.0, 0.0, 150.0]], [20.0, 60.0], dim=3)
    low, high = np.full(3, -500.0), np.full(3, 500.0)
    return field, starts, goals, low, high


@pytest.mark.parametrize("seed", range(3))
def test_a_local_bias_connects_a_tight_lattice_that_uniform_samples_leave_stranded(seed):
    """Uniform samples in a 1 000 m box almost never fall within reach of a start whose free
    sphere is 6 m; with half of a stranded agent's samples drawn near its start every graph
    connects (checked by Dijkstra on each agent's own graph), and stays out of the spheres."""
    field, starts, goals, low, high = _tight_lattice_case()
    margins = np.full(2, 1.0)
    base = _params(r_max=4.0, max_iterations=150, expansion={"narrow_cost": 2.0})
    stranded = explore(field, starts, goals, margins, np.random.default_rng(seed), base,
                       low=low, high=high)  # fmt: skip
    assert not stranded.connected
    biased = explore(field, starts, goals, margins, np.random.default_rng(seed),
                     dataclasses.replace(base, local_bias=0.5), low=low, high=high)  # fmt: skip
    assert biased.connected
    assert np.isfinite(biased.costs).all()
    g = biased.graphs
    for i in range(len(starts)):
        mine = np.flatnonzero(g.owners == i)
        others = np.delete(starts, i, axis=0)
        gaps = np.linalg.norm(g.centers[mine][:, None] - others[None], axis=-1)
        assert gaps.min() >= g.params.teammate_radius + g.params.expansion.min_radius - 1e-9


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), agent=st.integers(0, 6))
def test_local_biased_samples_lie_in_the_ball_around_the_start_and_in_the_bounds(seed, agent):
    field, starts, goals, low, high = _tight_lattice_case()
    high = high.copy()
    high[2] = 3.0  # a bound that cuts the ball: samples are clipped into the box
    p = dataclasses.replace(_params(r_max=4.0), local_bias=1.0)
    g = SwarmGraphs(field, starts, goals, np.full(2, 1.0), p, low=low, high=high)
    rng = np.random.default_rng(seed)
    points = np.array([g._local_sample(agent, rng) for _ in range(20)])
    reach = 3.0 * p.teammate_radius
    assert np.all(np.linalg.norm(points - starts[agent], axis=1) <= reach + 1e-9)
    assert np.all((points >= low) & (points <= high))


def test_an_agent_whose_chain_fails_samples_near_its_position_and_its_goal_until_it_has_one():
    field, starts, goals, low, high = _tight_lattice_case()
    p = dataclasses.replace(_params(r_max=4.0), local_bias=1.0)
    g = SwarmGraphs(field, starts, goals, np.full(2, 1.0), p, low=low, high=high)
    g.reached[:] = True  # as after a connected exploration: only a failed chain makes samples local
    g.assigned = np.arange(7)
    g.move(starts + np.array([0.0, 0.0, 30.0]))
    chain, _ = g.chain_to(3, 3)  # nothing but the starts and the goals yet: no path
    assert not chain.success and g.stranded[3] and not g.stranded[2]
    rng = np.random.default_rng(5)
    reach = 3.0 * p.teammate_radius
    points = np.array([g._local_sample(3, rng) for _ in range(200)])
    near = np.minimum(np.linalg.norm(points - g.positions[3], axis=1),
                      np.linalg.norm(points - goals[3], axis=1))  # fmt: skip
    assert np.all(near <= reach + 1e-9)
    for _ in range(400):
        g.iterate(rng)
        if g.chain_to(3, 3)[0].success:
            break
    assert not g.stranded[3]


# --- assignment ---------------------------------------------------------------------------------


def _brute_force(costs: np.ndarray) -> float:
    n = len(costs)
    return min(sum(costs[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))


@settings(max_examples=80, deadline=None)
@given(
    st.integers(1, 6).flatmap(
        lambda n: st.lists(
            st.one_of(st.floats(0.0, 1e4, allow_nan=False), st.just(math.inf)),
            min_size=n * n,
            max_size=n * n,
        ).map(lambda v: np.array(v).reshape(n, n))
    )
)
def test_the_hungarian_assignment_totals_the_brute_force_optimum(costs):
    goal, total = assign_goals(costs)
    assert sorted(goal.tolist()) == list(range(len(costs)))
    assert total == pytest.approx(float(costs[np.arange(len(costs)), goal].sum()))
    best = _brute_force(costs)
    if math.isinf(best):
        assert math.isinf(total)
    else:
        assert total == pytest.approx(best, rel=1e-9, abs=1e-6)


# --- bad input ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [({"r_col": -1.0}, "r_col"), ({"r_max": math.nan}, "r_max"), ({"r_col": True}, "r_col"),
     ({"max_iterations": 0}, "max_iterations"), ({"share_nodes": 1}, "share_nodes"),
     ({"local_bias": 1.5}, "local_bias"), ({"local_bias": math.nan}, "local_bias"),
     ({"parked_radius": -1.0}, "parked_radius"), ({"parked_radius": math.inf}, "parked_radius")],
)  # fmt: skip
def test_bad_parameters_raise_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SwarmParams(**{"r_col": 2.0, "r_max": 5.0, **kwargs})


@pytest.mark.parametrize(
    ("starts", "goals", "name"),
    [
        ([[0.0, 0.0], [10.0, 0.0]], [[50.0, 0.0]], "goals"),
        ([[0.0, math.nan]], [[50.0, 0.0]], "starts"),
        ([[0.0, 0.0]], [[math.inf, 0.0]], "goals"),
        ([[0.0, 0.0, 0.0]], [[5.0, 0.0, 0.0]], "starts"),
    ],
)
def test_bad_agents_raise_naming_the_parameter(starts, goals, name):
    field = Spheres(np.zeros((0, 2)), np.zeros(0))
    with pytest.raises(ValueError, match=name):
        SwarmGraphs(field, starts, goals, np.zeros(0), _params(), low=BOX[0], high=BOX[1])


@pytest.mark.parametrize("costs", [np.ones((2, 3)), np.array([[1.0, math.nan], [0.0, 1.0]]),
                                   -np.ones((2, 2))])  # fmt: skip
def test_bad_costs_raise(costs):
    with pytest.raises(ValueError, match="costs"):
        assign_goals(costs)
