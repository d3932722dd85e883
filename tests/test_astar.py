"""Tests of agents.planners.grid_search (A* on a grid): optimality against networkx Dijkstra,
path validity, corner cutting."""

from __future__ import annotations

import itertools
import math
import time

import networkx as nx
import numpy as np
import pytest

from agents.planners.grid_search import astar, path_cost

# --------------------------------------------------------------------------------------------------
# independent reference: the same grid graph built cell by cell for networkx
# --------------------------------------------------------------------------------------------------


def _box_free(occ: np.ndarray, a: tuple[int, ...], b: tuple[int, ...]) -> bool:
    """All cells of the axis-aligned box with corners a and b are free."""
    ranges = [range(min(i, j), max(i, j) + 1) for i, j in zip(a, b, strict=True)]
    return not any(occ[cell] for cell in itertools.product(*ranges))


def _grid_graph(occ: np.ndarray, diagonal: bool) -> nx.Graph:
    """Free cells joined to neighbours whose whole spanned box is free (no corner cutting)."""
    graph = nx.Graph()
    for cell in zip(*np.nonzero(~occ), strict=True):
        cell = tuple(int(c) for c in cell)
        graph.add_node(cell)
        for step in itertools.product((-1, 0, 1), repeat=occ.ndim):
            norm1 = sum(abs(s) for s in step)
            if norm1 == 0 or (not diagonal and norm1 > 1):
                continue
            nb = tuple(c + s for c, s in zip(cell, step, strict=True))
            if not all(0 <= c < n for c, n in zip(nb, occ.shape, strict=True)):
                continue
            if _box_free(occ, cell, nb):
                graph.add_edge(cell, nb, weight=math.sqrt(norm1))
    return graph


def _check_path(occ: np.ndarray, path, start, goal, diagonal: bool) -> None:
    """Contiguous, collision free, no corner cutting, right ends, plain int tuples."""
    assert path[0] == tuple(start) and path[-1] == tuple(goal)
    for cell in path:
        assert isinstance(cell, tuple) and all(type(c) is int for c in cell)
        assert not occ[cell]
    for a, b in itertools.pairwise(path):
        diff = [abs(i - j) for i, j in zip(a, b, strict=True)]
        assert max(diff) == 1
        if not diagonal:
            assert sum(diff) == 1
        assert _box_free(occ, a, b)


def _compare_with_networkx(occ: np.ndarray, diagonal: bool, pairs) -> int:
    """Runs A* on every (start, goal) pair; returns how many had a path."""
    graph = _grid_graph(occ, diagonal)
    found = 0
    for start, goal in pairs:
        path = astar(occ, start, goal, diagonal=diagonal)
        if occ[start] or occ[goal] or not nx.has_path(graph, start, goal):
            assert path is None
            continue
        expected = nx.dijkstra_path_length(graph, start, goal)
        assert path is not None
        _check_path(occ, path, start, goal, diagonal)
        assert path_cost(path) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        found += 1
    return found


def _random_pairs(rng, shape, k):
    cells = [tuple(int(c) for c in rng.integers(0, shape)) for _ in range(2 * k)]
    return list(zip(cells[::2], cells[1::2], strict=True))


# --------------------------------------------------------------------------------------------------
# optimality against networkx
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("diagonal", [True, False])
def test_random_2d_grids_match_dijkstra(diagonal):
    rng = np.random.default_rng(2024 + diagonal)
    total = found = 0
    for _ in range(30):
        occ = rng.random((30, 30)) < 0.3
        pairs = _random_pairs(rng, occ.shape, 6)
        # always include one pair of free cells far apart
        free = np.argwhere(~occ)
        pairs.append((tuple(int(c) for c in free[0]), tuple(int(c) for c in free[-1])))
        found += _compare_with_networkx(occ, diagonal, pairs)
        total += len(pairs)
    # the sample must exercise both outcomes
    assert 0 < found < total


@pytest.mark.parametrize("diagonal", [True, False])
def test_random_3d_grids_match_dijkstra(diagonal):
    rng = np.random.default_rng(77 + diagonal)
    total = found = 0
    for _ in range(6):
        occ = rng.random((10, 10, 10)) < 0.3
        pairs = _random_pairs(rng, occ.shape, 8)
        found += _compare_with_networkx(occ, diagonal, pairs)
        total += len(pairs)
    assert 0 < found < total


def test_random_non_square_grids_match_dijkstra():
    rng = np.random.default_rng(5)
    for shape in [(1, 17), (23, 7), (3, 9, 5), (1, 1, 12)]:
        occ = rng.random(shape) < 0.2
        for diagonal in (True, False):
            # plus the two ends of the largest free region: a pair that must have a path
            region = sorted(max(nx.connected_components(_grid_graph(occ, diagonal)), key=len))
            pairs = [*_random_pairs(rng, shape, 10), (region[0], region[-1])]
            found = _compare_with_networkx(occ, diagonal, pairs)
            # each sample exercises both outcomes: paths found and refused
            assert 0 < found < len(pairs), (shape, diagonal, found)


# --------------------------------------------------------------------------------------------------
# hand-made examples
# --------------------------------------------------------------------------------------------------


def test_no_corner_cutting_between_two_diagonal_blocks():
    # Two blocks touching at one corner seal off the top-left 2×2 room:
    #   . . # .
    #   . . # .
    #   # # . .
    #   . . . .
    occ = np.zeros((4, 4), dtype=bool)
    occ[0:2, 2] = True
    occ[2, 0:2] = True
    assert astar(occ, (0, 0), (3, 3)) is None
    assert astar(occ, (1, 1), (2, 2)) is None
    assert astar(occ, (0, 0), (1, 1)) == [(0, 0), (1, 1)]
    assert astar(occ, (2, 2), (3, 3)) == [(2, 2), (3, 3)]


