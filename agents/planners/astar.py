"""A* grid planner on the debris field: field → occupancy grid → A* cell path → shortcut waypoints
(the "astar" baseline flies it with the MPC tracker: :class:`agents.policies.astar.AStarAgent`).

Reference: [APF-MPC] Alg. 3 ("Simplified A*"), its grid baseline (key in docs/references.md);
the search itself is :func:`agents.planners.grid_search.astar` (optimal, 8-/26-connected, no
corner cutting).

The field is rasterised on cell centres like :func:`debris_gym.solvability.occupancy_grid` (centre
of cell i along an axis at ``low + (i + ½)·cell``), but with one inflation per body, so the goal
target can be inflated less than the obstacles (its approach point must stay free). With
``conservative=True`` a cell is blocked when its centre is within inflation + half the cell
diagonal of a body: every point of a free cell then clears the inflated bodies, so the straight
steps between free cells (no corner cutting) do too. Start and goal snap to the nearest free cell
reachable by a straight collision-free hop (they may sit inside an inflation margin, e.g. the
chaser at the approach point of the target it has just captured). The cell path becomes world
waypoints and is shortcut greedily, only where the straight segment clears every inflated body
(:meth:`FieldGeometry.first_hit`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from agents.planners.grid_search import astar, path_cost
from agents.planners.result import PlanResult
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

__all__ = ["GridMap", "SegmentChecker", "astar_path", "default_cell"]


def default_cell(scenario: Scenario) -> float:
    """Default cell size (m): world size / 250 in 2D (4 m on the 1 km field), / 40 in 3D (25 m,
    a 40³ grid)."""
    return scenario.size / (250.0 if scenario.dim == 2 else 40.0)


class SegmentChecker:
    """Swept segment checks against bodies inflated by one distance each.

    Args:
        scenario: the field.
        geometry: its un-inflated :class:`FieldGeometry` (built if None).
    """

    def __init__(self, scenario: Scenario, geometry: FieldGeometry | None = None) -> None:
        self.scenario = scenario
        self.geometry = geometry if geometry is not None else FieldGeometry(scenario)
        self._geoms: dict[float, FieldGeometry] = {}

    def geometry_for(self, inflate: float) -> FieldGeometry:
        """A :class:`FieldGeometry` of the field inflated by ``inflate`` (m), cached."""
        key = float(inflate)
        if key not in self._geoms:
            self._geoms[key] = FieldGeometry(self.scenario, inflate=key)
        return self._geoms[key]

    def clear(self, a: np.ndarray, b: np.ndarray, inflate: np.ndarray) -> bool:
        """True if the segment a→b touches no body inflated by its own ``inflate`` (m).

        Bodies with ``-inf`` inflation are ignored. One swept check
        (:meth:`FieldGeometry.first_hit`) per distinct inflation value, the other bodies masked
        out of its broad phase (their start gaps set to +inf).
        """
        path = np.array([a, b], dtype=float)
        gaps = self.geometry.point_gaps(path[0])
        inflate = np.asarray(inflate, dtype=float)
        for value in np.unique(inflate[np.isfinite(inflate)]):
            masked = np.where(inflate == value, gaps, np.inf)
            if self.geometry_for(max(float(value), 0.0)).first_hit(path, masked) >= 0:
                return False
        return True


class GridMap:
    """Cell centres of a field and the signed distance from each centre to each body.

    Built once per (scenario, cell); occupancy for any per-body inflation is then one comparison.

    Args:
        scenario: the field.
        cell: cell edge length (m).
    """

    def __init__(self, scenario: Scenario, cell: float) -> None:
        if not (math.isfinite(cell) and cell > 0):
            raise ValueError(f"cell must be > 0 m, got {cell!r}")
        self.scenario = scenario
        self.cell = float(cell)
        self.dim = scenario.dim
        self.low = scenario.low
        self.axes = [np.arange(lo + cell / 2.0, hi, cell) for lo, hi in scenario.bounds]
        self.shape = tuple(len(a) for a in self.axes)
        if min(self.shape) < 1:
            raise ValueError(f"cell {cell} m is larger than the world")
        self.geometry = FieldGeometry(scenario)
        mesh = np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1).reshape(-1, self.dim)
        dist = np.empty((mesh.shape[0], self.geometry.n_bodies), dtype=np.float32)
        for start in range(0, mesh.shape[0], 4096):
            dist[start : start + 4096] = self.geometry.signed_distance(mesh[start : start + 4096])
        self.distances = dist
        self.checker = SegmentChecker(scenario, self.geometry)

    def body_inflation(
        self, inflate: float, goal_index: int | None = None, goal_inflate: float | None = None
    ) -> np.ndarray:
        """Per-body inflation (m): ``inflate`` everywhere, ``goal_inflate`` for the goal body."""
        out = np.full(self.geometry.n_bodies, float(inflate))
        if goal_index is not None and goal_inflate is not None:
            out[goal_index] = goal_inflate
        return out

    def occupancy(self, inflate: np.ndarray, conservative: bool = True) -> np.ndarray:
        """Boolean grid: True where a cell centre is within its body's inflation (m).

        ``-inf`` inflation leaves a body out. ``conservative`` adds half a cell diagonal.
        """
        extra = 0.5 * self.cell * math.sqrt(self.dim) if conservative else 0.0
        reach = np.asarray(inflate, dtype=float) + extra
        occ = (self.distances <= reach[None, :].astype(np.float32)).any(axis=1)
        return occ.reshape(self.shape)

    def cell_of(self, point: np.ndarray) -> tuple[int, ...]:
        """Index of the cell containing ``point`` (clipped to the grid)."""
        idx = np.floor((np.asarray(point, float) - self.low) / self.cell).astype(int)
        return tuple(int(min(max(i, 0), n - 1)) for i, n in zip(idx, self.shape, strict=True))

    def centre(self, cells: Sequence[Sequence[int]]) -> np.ndarray:
        """World coordinates (m) of cell centres, shape (K, dim)."""
        idx = np.asarray(cells, dtype=float).reshape(-1, self.dim)
        return self.low + (idx + 0.5) * self.cell

    def segment_clear(self, a: np.ndarray, b: np.ndarray, inflate: np.ndarray) -> bool:
        """See :meth:`SegmentChecker.clear`."""
        return self.checker.clear(a, b, inflate)


def _snap(
    grid: GridMap, occ: np.ndarray, point: np.ndarray, inflate: np.ndarray, radius: int
) -> tuple[int, ...] | None:
    """The nearest free cell whose centre a straight hop from ``point`` reaches safely."""
    cell = grid.cell_of(point)
    if not occ[cell] and grid.segment_clear(point, grid.centre([cell])[0], inflate):
        return cell
    ranges = [
        np.arange(max(c - radius, 0), min(c + radius + 1, n))
        for c, n in zip(cell, grid.shape, strict=True)
    ]
    block = np.stack(np.meshgrid(*ranges, indexing="ij"), axis=-1).reshape(-1, grid.dim)
    free = block[~occ[tuple(block.T)]]
    if free.size == 0:
        return None
    centres = grid.centre(free)
    order = np.argsort(np.linalg.norm(centres - point, axis=1), kind="stable")
    for k in order[:64]:
        if grid.segment_clear(point, centres[k], inflate):
            return tuple(int(i) for i in free[k])
    return None


def _shortcut(grid: GridMap, points: np.ndarray, inflate: np.ndarray) -> np.ndarray:
    """Greedy shortcutting: from each kept point, jump to the farthest point in an unbroken run
    of points whose straight segment from it is clear. Raw steps are always allowed."""
    out = [points[0]]
    i, last = 0, len(points) - 1
    while i < last:
        j = i + 1
        while j < last and grid.segment_clear(points[i], points[j + 1], inflate):
            j += 1
        out.append(points[j])
        i = j
    return np.asarray(out)


def _turning_points(cells: list[tuple[int, ...]]) -> list[tuple[int, ...]]:
    """Drop the cells in the middle of straight runs."""
    if len(cells) <= 2:
        return list(cells)
    keep = [cells[0]]
    for a, b, c in zip(cells, cells[1:], cells[2:]):
        if tuple(np.subtract(b, a)) != tuple(np.subtract(c, b)):
            keep.append(b)
    keep.append(cells[-1])
    return keep


def astar_path(
    scenario: Scenario,
    start: np.ndarray,
    goal: np.ndarray,
    *,
    cell: float,
    inflate: float | np.ndarray,
    ignore: Iterable[int] = (),
    min_inflate: float = 0.0,
    conservative: bool = True,
    grid: GridMap | None = None,
) -> PlanResult:
    """Shortest grid path from ``start`` to ``goal`` (m), simplified where it is safe.

    Args:
        scenario: the field.
        start: start position (m).
        goal: goal position (m).
        cell: cell edge length (m).
        inflate: inflation (m) of every body, or one per body (targets first).
        ignore: body indices left out of the grid and the checks.
        min_inflate: clearance (m) the straight hops from start/goal to their snapped cells must
            keep (those points may lie inside the ``inflate`` margin).
        conservative: block cells whose centre is within inflation + half a cell diagonal.
        grid: a prebuilt :class:`GridMap` of ``scenario`` with this ``cell``.

    Returns:
        :class:`PlanResult`. On success the waypoints run start → snapped start cell → … → snapped
        goal cell → goal, shortcut. ``info``: ``grid_cost`` (m, the A* cell path's length before
        simplification), ``cells``, ``start_cell``, ``goal_cell``, ``occupancy`` (the grid
        searched), ``raw_waypoints``; ``reason`` on failure ("start_blocked", "goal_blocked",
        "no_path").
    """
    grid = grid if grid is not None else GridMap(scenario, cell)
    if not math.isclose(grid.cell, cell):
        raise ValueError(f"grid has cell {grid.cell} m, asked for {cell} m")
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    n_bodies = grid.geometry.n_bodies
    infl = np.broadcast_to(np.asarray(inflate, dtype=float), (n_bodies,)).copy()
    ignored = list(ignore)
    infl[ignored] = -np.inf
    occ = grid.occupancy(infl, conservative)
    hop = np.where(np.isfinite(infl), np.minimum(infl, min_inflate), -np.inf)
    radius = max(3, math.ceil((np.max(infl, initial=0.0) + grid.cell) / grid.cell) + 2)
    info: dict[str, Any] = {"occupancy": occ}
    s_cell = _snap(grid, occ, start, hop, radius)
    g_cell = _snap(grid, occ, goal, hop, radius)
    info.update(start_cell=s_cell, goal_cell=g_cell)
    cells = None
    if s_cell is None:
        failure = "start_blocked"
    elif g_cell is None:
        failure = "goal_blocked"
    else:
        cells = astar(occ, s_cell, g_cell)
        failure = "no_path"
    if cells is None:
        info["reason"] = failure
        return PlanResult(False, start[None].copy(), 0.0, info)
    info["cells"] = cells
    info["grid_cost"] = path_cost(cells) * grid.cell
    raw = np.vstack([start, grid.centre(_turning_points(cells)), goal])
    keep = np.ones(len(raw), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(raw, axis=0), axis=1) > 1e-9
    raw = raw[keep]
    info["raw_waypoints"] = raw
    waypoints = _shortcut(grid, raw, infl) if len(raw) > 2 else raw
    return PlanResult(True, waypoints, PlanResult.path_length(waypoints), info)
