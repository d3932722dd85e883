"""The "apf-rrt" baseline: the APF agent that escapes local minima with an RRT ([An23] §3).

The detection test, the RRT and the virtual repulsive points are :mod:`agents.planners.apf` and
:mod:`agents.planners.rrt`; this module watches the flight for a stall and follows the escape
route.

In a moving field (the v1 world) a trap is rarely a point at rest: the bodies that form it drift,
and a chaser caught in it is carried along, often pushed away from the goal by a body closing in
on it, for many minutes. The repulsion then opposes the attraction but outweighs it (the body
pushes harder than the goal pulls), so eq. 14's balance test misses it. There a stall is declared
on eq. 14 with its balance test one-sided (:func:`~agents.planners.apf.is_held_back`: repulsion
nearly opposite the attraction and at least half as strong), and "no progress" means that the
closest approach to the goal has not improved over the window (the goal distance of a chaser
carried by a drifting trap wanders, so its change from the window's start is no measure). In a
frozen field the test is eq. 14 itself, with the goal distance's net progress over the window.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from agents.planners.apf import APFParams, VirtualPoint, is_held_back, is_local_minimum
from agents.planners.mission import Goal
from agents.planners.rrt import EdgeChecker, RRTParams, escape_route, exit_index, virtual_point
from agents.policies.apf import APFAgent, APFGuidance
from debris_gym.scenario import Scenario

__all__ = ["APFRRTAgent"]


class APFRRTAgent(APFAgent):
    """APF agent that escapes local minima with an RRT ("apf-rrt"; [An23] §3).

    A local minimum is declared when the goal distance has not dropped by ``stall_progress`` over
    the last ``stall_time`` and the forces averaged over that window pass the eq. 14 test
    (:func:`~agents.planners.apf.is_local_minimum`; the average also catches a chaser that
    chatters in the minimum instead of stopping). Then an RRT is grown from the chaser to the
    goal, a virtual repulsive point is placed at the stall point, and the RRT waypoints become the
    attractor (one at a time) until the exit waypoint (:func:`~agents.planners.rrt.exit_index`);
    APF then continues to the goal, the virtual point in force. Virtual points are cleared when
    the mission moves on.

    In a moving field the balance test is one-sided and progress is measured by the closest
    approach (module docstring); the RRT is grown
    on the field as it is at the stall, and the route and the virtual point are kept in the
    goal's frame (like the APF itself), so they move with the target.

    Until the first escape the agent flies exactly as :class:`APFAgent`; with
    ``RRTParams(max_escapes=0)`` it never escapes and only counts the minima APF falls into
    (:attr:`detections`), which is how the ``hard`` suite is selected
    (:mod:`agents.experiments.hard_suite`).

    Attributes (per episode):
        detections: local minima detected (each stall counted once; escapes or not).
        escapes: RRT escapes started.
        stall_points: where they started (m, LVLH at the time).

    Args:
        env: the DebrisGym env.
        params, guidance, ordering: as :class:`APFAgent`.
        rrt: RRT parameters; default :meth:`RRTParams.for_scenario`.
        seed: seed of the RRT's generator (re-seeded every episode, so episodes are repeatable).
    """

    name = "apf-rrt"

    def __init__(
        self,
        env: Any,
        params: APFParams | None = None,
        guidance: APFGuidance | None = None,
        ordering: str = "shortest",
        rrt: RRTParams | None = None,
        seed: int = 0,
    ) -> None:
        super().__init__(env, params, guidance, ordering)
        self._fixed_rrt = rrt
        self.seed = seed

    def plan(self, scenario: Scenario) -> None:
        super().plan(scenario)
        self.rrt = self._fixed_rrt or RRTParams.for_scenario(scenario)
        self.rng = np.random.default_rng(self.seed)
        self.escapes = 0
        self.detections = 0
        self.stall_points: list[np.ndarray] = []
        self._checkers: dict[tuple, EdgeChecker] = {}
        self._reset_goal_state()

    @property
    def route(self) -> np.ndarray | None:
        """The RRT waypoints being followed (m, where they are now), or None."""
        if self._route is None:
            return None
        return self._route + self.frame_pos

    @route.setter
    def route(self, waypoints: np.ndarray | None) -> None:
        # kept in the goal's frame (the frame's origin is zero in a frozen field)
        self._route = None if waypoints is None else np.asarray(waypoints) - self.frame_pos

    def _reset_goal_state(self) -> None:
        self.route = None  # RRT waypoints being followed
        self.route_index = 0
        self.route_exit = 0
        self.route_history: list[float] = []
        self.goal_escapes = 0
        self.history: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.best_gap = math.inf  # closest approach to the goal (m) before the window
        self.stall_steps = max(1, round(self.guidance.stall_time / self.scenario.dt))

    def on_new_goal(self, goal: Goal) -> None:
        super().on_new_goal(goal)
        self._reset_goal_state()

    def attractor(self, pos: np.ndarray, goal: Goal) -> np.ndarray:
        if self.route is None:
            return goal.point
        last = len(self.route) - 1
        while self.route_index < last and (
            float(np.linalg.norm(self.route[self.route_index] - pos)) <= self.rrt.waypoint_tol
        ):
            if self.route_index >= self.route_exit:
                self._leave_route()
                return goal.point
            self.route_index += 1
            self.route_history = []
        if self.route_index < last:
            return self.route[self.route_index]
        # the last leg aims at the goal's current approach point (the RRT's goal was the one on
        # the side the chaser faced when it got stuck); APF takes over close to it
        if float(np.linalg.norm(goal.point - pos)) <= self.rrt.waypoint_tol:
            self._leave_route()
        return goal.point

    def repulsion_scale(self) -> float:
        return 1.0 if self.route is None else self.rrt.route_repulsion

    def active_virtual(self) -> list[VirtualPoint]:
        # on the RRT route the route leads out of the trap; the virtual points act after it
        return super().active_virtual() if self._route is None else []

    def _leave_route(self) -> None:
        """Past the exit waypoint (or stuck on the route): APF takes over."""
        self.route = None
        self._restart_window()

    def _restart_window(self) -> None:
        """Forget the flight so far: the next stall is judged on a fresh window."""
        self.history = []
        self.best_gap = math.inf

    def observe_forces(
        self, pos: np.ndarray, vel: np.ndarray, goal: Goal, f_att: np.ndarray, f_rep: np.ndarray
    ) -> None:
        g = self.guidance
        w = self.stall_steps
        if self.route is not None:
            # stuck short of a waypoint (the repulsion holds the chaser off it): skip it
            aim = goal.point if self.route_index == len(self.route) - 1 else None
            aim = self.route[self.route_index] if aim is None else aim
            self.route_history.append(float(np.linalg.norm(aim - pos)))
            hist = self.route_history
            if len(hist) > w and hist[-1 - w] - hist[-1] < g.stall_progress:
                if self.route_index >= self.route_exit:
                    self._leave_route()
                else:
                    self.route_index += 1
                    self.route_history = []
            return
        self.history.append((float(np.linalg.norm(goal.point - pos)), f_att, f_rep))
        if len(self.history) <= w:
            return
        if self.motion is None:
            del self.history[: -w - 1]
            if self.history[0][0] - self.history[-1][0] >= g.stall_progress:
                return
        else:
            # closest approach before the window vs. within it (a drifting trap's goal
            # distance wanders, so only a new closest approach is progress)
            for gap, _, _ in self.history[: -w - 1]:
                self.best_gap = min(self.best_gap, gap)
            del self.history[: -w - 1]
            closest = min(h[0] for h in self.history[1:])
            if min(self.best_gap, self.history[0][0]) - closest >= g.stall_progress:
                return
        # eq. 14 on the window-mean forces: a chaser chattering in a minimum still passes
        mean_att = np.mean([h[1] for h in self.history], axis=0)
        mean_rep = np.mean([h[2] for h in self.history], axis=0)
        stalled = is_local_minimum if self.motion is None else is_held_back
        if not stalled(mean_att, mean_rep, self.params):
            return
        self.detections += 1
        if self.goal_escapes >= self.rrt.max_escapes:
            self._restart_window()  # counted once; APF flies on
            return
        self._escape(pos, goal)

    def _escape(self, pos: np.ndarray, goal: Goal) -> None:
        ignore = () if goal.index is None else (goal.index,)
        found = escape_route(
            self.geometry,
            pos,
            goal.point,
            self.inflate,
            ignore,
            self.params,
            self.rrt,
            self.rng,
            self._checkers if self.motion is None else {},  # a moving field: this snapshot's
        )
        self._restart_window()
        if not found.success:
            return
        self.goal_escapes += 1
        self.escapes += 1
        self.stall_points.append(pos.copy())
        vp = virtual_point(pos, goal.point, self.rrt)
        self.virtual.append((vp[0] - self.frame_pos, vp[1]))
        self.route = found.waypoints
        self.route_index = 1
        self.route_exit = exit_index(
            found.waypoints, pos, goal.point, vp[1], self.guidance.stall_progress
        )
        self.route_history = []
