"""The fixed data of the compiled safety shield: tunables, models and candidate grid, built once
per batch (plain data, no numba).

The compiled shield (:mod:`debris_gym.shield_kernel`) makes the decisions of the Python
run-time assurance filter of the agents package (``agents.policies.shield.SafetyShield``) with
its default tunables, which are the constants below; a test holds the two to each other.
:func:`make_shield_model` turns an env config and the batch's physics into a
:class:`ShieldModel`, the one record the kernel reads.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.dynamics import cwh_matrices, discretize

HORIZON_STEPS = 10
"""Look-ahead (steps): the candidate step plus the backup manoeuvre."""
SUBSTEPS = 4
"""Samples of the predicted path per step (the clearance between them is bounded)."""
TARGET_MARGIN = 0.0
"""Clearance (m) kept from targets beyond contact."""
DIRECTIONS = 16
"""Thrust directions of the candidate grid (ball thrust)."""
LEVELS = 2
"""Thrust magnitudes of the candidate grid (k / LEVELS of the limit)."""
FALLBACK_BODIES = 3
"""Nearest bodies whose velocity a backup may brake to (besides rest in LVLH)."""
SCALES = (1.0, 0.75, 0.5, 0.25, 0.0)
"""Scaled copies of the command among the candidates."""
BLENDS = (0.25, 0.5, 0.75, 1.0)
"""Weights of each backup's first action in the candidates that blend it with the command."""


class ShieldModel(NamedTuple):
    """What every decision of a batch shares (SI units; see :mod:`debris_gym.shield_kernel`)."""

    dim: int
    """2 or 3."""
    horizon_steps: int
    """H, the look-ahead in steps."""
    substeps: int
    """S, path samples per step (the sample interval is h = dt / S)."""
    mean_motion: float
    """n (rad/s)."""
    h: float
    """Sample interval (s)."""
    max_accel: float
    """Thrust limit (m/s²)."""
    box_thrust: bool
    """Thrust model "box" (per-axis clip), else "ball"."""
    discrete: bool
    """The env's actions are discrete: the candidates are the rows of ``table``."""
    table: np.ndarray
    """(M, dim) the discrete actions' normalised thrust (empty for continuous actions)."""
    grid: np.ndarray
    """(G, dim) candidate accelerations (m/s²) besides the command's copies and blends: the
    grid of the action space (continuous), or every discrete action."""
    sub_ad: np.ndarray
    """(2·dim, 2·dim) exact zero-order-hold state matrix over one sample interval."""
    sub_bd: np.ndarray
    """(2·dim, dim) its input matrix."""
    step_ad: np.ndarray
    """(2·dim, 2·dim) the state-transition matrix Φ(dt) of a free body over one step."""
    brake_gain: np.ndarray
    """(dim, 2·dim) deadbeat gain: u = gain · (state relative to a reference) cancels the
    relative velocity at the end of one step."""
    thrust_bound: float
    """Largest thrust acceleration (m/s²): the limit, times √dim for box thrust."""
    chaser_radius: float
    """Chaser radius (m): every body is grown by it."""
    margin: float
    """Clearance (m) kept from debris beyond contact."""
    target_margin: float
    """Clearance (m) kept from targets beyond contact."""
    n_targets: int
    """Targets per field (the first bodies)."""
    fallback_bodies: int
    """Nearest bodies a backup may brake to the velocity of (moving fields only)."""
    moving: bool
    """The bodies move on unforced CWH motion."""
    body_samples: int
    """Samples of the bodies' motion over which their interpolation error is bounded: the
    H·S + 1 of the path, or one more when H·dt / h rounds up."""
    reach_position: float
    """Largest 2-norm of Φ_pp(t) − I over the path's samples: with ``reach_velocity`` it
    bounds how far a free body moves over the horizon, ≤ this·|p| + that·|v|."""
    reach_velocity: float
    """Largest 2-norm of Φ_pv(t) over the path's samples (s)."""
    accel_position: float
    """Largest 2-norm of the position block of N·Φ(t) over the body samples (1/s², N the
    natural acceleration rows of the CWH matrix): with ``accel_velocity`` it bounds a free
    body's natural acceleration over the horizon, ≤ this·|p| + that·|v|."""
    accel_velocity: float
    """Largest 2-norm of the velocity block of N·Φ(t) over the body samples (1/s)."""
    natural_phi: np.ndarray
    """(H·S + 1, dim, 2·dim) N·Φ(k·h): the natural acceleration at sample k of a chaser that
    starts in state x₀ and does not thrust is natural_phi[k] · x₀."""
    natural_gain: np.ndarray
    """(H·S + 1,) Σ_{m<k} ‖N·Φ(m·h)·Γ(h)‖₂ (s): with thrust of at most ``thrust_bound`` in every
    sample interval, the natural acceleration at sample k strays from the unthrusted one by at
    most natural_gain[k] · thrust_bound."""


