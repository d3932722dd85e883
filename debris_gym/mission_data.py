"""The named structures the compiled step passes around (as gymnax passes EnvState / EnvParams).

Each is a module-level :class:`~typing.NamedTuple`, which numba compiles as a record of typed
fields (arrays and scalars alike) and which its on-disk cache can key on:

* :class:`Rules` — what stays fixed for a batch: the physics of a step, the mission's rules,
  the reward weights;
* :class:`Shaping` — the optional terms of the potential, or None when all are off (the
  kernels are then compiled without them);
* :class:`Missions` — the per-mission state arrays (row i = mission i);
* :class:`Field` — the per-field arrays: the bodies (the six geometry arrays of
  :class:`~debris_gym.batch_geometry.FieldBatch`), the dock, the bounds and the scales;
* :class:`StepOutputs` — what a step returns: rewards, flags and reward terms.

No numba or gymnasium import: these are plain data.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.rewards import REWARD_TERMS


class Rules(NamedTuple):
    """The fixed rules of every mission of a batch (SI units)."""

    dt: float
    """Step length (s)."""
    max_accel: float
    """Thrust limit (m/s²)."""
    box_thrust: bool
    """Thrust model: True "box" (per-axis clip, Δv rate Σ|u_i|), False "ball"."""
    step_matrix_t: np.ndarray
    """(2·dim + dim, n_sub·dim + dim): [x₀, u] @ it gives every sub-step position, the last
    being the end position, then the end velocity (exact zero-order hold)."""
    delta_v_budget: float
    """Δv budget (m/s); inf when there is none."""
    chaser_radius: float
    """Chaser radius (m)."""
    capture_radius: float
    """Capture distance from a target's surface (m)."""
    capture_speed: float
    """Highest speed at which a capture counts (m/s)."""
    n_targets: int
    """Targets per field T (the first T bodies)."""
    queued: bool
    """``target_order == "queued"``: only the first uncaptured target counts."""
    return_to_dock: bool
    """Success needs the chaser back at the dock, slow."""
    max_steps: int
    """Truncation limit (steps); −1 for none."""
    gamma: float
    """Discount of the potential-based shaping."""
    terminal_zero: bool
    """``shaping_terminal == "zero"``: Φ = 0 after termination."""
    # the reward weights, named like their config keys (penalties as positive magnitudes);
    # flat fields, not a nested structure: numba's threaded loops take no nested tuples
    reward_capture: float
    reward_success: float
    reward_progress: float
    reward_delta_v: float
    reward_collision: float
    reward_out_of_bounds: float
    reward_time: float


class Shaping(NamedTuple):
    """The optional terms of the potential (config keys ``shaping_*``; see
    :mod:`debris_gym.rewards`)."""

    speed: float
    speed_slope: float
    clearance: float
    clearance_distance: float
    closing: float
    closing_distance: float


class Missions(NamedTuple):
    """Per-mission state, row i = mission i (SI units; see :class:`MissionBatch`)."""

    state: np.ndarray
    """(N, 2·dim) LVLH position (m) and velocity (m/s)."""
    time: np.ndarray
    """(N,) time since the episode began (s)."""
    steps: np.ndarray
    """(N,) int64 steps since the episode began."""
    delta_v: np.ndarray
    """(N,) Δv spent (m/s)."""
    captured: np.ndarray
    """(N, T) bool capture flags."""
    collision: np.ndarray
    """(N,) bool."""
    out_of_bounds: np.ndarray
    """(N,) bool."""
    success: np.ndarray
    """(N,) bool."""
    gaps: np.ndarray
    """(N, B) signed distance from the chaser's centre to every body's surface (m)."""
    nearest: np.ndarray
    """(N, O) int64 the obstacles by gap, nearest first (empty unless the kinematics
    observation shows obstacles)."""
    min_clearance: np.ndarray
    """(N,) smallest obstacle gap so far (m, chaser radius not subtracted)."""
    potential: np.ndarray
    """(N,) the shaping potential Φ."""
    accel: np.ndarray
    """(N, dim) acceleration the last step applied (m/s², after the budget cut)."""


