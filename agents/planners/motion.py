"""Where the bodies of a moving field will be: the prediction every classical baseline plans with.

In a ``motion="cwh"`` scenario (the v1 world) every body moves on exact unforced CWH motion, which
is deterministic and known: the source papers' known-field assumption, now with time
([Zhou24], the one CWH paper among them, plans around time-varying obstacles; keys refer to
docs/references.md). :class:`FieldMotion` answers, for any time t (s since the episode began):

* body states (position m, velocity m/s), by the state-transition matrix of the env's own exact
  model (:func:`debris_gym.dynamics.discretize`); at whole steps t = k·dt by powers of the
  one-step matrix, cached, so a planner asking for a whole horizon pays no matrix exponential;
  between steps by the closed-form CW transition matrix (:func:`debris_gym.dynamics.cw_transition`;
  [Curtis14] eq. 7.53), which a tour search asks at many times;
* a *snapshot*: the field frozen as it is at t (bodies at their positions, polygons turned), a
  ``motion="frozen"`` :class:`Scenario` the static planners (APF, RRT, A*) run on unchanged;
* a :class:`FieldGeometry` of that snapshot (cached per step), for time-indexed keep-out.

The chaser's state relative to any body obeys the same CWH law (the bodies are unforced and the
law is linear), so a path planned in a body's frame stays a path in that frame: the MPC agents
plan toward a target in the target's frame and add the target's predicted motion back
(:class:`agents.policies.tracking.MPCPathAgent`).

A frozen scenario is its own prediction: every query returns the t = 0 field.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from debris_gym.dynamics import cw_transition, discretize
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Body, Scenario

__all__ = ["FieldMotion"]

_CACHE = 64
"""Snapshots / geometries kept per :class:`FieldMotion` (a horizon of 20 steps and a few
plans)."""


class FieldMotion:
    """Predicted body motion of one scenario.

    Args:
        scenario: the field (frozen or ``motion="cwh"``).
    """

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.moving = scenario.moving
        self.dim = scenario.dim
        self.dt = float(scenario.dt)
        self.n_targets = len(scenario.targets)
        self._start = np.array(scenario.initial_body_states(), dtype=float)
        self._step = discretize(scenario.mean_motion, self.dt, self.dim).ad
        self._powers: list[np.ndarray] = [np.eye(2 * self.dim)]
        self._snapshots: OrderedDict[float, Scenario] = OrderedDict()
        self._geometries: OrderedDict[tuple[float, float], FieldGeometry] = OrderedDict()

    # --- states -------------------------------------------------------------------------------

    def _transition(self, t: float) -> np.ndarray:
        """State-transition matrix Φ(t) of unforced CWH motion over ``t`` seconds."""
        k = t / self.dt
        whole = round(k)
        if abs(k - whole) <= 1e-9 * max(1.0, abs(k)) and 0 <= whole <= 100_000:
            while len(self._powers) <= whole:
                self._powers.append(self._step @ self._powers[-1])
            return self._powers[whole]
        return cw_transition(self.scenario.mean_motion, float(t), self.dim)

    def states(self, t: float) -> np.ndarray:
        """(B, 2·dim) every body's position (m) and velocity (m/s) at time ``t`` (s)."""
        if not self.moving or t == 0.0:
            return self._start
        return self._start @ self._transition(t).T

    def positions(self, t: float) -> np.ndarray:
        """(B, dim) body centres (m) at time ``t`` (s)."""
        return self.states(t)[:, : self.dim]

    def body_state(self, index: int | None, t: float) -> np.ndarray:
        """State (2·dim,) of body ``index`` at ``t``; zeros for None (the dock, an equilibrium)."""
        if index is None:
            return np.zeros(2 * self.dim)
        return self.states(t)[index]

    def body_track(self, index: int | None, t: float, steps: int) -> np.ndarray:
        """(steps, 2·dim) states of body ``index`` at t + dt, …, t + steps·dt (zeros: dock)."""
        if index is None or not self.moving:
            out = np.zeros((steps, 2 * self.dim))
            if index is not None:
                out[:] = self._start[index]
            return out
        return np.array([self.states(t + k * self.dt)[index] for k in range(1, steps + 1)])

    # --- frozen views -------------------------------------------------------------------------

    def snapshot(self, t: float) -> Scenario:
        """The field as it is at ``t`` (s), frozen: a ``motion="frozen"`` scenario with every
        body at its position then and every polygon turned to its attitude then (the scenario
        itself when it does not move)."""
        if not self.moving:
            return self.scenario
        key = round(float(t), 6)
        cached = self._snapshots.get(key)
        if cached is not None:
            self._snapshots.move_to_end(key)
            return cached
        scen = self.scenario
        positions = self.positions(t)
        angles = scen.body_angles(t)
        zero = (0.0,) * self.dim
        bodies = []
        for b, body in enumerate(scen.bodies):
            vertices = None
            if body.is_polygon:
                c, s = math.cos(angles[b]), math.sin(angles[b])
                turned = np.asarray(body.vertices, dtype=float) @ np.array([[c, s], [-s, c]])
                vertices = tuple(map(tuple, turned.tolist()))
            bodies.append(Body(tuple(positions[b].tolist()), body.radius, zero, vertices))
        t_count = self.n_targets
        frozen = Scenario(
            dim=scen.dim, bounds=scen.bounds, dock=scen.dock, targets=tuple(bodies[:t_count]),
            obstacles=tuple(bodies[t_count:]), mean_motion=scen.mean_motion, dt=scen.dt,
            max_accel=scen.max_accel, motion="frozen", name=scen.name,
        )  # fmt: skip
        self._snapshots[key] = frozen
        if len(self._snapshots) > _CACHE:
            self._snapshots.popitem(last=False)
        return frozen

    def geometry(self, t: float, inflate: float = 0.0) -> FieldGeometry:
        """:class:`FieldGeometry` of the field as it is at ``t`` (s), cached."""
        key = (round(float(t), 6) if self.moving else 0.0, float(inflate))
        cached = self._geometries.get(key)
        if cached is not None:
            self._geometries.move_to_end(key)
            return cached
        geometry = FieldGeometry(self.snapshot(t), inflate=inflate)
        self._geometries[key] = geometry
        if len(self._geometries) > _CACHE:
            self._geometries.popitem(last=False)
        return geometry
