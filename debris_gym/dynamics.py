"""Clohessy-Wiltshire-Hill (CWH) relative dynamics in the LVLH / Hill frame.

Frame: x radial (away from Earth), y along-track, z cross-track (orbit normal). State vectors are
``[position (m), velocity (m/s)]`` of length ``2 * dim``; control is a commanded acceleration
(m/s²) of length ``dim``. The equations ([Clohessy60], [Hill1878]; written as in [Curtis14] §7.4
and [Zhou24] eq. 1a-1c)::

    ẍ = 3 n² x + 2 n ẏ + u_x
    ÿ =     − 2 n ẋ    + u_y
    z̈ =   − n² z       + u_z

The 2D model is the exactly decoupled in-plane (x, y) subsystem; ``n = 0`` is the double
integrator. Discretisation is an exact zero-order hold: the matrix exponential of the augmented
matrix ``[[A, B], [0, 0]] · dt`` ([VanLoan78]; scipy's scaled-and-squared Padé), which stays
accurate from millisecond to ten-minute steps where the textbook closed form loses digits to
cancellation.

This module knows nothing of gymnasium; the single env, the vector env, the MPC's prediction model
and the tests all use it. Keys in square brackets refer to docs/references.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg

MU_EARTH = 3.986004418e14
"""Earth's gravitational parameter μ (m³/s²)."""

R_EARTH = 6_378_137.0
"""Earth's equatorial radius (m)."""

DEFAULT_ORBIT_RADIUS = 6_778_137.0
"""Reference orbit radius (m): about 400 km altitude in LEO."""


def mean_motion(orbit_radius: float, mu: float = MU_EARTH) -> float:
    """Mean motion n = sqrt(μ / r³) (rad/s) of a circular orbit of radius ``orbit_radius`` (m)."""
    if not orbit_radius > 0:
        raise ValueError(f"orbit_radius must be > 0 m, got {orbit_radius!r}")
    return math.sqrt(mu / orbit_radius**3)


def _check_dim(dim: int) -> None:
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")


