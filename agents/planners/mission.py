"""The mission a classical agent flies: the visiting order and the current goal.

Targets are visited in the shortest closed-tour order from the dock
(:mod:`agents.planners.ordering`), or the env's queue order when ``target_order="queued"``, then
the dock if a return is required. With ``ordering="nearest"`` the current goal is the one the env
itself names (its ``obs_goal`` and shaping): the uncaptured target whose surface is nearest the
chaser *now*, re-chosen at every call, so it can change mid-leg; the later ones follow greedily.
A goal is an *approach point*: the chaser position from which a target counts as reached — half
the capture depth outside the target's surface, on the side facing the chaser — or the dock
itself.

In a moving field (a :class:`~agents.planners.motion.FieldMotion` that moves) every target is
taken where it is at the time asked, a goal carries the target's velocity (the chaser must match
it to capture), and the "shortest" order is the tour of least estimated time with each target met
where it will be (:func:`~agents.planners.ordering.moving_order`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agents.planners.motion import FieldMotion
from agents.planners.ordering import moving_order, polygon_order, shortest_order
from debris_gym.config import EnvConfig
from debris_gym.goal import current_goal
from debris_gym.scenario import Scenario

ORDERINGS = ("shortest", "polygon", "nearest")
"""Target visiting orders a :class:`MissionPlan` can follow."""


@dataclass(frozen=True)
class Goal:
    """Where to go next.

    Attributes:
        kind: "target" or "dock".
        index: target index in the scenario (None for the dock).
        point: approach point (m) to stop at.
        centre: the target centre or the dock (m).
        velocity: the target's (or dock's) velocity (m/s) at the time the goal was given; zero
            in a frozen field.
    """

    kind: str
    index: int | None
    point: np.ndarray
    centre: np.ndarray
    velocity: np.ndarray | None = None


class MissionPlan:
    """Visiting order and goals for one scenario.

    Args:
        scenario: the field.
        config: the env's configuration (capture geometry, order rule, return to dock).
        ordering: "shortest" (exact/heuristic shortest tour), "polygon" ([APF-MPC] Alg. 1) or
            "nearest" (the env's own current goal, see above); ignored when the env fixes the
            order.
        motion: the bodies' predicted motion (a moving field); None: the field as it is at t = 0.
        speed: planning speed (m/s) of the moving tour; None: 1.3 m/s scaled by the world size.
        overhead: time per visit (s) the moving tour adds (braking, matching, the hold); None:
            the capture hold plus five steps.
    """

    def __init__(
        self,
        scenario: Scenario,
        config: EnvConfig,
        ordering: str = "shortest",
        motion: FieldMotion | None = None,
        speed: float | None = None,
        overhead: float | None = None,
    ) -> None:
        self.scenario = scenario
        self.config = config
        self.motion = motion if motion is not None and motion.moving else None
        self.time = 0.0
        self.centres = np.array([t.position for t in scenario.targets], dtype=float)
        self.radii = np.array([t.radius for t in scenario.targets], dtype=float)
        self.dock = np.asarray(scenario.dock, dtype=float)
        self.nearest = False
        if ordering not in ORDERINGS:
            raise ValueError(f"ordering must be one of {', '.join(ORDERINGS)}, got {ordering!r}")
        if config.target_order == "queued" or len(scenario.targets) == 1:
            self.order = list(range(len(scenario.targets)))
        elif ordering == "nearest":
            self.order = list(range(len(scenario.targets)))
            self.nearest = True
        elif ordering == "shortest" and self.motion is not None:
            n_t = len(scenario.targets)
            speed = speed if speed is not None else 1.3 * scenario.size / 1000.0
            overhead = overhead if overhead is not None else config.capture_hold + 5 * scenario.dt
            track = self.motion.positions
            self.order = moving_order(lambda t: track(t)[:n_t], self.dock, speed, overhead)
        elif ordering == "shortest":
            self.order = shortest_order(self.centres, self.dock)
        else:
            self.order = polygon_order(self.centres)

    def at(self, time: float) -> None:
        """Take the targets where they are at ``time`` (s) for the goals asked next."""
        if self.motion is None:
            return
        self.time = float(time)
        self.centres = self.motion.positions(time)[: len(self.radii)].copy()

    def velocity(self, index: int | None) -> np.ndarray:
        """Velocity (m/s) of target ``index`` (None: the dock) at the current :attr:`time`."""
        d = len(self.dock)
        if index is None or self.motion is None:
            return np.zeros(d)
        return self.motion.states(self.time)[index, d:].copy()

    def stand_off(self, index: int) -> float:
        """Distance (m) from target ``index``'s centre to its approach points."""
        cfg = self.config
        return float(self.radii[index] + cfg.chaser_radius + 0.5 * cfg.capture_radius)

    def approach_point(self, index: int, toward: np.ndarray) -> np.ndarray:
        """Approach point of target ``index`` on the side facing ``toward`` (m)."""
        centre = self.centres[index]
        offset = np.asarray(toward, dtype=float) - centre
        norm = float(np.linalg.norm(offset))
        direction = offset / norm if norm > 1e-9 else np.eye(len(centre))[0]
        return centre + direction * self.stand_off(index)

    def goals(self, captured: np.ndarray, position: np.ndarray) -> list[Goal]:
        """Remaining goals in order, approach sides chosen along the way (first is current)."""
        out: list[Goal] = []
        here = np.asarray(position, dtype=float)
        for i in self._order(captured, here):
            point = self.approach_point(i, here)
            out.append(Goal("target", i, point, self.centres[i].copy(), self.velocity(i)))
            here = point
        if self.config.return_to_dock:
            dock = self.dock.copy()
            out.append(Goal("dock", None, dock, dock.copy(), self.velocity(None)))
        return out

    def _order(self, captured: np.ndarray, position: np.ndarray) -> list[int]:
        """Uncaptured targets in visiting order from ``position``."""
        left = [i for i in self.order if not captured[i]]
        if not self.nearest:
            return left
        out: list[int] = []
        here = np.asarray(position, dtype=float)
        taken = np.array(captured, dtype=bool).reshape(1, -1)
        while len(out) < len(left):
            # the env's own rule, from each approach point in turn
            gaps = np.linalg.norm(self.centres - here, axis=1) - self.radii
            i = int(current_goal(0, gaps[None], taken, False, False, 0.0)[0])
            taken[0, i] = True
            out.append(i)
            here = self.approach_point(i, here)
        return out

    def current_goal(
        self, captured: np.ndarray, position: np.ndarray, time: float | None = None
    ) -> Goal | None:
        """The next goal, or None when nothing is left to do (targets where they are at
        ``time`` (s) in a moving field; None keeps the last time asked)."""
        if time is not None:
            self.at(time)
        goals = self.goals(captured, position)
        return goals[0] if goals else None
