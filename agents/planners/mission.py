"""The mission a classical agent flies: the visiting order and the current goal.

Targets are visited in the shortest closed-tour order from the dock
(:mod:`agents.planners.ordering`), or the env's queue order when ``target_order="queued"``, then
the dock if a return is required. With ``ordering="nearest"`` the current goal is the one the env
itself names (its ``obs_goal`` and shaping): the uncaptured target whose surface is nearest the
chaser *now*, re-chosen at every call, so it can change mid-leg; the later ones follow greedily.
A goal is an *approach point*: the chaser position from which a target counts as reached — half
the capture depth outside the target's surface, on the side facing the chaser — or the dock
itself."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agents.planners.ordering import polygon_order, shortest_order
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
    """

    kind: str
    index: int | None
    point: np.ndarray
    centre: np.ndarray


class MissionPlan:
    """Visiting order and goals for one scenario.

    Args:
        scenario: the field.
        config: the env's configuration (capture geometry, order rule, return to dock).
        ordering: "shortest" (exact/heuristic shortest tour), "polygon" ([APF-MPC] Alg. 1) or
            "nearest" (the env's own current goal, see above); ignored when the env fixes the
            order.
    """

    def __init__(self, scenario: Scenario, config: EnvConfig, ordering: str = "shortest") -> None:
        self.scenario = scenario
        self.config = config
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
        elif ordering == "shortest":
            self.order = shortest_order(self.centres, self.dock)
        else:
            self.order = polygon_order(self.centres)

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
            out.append(Goal("target", i, point, self.centres[i]))
            here = point
        if self.config.return_to_dock:
            out.append(Goal("dock", None, self.dock.copy(), self.dock.copy()))
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

    def current_goal(self, captured: np.ndarray, position: np.ndarray) -> Goal | None:
        """The next goal, or None when nothing is left to do."""
        goals = self.goals(captured, position)
        return goals[0] if goals else None
