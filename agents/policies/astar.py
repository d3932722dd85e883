"""The "astar" baseline: an A* grid path (:func:`agents.planners.astar.astar_path`) tracked by the
same MPC as "apf-mpc" (:class:`agents.policies.tracking.MPCPathAgent`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from agents.control.mpc import MPCParams
from agents.control.reference import ReferenceParams
from agents.planners.astar import GridMap, astar_path, default_cell
from agents.planners.mission import Goal
from agents.planners.result import PlanResult
from agents.policies.tracking import MPCPathAgent
from debris_gym.scenario import Scenario

__all__ = ["AStarAgent"]


class AStarAgent(MPCPathAgent):
    """A* grid path + the same MPC tracker as APF-MPC ("astar").

    Args:
        env: the DebrisGym env (``action="continuous"``).
        cell: grid cell (m); None: :func:`default_cell` (4 m in 2D, 25 m in 3D on 1 km fields).
        margin: safety margin (m) on top of the chaser radius for the obstacles; None: the
            tracker's keep-out margin. The goal target is inflated by the chaser radius only.
        mpc: MPC tracker parameters (the same defaults as "apf-mpc").
        reference: speed profile of the reference.
        ordering: "shortest", "polygon" or "nearest" target order (see :class:`MissionPlan`).
        replan_distance: deviation from the path (m) that triggers a re-plan; None: 2 % of the
            world size.

    The grid is searched with conservative rasterisation first; if that closes every route (a
    coarse cell can seal a narrow gap), once more with cell centres only, counted in
    ``stats["exact_grid_retries"]`` (the tracker's keep-out still guards that path).
    """

    name = "astar"

    def __init__(
        self,
        env: Any,
        cell: float | None = None,
        margin: float | None = None,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
    ) -> None:
        super().__init__(env, mpc, reference, ordering=ordering, replan_distance=replan_distance)
        self.cell = cell
        self.margin = margin
        self.grid: GridMap | None = None

    def prepare(self, scenario: Scenario) -> None:
        cell = self.cell if self.cell is not None else default_cell(scenario)
        if self.grid is None or self.grid.scenario is not scenario or self.grid.cell != cell:
            self.grid = GridMap(scenario, cell)
        self.stats.update(exact_grid_retries=0)

    def prepare_snapshot(self, snapshot: Scenario) -> None:
        self.grid = GridMap(snapshot, self._prepared_grid().cell)

    def _prepared_grid(self) -> GridMap:
        if self.grid is None:
            raise RuntimeError("the A* grid is built when the agent first acts (predict())")
        return self.grid

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        cfg = self.env.config
        margin = self.margin if self.margin is not None else self.tracker.keepout_margin
        grid = self._prepared_grid()
        inflate = grid.body_inflation(cfg.chaser_radius + margin, goal.index, cfg.chaser_radius)
        for conservative in (True, False):
            result = astar_path(
                self.plan_scenario,
                start,
                goal.point,
                cell=grid.cell,
                inflate=inflate,
                min_inflate=cfg.chaser_radius,
                conservative=conservative,
                grid=grid,
            )
            if result.success:
                break
            self.stats["exact_grid_retries"] += 1
        return result