def cwh_matrices(n: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time CWH matrices ``A`` (2d × 2d) and ``B`` (2d × d) for ẋ = A x + B u.

    Args:
        n: mean motion of the reference orbit (rad/s); 0 gives the double integrator.
        dim: 2 (in-plane x, y) or 3 (x, y, z).
    """
    _check_dim(dim)
    if not (math.isfinite(n) and n >= 0):
        raise ValueError(f"mean motion n must be finite and >= 0 rad/s, got {n!r}")
    a = np.zeros((2 * dim, 2 * dim))
    a[:dim, dim:] = np.eye(dim)
    a[dim + 0, 0] = 3.0 * n * n  # ẍ ← 3n² x
    a[dim + 0, dim + 1] = 2.0 * n  # ẍ ← 2n ẏ
    a[dim + 1, dim + 0] = -2.0 * n  # ÿ ← −2n ẋ
    if dim == 3:
        a[dim + 2, 2] = -n * n  # z̈ ← −n² z
    b = np.zeros((2 * dim, dim))
    b[dim:, :] = np.eye(dim)
    return a, b


@dataclass(frozen=True)
class DiscreteModel:
    """Exact zero-order-hold model x⁺ = ``ad`` x + ``bd`` u over one step of ``dt`` seconds.

    Attributes:
        n: mean motion (rad/s).
        dt: step length (s).
        dim: 2 or 3.
        ad: state-transition matrix Φ(dt), shape (2d, 2d).
        bd: input matrix Γ(dt) = ∫₀^dt Φ(s) ds B, shape (2d, d).
    """

    n: float
    dt: float
    dim: int
    ad: np.ndarray
    bd: np.ndarray

    def step(self, states: np.ndarray, accels: np.ndarray) -> np.ndarray:
        """Propagate one step: one state (2d,) or a batch (..., 2d) with accels (..., d)."""
        return propagate(states, accels, self.ad, self.bd)


@lru_cache(maxsize=256)
def discretize(n: float, dt: float, dim: int) -> DiscreteModel:
    """Exact ZOH discretisation of the CWH model, cached per ``(n, dt, dim)``.

    Args:
        n: mean motion (rad/s), >= 0.
        dt: step length (s), > 0.
        dim: 2 or 3.

    Returns:
        A :class:`DiscreteModel` whose matrices are read-only.
    """
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    a, b = cwh_matrices(n, dim)
    m = 2 * dim
    augmented = np.zeros((m + dim, m + dim))
    augmented[:m, :m] = a
    augmented[:m, m:] = b
    phi = scipy.linalg.expm(augmented * dt)
    ad = np.ascontiguousarray(phi[:m, :m])
    bd = np.ascontiguousarray(phi[:m, m:])
    ad.setflags(write=False)
    bd.setflags(write=False)
    return DiscreteModel(n=float(n), dt=float(dt), dim=dim, ad=ad, bd=bd)


def propagate(states: np.ndarray, accels: np.ndarray, ad: np.ndarray, bd: np.ndarray) -> np.ndarray:
    """Batched x⁺ = Φ x + Γ u over any leading batch shape.

    Args:
        states: (..., 2d) positions (m) and velocities (m/s).
        accels: (..., d) commanded accelerations (m/s²), held constant over the step.
        ad: (2d, 2d) state-transition matrix.
        bd: (2d, d) input matrix.
    """
    return states @ ad.T + accels @ bd.T


@lru_cache(maxsize=64)
def substep_position_matrix(n: float, dt: float, dim: int, substeps: int) -> np.ndarray:
    """Matrix giving the chaser position at ``substeps`` evenly spaced times inside one step.

    Row block k (k = 1 … substeps) maps the stacked vector ``[x₀ (2d), u (d)]`` to the position
    at time ``k · dt / substeps``. The last block is the end-of-step position. Used for continuous
    collision checking: consecutive sub-positions are swept as straight segments.

    Returns:
        Read-only array of shape (substeps · d, 3d).
    """
    if substeps < 1:
        raise ValueError(f"substeps must be >= 1, got {substeps!r}")
    sub = discretize(n, dt / substeps, dim)
    blocks = []
    ad_k = np.eye(2 * dim)
    bd_k = np.zeros((2 * dim, dim))
    for _ in range(substeps):
        bd_k = sub.ad @ bd_k + sub.bd
        ad_k = sub.ad @ ad_k
        blocks.append(np.hstack([ad_k[:dim], bd_k[:dim]]))
    out = np.ascontiguousarray(np.vstack(blocks))
    out.setflags(write=False)
    return out


def chord_error_bound(max_accel_total: float, dt: float, substeps: int) -> float:
    """Upper bound (m) on how far the true path strays from the chords between sub-samples.

    For a path with |acceleration| <= ``max_accel_total`` (m/s²) the deviation from the chord over
    a sub-interval h = dt / substeps is at most ``a h² / 8``.
    """
    h = dt / substeps
    return max_accel_total * h * h / 8.0


def cw_transition(n: float, t: float, dim: int) -> np.ndarray:
    """Closed-form state-transition matrix Φ(t) of unforced CW motion: x(t) = Φ(t) x(0).

    The textbook solution ([Curtis14] eq. 7.53, [Vallado13] §6.8) as a matrix, for any time
    ``t`` without a matrix exponential (the planners ask it at many times between steps). It
    loses relative precision to cancellation when ``n * t`` is tiny, where :func:`discretize`
    does not; ``n = 0`` gives straight-line motion.

    Args:
        n: mean motion (rad/s), >= 0.
        t: elapsed time (s); negative runs the motion backwards.
        dim: 2 (in-plane x, y) or 3 (x, y, z).

    Returns:
        (2·dim, 2·dim) matrix acting on states [position (m), velocity (m/s)].
    """
    _check_dim(dim)
    if not (math.isfinite(n) and n >= 0):
        raise ValueError(f"mean motion n must be finite and >= 0 rad/s, got {n!r}")
    if not math.isfinite(t):
        raise ValueError(f"t must be finite (s), got {t!r}")
    phi = np.eye(2 * dim)
    if n == 0.0:
        phi[:dim, dim:] = t * np.eye(dim)
        return phi
    s, c = math.sin(n * t), math.cos(n * t)
    x, y, vx, vy = 0, 1, dim, dim + 1
    phi[x, [x, y, vx, vy]] = (4 - 3 * c), 0.0, s / n, 2 / n * (1 - c)
    phi[y, [x, y, vx, vy]] = 6 * (s - n * t), 1.0, 2 / n * (c - 1), (4 * s - 3 * n * t) / n
    phi[vx, [x, y, vx, vy]] = 3 * n * s, 0.0, c, 2 * s
    phi[vy, [x, y, vx, vy]] = 6 * n * (c - 1), 0.0, -2 * s, (4 * c - 3)
    if dim == 3:
        phi[2, [2, 5]] = c, s / n
        phi[5, [2, 5]] = -n * s, c
    return phi


def cwh_acceleration(state: np.ndarray, n: float) -> np.ndarray:
    """Natural (unforced) CWH acceleration (m/s²) of a state: the velocity rows of ``A x``.

    The same ``A`` as :func:`cwh_matrices`, so an agent that cancels or predicts the orbital
    dynamics uses exactly the model the env flies: ``[3n²x + 2nẏ, −2nẋ(, −n²z)]``.

    Args:
        state: (2d,) or a batch (..., 2d) of [position (m), velocity (m/s)], d = 2 or 3.
        n: mean motion (rad/s), >= 0.

    Returns:
        (..., d) accelerations (m/s²).
    """
    x = np.asarray(state, dtype=float)
    if x.ndim == 0 or x.shape[-1] not in (4, 6):
        raise ValueError(f"state must have a last axis of 4 or 6 (dim 2 or 3), got {x.shape}")
    dim = x.shape[-1] // 2
    a, _ = cwh_matrices(n, dim)
    # element-wise products summed in order (no BLAS): each term is rounded as when written out
    return (a[dim:] * x[..., None, :]).sum(axis=-1)
