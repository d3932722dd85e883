"""Planner + tracker baselines: plan a waypoint path per goal, track it with the MPC.

:class:`MPCPathAgent` is the shared base of "apf-mpc" and "astar": the only difference between
them is the planner (:meth:`MPCPathAgent.plan_path`), so comparing them compares planners.

In a moving field (the v1 world) the agent plans against the bodies' predicted motion
(:class:`~agents.planners.motion.FieldMotion`):

* the path to a target is planned on the field frozen as it is now (a snapshot) and kept in the
  *target's frame*: the waypoints minus the target's position now. The chaser's motion relative
  to the target obeys the same CWH law, so the tracker flies the path in that frame and the
  reference handed to the MPC is the relative reference plus the target's predicted state at
  every step of the horizon: near the target the reference is a point that moves with it, at its
  velocity, which is what capture asks (low speed relative to the target, held);
* the MPC's keep-out half-spaces come from the bodies where they will be at each step of the
  horizon (:class:`~agents.control.mpc.MPCTracker` with ``motion``);
* the path is re-planned every ``replan_every`` decisions on a fresh snapshot, as the field moves;
* the targets' order is the tour of least estimated time, each met where it will be.

In a frozen field (v0) none of this applies: the path is planned on the field itself, in LVLH,
and re-planned only as :class:`MPCPathAgent` describes (a new goal, straying, a stall).

Flying one chaser of a swarm (a view with ``teammates``:
:class:`~agents.policies.chaser_view.ChaserView`), the other chasers still in the field are
spheres on their predicted tracks (:mod:`agents.planners.teammates`) that the MPC keeps out
like the bodies, ``MPCParams.teammates_per_step`` nearest per step; the path itself is planned
on the field alone. The agent shares what it plans to fly (:meth:`MPCPathAgent.planned_states`),
which a team hands to the others' predictions (:class:`agents.policies.team.TeamOfSingles`).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from agents.control.mpc import MPCParams, MPCTracker
from agents.control.reference import PathReference, ReferenceParams
from agents.planners.mission import Goal, MissionPlan
from agents.planners.motion import FieldMotion
from agents.planners.result import PlanResult
from agents.policies.base import ClassicalAgent, teammates_of
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
        replan_every: in a moving field, re-plan on a fresh snapshot after this many decisions.

    Attributes:
        tracker: the episode's :class:`MPCTracker` (its ``stats``: solves, QP fallbacks to
            braking, steps that needed keep-out slack, OSQP iterations).
        stats: per-episode planner counters: plans, replans (deviation), stall_replans,
            plan_failures, plan_time (s), plus the subclass's own.
        path_log: the waypoint path of every plan this episode (m).
        decision_times: wall time (s) of every :meth:`act` call since the agent was built.
    """

    name = "mpc-path"

    replans_frozen_field = False
    """Whether :meth:`plan_expired` is asked in a frozen field too (a subclass whose plans
    age for another reason than the bodies' motion: teammates that move)."""

    def __init__(
        self,
        env: Any,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
        stall_steps: int = 60,
        replan_every: int = 3,
    ) -> None:
        super().__init__(env)
        if not (isinstance(replan_every, int) and replan_every >= 1):
            raise ValueError(f"replan_every must be an integer >= 1, got {replan_every!r}")
        self.replan_every = replan_every
        self.mpc_params = mpc or MPCParams()
        cfg = self.env.config
        reference = reference or ReferenceParams()
        self.reference_params = dataclasses.replace(
            reference, end_speed=min(reference.end_speed, 0.3 * cfg.capture_speed)
        )
        self.ordering = ordering
        self.replan_distance = replan_distance
        self.stall_steps = stall_steps
        self._tracker: MPCTracker | None = None
        self.stats: dict[str, Any] = {}
        self.decision_times: list[float] = []
        self._teammates = teammates_of(self.env) if self.mpc_params.teammates_per_step else None
        self._planned: tuple[float, np.ndarray] | None = None

    @property
    def tracker(self) -> MPCTracker:
        """The episode's :class:`MPCTracker`.

        Raises:
            RuntimeError: before the first episode's plan (the agent has not acted yet).
        """
        if self._tracker is None:
            raise RuntimeError(f"the {self.name!r} agent has no tracker before it first acts")
        return self._tracker

    # --- hooks --------------------------------------------------------------------------------

    @property
    def reference(self) -> PathReference | None:
        """The reference being flown (None between plans or at the mission's end)."""
        return self._ref

    @property
    def goal(self) -> Goal | None:
        """The goal the current plan leads to (None before the first plan)."""
        return self._goal

    def prepare(self, scenario: Scenario) -> None:
        """Per-scenario planner set-up (e.g. a grid); called by :meth:`plan`."""

    def prepare_snapshot(self, snapshot: Scenario) -> None:
        """Moving field: set up the planner on the field frozen as it is now (called before
        every :meth:`plan_path`; :attr:`plan_scenario` and :attr:`plan_geometry` are set)."""

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        """A collision-free path (m) from ``start`` to ``goal.point`` on :attr:`plan_scenario`
        (the field, or in a moving field the field frozen as it is now)."""
        raise NotImplementedError

    def plan_expired(self, now: float) -> bool:
        """Moving field: whether to re-plan on a fresh snapshot at time ``now`` (s); by default
        every ``replan_every`` decisions."""
        return self._since_plan >= self.replan_every

    # --- ClassicalAgent -----------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.motion = FieldMotion(scenario) if scenario.moving else None
        self.mission = MissionPlan(scenario, cfg, self.ordering, motion=self.motion)
        self.geometry = FieldGeometry(scenario)
        self.plan_scenario = scenario
        self.plan_geometry = self.geometry
        self._tracker = MPCTracker(
            scenario,
            self.mpc_params,
            thrust_model=cfg.thrust_model,
            chaser_radius=cfg.chaser_radius,
            geometry=self.geometry,
            motion=self.motion,
            movers=self.mpc_params.teammates_per_step if self._teammates is not None else 0,
        )
        self._planned = None
        self._since_plan = 0
        self._replan_distance = (
            self.replan_distance if self.replan_distance is not None else 0.02 * scenario.size
        )
        self._goal_key: tuple | None = None
        self._goal: Goal | None = None
        self._ref: PathReference | None = None
        self._best_progress = 0  # the path sample reached, and decisions since it was
        self._since_progress = 0
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
        elapsed = env.elapsed
        now = elapsed if self.motion is not None else None
        captured = env.captured
        key: tuple[Any, ...] = tuple(bool(c) for c in captured)
        goal = None
        self._since_plan += 1
        if self.mission.nearest:  # the env's goal can change without a capture
            goal = self.mission.current_goal(captured, pos, now)
            key += (None if goal is None else goal.index,)
        if key != self._goal_key:
            self._goal_key = key
            self._goal = goal or self.mission.current_goal(captured, pos, now)
            self.tracker.reset()
            self._new_path(pos)
        elif (self.motion is not None or self.replans_frozen_field) and self.plan_expired(elapsed):
            self._new_path(pos)
        elif self._ref is not None and self._ref.deviation > self._replan_distance:
            self.stats["replans"] += 1
            self._new_path(pos)
        elif self._ref is not None and self._stalled(self._ref):
            self.stats["stall_replans"] += 1
            self._new_path(pos)
        mates = None if self._teammates is None else self._teammates(self.tracker.N)
        # a path (_ref) is only ever made for a goal
        if self._ref is None or self._goal is None:  # nothing left to do: hold still
            accel = self.tracker.brake(state)
        elif self.motion is None:
            ref_pos, ref_vel = self._ref.horizon(state, self.tracker.N)
            accel = self.tracker.command(
                state, ref_pos, ref_vel, margins=self._margins, movers=mates
            )
        else:  # the path lives in the goal's frame: add the goal's predicted motion back
            frame = self._goal.index  # None for the dock
            rel = state - self.motion.body_state(frame, elapsed)
            rel_pos, rel_vel = self._ref.horizon(rel, self.tracker.N)
            track = self.motion.body_track(frame, elapsed, self.tracker.N)
            accel = self.tracker.command(
                state, rel_pos + track[:, :d], rel_vel + track[:, d:],
                margins=self.tracker.reachable_margins(pos, elapsed, self._margins), now=elapsed,
                movers=mates,
            )  # fmt: skip
        if self._teammates is not None:
            self._share_plan(state, elapsed, braked=self._ref is None or self._goal is None)
        action = self.accel_to_action(accel)
        self.decision_times.append(time.perf_counter() - t0)
        return action

    def planned_states(self) -> tuple[float, np.ndarray] | None:
        """What the agent plans to fly, as of its last decision (kept only when it flies one
        chaser of a team): the decision's time (s) and the states (N + 1, 2·dim) at it and
        after each of the MPC's N steps (m, m/s); None when it braked instead (the MPC failed,
        or nothing is left to do) or has not decided this episode."""
        return self._planned

    def _share_plan(self, state: np.ndarray, now: float, braked: bool) -> None:
        """Keep this decision's plan for :meth:`planned_states`."""
        solution = self.tracker.last_solution
        if braked or solution is None or not solution.ok:
            self._planned = None
        else:
            self._planned = (now, np.vstack([state, solution.states]))

    def _stalled(self, ref: PathReference) -> bool:
        """No progress along ``ref``, short of its end, for ``stall_steps`` decisions."""
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
        cfg = self.env.config
        self._since_plan = 0
        frame_pos = np.zeros(len(pos))
        t0 = time.perf_counter()
        if self.motion is not None:  # plan on the field as it is now, in the goal's frame
            now = self.env.elapsed
            self.plan_scenario = self.motion.snapshot(now)
            self.plan_geometry = self.motion.geometry(now)
            goal = self._goal = self.mission.current_goal(self.env.captured, pos, now) or goal
            if goal.kind == "target":
                frame_pos = self.motion.body_state(goal.index, now)[: len(pos)]
            self.prepare_snapshot(self.plan_scenario)
        target = goal.index  # None for the dock
        self._margins = {target: 0.25 * cfg.capture_radius} if target is not None else {}
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
        self._ref = self.make_reference(np.asarray(waypoints) - frame_pos, result)

    def make_reference(self, waypoints: np.ndarray, result: PlanResult) -> PathReference:
        """The reference the tracker follows for a new plan: ``waypoints`` (m, in the goal's
        frame in a moving field) with the speed profile of :class:`PathReference`. A subclass
        whose planner times its path (``result``) may return any object with the same
        ``horizon`` / ``deviation`` / ``progress`` / ``s`` / ``spacing``."""
        scen = self.scenario
        return PathReference(
            waypoints,
            max_accel=scen.max_accel,
            dt=scen.dt,
            params=self.reference_params,
            world_size=scen.size,
        )