def candidate_grid(dim: int, box: bool, max_accel: float) -> np.ndarray:
    """(G, dim) the candidate grid (m/s²): per-axis ticks of the box for box thrust, else
    :data:`LEVELS` magnitudes on :data:`DIRECTIONS` directions (a circle in 2D, a Fibonacci
    sphere in 3D)."""
    if box:
        ticks = np.linspace(-1.0, 1.0, 2 * LEVELS + 1)
        grid = np.stack(np.meshgrid(*[ticks] * dim, indexing="ij"), -1)
        return np.ascontiguousarray(grid.reshape(-1, dim) * max_accel)
    k = DIRECTIONS
    if dim == 2:
        angle = 2.0 * math.pi * np.arange(k) / k
        unit = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    else:
        i = np.arange(k) + 0.5  # Fibonacci sphere: near-uniform directions
        polar = np.arccos(1.0 - 2.0 * i / k)
        azimuth = math.pi * (1.0 + 5**0.5) * i
        unit = np.stack(
            [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)],
            axis=1,
        )
    levels = np.arange(1, LEVELS + 1) / LEVELS
    return np.ascontiguousarray((levels[:, None, None] * unit[None]).reshape(-1, dim) * max_accel)


def make_shield_model(
    cfg: EnvConfig,
    *,
    mean_motion: float,
    dt: float,
    max_accel: float,
    n_targets: int,
    table: np.ndarray,
) -> ShieldModel:
    """The :class:`ShieldModel` of a batch flying ``cfg`` with the given physics (rad/s, s,
    m/s²), ``n_targets`` targets per field and the discrete action ``table`` (M, dim) (used
    only when ``cfg.action == "discrete"``)."""
    d = cfg.dim
    box = cfg.thrust_model == "box"
    discrete = cfg.action == "discrete"
    h = dt / SUBSTEPS
    step = discretize(mean_motion, dt, d)
    sub = discretize(mean_motion, h, d)
    table = np.ascontiguousarray(table, dtype=float) if discrete else np.zeros((0, d))
    grid = table * max_accel if discrete else candidate_grid(d, box, max_accel)
    samples = max(2, math.ceil(HORIZON_STEPS * dt / h) + 1)
    reach = motion_bounds(mean_motion, h, d, samples)
    phis, gains = natural_bounds(mean_motion, h, d, HORIZON_STEPS * SUBSTEPS + 1)
    return ShieldModel(
        dim=d,
        horizon_steps=HORIZON_STEPS,
        substeps=SUBSTEPS,
        mean_motion=float(mean_motion),
        h=float(h),
        max_accel=float(max_accel),
        box_thrust=box,
        discrete=discrete,
        table=table,
        grid=np.ascontiguousarray(grid, dtype=float),
        sub_ad=np.ascontiguousarray(sub.ad),
        sub_bd=np.ascontiguousarray(sub.bd),
        step_ad=np.ascontiguousarray(step.ad),
        brake_gain=np.ascontiguousarray(-np.linalg.solve(step.bd[d:], step.ad[d:])),
        thrust_bound=float(max_accel * (math.sqrt(d) if box else 1.0)),
        chaser_radius=float(cfg.chaser_radius),
        margin=float(cfg.chaser_radius),
        target_margin=TARGET_MARGIN,
        n_targets=int(n_targets),
        fallback_bodies=FALLBACK_BODIES,
        moving=cfg.debris_motion != "frozen",
        body_samples=samples,
        reach_position=reach[0],
        reach_velocity=reach[1],
        accel_position=reach[2],
        accel_velocity=reach[3],
        natural_phi=phis,
        natural_gain=gains,
    )


def motion_bounds(mean_motion: float, h: float, dim: int, samples: int) -> tuple[float, ...]:
    """Bounds of a free body's motion over ``samples`` sample times k·h (s): the largest
    2-norms of Φ_pp − I, Φ_pv, and the position and velocity blocks of N·Φ (N the natural
    acceleration rows of the CWH matrix), each widened by 1e-9 of itself so that rounding
    never shrinks it below the truth."""
    a, _ = cwh_matrices(mean_motion, dim)
    natural = a[dim:]
    step = discretize(mean_motion, h, dim).ad
    phi = np.eye(2 * dim)
    bounds = np.zeros(4)
    for _ in range(samples):
        acc = natural @ phi
        blocks = (phi[:dim, :dim] - np.eye(dim), phi[:dim, dim:], acc[:, :dim], acc[:, dim:])
        for m, block in enumerate(blocks):
            bounds[m] = max(bounds[m], float(np.linalg.norm(block, 2)))
        phi = step @ phi
    return tuple(float(b) * (1.0 + 1e-9) for b in bounds)


def natural_bounds(mean_motion: float, h: float, dim: int, samples: int) -> tuple[np.ndarray, ...]:
    """:attr:`ShieldModel.natural_phi` and :attr:`ShieldModel.natural_gain` over ``samples``
    sample times k·h (s); the gains widened by 1e-9 of themselves."""
    a, _ = cwh_matrices(mean_motion, dim)
    natural = a[dim:]
    sub = discretize(mean_motion, h, dim)
    phis = np.empty((samples, dim, 2 * dim))
    gains = np.zeros(samples)
    phi = np.eye(2 * dim)
    total = 0.0
    for k in range(samples):
        phis[k] = natural @ phi
        gains[k] = total * (1.0 + 1e-9)
        total += float(np.linalg.norm(natural @ phi @ sub.bd, 2))
        phi = sub.ad @ phi
    return np.ascontiguousarray(phis), gains
