"""The "st-rrt" baseline: Tube-ST-RRT* plans in space-time, the shared MPC tracks the result.

Reference: [Zhou24] (key in docs/references.md). Leg by leg of the mission
(:class:`~agents.planners.mission.MissionPlan`, the same tour as the other baselines):

1. the moving bodies are seen from the goal's frame (the goal target's, or LVLH for the dock) over
   a planning window from now (:class:`~agents.planners.spacetime.SpaceTimeField`), every body
   grown by the chaser's radius plus the tracker's keep-out margin (the goal target by a quarter
   of the capture depth, as the other MPC agents do);
2. Tube-ST-RRT* (:func:`~agents.planners.st_rrt.st_rrt_star`) finds the earliest arrival at the
   approach point, a path of space-time nodes;
3. the path is cut at the env's step times into a tube of clearance balls and smoothed by the
   minimum-snap QP inside it (:mod:`agents.planners.tube`), starting at the chaser's velocity
   and arriving at rest in the goal's frame — at the target's velocity;
4. the MPC tracker (:class:`~agents.control.mpc.MPCTracker`, time-indexed keep-out) follows the
   trajectory *in time*: the reference over its horizon is the trajectory at now + k·dt plus the
   goal's predicted motion; after the arrival it is the approach point moving with the target,
   where the env counts the capture.

The plan is made again when the goal changes (a capture), when the chaser strays more than
``replan_distance`` from where the trajectory says it should be now, when the trajectory has
ended ``stall_steps`` ago without the goal being met, and ``retry_steps`` after a failed search
(meanwhile a straight line to the goal at half the planning speed is tracked, guarded by the
MPC's keep-out). The search's generator is re-seeded from ``seed`` every episode, so episodes
are repeatable.

Flying one chaser of a swarm (a view with ``teammates``:
:class:`~agents.policies.chaser_view.ChaserView`), the planning is *prioritised*: the chasers
decide in their team's order and share their plans, and a chaser's space-time field holds, as
moving bodies besides the debris, the chasers ahead of it in that order (and any held at its
formation slot) — each a sphere of the collision distance on its predicted track, the plan it
shared flown on from where it is (:meth:`ChaserView.teammates` with ``ahead=True``), grown by
the chaser's radius and the keep-out margin; the chasers behind it plan around it in turn. The
plan is made again, at most every ``retry_steps`` decisions, when a teammate ahead has changed
its plan so that the trajectory would come within the collision distance plus half the margin
of it. The plan shared (:meth:`STRRTAgent.planned_states`) is the MPC's solution over its
horizon followed by the trajectory, to its end and ``stall_steps`` beyond (held at the goal).
The MPC keeps out of every teammate besides (``MPCParams.teammates_per_step`` nearest, as the
other MPC members do), a safety net for what the prediction misses.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from agents.control.mpc import MPCParams, MPCTracker
from agents.planners.mission import Goal, MissionPlan
from agents.planners.motion import FieldMotion
from agents.planners.spacetime import SpaceTimeField
from agents.planners.st_rrt import STRRTParams, st_rrt_star
from agents.planners.teammates import MovingSpheres
from agents.planners.tube import SmoothParams, build_tube, smooth_in_tube
from agents.policies.base import ClassicalAgent, teammates_of
from debris_gym.dynamics import discretize
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

__all__ = ["STRRTAgent"]


class STRRTAgent(ClassicalAgent):
    """Tube-ST-RRT* trajectory + MPC tracker ("st-rrt").

    Args:
        env: the DebrisGym env (``action="continuous"``).
        planner: Tube-ST-RRT* parameters; None: :class:`STRRTParams` scaled to the field:
            ``max_speed`` 0.75 × the tracker's default cruise speed sqrt(0.035 · max_accel ·
            size) (0.99 m/s on the 1 km fields), steer range and sampling padding 20 % of the
            world size, bounds margin 1 %, horizon 400 steps.
        smoothing: minimum-snap parameters.
        mpc: tracker parameters (the same defaults as the other MPC agents).
        ordering: "shortest", "polygon" or "nearest" target order (:class:`MissionPlan`).
        seed: seed of the search's generator, re-seeded every episode.
        replan_distance: distance (m) from the trajectory's present point that triggers a
            re-plan; None: 2 % of the world size.
        stall_steps: re-plan after the trajectory has ended this many steps ago with the goal
            unmet.
        retry_steps: decisions between attempts after a failed search (and between re-plans
            for a teammate ahead).
        teammates: flying one chaser of a swarm, plan around the teammates ahead of it
            (prioritised planning, above); False: the plan leaves them out (the MPC still keeps
            out of them, per ``mpc.teammates_per_step``). No effect on a single env.

    Attributes:
        tracker: the episode's :class:`MPCTracker`.
        stats: per-episode counters: plans, replans, stall_replans, teammate_replans,
            plan_failures, smooth_failures (QP unsolved: the raw path is tracked),
            unbounded_smooths (solved only without the acceleration bound), plan_time (s,
            total).
        plan_times: wall time (s) of every plan since the agent was built.
        decision_times: wall time (s) of every :meth:`act` call since the agent was built.
        trajectory_log: (times, LVLH positions) of every trajectory this episode.
    """

    name = "st-rrt"

    def __init__(
        self,
        env: Any,
        planner: STRRTParams | None = None,
        smoothing: SmoothParams | None = None,
        mpc: MPCParams | None = None,
        *,
        ordering: str = "shortest",
        seed: int = 0,
        replan_distance: float | None = None,
        stall_steps: int = 20,
        retry_steps: int = 5,
        teammates: bool = True,
    ) -> None:
        super().__init__(env)
        for name, value in (("stall_steps", stall_steps), ("retry_steps", retry_steps)):
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not (isinstance(seed, int) and seed >= 0):
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        if not isinstance(teammates, bool):
            raise ValueError(f"teammates must be True or False, got {teammates!r}")
        if replan_distance is not None and not replan_distance > 0:
            raise ValueError(f"replan_distance must be > 0 m or None, got {replan_distance!r}")
        self.planner_params = planner
        self.smooth_params = smoothing or SmoothParams()
        self.mpc_params = mpc or MPCParams()
        self.ordering = ordering
        self.seed = seed
        self.replan_distance = replan_distance
        self.stall_steps = stall_steps
        self.retry_steps = retry_steps
        self.plan_around_teammates = teammates
        self._teammates = teammates_of(self.env)
        self._planned: tuple[float, np.ndarray] | None = None
        self._tracker: MPCTracker | None = None
        self.stats: dict[str, Any] = {}
        self.plan_times: list[float] = []
        self.decision_times: list[float] = []

    @property
    def tracker(self) -> MPCTracker:
        """The episode's :class:`MPCTracker` (``RuntimeError`` before the agent first acts)."""
        if self._tracker is None:
            raise RuntimeError(f"the {self.name!r} agent has no tracker before it first acts")
        return self._tracker

    # --- ClassicalAgent -----------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.motion = FieldMotion(scenario)
        moving = self.motion if scenario.moving else None
        self.mission = MissionPlan(scenario, cfg, self.ordering, motion=moving)
        self.geometry = FieldGeometry(scenario)
        movers = self.mpc_params.teammates_per_step if self._teammates is not None else 0
        self._tracker = MPCTracker(
            scenario, self.mpc_params, thrust_model=cfg.thrust_model,
            chaser_radius=cfg.chaser_radius, geometry=self.geometry, motion=moving,
            movers=movers,
        )  # fmt: skip
        self._step_matrix = discretize(scenario.mean_motion, scenario.dt, scenario.dim).ad
        self._planned = None
        self._mates_retry_at = -np.inf
        size = scenario.size
        cruise = np.sqrt(0.035 * scenario.max_accel * size)
        self.params = self.planner_params or STRRTParams(
            max_speed=0.75 * float(cruise), steer_range=0.2 * size, horizon=400 * scenario.dt,
            sample_padding=0.2 * size, bounds_margin=0.01 * size,
        )  # fmt: skip
        self.rng = np.random.default_rng(self.seed)
        self._replan_distance = (
            self.replan_distance if self.replan_distance is not None else 0.02 * size
        )
        self._goal_key: tuple | None = None
        self._goal: Goal | None = None
        self._traj: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._frame: int | None = None
        self._retry_at = -np.inf
        self._margins: dict[int, float] = {}
        self.stats = {
            "plans": 0, "replans": 0, "stall_replans": 0, "teammate_replans": 0,
            "plan_failures": 0, "smooth_failures": 0, "unbounded_smooths": 0, "plan_time": 0.0,
        }  # fmt: skip
        self.trajectory_log: list[tuple[np.ndarray, np.ndarray]] = []

    def act(self) -> np.ndarray:
        t0 = time.perf_counter()
        env, d = self.env, self.env.dim
        state = np.asarray(env.chaser_state, float)
        now = float(env.elapsed)
        captured = env.captured
        key: tuple = tuple(bool(c) for c in captured)
        if self.mission.nearest:
            goal = self.mission.current_goal(captured, state[:d], now)
            key += (None if goal is None else goal.index,)
        if key != self._goal_key:
            self._goal_key = key
            self._goal = self.mission.current_goal(captured, state[:d], now)
            self.tracker.reset()
            self._new_plan(state, now)
        elif self._goal is not None and self._needs_plan(state, now):
            self._new_plan(state, now)
        mates = None
        if self._teammates is not None and self.mpc_params.teammates_per_step:
            mates = self._teammates(self.tracker.N)
        braked = self._goal is None or self._traj is None
        if braked:
            accel = self.tracker.brake(state)
        else:
            ref_pos, ref_vel = self._reference(now)
            accel = self.tracker.command(
                state,
                ref_pos,
                ref_vel,
                margins=self.tracker.reachable_margins(state[:d], now, self._margins),
                now=now,
                movers=mates,
            )
        if self._teammates is not None:
            self._share_plan(state, now, braked)
        action = self.accel_to_action(accel)
        self.decision_times.append(time.perf_counter() - t0)
        return action

    def planned_states(self) -> tuple[float, np.ndarray] | None:
        """What the agent plans to fly, as of its last decision (kept only when it flies one
        chaser of a team): the decision's time (s) and the LVLH states (P + 1, 2·dim) at it and
        at each of the P steps after (m, m/s) — the MPC's solution over its horizon, then the
        trajectory to its end and ``stall_steps`` beyond, held at the goal; None when it
        braked instead (the MPC failed, or nothing is left to do) or has not decided this
        episode."""
        return self._planned

    def _share_plan(self, state: np.ndarray, now: float, braked: bool) -> None:
        """Keep this decision's plan for :meth:`planned_states`."""
        solution = self.tracker.last_solution
        if braked or self._traj is None or solution is None or not solution.ok:
            self._planned = None
            return
        head = np.vstack([state, solution.states])
        dt = self.scenario.dt
        steps = int(np.ceil((self._traj[0][-1] - now) / dt - 1e-9)) + self.stall_steps
        if steps < len(head):
            self._planned = (now, head)
            return
        k = np.arange(len(head), steps + 1)
        rel_pos, rel_vel = self._planned_track(now + dt * k)
        frame = self._frame_states(now, steps)[k]
        tail = np.concatenate([rel_pos, rel_vel], axis=1) + frame
        self._planned = (now, np.vstack([head, tail]))

    def _frame_states(self, now: float, steps: int) -> np.ndarray:
        """(steps + 1, 2·dim) LVLH states of the planning frame's origin at now, now + dt, …
        (the frame body's unforced CW motion, stepped exactly)."""
        out = np.empty((steps + 1, 2 * self.env.dim))
        out[0] = self._frame_state(now)
        moving = self._frame is not None and self.motion.moving
        for i in range(1, steps + 1):
            out[i] = self._step_matrix @ out[i - 1] if moving else out[0]
        return out

    def _trajectory_positions(self, now: float, steps: int) -> np.ndarray:
        """(steps + 1, dim) LVLH positions of the trajectory at now, now + dt, … (held at its
        end)."""
        d, dt = self.env.dim, self.scenario.dt
        rel, _ = self._planned_track(now + dt * np.arange(steps + 1))
        return rel + self._frame_states(now, steps)[:, :d]

    def _conflicts_with_teammates(self, now: float) -> bool:
        """Whether the trajectory, from now to its end, comes within the collision distance
        plus half the keep-out margin of a teammate ahead on its predicted track."""
        if self._teammates is None or not self.plan_around_teammates or self._traj is None:
            return False
        if now < self._mates_retry_at:
            return False
        steps = max(1, int(np.ceil((self._traj[0][-1] - now) / self.scenario.dt - 1e-9)))
        mates = self._teammates(steps, ahead=True)
        if mates.count == 0:
            return False
        mine = self._trajectory_positions(now, steps)
        # between two steps both are taken on their chords: the least distance of the
        # relative segment from the origin, in closed form
        rel = mine[None] - mates.tracks[:, : steps + 1]  # (J, S + 1, d)
        a, seg = rel[:, :-1], rel[:, 1:] - rel[:, :-1]
        den = np.maximum(np.einsum("jsd,jsd->js", seg, seg), 1e-300)
        frac = np.clip(-np.einsum("jsd,jsd->js", a, seg) / den, 0.0, 1.0)
        gaps = np.linalg.norm(a + frac[..., None] * seg, axis=2)
        keep = mates.radii + self.env.config.chaser_radius + 0.5 * self.tracker.keepout_margin
        return bool(np.any(gaps < keep[:, None]))

    # --- reference ----------------------------------------------------------------------------

    def _frame_state(self, t: float) -> np.ndarray:
        """LVLH state (2·dim,) of the planning frame's origin at ``t`` (s): the goal target's,
        or zeros for the dock."""
        return self.motion.body_state(self._frame, t if self.motion.moving else 0.0)

    def _planned_track(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Trajectory positions and velocities (goal frame) at times ``t`` (held at the end)."""
        if self._traj is None:
            raise RuntimeError("no trajectory planned")
        times, pos, vel = self._traj
        p = np.stack([np.interp(t, times, pos[:, i]) for i in range(pos.shape[1])], -1)
        v = np.stack([np.interp(t, times, vel[:, i]) for i in range(vel.shape[1])], -1)
        v = np.where((np.asarray(t) >= times[-1])[..., None], 0.0, v)
        return p, v

    def _reference(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference positions / velocities (LVLH) at now + k·dt, k = 1 … N."""
        n_steps, d, dt = self.tracker.N, self.env.dim, self.scenario.dt
        rel_pos, rel_vel = self._planned_track(now + dt * np.arange(1, n_steps + 1))
        track = self.motion.body_track(self._frame, now, n_steps)
        return rel_pos + track[:, :d], rel_vel + track[:, d:]

    def _needs_plan(self, state: np.ndarray, now: float) -> bool:
        """Whether to plan again now (counts the reason in :attr:`stats`)."""
        d = self.env.dim
        if self._traj is None:
            return now >= self._retry_at
        here = state[:d] - self._frame_state(now)[:d]
        planned, _ = self._planned_track(np.array([now]))
        if np.linalg.norm(here - planned[0]) > self._replan_distance:
            self.stats["replans"] += 1
            return True
        if now > self._traj[0][-1] + self.stall_steps * self.scenario.dt:
            self.stats["stall_replans"] += 1
            return True
        if self._conflicts_with_teammates(now):
            self.stats["teammate_replans"] += 1
            self._mates_retry_at = now + self.retry_steps * self.scenario.dt
            return True
        return False

    # --- planning -----------------------------------------------------------------------------

    def _inflation(self, position: np.ndarray, now: float, goal: Goal) -> np.ndarray:
        """Per-body growth (m): chaser radius + keep-out margin (goal target: a quarter of the
        capture depth), never more than the chaser's present gap to a body's circumscribed
        circle, so the start is always a valid state."""
        cfg = self.env.config
        scen = self.scenario
        n_bodies = len(scen.bodies)
        inflation = np.full(n_bodies, cfg.chaser_radius + self.tracker.keepout_margin)
        if goal.kind == "target":
            inflation[goal.index] = cfg.chaser_radius + 0.25 * cfg.capture_radius
        radii = np.array([b.radius for b in scen.bodies])
        centres = self.motion.positions(now) if scen.moving else self.motion.positions(0.0)
        present = np.linalg.norm(centres - position, axis=1) - radii
        return np.minimum(inflation, present - 0.05)

    def _mates_ahead(self, now: float, horizon: float) -> MovingSpheres | None:
        """The teammates ahead of this chaser on their predicted tracks over a planning
        window of ``horizon`` s from ``now`` (None: none to plan around)."""
        if self._teammates is None or not self.plan_around_teammates:
            return None
        dt = self.scenario.dt
        steps = max(2, int(np.ceil(horizon / dt)) + 1) - 1  # the window's grid (SpaceTimeField)
        return self._teammates(steps, ahead=True)

    def _mover_inflation(self, position: np.ndarray, movers: MovingSpheres | None) -> np.ndarray:
        """Per-teammate growth (m): chaser radius + keep-out margin, never more than the
        chaser's present gap to its sphere (the start stays a valid state)."""
        if movers is None or movers.count == 0:
            return np.zeros(0)
        grow = self.env.config.chaser_radius + self.tracker.keepout_margin
        present = np.linalg.norm(movers.tracks[:, 0] - position, axis=1) - movers.radii
        return np.minimum(grow, present - 0.05)

    def _new_plan(self, state: np.ndarray, now: float) -> None:
        goal = self._goal
        if goal is None:
            self._traj = None
            return
        cfg, scen, d = self.env.config, self.scenario, self.env.dim
        t0 = time.perf_counter()
        goal = self._goal = self.mission.current_goal(self.env.captured, state[:d], now) or goal
        self._frame = goal.index if goal.kind == "target" else None
        target = goal.index  # None for the dock
        self._margins = {target: 0.25 * cfg.capture_radius} if target is not None else {}
        frame_state = self._frame_state(now)
        rel = state - frame_state
        goal_rel = goal.point - frame_state[:d]
        p = self.params
        movers = self._mates_ahead(now, p.horizon)
        thrust = scen.max_accel * (np.sqrt(d) if cfg.thrust_model == "box" else 1.0)
        field = SpaceTimeField(
            self.motion, now, p.horizon, self._frame, self._inflation(state[:d], now, goal),
            movers=movers, mover_inflation=self._mover_inflation(state[:d], movers),
            mover_thrust=float(thrust),
        )  # fmt: skip
        result = st_rrt_star(field, rel[:d], goal_rel, p, self.rng)
        self.stats["plans"] += 1
        if result.success:
            tube = build_tube(field, result.times, result.positions, self.smooth_params.hold_steps)
            traj = smooth_in_tube(tube, rel[d:], scen.max_accel, self.smooth_params)
            self.stats["smooth_failures"] += int(not traj.success)
            self.stats["unbounded_smooths"] += int(not traj.info.get("accel_bounded", True))
            self._traj = (traj.times, traj.positions, traj.velocities)
        else:
            self.stats["plan_failures"] += 1
            self._retry_at = now + self.retry_steps * scen.dt
            self._traj = self._straight(rel[:d], goal_rel, now)
        times, pos, _ = self._traj
        track = np.array([self._frame_state(t)[:d] for t in times])
        self.trajectory_log.append((times.copy(), pos + track))
        elapsed = time.perf_counter() - t0
        self.stats["plan_time"] += elapsed
        self.plan_times.append(elapsed)

    def _straight(
        self, start: np.ndarray, goal: np.ndarray, now: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A straight line to the goal at half the planning speed (after a failed search)."""
        dt = self.scenario.dt
        length = float(np.linalg.norm(goal - start))
        steps = max(1, int(np.ceil(length / (0.5 * self.params.max_speed * dt))))
        frac = np.linspace(0.0, 1.0, steps + 1)[:, None]
        pos = start + frac * (goal - start)
        vel = np.zeros_like(pos)
        vel[:-1] = (goal - start) / (steps * dt)
        return now + dt * np.arange(steps + 1), pos, vel
