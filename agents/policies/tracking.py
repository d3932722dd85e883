"""Planner + tracker baselines: plan a waypoint path per goal, track it with the MPC.

:class:`MPCPathAgent` is the shared base of "apf-mpc" and "astar": the only difference between
them is the planner (:meth:`MPCPathAgent.plan_path`), so comparing them compares planners.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from agents.control.mpc import MPCParams, MPCTracker
from agents.control.reference import PathReference, ReferenceParams
from agents.planners.mission import Goal, MissionPlan
from agents.planners.result import PlanResult
from agents.policies.base import ClassicalAgent
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

__all__ = ["MPCPathAgent"]


class MPCPathAgent(ClassicalAgent):
    """Base of the planner + MPC-tracker baselines (APF-MPC, A*): plan a path per goal, track it.

    For each goal of the :class:`~agents.planners.mission.MissionPlan` (an approach point next to
    the next uncaptured target, then the dock) a subclass's :meth:`plan_path` gives a waypoint path
    from the chaser's position; :class:`PathReference` turns it into a reference and
    :class:`MPCTracker` flies it. The path is re-planned when the goal changes (a capture) or
    when the chaser strays farther than ``replan_distance`` from it. At the path's end the
    reference stops at the approach point, so the tracker holds there until the env counts the
    capture. The goal target keeps a smaller keep-out margin (a quarter of the capture depth) so
    the approach point stays reachable.

    Args:
        env: the DebrisGym env.
        mpc: tracker parameters (shared by every subclass, so comparisons are of planners).
        reference: speed-profile parameters; ``end_speed`` is capped at 0.3 × capture speed.
        ordering: target visiting order, "shortest", "polygon" or "nearest" (the env's own
            current goal; see :class:`MissionPlan`).
        replan_distance: deviation from the path (m) that triggers a re-plan; None: 2 % of the
            world size.
        stall_steps: re-plan when the chaser has not advanced along the path (short of its end)
            for this many steps.

    Attributes:
        tracker: the episode's :class:`MPCTracker` (its ``stats``: solves, QP fallbacks to
            braking, steps that needed keep-out slack, OSQP iterations).
        stats: per-episode planner counters: plans, replans (deviation), stall_replans,
            plan_failures, plan_time (s), plus the subclass's own.
        path_log: the waypoint path of every plan this episode (m).
        decision_times: wall time (s) of every :meth:`act` call since the agent was built.
    """

    name = "mpc-path"

    def __init__(
        self,
        env: Any,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
        stall_steps: int = 60,
    ) -> None:
        super().__init__(env)
        self.mpc_params = mpc or MPCParams()
        cfg = self.env.config
        reference = reference or ReferenceParams()
        self.reference_params = dataclasses.replace(
            reference, end_speed=min(reference.end_speed, 0.3 * cfg.capture_speed)
        )
        self.ordering = ordering
        self.replan_distance = replan_distance
        self.stall_steps = stall_steps
        self.tracker: MPCTracker | None = None
        self.stats: dict[str, Any] = {}
        self.decision_times: list[float] = []

    # --- hooks --------------------------------------------------------------------------------

    def prepare(self, scenario: Scenario) -> None:
        """Per-scenario planner set-up (e.g. a grid); called by :meth:`plan`."""

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        """A collision-free path (m) from ``start`` to ``goal.point``."""
        raise NotImplementedError

    # --- ClassicalAgent -----------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.mission = MissionPlan(scenario, cfg, self.ordering)
        self.geometry = FieldGeometry(scenario)
        self.tracker = MPCTracker(
            scenario,
            self.mpc_params,
            thrust_model=cfg.thrust_model,
            chaser_radius=cfg.chaser_radius,
            geometry=self.geometry,
        )
        self._replan_distance = (
            self.replan_distance if self.replan_distance is not None else 0.02 * scenario.size
        )
        self._goal_key: tuple | None = None
        self._goal: Goal | None = None
        self._ref: PathReference | None = None
        self._margins: dict[int, float] = {}
        self.stats = {
            "plans": 0,
            "replans": 0,
            "stall_replans": 0,
            "plan_failures": 0,
            "plan_time": 0.0,
        }
        self.path_log: list[np.ndarray] = []
        self.prepare(scenario)

    def act(self) -> np.ndarray:
        t0 = time.perf_counter()
        env, d = self.env, self.env.dim
        state = env.chaser_state
        pos = state[:d]
        captured = env.captured
        key = tuple(bool(c) for c in captured)
        goal = None
        if self.mission.nearest:  # the env's goal can change without a capture
            goal = self.mission.current_goal(captured, pos)
            key += (None if goal is None else goal.index,)
        if key != self._goal_key:
            self._goal_key = key
            self._goal = goal or self.mission.current_goal(captured, pos)
            self.tracker.reset()
            self._new_path(pos)
        elif self._ref is not None and self._ref.deviation > self._replan_distance:
            self.stats["replans"] += 1
            self._new_path(pos)
        elif self._ref is not None and self._stalled():
            self.stats["stall_replans"] += 1
            self._new_path(pos)
        if self._ref is None:  # nothing left to do: hold still
            accel = self.tracker.brake(state)
        else:
            ref_pos, ref_vel = self._ref.horizon(state, self.tracker.N)
            accel = self.tracker.command(state, ref_pos, ref_vel, margins=self._margins)
        action = self.accel_to_action(accel)
        self.decision_times.append(time.perf_counter() - t0)
        return action

    def _stalled(self) -> bool:
        """No progress along the path, short of its end, for ``stall_steps`` decisions."""
        ref = self._ref
        if ref.progress > self._best_progress:
            self._best_progress = ref.progress
            self._since_progress = 0
            return False
        self._since_progress += 1
        near_end = (len(ref.s) - 1 - ref.progress) * ref.spacing <= 2.0 * self.tracker.ell
        return not near_end and self._since_progress >= self.stall_steps

    def _new_path(self, pos: np.ndarray) -> None:
        goal = self._goal
        if goal is None:
            self._ref = None
            return
        cfg, scen = self.env.config, self.env.scenario
        self._margins = {goal.index: 0.25 * cfg.capture_radius} if goal.kind == "target" else {}
        t0 = time.perf_counter()
        result = self.plan_path(pos, goal)
        self.stats["plan_time"] += time.perf_counter() - t0
        self.stats["plans"] += 1
        waypoints = result.waypoints
        if not result.success:
            self.stats["plan_failures"] += 1
            # Keep what the planner found and finish with a straight hop to the goal: the
            # tracker's keep-out constraints guard it.
            waypoints = np.vstack([waypoints, goal.point[None]])
        self.path_log.append(np.asarray(waypoints))
        self._best_progress = 0
        self._since_progress = 0
        self._ref = PathReference(
            waypoints,
            max_accel=scen.max_accel,
            dt=scen.dt,
            params=self.reference_params,
            world_size=scen.size,
        )
