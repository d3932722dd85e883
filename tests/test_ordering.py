"""Tests of agents.planners.ordering: the polygon queue ([APF-MPC] Alg. 1) and the shortest
tour."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from agents.planners.ordering import EXACT_MAX_N, polygon_order, shortest_order, tour_length

# --------------------------------------------------------------------------------------------------
# independent helpers
# --------------------------------------------------------------------------------------------------


def _orient(p, q, r) -> float:
    """Twice the signed area of triangle pqr (> 0 counter-clockwise)."""
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


def _properly_cross(p1, p2, q1, q2) -> bool:
    """True when segments p1p2 and q1q2 cross at one point interior to both."""
    d1, d2 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    d3, d4 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    return d1 * d2 < 0 and d3 * d4 < 0


def _crossing_pairs(points, order) -> list[tuple[int, int]]:
    """Pairs of non-adjacent edges of the closed tour ``order`` that properly cross."""
    n = len(order)
    edges = [(points[order[k]], points[order[(k + 1) % n]]) for k in range(n)]
    bad = []
    for i, j in itertools.combinations(range(n), 2):
        if j == i + 1 or (i == 0 and j == n - 1):
            continue
        if _properly_cross(*edges[i], *edges[j]):
            bad.append((i, j))
    return bad


def _closed_length(points, start, order) -> float:
    """start → points[order] → start, summed edge by edge."""
    path = [np.asarray(start, float)] + [np.asarray(points[i], float) for i in order]
    path.append(path[0])
    return float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(path)))


def _brute_force(points, start) -> float:
    """Optimal closed-tour length by enumerating every permutation (vectorised)."""
    points = np.asarray(points, float)
    n = len(points)
    nodes = np.vstack([start, points])
    dist = np.linalg.norm(nodes[:, None] - nodes[None, :], axis=-1)
    perms = np.array(list(itertools.permutations(range(1, n + 1))), dtype=np.int64)
    inner = dist[perms[:, :-1], perms[:, 1:]].sum(axis=1) if n > 1 else 0.0
    total = dist[0, perms[:, 0]] + inner + dist[perms[:, -1], 0]
    return float(total.min())


def _polygon_tour_length(points, start) -> tuple[float, float]:
    """Lengths of the polygon tour closed through ``start``.

    Returns (plain, best): *plain* is start → polygon order as returned → start; *best* enters the
    polygon cycle from ``start`` at its best rotation (either direction, which is the same
    length), i.e. the shortest way of inserting ``start`` into one edge of the polygon cycle.
    """
    order = polygon_order(points)
    plain = _closed_length(points, start, order)
    best = min(_closed_length(points, start, order[k:] + order[:k]) for k in range(len(order)))
    return plain, best


def _general_position(points, tol: float) -> bool:
    """No repeated points and no three (nearly) collinear points."""
    for p, q, r in itertools.combinations(points, 3):
        scale = max(1.0, float(np.ptp(np.array([p, q, r]))) ** 2)
        if abs(_orient(p, q, r)) <= tol * scale:
            return False
    return len({tuple(p) for p in points}) == len(points)


# --------------------------------------------------------------------------------------------------
# polygon_order
# --------------------------------------------------------------------------------------------------


def test_polygon_hand_example():
    # min-x (0,0) #0, max-x (4,0) #1; line y = 0. Above or on: (2,0) #5, (2,2) #2 (ascending x, y);
    # below: (3,-2) #4, (1,-1) #3 (descending x).
    pts = [(0, 0), (4, 0), (2, 2), (1, -1), (3, -2), (2, 0)]
    assert polygon_order(pts) == [0, 5, 2, 1, 4, 3]


def test_polygon_square_and_x_ties():
    # Unit square given in a scrambled order; ties in x broken by y.
    pts = [(1, 1), (0, 0), (1, 0), (0, 1)]
    # first = (0,0) #1, last = (1,1) #0; (0,1) #3 above the diagonal, (1,0) #2 below.
    assert polygon_order(pts) == [1, 3, 0, 2]
    assert _crossing_pairs(np.array(pts, float), polygon_order(pts)) == []


def test_polygon_small_and_degenerate_sets():
    assert polygon_order([(3.0, 4.0)]) == [0]
    assert polygon_order([(5.0, 0.0), (1.0, 0.0)]) == [1, 0]
    # all on one vertical line: everything is "on the line" → ascending y, then back.
    assert polygon_order([(0, 2), (0, 0), (0, 1)]) == [1, 2, 0]
    # duplicates are kept, each index once.
    assert sorted(polygon_order([(1, 1), (1, 1), (0, 0), (2, 0)])) == [0, 1, 2, 3]


def test_polygon_3d_projects_on_xy():
    pts2 = np.array([(0, 0), (4, 0), (2, 2), (1, -1), (3, -2), (2, 0)], float)
    z = np.array([5.0, -3.0, 0.0, 9.0, 1.0, -7.0])
    assert polygon_order(np.column_stack([pts2, z])) == polygon_order(pts2)


def test_polygon_orders_paper_convention():
    rng = np.random.default_rng(7)
    pts = 10 * rng.random((25, 2))  # the paper's t = 10 × rand(2, N)
    order = polygon_order(pts)
    assert sorted(order) == list(range(25))
    assert order[0] == int(np.argmin(pts[:, 0]))
    k = order.index(int(np.argmax(pts[:, 0])))
    a, b = pts[order[0]], pts[order[k]]
    slope = (b[1] - a[1]) / (b[0] - a[0])
    line = a[1] + slope * (pts[:, 0] - a[0])
    upper, lower = order[1:k], order[k + 1 :]
    assert np.all(pts[upper, 1] >= line[upper]) and np.all(pts[lower, 1] < line[lower])
    assert np.all(np.diff(pts[upper, 0]) > 0) and np.all(np.diff(pts[lower, 0]) < 0)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 30), st.integers(-1000, 1000)),
        min_size=1,
        max_size=25,
    )
)
def test_polygon_never_properly_crosses_integer_points(raw):
    # Small x range: many ties in x, collinear triples and duplicates. Orientation products are
    # exact for these integers, so "no proper crossing" must hold without general position.
    pts = np.array(raw, dtype=float)
    order = polygon_order(pts)
    assert sorted(order) == list(range(len(pts)))
    assert _crossing_pairs(pts, order) == []


@settings(max_examples=120, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-50, 50, allow_nan=False, allow_subnormal=False),
            st.floats(-50, 50, allow_nan=False, allow_subnormal=False),
        ),
        min_size=3,
        max_size=12,
    )
)
def test_polygon_simple_in_general_position(raw):
    pts = np.array(raw, dtype=float)
    assume(_general_position(pts, 1e-6))
    order = polygon_order(pts)
    assert sorted(order) == list(range(len(pts)))
    assert _crossing_pairs(pts, order) == []


@pytest.mark.parametrize("seed", range(20))
def test_polygon_random_uniform_sets(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0.0, 20.0, size=(rng.integers(3, 80), 2))
    assert _crossing_pairs(pts, polygon_order(pts)) == []


# --------------------------------------------------------------------------------------------------
# tour_length / shortest_order
# --------------------------------------------------------------------------------------------------


def test_tour_length_hand_example():
    pts = [(3.0, 0.0), (3.0, 4.0)]
    # (0,0) → (3,0) → (3,4) → (0,0): 3 + 4 + 5.
    assert tour_length(pts, (0.0, 0.0), [0, 1]) == pytest.approx(12.0)
    assert tour_length(pts, (0.0, 0.0), [1, 0]) == pytest.approx(12.0)
    assert tour_length([(1.0, 2.0, 2.0)], (0.0, 0.0, 0.0), [0]) == pytest.approx(6.0)


def test_shortest_order_square():
    # Start (0,0); the optimum walks the hull (0,0) (0,1) [(1,1)] (2,1) (1,0): 4 + √2.
    pts = [(1, 1), (0, 1), (1, 0), (2, 1)]
    order = shortest_order(pts, (0, 0))
    assert order in ([1, 0, 3, 2], [2, 3, 0, 1])
    assert tour_length(pts, (0, 0), order) == pytest.approx(4 + np.sqrt(2))


def test_shortest_order_single_point():
    assert shortest_order([(4.0, 5.0)], (0.0, 0.0)) == [0]
    assert shortest_order([(4.0, 5.0, 1.0)], (0.0, 0.0, 0.0)) == [0]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(12))
def test_shortest_order_matches_brute_force_small(dim, seed):
    rng = np.random.default_rng(1000 * dim + seed)
    n = 2 + seed % 6  # 2..7
    pts = rng.uniform(0.0, 20.0, size=(n, dim))
    start = rng.uniform(0.0, 20.0, size=dim)
    order = shortest_order(pts, start)
    assert sorted(order) == list(range(n))
    assert tour_length(pts, start, order) == pytest.approx(_brute_force(pts, start), rel=1e-12)


@pytest.mark.parametrize(("n", "dim", "seed"), [(8, 2, 0), (8, 3, 1), (9, 2, 2)])
def test_shortest_order_exact_at_8_and_9(n, dim, seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0.0, 20.0, size=(n, dim))
    start = np.zeros(dim)
    length = tour_length(pts, start, shortest_order(pts, start))
    assert length == pytest.approx(_brute_force(pts, start), rel=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_exact_never_worse_than_heuristic(dim):
    rng = np.random.default_rng(42 + dim)
    for n in (5, 8, EXACT_MAX_N):
        pts = rng.uniform(0.0, 20.0, size=(n, dim))
        start = rng.uniform(0.0, 20.0, size=dim)
        exact = tour_length(pts, start, shortest_order(pts, start))
        heur_order = shortest_order(pts, start, exact_max_n=0)
        assert sorted(heur_order) == list(range(n))
        assert exact <= tour_length(pts, start, heur_order) + 1e-9


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(5))
def test_heuristic_beats_polygon_tour_on_40_points(dim, seed):
    rng = np.random.default_rng(500 + 10 * dim + seed)
    pts = rng.uniform(0.0, 20.0, size=(40, dim))
    start = rng.uniform(0.0, 20.0, size=dim)
    order = shortest_order(pts, start)
    assert sorted(order) == list(range(40))
    length = tour_length(pts, start, order)
    assert length == pytest.approx(_closed_length(pts, start, order))
    plain, best = _polygon_tour_length(pts, start)
    assert best <= plain + 1e-9
    assert length <= best + 1e-9


def test_heuristic_on_convex_polygon_is_optimal():
    # Points on a circle with the start on it too: the optimal tour is the circle itself.
    ang = np.sort(np.random.default_rng(3).uniform(0.0, 2 * np.pi, 30))
    pts = np.column_stack([np.cos(ang), np.sin(ang)])
    start = np.array([1.0, 0.0])
    order = shortest_order(pts, start)
    hull = np.vstack([start, pts, start])
    # walking the circle once in angular order (either way) is optimal
    best = float(np.linalg.norm(np.diff(hull, axis=0), axis=1).sum())
    assert tour_length(pts, start, order) == pytest.approx(best, rel=1e-9)


def test_shortest_order_is_deterministic():
    rng = np.random.default_rng(11)
    pts = rng.uniform(0.0, 20.0, size=(25, 2))
    assert shortest_order(pts, (0, 0)) == shortest_order(pts.copy(), (0, 0))


# --------------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((0, 2)),
        [],
        np.zeros(4),
        np.zeros((3, 1)),
        np.zeros((3, 4)),
        np.zeros((2, 2, 2)),
        [(0.0, np.nan)],
        [(0.0, np.inf)],
        [("a", "b")],
    ],
)
def test_bad_points_raise(bad):
    with pytest.raises(ValueError, match="points"):
        polygon_order(bad)
    with pytest.raises(ValueError, match="points"):
        shortest_order(bad, (0.0, 0.0))
    with pytest.raises(ValueError, match="points"):
        tour_length(bad, (0.0, 0.0), [0])


@pytest.mark.parametrize("bad", [(0.0,), (0.0, 0.0, 0.0), (np.nan, 0.0), [[0.0, 0.0]], "xy"])
def test_bad_start_raises(bad):
    pts = [(1.0, 2.0), (3.0, 4.0)]
    with pytest.raises(ValueError, match="start"):
        shortest_order(pts, bad)
    with pytest.raises(ValueError, match="start"):
        tour_length(pts, bad, [0, 1])


@pytest.mark.parametrize("bad", [[0], [0, 0], [0, 2], [1, 0, 2], ["a", 1], [0.5, 1]])
def test_bad_order_raises(bad):
    with pytest.raises(ValueError, match="order"):
        tour_length([(1.0, 2.0), (3.0, 4.0)], (0.0, 0.0), bad)
