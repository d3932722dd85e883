"""Thrust models: from a normalised action to a commanded acceleration and the Δv it costs.

Both functions work on one action (d,) or a batch (..., d); no gymnasium import. The formulas
live in the compiled row functions :func:`thrust_row` and :func:`delta_v_rate_row`, which the
envs' compiled step (:mod:`debris_gym.mission_batch`) calls directly.
"""

from __future__ import annotations

import math

import numpy as np

from debris_gym.jit import inlined, kernel

THRUST_MODELS = ("ball", "box")


def _is_box(model: str) -> bool:
    if model not in THRUST_MODELS:
        raise ValueError(f"thrust_model must be one of {THRUST_MODELS}, got {model!r}")
    return model == "box"


def commanded_accel(action: np.ndarray, max_accel: float, model: str) -> np.ndarray:
    """Acceleration (m/s²) commanded by a normalised action.

    Args:
        action: (..., d) finite values; "box" clips each axis to [-1, 1], "ball" scales vectors
            longer than 1 back onto the unit ball (direction kept, however large they are).
        max_accel: thrust limit (m/s²).
        model: "box" (independent per-axis thrusters) or "ball" (one gimballed engine).
    """
    box = _is_box(model)
    a = np.asarray(action, dtype=float)
    rows = np.ascontiguousarray(a.reshape(-1, a.shape[-1]))
    out = np.empty_like(rows)
    _commanded_rows(rows, float(max_accel), box, out)
    return out.reshape(a.shape)


def delta_v_rate(accel: np.ndarray, model: str) -> np.ndarray:
    """Δv spent per second (m/s²) by an acceleration held constant.

    "ball": ‖u‖ (one engine); "box": Σ|u_i| (each axis fires its own thruster). Multiply by the
    step length to get the Δv of a step.
    """
    box = _is_box(model)
    u = np.asarray(accel, dtype=float)
    rows = np.ascontiguousarray(u.reshape(-1, u.shape[-1]))
    out = np.empty(rows.shape[0])
    _rate_rows(rows, box, out)
    return out.reshape(u.shape[:-1])


@inlined
def thrust_row(action, max_accel, box, out):
    """Commanded acceleration (m/s²) of one normalised action into ``out`` (d,)."""
    d = action.shape[0]
    if box:
        for k in range(d):
            out[k] = max_accel * min(max(action[k], -1.0), 1.0)
        return
    s = 0.0
    for k in range(d):
        s += action[k] * action[k]
    if s == math.inf:  # the squares overflow (components beyond ~1e154): norm the direction
        big = 0.0
        for k in range(d):
            big = max(big, abs(action[k]))
        s = 0.0
        for k in range(d):
            s += (action[k] / big) * (action[k] / big)
        root = math.sqrt(s)
        for k in range(d):
            out[k] = max_accel * (action[k] / big) / root
        return
    scale = max(math.sqrt(s), 1.0)
    for k in range(d):
        out[k] = max_accel * action[k] / scale


@inlined
def delta_v_rate_row(u, box):
    """Δv rate (m/s²) of one acceleration (d,): Σ|u_i| for "box", ‖u‖ for "ball"."""
    s = 0.0
    for k in range(u.shape[0]):
        s += abs(u[k]) if box else u[k] * u[k]
    return s if box else math.sqrt(s)


@kernel
def _commanded_rows(actions, max_accel, box, out):
    for k in range(actions.shape[0]):
        thrust_row(actions[k], max_accel, box, out[k])


@kernel
def _rate_rows(accels, box, out):
    for k in range(accels.shape[0]):
        out[k] = delta_v_rate_row(accels[k], box)


def action_for_accel(accel: np.ndarray, max_accel: float, model: str) -> np.ndarray:
    """The normalised action that commands ``accel`` (m/s²): the inverse of
    :func:`commanded_accel` inside the thrust limit, the nearest feasible command outside it.

    "ball" scales a vector longer than ``max_accel`` back onto the limit (direction kept); "box"
    clips each axis to ±``max_accel``.

    Args:
        accel: (..., d) desired accelerations (m/s²).
        max_accel: thrust limit (m/s²), > 0.
        model: "box" or "ball".

    Returns:
        (..., d) actions in [-1, 1] ("box") or in the unit ball ("ball").
    """
    box = _is_box(model)
    if not (math.isfinite(max_accel) and max_accel > 0):
        raise ValueError(f"max_accel must be finite and > 0 m/s², got {max_accel!r}")
    a = np.asarray(accel, dtype=float) / max_accel
    if a.ndim == 0:
        raise ValueError("accel must be a vector (..., d) of accelerations, got a scalar")
    if box:
        return np.clip(a, -1.0, 1.0)
    rows = a.reshape(-1, a.shape[-1])
    out = rows.copy()
    for k, row in enumerate(rows):
        norm = float(np.linalg.norm(row))
        if norm > 1.0:
            out[k] = row / norm
    return out.reshape(a.shape)
