"""Tests of the spherical-expansion graph (agents.planners.spherical_expansion): every sphere
radius against an independent clearance (pymunk in 2D, closed-form spheres in 3D), edges exactly
where the spheres overlap enough, and the chain against a Floyd–Warshall search typed here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.planners.spherical_expansion import (
    ExpansionParams,
    SphereChain,
    chain_waypoints,
    edge_cost,
    expand_spheres,
    joinable,
    shortest_chain,
    thin_chain,
)
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Body, Scenario
from tests.geometry_oracle import OracleField

KAPPA = math.cos(math.pi / 16)


def _field(dim: int = 2, bodies=None) -> Scenario:
    """A 600 m field with circles/spheres (and a square in 2D) between start and goal."""
    zero = (0.0,) * dim
    if bodies is None:
        bodies = [((0.0,) * dim, 60.0), ((120.0,) + (90.0,) * (dim - 1), 40.0)]
        if dim == 3:
            bodies.append(((-100.0, 80.0, -60.0), 30.0))
    obstacles = [Body(tuple(map(float, p)), float(r), zero) for p, r in bodies]
    if dim == 2:
        square = ((-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0))
        obstacles.append(Body((-120.0, 100.0), 20.0 * math.sqrt(2), zero, square))
    target = Body((250.0,) * dim, 5.0, zero)
    return Scenario(
        dim=dim, bounds=((-300.0, 300.0),) * dim, dock=(-250.0,) * dim, targets=(target,),
        obstacles=tuple(obstacles), mean_motion=0.0, dt=10.0, max_accel=0.05,
    )  # fmt: skip


def _oracle_radius(field: OracleField, scen: Scenario, point, margins) -> float:
    """Largest body-free sphere: least (gap − margin) over bodies and distance to the walls."""
    gaps = np.asarray(field.point_gaps(point)) - margins
    low = np.array([lo for lo, _ in scen.bounds])
    high = np.array([hi for _, hi in scen.bounds])
    walls = min(float(np.min(point - low)), float(np.min(high - point)))
    return min(float(gaps.min()), walls)


def _grow(scen: Scenario, seed: int = 0, **params):
    geometry = FieldGeometry(scen)
    margins = np.full(geometry.n_bodies, 3.0)
    start = np.array(scen.dock, float)
    goal = np.array(scen.targets[0].position, float) - 12.0
    options = {"polytope_factor": KAPPA, "max_nodes": 250, **params}
    graph = expand_spheres(
        geometry, start, goal, margins, np.random.default_rng(seed), ExpansionParams(**options),
        low=scen.low, high=scen.high,
    )  # fmt: skip
    return graph, margins


@pytest.mark.parametrize("dim", [2, 3])
def test_every_sphere_radius_is_the_true_clearance_minus_the_margin(dim):
    scen = _field(dim)
    graph, margins = _grow(scen)
    oracle = OracleField(scen)
    assert graph.n_nodes > 2
    for point, radius in zip(graph.centers, graph.radii, strict=True):
        assert radius == pytest.approx(_oracle_radius(oracle, scen, point, margins), abs=1e-6)


@settings(max_examples=30, deadline=None)
@given(
    xs=st.lists(st.floats(-200, 200), min_size=1, max_size=4),
    ys=st.lists(st.floats(-200, 200), min_size=4, max_size=4),
    rs=st.lists(st.floats(5, 50), min_size=4, max_size=4),
    seed=st.integers(0, 1000),
)
def test_sphere_radii_match_pymunk_on_random_circle_fields(xs, ys, rs, seed):
    bodies = [((x, y), r) for x, y, r in zip(xs, ys, rs)]
    scen = _field(2, bodies)
    graph, margins = _grow(scen, seed, max_nodes=60)
    oracle = OracleField(scen)
    for point, radius in zip(graph.centers[2:], graph.radii[2:], strict=True):
        expected = _oracle_radius(oracle, scen, point, margins)
        assert radius == pytest.approx(expected, abs=1e-6)
        assert radius >= 1.0  # min_radius: no node inside a margin


def test_edges_exist_exactly_between_spheres_that_overlap_enough():
    scen = _field(2)
    params = {"min_overlap": 0.5, "narrow_cost": 2.0}
    graph, _ = _grow(scen, **params)
    adjacency = graph.adjacency.toarray()
    c, r = graph.centers, graph.radii
    for i in range(graph.n_nodes):
        for j in range(graph.n_nodes):
            if i == j:
                continue
            dist = float(np.linalg.norm(c[i] - c[j]))
            should = dist <= KAPPA * (r[i] + r[j]) - 0.5
            assert (adjacency[i, j] > 0) == should, (i, j)
            if should:
                assert dist <= r[i] + r[j]  # the spheres overlap
                cost = dist * (1.0 + 2.0 / min(r[i], r[j]))
                assert adjacency[i, j] == pytest.approx(max(cost, 1e-9), rel=1e-12)


def _floyd_warshall(weights: np.ndarray) -> np.ndarray:
    """All-pairs shortest path lengths, the textbook triple loop (inf: no edge)."""
    dist = weights.copy()
    n = len(dist)
    for k in range(n):
        dist = np.minimum(dist, dist[:, k : k + 1] + dist[k : k + 1, :])
    return dist


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shortest_chain_matches_floyd_warshall(seed):
    scen = _field(2)
    graph, _ = _grow(scen, seed)
    chain = shortest_chain(graph)
    c, r = graph.centers, graph.radii
    weights = np.full((graph.n_nodes, graph.n_nodes), np.inf)
    np.fill_diagonal(weights, 0.0)
    for i in range(graph.n_nodes):
        for j in range(graph.n_nodes):
            dist = float(np.linalg.norm(c[i] - c[j]))
            if i != j and dist <= KAPPA * (r[i] + r[j]) - 0.5:
                weights[i, j] = dist * (1.0 + 2.0 / min(r[i], r[j]))
    best = _floyd_warshall(weights)[0, 1]
    assert chain.success == np.isfinite(best) == graph.connected
    assert chain.success
    assert chain.cost == pytest.approx(best, rel=1e-9)
    assert chain.nodes[0] == 0 and chain.nodes[-1] == 1
    walked = sum(weights[a, b] for a, b in zip(chain.nodes[:-1], chain.nodes[1:], strict=True))
    assert walked == pytest.approx(best, rel=1e-9)


def test_chain_waypoints_lie_pairwise_in_one_sphere():
    scen = _field(2)
    chain = shortest_chain(_grow(scen)[0])
    points = chain_waypoints(chain, KAPPA)
    assert len(points) == len(chain.radii) + 1
    for j in range(len(chain.radii)):  # segment j joins points j and j+1 inside sphere j
        for p in points[j : j + 2]:
            assert np.linalg.norm(p - chain.centers[j]) <= KAPPA * chain.radii[j] + 1e-9


def test_no_chain_when_the_goal_is_walled_off():
    zero = (0.0, 0.0)
    ring = [((250.0 + 30 * math.cos(a), 250.0 + 30 * math.sin(a)), 12.0) for a in
            np.linspace(0, 2 * math.pi, 12, endpoint=False)]  # fmt: skip
    obstacles = tuple(Body(p, r, zero) for p, r in ring)
    scen = Scenario(
        dim=2, bounds=((-300.0, 300.0),) * 2, dock=(-250.0, -250.0),
        targets=(Body((-250.0, 250.0), 5.0, zero),), obstacles=obstacles, mean_motion=0.0,
        dt=10.0, max_accel=0.05,
    )  # fmt: skip
    geometry = FieldGeometry(scen)
    graph = expand_spheres(
        geometry, np.array([-250.0, -250.0]), np.array([250.0, 250.0]),
        np.full(geometry.n_bodies, 3.0), np.random.default_rng(0), ExpansionParams(max_nodes=80),
        low=scen.low, high=scen.high,
    )  # fmt: skip
    chain = shortest_chain(graph)
    assert not graph.connected and not chain.success and math.isinf(chain.cost)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("max_nodes", 1),
        ("extra_nodes", -1),
        ("goal_bias", 1.5),
        ("min_radius", 0.0),
        ("min_overlap", -1.0),
        ("polytope_factor", 0.0),
        ("narrow_cost", -1.0),
    ],
)
def test_bad_parameters_are_refused_by_name(name, value):
    with pytest.raises(ValueError, match=name):
        ExpansionParams(**{name: value})


def test_margins_of_the_wrong_length_are_refused():
    scen = _field(2)
    geometry = FieldGeometry(scen)
    with pytest.raises(ValueError, match="margins"):
        expand_spheres(
            geometry, np.zeros(2), np.ones(2), np.zeros(1), np.random.default_rng(0),
            low=scen.low, high=scen.high,
        )  # fmt: skip


# --- thin_chain ---------------------------------------------------------------------------------


def _chain(centers, radii) -> SphereChain:
    centers, radii = np.asarray(centers, float), np.asarray(radii, float)
    n = len(radii)
    return SphereChain(True, np.arange(n, dtype=np.int64), centers, radii, 0.0)


def test_thin_chain_skips_a_sphere_its_neighbours_overlap_past():
    params = ExpansionParams(min_overlap=0.1, polytope_factor=1.0)
    # spheres 0 and 2 are 9 m apart with radii 5 + 5: joined (9 <= 10 - 0.1), 1 is skipped;
    # 2 and 3 are 9.95 m apart: not joinable past 3, which is the last anyway
    chain = _chain([[0, 0], [4.5, 0], [9, 0], [18.95, 0]], [5, 1, 5, 5])
    thin = thin_chain(chain, params)
    assert thin.nodes.tolist() == [0, 2, 3]
    expected = edge_cost(
        np.array([[0, 0], [9, 0]]), np.array([5, 5]), np.array([[9, 0], [18.95, 0]]),
        np.array([5, 5]), params.narrow_cost,
    ).sum()  # fmt: skip
    assert thin.cost == pytest.approx(expected)


def test_thin_chain_collapses_tiny_steps_converging_on_the_goal():
    # an expansion grown toward a goal 12 m off ends in spheres a few millimetres apart
    steps = np.concatenate([[0.0, 1.3, 3.3, 6.4, 9.1, 10.4], 11.7 - 0.5 ** np.arange(1, 9)])
    centers = np.stack([steps, np.zeros_like(steps), np.zeros_like(steps)], axis=1)
    radii = np.concatenate([[1.4, 2.0, 3.2, 5.7, 6.5, 5.7], np.full(8, 5.05)])
    thin = thin_chain(_chain(centers, radii), ExpansionParams())
    assert len(thin.radii) <= 4 < len(radii)
    assert thin.nodes[0] == 0 and thin.nodes[-1] == len(radii) - 1


def test_thin_chain_leaves_failed_and_short_chains_alone():
    params = ExpansionParams()
    empty = SphereChain(False, np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), math.inf)
    assert thin_chain(empty, params) is empty
    pair = _chain([[0, 0], [3, 0]], [2, 2])
    assert thin_chain(pair, params) is pair


@st.composite
def _joined_chains(draw):
    """Chains whose consecutive spheres are joinable, as a graph's shortest chain's are."""
    params = ExpansionParams(min_overlap=draw(st.floats(0.0, 0.5)), polytope_factor=1.0)
    n = draw(st.integers(3, 12))
    radii = np.array(draw(st.lists(st.floats(0.8, 10.0), min_size=n, max_size=n)))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    centers = [np.zeros(3)]
    for j in range(1, n):
        reach = max(radii[j - 1] + radii[j] - params.min_overlap, 0.0)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        centers.append(centers[-1] + direction * reach * rng.uniform(0.0, 1.0))
    return _chain(np.array(centers), radii), params


@settings(max_examples=200, deadline=None)
@given(_joined_chains())
def test_thin_chain_keeps_joined_spheres_of_the_chain_and_skips_all_it_can(case):
    chain, params = case
    thin = thin_chain(chain, params)
    kept = thin.nodes
    assert kept[0] == 0 and kept[-1] == len(chain.radii) - 1
    assert np.all(np.diff(kept) > 0)
    np.testing.assert_array_equal(thin.centers, chain.centers[kept])
    np.testing.assert_array_equal(thin.radii, chain.radii[kept])
    c, r = chain.centers, chain.radii
    for a, b in zip(kept[:-1], kept[1:], strict=True):
        assert joinable(np.linalg.norm(c[b] - c[a]), r[a], r[b], params)
        # the farthest joinable sphere is the next one kept
        later = np.arange(b + 1, len(r))
        assert not np.any(joinable(np.linalg.norm(c[later] - c[a], axis=1), r[later], r[a], params))
    a, b = kept[:-1], kept[1:]
    expected = edge_cost(c[a], r[a], c[b], r[b], params.narrow_cost).sum()
    assert thin.cost == pytest.approx(float(expected))
