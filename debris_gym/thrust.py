"""Thrust models: from a normalised action to a commanded acceleration and the Δv it costs.

Both functions work on one action (d,) or a batch (..., d); no gymnasium import.
"""

from __future__ import annotations

import numpy as np

THRUST_MODELS = ("ball", "box")


def commanded_accel(action: np.ndarray, max_accel: float, model: str) -> np.ndarray:
    """Acceleration (m/s²) commanded by a normalised action.

    Args:
        action: (..., d) values; "box" clips each axis to [-1, 1], "ball" scales vectors longer
            than 1 back onto the unit ball (direction kept).
        max_accel: thrust limit (m/s²).
        model: "box" (independent per-axis thrusters) or "ball" (one gimballed engine).
    """
    a = np.asarray(action, dtype=float)
    if model == "box":
        return max_accel * np.clip(a, -1.0, 1.0)
    if model == "ball":
        norm = np.sqrt((a * a).sum(axis=-1, keepdims=True))
        return max_accel * a / np.maximum(norm, 1.0)
    raise ValueError(f"thrust_model must be one of {THRUST_MODELS}, got {model!r}")


def delta_v_rate(accel: np.ndarray, model: str) -> np.ndarray:
    """Δv spent per second (m/s²) by an acceleration held constant.

    "ball": ‖u‖ (one engine); "box": Σ|u_i| (each axis fires its own thruster). Multiply by the
    step length to get the Δv of a step.
    """
    u = np.asarray(accel, dtype=float)
    if model == "box":
        return np.abs(u).sum(axis=-1)
    if model == "ball":
        return np.sqrt((u * u).sum(axis=-1))
    raise ValueError(f"thrust_model must be one of {THRUST_MODELS}, got {model!r}")
