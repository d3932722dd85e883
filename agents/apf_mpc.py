"""APF-MPC: an artificial-potential-field path tracked by a linear MPC on the CWH model.

Reference: seed paper 000 (hybrid APF–MPC multi-target debris rendezvous): the targets are queued
(:class:`~agents.mission.MissionPlan`), an APF path is planned between consecutive goals
(:func:`agents.apf.apf_path`, eq. 1–6) and an MPC with horizon N = 20 and the cost of eq. 8
tracks it (:class:`~agents.mpc.MPCTracker`, OSQP on the exact discretised CWH model).

Gradient-descent paths chatter: near a body lying straight in the way to the goal the descent
zig-zags with its step length while it slides round. The path handed to the tracker is therefore
de-jittered (:func:`dejitter`): from each kept point it jumps to the last later point within a few
APF steps *in space* whose straight chord clears every body inflated like the tracker's keep-out.
Over such short hops the path keeps its APF shape (its distance to the bodies), but loses the
back-and-forth that would make the arc-length reference stall.

APF descent can also stall in a local minimum. Then the agent keeps the path up to the stall and
completes it with an A* path from the stall point to the goal (:func:`agents.astar_agent.
astar_path`); if that fails too, with an A* path from the start; every such fallback is counted
in ``agent.stats`` (``apf_stalls``, ``astar_fallbacks``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from agents.apf import APFParams, apf_path
from agents.astar_agent import GridMap, SegmentChecker, astar_path, default_cell
from agents.mission import Goal
from agents.mpc import MPCParams, MPCPathAgent, ReferenceParams
from agents.planning import PlanResult
from debris_gym.scenario import Scenario


def dejitter(
    points: np.ndarray, reach: float, clear: Callable[[np.ndarray, np.ndarray], bool]
) -> np.ndarray:
    """Drop back-and-forth detours from a dense path without changing its course.

    From each kept point, jump to the highest-index later point within ``reach`` (m, straight
    distance) whose chord ``clear(a, b)`` accepts (at most 8 candidates tried, farthest index
    first); the next point is always allowed.

    Args:
        points: (K, dim) path (m).
        reach: largest hop (m).
        clear: collision test of a straight segment.

    Returns:
        (K', dim) sub-sequence of ``points`` with the same first and last point.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) <= 2:
        return pts
    out = [pts[0]]
    i, last = 0, len(pts) - 1
    while i < last:
        dist = np.linalg.norm(pts[i + 1 :] - pts[i], axis=1)
        within = np.flatnonzero(dist <= reach) + i + 1
        j = i + 1
        for c in within[::-1][:8]:
            if c == i + 1 or clear(pts[i], pts[c]):
                j = int(c)
                break
        out.append(pts[j])
        i = j
    return np.asarray(out)


class APFMPCAgent(MPCPathAgent):
    """APF reference path + MPC tracker ("apf-mpc").

    Args:
        env: the DebrisGym env (``action="continuous"``).
        apf: APF planner parameters; None: :meth:`APFParams.for_scenario` (scaled to the field).
        mpc: MPC tracker parameters (the same defaults as the "astar" agent).
        reference: speed profile of the reference.
        ordering: "shortest", "polygon" (seed 000 Alg. 1) or "nearest" (the env's goal) order.
        replan_distance: deviation from the path (m) that triggers a re-plan; None: 2 % of the
            world size.
        fallback_cell: grid cell (m) of the A* fallback after an APF stall; None: the "astar"
            agent's default.
        dejitter_steps: largest de-jitter hop, in APF steps (0 disables the de-jitter).
    """

    name = "apf-mpc"

    def __init__(
        self,
        env: Any,
        apf: APFParams | None = None,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
        fallback_cell: float | None = None,
        dejitter_steps: float = 5.0,
    ) -> None:
        super().__init__(env, mpc, reference, ordering=ordering, replan_distance=replan_distance)
        self.apf_params = apf
        self.fallback_cell = fallback_cell
        self.dejitter_steps = dejitter_steps
        self._grid: GridMap | None = None

    def prepare(self, scenario: Scenario) -> None:
        self._apf = self.apf_params or APFParams.for_scenario(scenario)
        self._grid = None  # built on the first stall only
        self._checker = SegmentChecker(scenario, self.geometry)
        self.stats.update(apf_stalls=0, astar_fallbacks=0)

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        cfg = self.env.config
        ignore = () if goal.index is None else (goal.index,)
        result = apf_path(
            self.env.scenario,
            start,
            goal.point,
            self._apf,
            inflate=cfg.chaser_radius,
            geometry=self.geometry,
            ignore=ignore,
        )
        if not result.success:
            self.stats["apf_stalls"] += 1
            result = self._astar_completion(result, start, goal)
        if self.dejitter_steps <= 0 or len(result.waypoints) <= 2:
            return result
        inflate = np.full(self.geometry.n_bodies, cfg.chaser_radius + self.tracker.keepout_margin)
        if goal.index is not None:
            inflate[goal.index] = cfg.chaser_radius
        waypoints = dejitter(
            result.waypoints,
            self.dejitter_steps * self._apf.step_size,
            lambda a, b: self._checker.clear(a, b, inflate),
        )
        info = dict(result.info, raw_waypoints=result.waypoints)
        return PlanResult(result.success, waypoints, PlanResult.path_length(waypoints), info)

    def _astar_completion(self, partial: PlanResult, start: np.ndarray, goal: Goal) -> PlanResult:
        """The APF path up to its stall, then A* from there to the goal (or A* from the start)."""
        scen, cfg = self.env.scenario, self.env.config
        if self._grid is None:
            cell = self.fallback_cell or default_cell(scen)
            self._grid = GridMap(scen, cell)
        inflate = self._grid.body_inflation(
            cfg.chaser_radius + self.tracker.keepout_margin, goal.index, cfg.chaser_radius
        )
        self.stats["astar_fallbacks"] += 1
        stall = partial.waypoints[-1]
        for origin, prefix in ((stall, partial.waypoints[:-1]), (start, partial.waypoints[:0])):
            tail = astar_path(
                scen,
                origin,
                goal.point,
                cell=self._grid.cell,
                inflate=inflate,
                min_inflate=cfg.chaser_radius,
                grid=self._grid,
            )
            if tail.success:
                waypoints = np.vstack([prefix, tail.waypoints])
                info = dict(partial.info, fallback="astar", astar=tail.info)
                return PlanResult(True, waypoints, PlanResult.path_length(waypoints), info)
        return partial
