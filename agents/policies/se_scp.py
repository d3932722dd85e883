"""The "se-scp" baseline: spherical expansion + sequential convex programming ([Bandyopadhyay17]),
tracked by the shared MPC.

Per goal of the tour (:class:`~agents.planners.mission.MissionPlan`), on the field as it is now:

1. :func:`~agents.planners.spherical_expansion.expand_spheres` grows a graph of body-free
   spheres from the chaser to the approach point (radii: the library's clearance minus the
   chaser's radius and the tracker's keep-out margin; the goal target keeps the smaller margin
   the other MPC baselines give it), and :func:`~agents.planners.spherical_expansion.shortest_chain`
   picks the shortest chain of overlapping spheres;
2. :func:`~agents.planners.scp.scp_trajectory` finds the fuel-optimal trajectory through that
   chain on the exact discretised CWH model, from the chaser's state to the approach point at the
   goal's velocity (in the goal target's frame in a moving field: the chaser's motion relative to
   the target obeys the same CWH law);
3. the shared :class:`~agents.control.mpc.MPCTracker` tracks that trajectory *in time*
   (:class:`TrajectoryReference`: the planned state at each coming step), with the same
   time-indexed keep-out and capture handling as "apf-mpc" and "astar".

Why track instead of flying the planned thrust open loop: the spheres are taken on the field
frozen now; in a moving field the other bodies drift between re-plans, and the MPC's keep-out
sees them where they will be at every step of its horizon. The tracker also absorbs what the
plan leaves out (the arc between plan points, solver tolerance). Tracking a dynamically feasible
reference whose thrust the MPC can reproduce costs little above the plan's own Δv.

In a moving field the plan is re-solved every ``replan_every`` decisions on a fresh snapshot
(receding horizon). If the chain or the programme fails, the chain's polyline (or a straight hop
to the goal) is flown with the other baselines' speed profile, counted in ``stats``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from agents.control.mpc import MPCParams
from agents.control.reference import ReferenceParams
from agents.planners.mission import Goal
from agents.planners.polytopes import inscribed_polytope
from agents.planners.result import PlanResult
from agents.planners.scp import SCPParams, SCPResult, scp_trajectory
from agents.planners.spherical_expansion import (
    ExpansionParams,
    SphereChain,
    chain_waypoints,
    expand_spheres,
    node_radii,
    shortest_chain,
)
from agents.policies.tracking import MPCPathAgent
from debris_gym.dynamics import discretize
from debris_gym.scenario import Scenario

__all__ = ["SESCPAgent", "TrajectoryReference"]


class TrajectoryReference:
    """A timed trajectory as the MPC tracker's reference (the interface of
    :class:`~agents.control.reference.PathReference`).

    Each call of :meth:`horizon` is one decision: it returns the planned states at the next
    ``steps`` steps and moves on one step; past the end it holds the last point at rest.

    Args:
        states: (K+1, 2·dim) planned states at the env's steps from now (m, m/s).
    """

    def __init__(self, states: np.ndarray) -> None:
        self.states = np.asarray(states, dtype=float)
        self.dim = self.states.shape[1] // 2
        count = len(self.states)
        steps = np.linalg.norm(np.diff(self.states[:, : self.dim], axis=0), axis=1)
        self.s = np.concatenate([[0.0], np.cumsum(steps)])
        self.spacing = float(self.s[-1] / max(count - 1, 1)) or 1e-9
        self.progress = 0
        self.deviation = 0.0
        self._calls = 0

    def horizon(self, state: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Reference positions (m) and velocities (m/s) at the next ``steps`` steps."""
        d, last = self.dim, len(self.states) - 1
        now = min(self._calls, last)
        self.progress = now
        self.deviation = float(np.linalg.norm(np.asarray(state)[:d] - self.states[now, :d]))
        index = np.minimum(now + 1 + np.arange(steps), last)
        ref = self.states[index].copy()
        ref[index >= last, d:] = self.states[last, d:]
        self._calls += 1
        return ref[:, :d], ref[:, d:]


