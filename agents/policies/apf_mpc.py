"""APF-MPC: an artificial-potential-field path tracked by a linear MPC on the CWH model.

Reference: [APF-MPC] (key in docs/references.md): the targets are queued
(:class:`~agents.planners.mission.MissionPlan`), an APF path is planned between consecutive goals
(:func:`agents.planners.apf.apf_path`, eq. 1–6) and an MPC with horizon N = 20 and the cost of
eq. 8 tracks it (:class:`~agents.control.mpc.MPCTracker`, OSQP on the exact discretised CWH
model).

The path handed to the tracker is de-jittered (:func:`agents.planners.paths.dejitter`): hops of a
few APF steps whose straight chord clears every body inflated like the tracker's keep-out.

APF descent can also stall in a local minimum. Then the agent keeps the path up to the stall and
completes it with an A* path from the stall point to the goal
(:func:`agents.planners.astar.astar_path`); if that fails too, with an A* path from the start;
every such fallback is counted in ``agent.stats`` (``apf_stalls``, ``astar_fallbacks``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.control.mpc import MPCParams
from agents.control.reference import ReferenceParams
from agents.planners.apf import APFParams, apf_path
from agents.planners.astar import GridMap, SegmentChecker, astar_path, default_cell
from agents.planners.mission import Goal
from agents.planners.paths import dejitter
from agents.planners.result import PlanResult
from agents.policies.tracking import MPCPathAgent
from debris_gym.scenario import Scenario

__all__ = ["APFMPCAgent"]


class APFMPCAgent(MPCPathAgent):
    """APF reference path + MPC tracker ("apf-mpc").

    Args:
        env: the DebrisGym env (``action="continuous"``).
        apf: APF planner parameters; None: :meth:`APFParams.for_scenario` (scaled to the field).
        mpc: MPC tracker parameters (the same defaults as the "astar" agent).
        reference: speed profile of the reference.
        ordering: "shortest", "polygon" ([APF-MPC] Alg. 1) or "nearest" (the env's goal) order.
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

    def prepare_snapshot(self, snapshot: Scenario) -> None:
        self._grid = None
        self._checker = SegmentChecker(snapshot, self.plan_geometry)

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        cfg = self.env.config
        ignore = () if goal.index is None else (goal.index,)
        result = apf_path(
            self.plan_scenario,
            start,
            goal.point,
            self._apf,
            inflate=cfg.chaser_radius,
            geometry=self.plan_geometry,
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
        scen, cfg = self.plan_scenario, self.env.config
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
