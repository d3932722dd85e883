"""What planners return: an explicit result, never a silent one-point "path"."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PlanResult:
    """The outcome of a path planner.

    Attributes:
        success: whether ``waypoints`` reaches the goal.
        waypoints: (K, dim) positions (m), start first; ends at the goal when ``success``.
        cost: path length (m) of ``waypoints``.
        info: planner-specific diagnostics (iterations, local minima met, run time, …).
    """

    success: bool
    waypoints: np.ndarray
    cost: float
    info: dict[str, Any] = field(default_factory=dict)

    @staticmethod
    def path_length(waypoints: np.ndarray) -> float:
        """Sum of segment lengths (m) of a (K, dim) polyline."""
        w = np.asarray(waypoints, dtype=float)
        if len(w) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(w, axis=0), axis=1).sum())
