"""Optimal A* search on a 2D or 3D boolean occupancy grid, without corner cutting.

References (keys refer to docs/references.md): [Hart68] — A* search; [APF-MPC] Alg. 3
("Simplified A*") — the grid baseline it serves.

Cells are integer index tuples into the grid; a step costs its Euclidean length in cell units (1,
√2 or √3). With ``diagonal=True`` a cell has 8 (2D) or 26 (3D) neighbours, otherwise 4 or 6. A
diagonal step never cuts a corner: every cell of the sub-square/sub-cube spanned by the step (the
cells reached by zeroing some of the step's nonzero components) must be free. The heuristic is the
exact step cost on an empty grid (octile distance in 2D and its 3D analogue; Manhattan distance
without diagonals), which is admissible and consistent, so the returned path is optimal.
"""

from __future__ import annotations

import heapq
import itertools
import math
import operator
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["astar", "path_cost"]

_SQRT2 = math.sqrt(2.0)
_SQRT3 = math.sqrt(3.0)

Cell = tuple[int, ...]


def _as_grid(grid: ArrayLike) -> np.ndarray:
    """Checks and converts the occupancy grid to a boolean array (True = occupied)."""
    arr = np.asarray(grid)
    if arr.dtype != bool:
        if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
            raise ValueError(f"grid must be a boolean array, got dtype {arr.dtype}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("grid must be finite")
        arr = arr != 0
    if arr.ndim not in (2, 3):
        raise ValueError(f"grid must be 2D or 3D, got {arr.ndim} dimensions")
    if arr.size == 0:
        raise ValueError(f"grid must not be empty, got shape {arr.shape}")
    return arr


def _as_cell(cell: Sequence[int], name: str, shape: tuple[int, ...]) -> Cell:
    """Checks that ``cell`` is an integer index tuple inside a grid of shape ``shape``."""
    try:
        idx = tuple(operator.index(c) for c in cell)
    except TypeError as exc:
        raise ValueError(f"{name} must be a sequence of {len(shape)} integers") from exc
    if len(idx) != len(shape):
        raise ValueError(f"{name} must have {len(shape)} indices, got {len(idx)}")
    if any(not 0 <= c < s for c, s in zip(idx, shape, strict=True)):
        raise ValueError(f"{name} {idx} is outside the grid of shape {shape}")
    return idx


def _moves(
    ndim: int, diagonal: bool, strides: Sequence[int]
) -> list[tuple[int, float, tuple[int, ...]]]:
    """Neighbour steps as (flat offset, cost, flat offsets of the cells that must be free)."""
    moves = []
    for step in itertools.product((-1, 0, 1), repeat=ndim):
        axes = [a for a in range(ndim) if step[a]]
        if not axes or (not diagonal and len(axes) > 1):
            continue
        # Intermediate cells: keep a nonempty proper subset of the nonzero components.
        corners = []
        for r in range(1, len(axes)):
            for keep in itertools.combinations(axes, r):
                corners.append(sum(step[a] * strides[a] for a in keep))
        offset = sum(step[a] * strides[a] for a in axes)
        moves.append((offset, math.sqrt(len(axes)), tuple(corners)))
    return moves


def _heuristic(shape: tuple[int, ...], goal: Cell, diagonal: bool) -> list[float]:
    """Cost-to-goal lower bound for every cell of a grid of shape ``shape`` (flat, C order)."""
    diff = np.abs(np.indices(shape) - np.reshape(goal, (-1,) + (1,) * len(shape)))
    if not diagonal:
        return diff.sum(axis=0).ravel().tolist()
    d = np.sort(diff, axis=0)[::-1].astype(float)  # d[0] >= d[1] (>= d[2])
    if len(shape) == 2:
        h = (d[0] - d[1]) + _SQRT2 * d[1]
    else:
        h = (d[0] - d[1]) + _SQRT2 * (d[1] - d[2]) + _SQRT3 * d[2]
    return h.ravel().tolist()


def astar(
    grid: ArrayLike, start: Sequence[int], goal: Sequence[int], diagonal: bool = True
) -> list[Cell] | None:
    """Shortest collision-free path between two cells of an occupancy grid.

    Args:
        grid: occupancy, shape (nx, ny) or (nx, ny, nz); True (nonzero) means occupied.
        start: start cell, one integer index per grid axis.
        goal: goal cell, one integer index per grid axis.
        diagonal: allow diagonal steps (8-/26-connectivity, no corner cutting); otherwise only
            axis-aligned steps (4-/6-connectivity).

    Returns:
        The cells from ``start`` to ``goal`` inclusive, as tuples of ints, along a path of least
        total step length (cell units; see :func:`path_cost`); ``[start]`` when start equals goal;
        None when the start or goal cell is occupied or no path exists.

    Raises:
        ValueError: if ``grid`` is not a nonempty 2D/3D array, or ``start``/``goal`` is not an
            integer index tuple inside the grid.
    """
    occ = _as_grid(grid)
    s = _as_cell(start, "start", occ.shape)
    g = _as_cell(goal, "goal", occ.shape)
    if occ[s] or occ[g]:
        return None
    if s == g:
        return [s]

    # A border of occupied cells keeps every neighbour index inside the flat array.
    padded = np.pad(occ, 1, constant_values=True)
    shape = padded.shape
    strides = [int(np.prod(shape[a + 1 :])) for a in range(len(shape))]
    free = (~padded).ravel().tolist()
    moves = _moves(len(shape), diagonal, strides)
    s_pad = tuple(c + 1 for c in s)
    g_pad = tuple(c + 1 for c in g)
    h = _heuristic(shape, g_pad, diagonal)
    src = int(np.ravel_multi_index(s_pad, shape))
    dst = int(np.ravel_multi_index(g_pad, shape))

    cost = {src: 0.0}
    parent = {src: -1}
    closed = bytearray(len(free))
    heap = [(h[src], h[src], src)]
    heappush, heappop = heapq.heappush, heapq.heappop
    found = False
    while heap:
        _, _, node = heappop(heap)
        if closed[node]:
            continue
        if node == dst:
            found = True
            break
        closed[node] = 1
        base = cost[node]
        for offset, step, corners in moves:
            nb = node + offset
            if not free[nb] or closed[nb]:
                continue
            if corners and not all(free[node + c] for c in corners):
                continue
            new = base + step
            if new < cost.get(nb, math.inf):
                cost[nb] = new
                parent[nb] = node
                heappush(heap, (new + h[nb], h[nb], nb))
    if not found:
        return None

    flat = []
    node = dst
    while node >= 0:
        flat.append(node)
        node = parent[node]
    coords = np.unravel_index(np.array(flat[::-1]), shape)
    return [tuple(int(c) - 1 for c in cell) for cell in zip(*coords, strict=True)]


def path_cost(path: Sequence[Sequence[int]]) -> float:
    """Total Euclidean length of a cell path.

    Args:
        path: cells (index tuples of equal length), e.g. the result of :func:`astar`.

    Returns:
        Sum of the distances between consecutive cells (cell units); 0.0 for fewer than 2 cells.

    Raises:
        ValueError: if the cells do not all have the same number of indices.
    """
    if len(path) < 2:
        return 0.0
    try:
        arr = np.asarray(path, dtype=float)
    except ValueError as exc:
        raise ValueError("path cells must all have the same number of indices") from exc
    if arr.ndim != 2:
        raise ValueError("path must be a sequence of index tuples")
    return float(np.linalg.norm(np.diff(arr, axis=0), axis=1).sum())