class Field(NamedTuple):
    """Per-field arrays, row i = the field of mission i."""

    centers: np.ndarray
    """(N, B, dim) body centres (m)."""
    radii: np.ndarray
    """(N, B) bounding radii (m)."""
    polygon_start: int
    """First body index that may be a polygon."""
    polygons: np.ndarray
    """(N, P + 1) the polygon list of each field (see FieldBatch)."""
    n_vertices: np.ndarray
    """(N, P) vertex counts of the bodies from ``polygon_start`` on."""
    vertices: np.ndarray
    """(N, P, V, 4) polygon vertices and edges (m; see FieldBatch)."""
    dock: np.ndarray
    """(N, dim) dock position (m)."""
    low: np.ndarray
    """(N, dim) lower bounds (m)."""
    high: np.ndarray
    """(N, dim) upper bounds (m)."""
    length_scale: np.ndarray
    """(N,) the observation's length scale L (m)."""
    speed_scale: np.ndarray
    """(N,) the observation's speed scale V (m/s)."""


class StepOutputs(NamedTuple):
    """What a step writes: rows not stepped are zero / False."""

    reward: np.ndarray
    """(N,) sum of the terms."""
    terminated: np.ndarray
    """(N,) bool: success, collision, out of bounds or budget spent."""
    truncated: np.ndarray
    """(N,) bool: the step limit reached."""
    terms: np.ndarray
    """(N, 7) reward terms, columns in :data:`REWARD_TERMS` order."""


def make_rules(
    cfg: EnvConfig,
    n_targets: int,
    step_matrix_t: np.ndarray,
    *,
    dt: float,
    max_accel: float,
    max_episode_steps: int | None,
) -> Rules:
    """The :class:`Rules` of ``cfg`` for fields of ``n_targets`` targets and the given physics."""
    return Rules(
        dt=float(dt),
        max_accel=float(max_accel),
        box_thrust=cfg.thrust_model == "box",
        step_matrix_t=step_matrix_t,
        delta_v_budget=math.inf if cfg.delta_v_budget is None else float(cfg.delta_v_budget),
        chaser_radius=float(cfg.chaser_radius),
        capture_radius=float(cfg.capture_radius),
        capture_speed=float(cfg.capture_speed),
        n_targets=int(n_targets),
        queued=cfg.target_order == "queued",
        return_to_dock=bool(cfg.return_to_dock),
        max_steps=-1 if max_episode_steps is None else int(max_episode_steps),
        gamma=float(cfg.shaping_gamma),
        terminal_zero=cfg.shaping_terminal == "zero",
        **{f"reward_{k}": float(getattr(cfg, f"reward_{k}")) for k in REWARD_TERMS},
    )


def make_shaping(cfg: EnvConfig) -> Shaping | None:
    """The optional potential terms of ``cfg``, or None when all three are off."""
    if not (cfg.shaping_speed > 0 or cfg.shaping_clearance > 0 or cfg.shaping_closing > 0):
        return None
    return Shaping(
        speed=float(cfg.shaping_speed),
        speed_slope=float(cfg.shaping_speed_slope),
        clearance=float(cfg.shaping_clearance),
        clearance_distance=float(cfg.shaping_clearance_distance),
        closing=float(cfg.shaping_closing),
        closing_distance=float(cfg.shaping_closing_distance),
    )


def new_missions(num: int, dim: int, n_targets: int, n_bodies: int, n_ranked: int) -> Missions:
    """Zeroed :class:`Missions` (``min_clearance`` inf) for ``num`` missions; ``n_ranked``
    obstacles kept sorted by gap."""
    return Missions(
        state=np.zeros((num, 2 * dim)),
        time=np.zeros(num),
        steps=np.zeros(num, dtype=np.int64),
        delta_v=np.zeros(num),
        captured=np.zeros((num, n_targets), dtype=bool),
        collision=np.zeros(num, dtype=bool),
        out_of_bounds=np.zeros(num, dtype=bool),
        success=np.zeros(num, dtype=bool),
        gaps=np.zeros((num, n_bodies)),
        nearest=np.zeros((num, n_ranked), dtype=np.int64),
        min_clearance=np.full(num, math.inf),
        potential=np.zeros(num),
        accel=np.zeros((num, dim)),
    )


def new_step_outputs(num: int) -> StepOutputs:
    """Zeroed :class:`StepOutputs` for ``num`` missions."""
    return StepOutputs(
        reward=np.zeros(num),
        terminated=np.zeros(num, dtype=bool),
        truncated=np.zeros(num, dtype=bool),
        terms=np.zeros((num, len(REWARD_TERMS))),
    )