def test_single_corner_blocks_the_diagonal():
    occ = np.zeros((2, 2), dtype=bool)
    occ[0, 1] = True
    path = astar(occ, (0, 0), (1, 1))
    assert path == [(0, 0), (1, 0), (1, 1)]
    assert path_cost(path) == pytest.approx(2.0)


def test_open_2d_grid_octile_cost():
    occ = np.zeros((12, 7), dtype=bool)
    path = astar(occ, (0, 0), (11, 6))
    assert path_cost(path) == pytest.approx(5 + 6 * math.sqrt(2))
    assert len(path) == 12
    path4 = astar(occ, (0, 0), (11, 6), diagonal=False)
    assert path_cost(path4) == pytest.approx(17.0)
    assert len(path4) == 18
    _check_path(occ, path4, (0, 0), (11, 6), diagonal=False)


def test_wall_with_gap_forces_detour():
    occ = np.zeros((7, 7), dtype=bool)
    occ[3, :6] = True  # gap at (3, 6)
    path = astar(occ, (0, 0), (6, 0))
    _check_path(occ, path, (0, 0), (6, 0), diagonal=True)
    # (2,5)→(3,6) and (3,6)→(4,5) would cut the wall's end cell (3,5), so the optimum passes
    # (2,6), (3,6), (4,6): octile legs (0,0)→(2,6) and (4,6)→(6,0) of 4 + 2√2 each, plus 2.
    expected = nx.dijkstra_path_length(_grid_graph(occ, True), (0, 0), (6, 0))
    assert path_cost(path) == pytest.approx(expected)
    assert (2, 6) in path and (3, 6) in path and (4, 6) in path
    assert path_cost(path) == pytest.approx(2 * (4 + 2 * math.sqrt(2)) + 2)


def test_3d_examples():
    occ = np.zeros((2, 2, 2), dtype=bool)
    assert astar(occ, (0, 0, 0), (1, 1, 1)) == [(0, 0, 0), (1, 1, 1)]
    assert path_cost([(0, 0, 0), (1, 1, 1)]) == pytest.approx(math.sqrt(3))
    # one edge-adjacent cell of the sub-cube occupied: no space diagonal, best is √2 + 1
    occ[1, 1, 0] = True
    path = astar(occ, (0, 0, 0), (1, 1, 1))
    assert path_cost(path) == pytest.approx(1 + math.sqrt(2))
    _check_path(occ, path, (0, 0, 0), (1, 1, 1), diagonal=True)
    # only the two opposite corners free: unreachable
    occ = np.ones((2, 2, 2), dtype=bool)
    occ[0, 0, 0] = occ[1, 1, 1] = False
    assert astar(occ, (0, 0, 0), (1, 1, 1)) is None
    # 6-connected: Manhattan
    occ = np.zeros((4, 5, 6), dtype=bool)
    path = astar(occ, (0, 0, 0), (3, 4, 5), diagonal=False)
    assert path_cost(path) == pytest.approx(12.0)
    path = astar(occ, (0, 0, 0), (3, 4, 5))
    assert path_cost(path) == pytest.approx(3 * math.sqrt(3) + math.sqrt(2) + 1)


def test_start_goal_cases():
    occ = np.zeros((5, 5), dtype=bool)
    occ[2, 2] = True
    assert astar(occ, (1, 1), (1, 1)) == [(1, 1)]
    assert astar(occ, (2, 2), (2, 2)) is None
    assert astar(occ, (2, 2), (0, 0)) is None
    assert astar(occ, (0, 0), (2, 2)) is None
    # numpy integers and lists are accepted; the result is plain int tuples
    path = astar(occ.astype(np.uint8), np.array([0, 0]), [np.int64(4), 4])
    _check_path(occ, path, (0, 0), (4, 4), diagonal=True)


def test_path_cost_small_inputs():
    assert path_cost([]) == 0.0
    assert path_cost([(3, 4)]) == 0.0
    assert path_cost([(0, 0), (3, 4)]) == pytest.approx(5.0)
    with pytest.raises(ValueError):
        path_cost([(0, 0), (1, 1, 1)])


# --------------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("start", "goal", "name"),
    [
        ((-1, 0), (0, 0), "start"),
        ((5, 0), (0, 0), "start"),
        ((0, 0), (0, 5), "goal"),
        ((0, 0, 0), (0, 0), "start"),
        ((0, 0), (1,), "goal"),
        ((0.5, 0), (0, 0), "start"),
        ((0, 0), None, "goal"),
    ],
)
def test_bad_cells_raise(start, goal, name):
    with pytest.raises(ValueError, match=name):
        astar(np.zeros((5, 5), dtype=bool), start, goal)


@pytest.mark.parametrize(
    "grid", [np.zeros(5, bool), np.zeros((2, 2, 2, 2), bool), np.zeros((0, 4), bool), [["a"]]]
)
def test_bad_grid_raises(grid):
    with pytest.raises(ValueError, match="grid"):
        astar(grid, (0, 0), (0, 0))


# --------------------------------------------------------------------------------------------------
# speed
# --------------------------------------------------------------------------------------------------


def test_200x200_grid_is_fast():
    rng = np.random.default_rng(1)
    occ = rng.random((200, 200)) < 0.2
    occ[0, 0] = occ[-1, -1] = False
    t0 = time.perf_counter()
    path = astar(occ, (0, 0), (199, 199))
    elapsed = time.perf_counter() - t0
    assert path is not None
    assert elapsed < 1.0
