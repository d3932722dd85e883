"""The "apf" baseline: flies the mission on the potential gradient under CWH dynamics.

The potentials and forces are :mod:`agents.planners.apf` ([Khatib86]; [APF-MPC] eq. 1-6, [An23]
eq. 2-5; keys refer to docs/references.md). Here they become an acceleration command: damped,
speed-limited toward the goal and every nearby body
(:func:`agents.control.reference.braking_speed`), with the natural CWH acceleration of the env's
own model (:func:`debris_gym.dynamics.cwh_acceleration`) cancelled. Forces are accelerations
(m/s²) here, so ``k_att`` is in 1/s² and ``k_rep`` in m⁴/s².

In a moving field (the v1 world) the agent flies in the *goal's frame*: the chaser's state
relative to the goal target obeys the same CWH law (the target is unforced), so the CWH terms of
the relative state are cancelled, damping and goal braking act on the velocity relative to the
target (the chaser arrives matching the target's velocity, as capture asks), the repulsion sees
the bodies where they are now (:class:`~agents.planners.motion.FieldMotion`), and the closing-speed
limits use the velocity relative to each body. The dock, an equilibrium, is its own frame.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.control.reference import braking_speed
from agents.planners.apf import (
    LEO_ACCEL,
    LEO_LENGTH,
    MIN_CLEARANCE_FRACTION,
    APFParams,
    VirtualPoint,
    active_mask,
    attractive_force,
    repulsion,
)
from agents.planners.mission import Goal, MissionPlan
from agents.planners.motion import FieldMotion
from agents.policies.base import ClassicalAgent
from debris_gym.dynamics import cwh_acceleration
from debris_gym.scenario import Scenario

__all__ = ["APFAgent", "APFGuidance", "limit_closing", "prioritised_sum"]


@dataclass(frozen=True)
class APFGuidance:
    """How :class:`APFAgent` turns the potential into thrust (SI units; LEO defaults).

    Attributes:
        damping: velocity damping k_d (1/s) in a = F − k_d v; the cruise speed is about
            ‖F_att‖max / k_d = k_att·d_star / k_d.
        brake_fraction: share β of the thrust limit the braking speed limits assume.
        stall_time: window (s) over which APF-RRT looks for a local minimum: no progress
            toward the goal, and the window-mean forces pass the eq. 14 test.
        stall_progress: goal-distance decrease (m) over ``stall_time`` that counts as progress.
    """

    damping: float = 0.0167
    brake_fraction: float = 0.5
    stall_time: float = 300.0
    stall_progress: float = 5.0

    def scaled(self, length: float, accel: float) -> APFGuidance:
        """Rescale for a world ``length`` times larger and thrust ``accel`` times stronger."""
        time = math.sqrt(length / accel)
        return dataclasses.replace(
            self,
            damping=self.damping / time,
            stall_time=self.stall_time * time,
            stall_progress=self.stall_progress * length,
        )

    @classmethod
    def for_scenario(cls, scenario: Scenario, **overrides: Any) -> APFGuidance:
        """Defaults scaled from the LEO field to ``scenario``."""
        base = cls(**overrides)
        return base.scaled(scenario.size / LEO_LENGTH, scenario.max_accel / LEO_ACCEL)


def prioritised_sum(first: np.ndarray, second: np.ndarray, limit: float) -> np.ndarray:
    """``first`` + λ·``second`` with the largest λ ∈ [0, 1] that keeps the norm ≤ ``limit``
    (``first`` alone scaled down if it already exceeds it)."""
    n1 = float(np.linalg.norm(first))
    if n1 >= limit:
        return first * (limit / n1)
    total = first + second
    if float(total @ total) <= limit * limit:
        return total
    # ‖first + λ second‖ = limit: a λ² + b λ + c = 0 with the positive root.
    a = float(second @ second)
    b = 2.0 * float(first @ second)
    c = n1 * n1 - limit * limit
    lam = (-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)
    return first + min(max(lam, 0.0), 1.0) * second


class APFAgent(ClassicalAgent):
    """Flies the mission on the potential gradient ("apf").

    Each step, toward the current goal (the approach point of the next target, then the dock):

    * a_nom = F_att + F_rep − D·v: the APF force as an acceleration (the current goal target does
      not repel; every other body, captured targets included, does, with the chaser's radius and
      the margin added), damped so the chaser settles instead of orbiting. D is light along the
      motion and stiff along the normals of nearby bodies (see ``_damping``), so a stiff
      repulsion sampled every dt cannot set up a limit cycle;
    * a braking speed limit toward the goal, v ≤ √(2βa·ρ) (one step of lag included), so the
      chaser stops at the approach point well below the capture speed;
    * the same limit on the closing speed toward every nearby body and the world bounds, as
      constraints: braking now where a limit is already exceeded, and the APF term projected so
      that it cannot push a closing speed past its limit on the next step (a potential alone does
      not know the chaser's stopping distance);
    * the CWH acceleration [3n²x + 2nẏ, −2nẋ(, −n²z)] is cancelled, so the potential alone
      shapes the motion (the debris is frozen in LVLH).

    Braking and the CWH compensation take the thrust first; the APF term gets what is left of the
    thrust limit (:func:`prioritised_sum`). A local minimum stops the chaser for good: that is
    APF's known failure, which :class:`agents.policies.apf_rrt.APFRRTAgent` repairs.

    Args:
        env: the DebrisGym env.
        params: potential parameters; default :meth:`APFParams.for_scenario` of each field.
        guidance: control gains; default :meth:`APFGuidance.for_scenario`.
        ordering: target order, "shortest", "polygon" or "nearest" (see :class:`MissionPlan`).
    """

    name = "apf"

    def __init__(
        self,
        env: Any,
        params: APFParams | None = None,
        guidance: APFGuidance | None = None,
        ordering: str = "shortest",
    ) -> None:
        super().__init__(env)
        self._fixed_params = params
        self._fixed_guidance = guidance
        self.ordering = ordering

    # --- episode set-up -------------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.params = self._fixed_params or APFParams.for_scenario(scenario)
        self.guidance = self._fixed_guidance or APFGuidance.for_scenario(scenario)
        self.motion = FieldMotion(scenario) if scenario.moving else None
        self.mission = MissionPlan(scenario, cfg, self.ordering, motion=self.motion)
        self.geometry = self.env.geometry if self.motion is None else self.motion.geometry(0.0)
        self.frame_pos = np.zeros(scenario.dim)  # the goal frame's origin now (m)
        self.body_vel: np.ndarray | None = None  # (B, dim) body velocities now (moving field)
        self.inflate = cfg.chaser_radius
        self.goal_key: tuple | None = None
        self.virtual: list[VirtualPoint] = []

    # --- one step ------------------------------------------------------------------------------

    def current_goal(self, pos: np.ndarray) -> Goal | None:
        """The mission's current goal, or None when everything is done."""
        now = self.env.elapsed if self.motion is not None else None
        return self.mission.current_goal(self.env.captured, pos, now)

    def attractor(self, pos: np.ndarray, goal: Goal) -> np.ndarray:
        """The point the attractive field pulls toward (APF-RRT swaps in RRT waypoints)."""
        del pos
        return goal.point

    def act(self) -> np.ndarray:
        state = self.env.chaser_state
        d = self.env.dim
        pos, vel = state[:d], state[d:]
        goal = self.current_goal(pos)
        if self.motion is not None:  # the goal's frame; bodies where they are now
            now = self.env.elapsed
            self.geometry = self.motion.geometry(now)
            self.body_vel = self.motion.states(now)[:, d:]
            frame = np.zeros(2 * d)
            if goal is not None and goal.kind == "target":
                frame = self.motion.body_state(goal.index, now)
            self.frame_pos = frame[:d]
            state = state - frame
            vel = state[d:]
        compensation = -cwh_acceleration(state, self.scenario.mean_motion)
        if goal is None:  # mission over: hold still
            accel = prioritised_sum(compensation, -vel / self.scenario.dt, self._limit())
            return self.accel_to_action(accel)
        key = (goal.kind, goal.index)
        if key != self.goal_key:
            self.goal_key = key
            self.on_new_goal(goal)
        ignore = () if goal.index is None else (goal.index,)
        aim = self.attractor(pos, goal)
        gaps, normals = self.geometry.gaps_and_normals(pos)
        active = active_mask(self.geometry.n_bodies, ignore)
        f_att = attractive_force(pos, aim, self.params)
        f_rep = repulsion(
            pos, gaps, normals, self.params, active, self.inflate, aim, self.active_virtual()
        )[1]
        f_rep *= self.repulsion_scale()
        self.observe_forces(pos, vel, goal, f_att, f_rep)
        nominal = f_att + f_rep + self._damping(pos, vel, aim, gaps, normals, active)
        nominal += self._goal_braking(pos, vel, aim)
        toward, allowed = self._closing_limits(pos, vel + self.frame_vel(), gaps, normals, active)
        # brake now where the closing speed already exceeds the limit ...
        braking = np.minimum(allowed, 0.0) @ toward  # (negative) · toward: away
        # ... and keep the APF term from pushing any closing speed past its limit next step
        limit = self._limit()
        nominal *= min(1.0, limit / max(float(np.linalg.norm(nominal)), 1e-300))
        nominal = limit_closing(nominal, toward, np.maximum(allowed - toward @ braking, 0.0))
        safety = compensation + braking
        return self.accel_to_action(prioritised_sum(safety, nominal, limit))

    # --- hooks for APF-RRT ---------------------------------------------------------------------

    def on_new_goal(self, goal: Goal) -> None:
        """Called when the mission moves on to a new goal."""
        self.virtual = []

    def observe_forces(
        self, pos: np.ndarray, vel: np.ndarray, goal: Goal, f_att: np.ndarray, f_rep: np.ndarray
    ) -> None:
        """Called every step with the forces (APF-RRT watches for local minima here)."""

    def active_virtual(self) -> list[VirtualPoint]:
        """Virtual repulsive points in force now (kept in the goal's frame)."""
        if self.motion is None:
            return self.virtual
        return [(point + self.frame_pos, radius) for point, radius in self.virtual]

    def frame_vel(self) -> np.ndarray:
        """Velocity (m/s) of the goal's frame now (zero in a frozen field or for the dock)."""
        if self.body_vel is None or self.goal_key is None or self.goal_key[1] is None:
            return np.zeros_like(self.frame_pos)
        return self.body_vel[self.goal_key[1]]

    def repulsion_scale(self) -> float:
        """Scale of the repulsion now (APF-RRT weakens it on a collision-checked route)."""
        return 1.0

    # --- helpers -------------------------------------------------------------------------------

    def _limit(self) -> float:
        return self.scenario.max_accel

    def _decel(self) -> float:
        return self.guidance.brake_fraction * self.scenario.max_accel

    def _damping(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        aim: np.ndarray,
        gaps: np.ndarray,
        normals: np.ndarray,
        active: np.ndarray,
    ) -> np.ndarray:
        """Damping acceleration −D·v (m/s²).

        D = k_d·I, raised along the normal of every body whose repulsion has stiffness
        s = ∂F/∂d (1/s²) to max(2√s, 0.6·s·dt) — critical damping, and at least what keeps the
        sampled-data loop stable (a spring s under zero-order hold every dt needs damping
        c > s·dt/2) — and isotropically to 2√ζ inside d*. Eigenvalues are capped at 1.6/dt.
        Sliding along a surface stays lightly damped.
        """
        p = self.params
        dt = self.scenario.dt
        cap = 1.6 / dt
        base = self.guidance.damping
        if float(np.linalg.norm(aim - pos)) <= p.d_star:
            base = max(base, 2.0 * math.sqrt(p.k_att), 0.6 * p.k_att * dt)
        base = min(base, cap)
        d = gaps - self.inflate - p.margin
        near = np.flatnonzero(active & (d <= p.d0))
        if near.size == 0:
            return -base * vel
        dn = np.maximum(d[near], MIN_CLEARANCE_FRACTION * p.d0)
        stiffness = p.k_rep * (3.0 / dn**4 - 2.0 / (p.d0 * dn**3)).clip(0.0)
        wanted = np.maximum(2.0 * np.sqrt(stiffness), 0.6 * dt * stiffness)
        extra = (wanted - base).clip(0.0)
        if not extra.any():
            return -base * vel
        n = normals[near]
        matrix = base * np.eye(len(vel)) + (n.T * extra) @ n
        values, vectors = np.linalg.eigh(matrix)
        matrix = (vectors * np.minimum(values, cap)) @ vectors.T
        return -matrix @ vel

    def _goal_braking(self, pos: np.ndarray, vel: np.ndarray, aim: np.ndarray) -> np.ndarray:
        """Cuts the speed down to the braking limit for the distance left to the goal."""
        dt = self.scenario.dt
        speed = float(np.linalg.norm(vel))
        limit = braking_speed(float(np.linalg.norm(aim - pos)), self._decel(), dt)
        if speed <= limit or speed == 0.0:
            return np.zeros_like(vel)
        return -(speed - limit) / dt * vel / speed

    def _closing_limits(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        gaps: np.ndarray,
        normals: np.ndarray,
        active: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Closing-speed limits toward the bodies within d₀ and the world bounds.

        The closing speed toward a body after the next step must not exceed the speed from
        which the chaser can still stop (:func:`braking_speed`) before the body's margin. The
        goal target (not repelled) counts too: the chaser must stop a quarter of the capture
        depth short of its surface, inside the capture zone.

        Args:
            vel: the chaser's velocity (m/s) in LVLH; toward a moving body the closing speed is
                taken relative to the body's velocity.

        Returns:
            (unit directions toward each body or bound (k, dim), the largest net acceleration
            along each (k,) (m/s²); negative means the chaser must brake now).
        """
        scen, dt = self.scenario, self.scenario.dt
        p = self.params
        decel = self._decel()
        buffer = np.where(active, p.margin, 0.25 * self.env.config.capture_radius)
        clear = gaps - self.inflate - buffer
        near = clear <= p.d0
        dirs = [-normals[near]]
        room = [clear[near]]
        low, high = scen.low + p.margin, scen.high - p.margin
        eye = np.eye(len(pos))
        for axis in range(len(pos)):
            for wall, sign in ((low[axis], -1.0), (high[axis], 1.0)):
                gap = sign * (wall - pos[axis])
                if gap <= p.d0:
                    dirs.append(sign * eye[axis][None])
                    room.append(np.array([gap]))
        toward = np.concatenate(dirs)
        lag = decel * dt
        limit = -lag + np.sqrt(lag * lag + 2.0 * decel * np.maximum(np.concatenate(room), 0.0))
        closing = toward @ vel
        if self.body_vel is not None:  # a moving body: the closing speed is relative to it
            k = int(near.sum())
            closing[:k] -= np.einsum("kd,kd->k", toward[:k], self.body_vel[near])
        return toward, (limit - closing) / dt


def limit_closing(accel: np.ndarray, toward: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Remove from ``accel`` the part along each unit direction ``toward[i]`` beyond
    ``allowed[i]`` >= 0: a few rounds of projection onto the most violated half-space, then a
    uniform scale-down that makes every constraint hold (zero always does)."""
    out = np.array(accel, dtype=float)
    if toward.size == 0:
        return out
    for _ in range(8):
        excess = toward @ out - allowed
        worst = int(np.argmax(excess))
        if excess[worst] <= 1e-15:
            return out
        out -= excess[worst] * toward[worst]
    along = toward @ out
    over = along > allowed
    if over.any():
        out *= float(np.min(allowed[over] / along[over]))
    return out