class SweptGeometry:
    """Clearance (m) of points fixed in a goal's frame against the moving bodies, the least
    over a few times: what :func:`~agents.planners.spherical_expansion.node_radii` needs.

    A point is given where it is at the first time; at a later time t it has moved with the
    frame (the goal target, or LVLH itself for the dock), and its clearance is taken against the
    bodies where they are at t. So a sphere of that radius stays body-free at every sampled
    time (time-indexed spheres, sampled).

    Args:
        motion: the bodies' predicted motion.
        frame: index of the body whose frame the points ride in; None: LVLH (the dock).
        times: (S,) times (s), the first one now.
    """

    def __init__(self, motion: Any, frame: int | None, times: np.ndarray) -> None:
        self.geometries = [motion.geometry(float(t)) for t in times]
        self.dim = self.geometries[0].dim
        self.n_bodies = self.geometries[0].n_bodies
        base = motion.body_state(frame, float(times[0]))[: self.dim]
        self.shifts = [motion.body_state(frame, float(t))[: self.dim] - base for t in times]

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(M, n_bodies) least signed distance (m) over the times."""
        pts = np.asarray(points, dtype=float).reshape(-1, self.dim)
        out = self.geometries[0].signed_distance(pts + self.shifts[0])
        for geometry, shift in zip(self.geometries[1:], self.shifts[1:], strict=True):
            out = np.minimum(out, geometry.signed_distance(pts + shift))
        return out


class SESCPAgent(MPCPathAgent):
    """Spherical-expansion graph + SCP trajectory, tracked by the shared MPC ("se-scp").

    Args:
        env: the DebrisGym env (``action="continuous"``).
        expansion: spherical-expansion tunables; None: the defaults.
        scp: trajectory-optimisation tunables; None: the defaults with soft spheres
            (``sphere_penalty`` 100 m/s per m: a re-plan from a chaser moving too fast to stay
            in its first sphere still has a plan; the tracker's keep-out guards the bodies). Its
            ``step`` must be a whole number of env steps; None: two env steps.
        mpc: MPC tracker parameters (the same defaults as "apf-mpc").
        reference: speed profile of the fallback path reference.
        ordering: "shortest", "polygon" or "nearest" target order.
        replan_distance: deviation (m) from the planned trajectory that triggers a re-plan;
            None: 2 % of the world size.
        replan_every: in a moving field, re-solve on a fresh snapshot after this many
            decisions at the latest (:meth:`plan_expired` re-solves sooner when the plan meets a
            body).
        check_steps: steps ahead (env steps) the plan is checked against the moving bodies.
        sweep_steps: moving field: every sphere is kept clear of the bodies over this many env
            steps from now (sampled every 3 steps; :class:`SweptGeometry`).
        keep_fraction: fraction of the margin the plan may lose to the bodies' motion before
            it is re-solved.
        fallback_every: decisions between attempts to re-plan while a fallback path is flown.
        margin: keep-out (m) beyond the chaser radius of the spheres; None: the tracker's.
        seed: seed of the sampling generator (re-seeded every episode).
    """

    name = "se-scp"

    programme_substeps = 2
    """Env steps per step of the trajectory programme when ``scp.step`` is None."""

    keep_arrival = True
    """Whether a re-plan toward the same goal keeps the arrival time of the first plan (a
    shrinking horizon) instead of a fresh time allocation."""

    def __init__(
        self,
        env: Any,
        expansion: ExpansionParams | None = None,
        scp: SCPParams | None = None,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
        replan_every: int = 30,
        margin: float | None = None,
        check_steps: int = 20,
        sweep_steps: int = 12,
        fallback_every: int = 3,
        keep_fraction: float = 0.5,
        seed: int = 0,
    ) -> None:
        super().__init__(
            env, mpc, reference, ordering=ordering, replan_distance=replan_distance,
            replan_every=replan_every,
        )  # fmt: skip
        if margin is not None and not (math.isfinite(margin) and margin >= 0):
            raise ValueError(f"margin must be >= 0 m or None, got {margin!r}")
        if not (isinstance(seed, int) and seed >= 0):
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        self.scp_params = scp or SCPParams(sphere_penalty=100.0)
        sphere_facets, _ = self.scp_params.facets(self.env.dim)
        kappa = inscribed_polytope(self.env.dim, sphere_facets, "fibonacci").offset
        self.expansion_params = expansion or ExpansionParams(polytope_factor=kappa)
        if not (isinstance(check_steps, int) and check_steps >= 1):
            raise ValueError(f"check_steps must be an integer >= 1, got {check_steps!r}")
        if not (math.isfinite(keep_fraction) and 0.0 <= keep_fraction <= 1.0):
            raise ValueError(f"keep_fraction must be in [0, 1], got {keep_fraction!r}")
        self.margin = margin
        self.check_steps = check_steps
        if not (isinstance(sweep_steps, int) and sweep_steps >= 0):
            raise ValueError(f"sweep_steps must be an integer >= 0, got {sweep_steps!r}")
        self.sweep_steps = sweep_steps
        if not (isinstance(fallback_every, int) and fallback_every >= 1):
            raise ValueError(f"fallback_every must be an integer >= 1, got {fallback_every!r}")
        self.fallback_every = fallback_every
        self.keep_fraction = keep_fraction
        self.seed = seed
        self.last_scp: SCPResult | None = None

    def prepare(self, scenario: Scenario) -> None:
        self._rng = np.random.default_rng(self.seed)
        step = self.scp_params.step
        if step is None:
            step = self.programme_substeps * scenario.dt
        ratio = round(step / scenario.dt)
        if ratio < 1 or abs(ratio * scenario.dt - step) > 1e-9 * step:
            raise ValueError(f"scp step must be a whole number of env steps, got {step!r} s")
        self._substeps = ratio
        self._scp = dataclasses.replace(self.scp_params, step=step)
        self._scp_step = step
        self._step_model = discretize(scenario.mean_motion, scenario.dt, scenario.dim)
        self._trajectory: np.ndarray | None = None
        self._arrival: tuple[tuple, float] | None = None
        self._age = 0
        self.stats.update(scp_failures=0, chain_failures=0, scp_delta_v=0.0, conflict_replans=0)

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        cfg, scen = self.env.config, self.plan_scenario
        geometry: Any = self.plan_geometry
        if self.motion is not None:  # spheres that stay clear while the bodies move
            frame_index = goal.index if goal.kind == "target" else None
            times = self.env.elapsed + scen.dt * np.arange(0, self.sweep_steps + 1, 3)
            geometry = SweptGeometry(self.motion, frame_index, times)
        d = scen.dim
        margin = self.margin if self.margin is not None else self.tracker.keepout_margin
        margins = np.full(geometry.n_bodies, cfg.chaser_radius + margin)
        if goal.kind == "target":
            margins[goal.index] = cfg.chaser_radius + 0.25 * cfg.capture_radius
        low, high = np.array(scen.low, float), np.array(scen.high, float)
        # the start sphere is needed now only: the field as it is; a chaser already inside a
        # margin (just after a capture) keeps half its true gap
        here = self.plan_geometry
        gap = node_radii(here, start, np.full(here.n_bodies, cfg.chaser_radius), low, high)
        own = node_radii(here, start, margins, low, high)
        start_radius = max(float(own), 0.5 * float(gap))
        self._trajectory = None
        self._age = 0
        floor = self.expansion_params.min_radius
        start_radius = max(start_radius, floor)
        goal_radius = max(float(node_radii(geometry, goal.point, margins, low, high)), floor)
        chain, nodes = self.sphere_chain(
            start, goal, geometry, margins, low, high, start_radius, goal_radius
        )
        if not chain.success or np.any(chain.radii <= 0):
            self.stats["chain_failures"] += 1
            return PlanResult(False, start[None].copy(), 0.0, {"nodes": nodes})
        waypoints = chain_waypoints(chain, self.expansion_params.polytope_factor)
        # the chaser's state and the chain in the goal's frame
        frame = np.zeros(2 * d)
        if self.motion is not None and goal.kind == "target":
            frame = self.motion.body_state(goal.index, self.env.elapsed)
        state = np.asarray(self.env.chaser_state, float) - frame
        # keep the arrival time of the first plan toward this goal (a shrinking horizon): a
        # re-plan re-solves the rest of the same manoeuvre instead of starting a new one
        now, step = self.env.elapsed, self._scp_step
        key = (goal.kind, goal.index)
        steps = None
        if self.keep_arrival and self._arrival is not None and self._arrival[0] == key:
            left = self._arrival[1] - now
            steps = max(math.ceil(left / step - 1e-9), 1) if left >= step else None
        result = scp_trajectory(
            state, chain.centers - frame[:d], chain.radii, np.zeros(d),
            mean_motion=scen.mean_motion, dt=scen.dt, max_accel=scen.max_accel,
            thrust_model=cfg.thrust_model, params=self._scp,
            waypoints=waypoints - frame[:d], steps=steps,
        )  # fmt: skip
        self.last_scp = result
        info = {"nodes": nodes, "chain": len(chain.radii)}
        if not result.success:
            self.stats["scp_failures"] += 1
            return PlanResult(True, waypoints, PlanResult.path_length(waypoints), info)
        self.stats["scp_delta_v"] += result.delta_v
        if steps is None or len(result.controls) != steps:
            self._arrival = (key, now + len(result.controls) * step)
        self._trajectory = self._fine_states(state, result.controls)
        path = self._trajectory[:, :d] + frame[:d]
        return PlanResult(True, path, PlanResult.path_length(path), info)

    def sphere_chain(
        self,
        start: np.ndarray,
        goal: Goal,
        geometry: Any,
        margins: np.ndarray,
        low: np.ndarray,
        high: np.ndarray,
        start_radius: float,
        goal_radius: float,
    ) -> tuple[SphereChain, int]:
        """The chain of spheres start → ``goal.point`` the programme keeps its trajectory in,
        and the nodes of the graph it was found in: a spherical expansion grown for this plan
        (``geometry`` and ``margins`` as :func:`~agents.planners.spherical_expansion.node_radii`
        takes them; the start and goal spheres given their radii, m)."""
        graph = expand_spheres(
            geometry, start, goal.point, margins, self._rng, self.expansion_params,
            low=low, high=high, start_radius=start_radius, goal_radius=goal_radius,
        )  # fmt: skip
        return shortest_chain(graph), graph.n_nodes

    def plan_expired(self, now: float) -> bool:
        """Re-plan when the planned trajectory, flown from now on, would come closer to a body
        (where that body will be then) than the chaser radius plus ``keep_fraction`` of the
        margin, or after ``replan_every`` decisions; a plan still clear is kept, so successive
        plans do not jump between corridors."""
        self._age += 1
        if super().plan_expired(now):
            return True
        if self._trajectory is None:  # a fallback path: re-try the programme now and then
            return self._age >= self.fallback_every
        if self._age < 2:  # a fresh plan gets one decision before it is judged again
            return False
        ref = self.reference
        if not isinstance(ref, TrajectoryReference):
            return True
        d = self.env.dim
        ahead = ref.states[min(ref.progress + 1, len(ref.states) - 1) :][: self.check_steps]
        dt = self.scenario.dt
        times = now + dt * np.arange(1, len(ahead) + 1)
        frame = self.goal.index if self.goal.kind == "target" else None
        cfg = self.env.config
        margin = self.margin if self.margin is not None else self.tracker.keepout_margin
        need = cfg.chaser_radius + self.keep_fraction * margin
        for k, t in enumerate(times):
            point = ahead[k, :d] + self.motion.body_state(frame, t)[:d]
            gaps = self.motion.geometry(t).point_gaps(point)
            if frame is not None:
                gaps[frame] = np.inf  # the goal's own approach is guarded by the tracker
            if gaps.min() < need:
                self.stats["conflict_replans"] += 1
                return True
        return False

    def _fine_states(self, state: np.ndarray, controls: np.ndarray) -> np.ndarray:
        """The planned states at every env step: each plan thrust held over its substeps."""
        ad, bd = self._step_model.ad, self._step_model.bd
        out = [np.asarray(state, float)]
        for u in controls:
            for _ in range(self._substeps):
                out.append(ad @ out[-1] + bd @ u)
        return np.array(out)

    def make_reference(self, waypoints: np.ndarray, result: PlanResult) -> Any:
        if self._trajectory is None:
            return super().make_reference(waypoints, result)
        return TrajectoryReference(self._trajectory)
