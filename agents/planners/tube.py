"""The tube of a Tube-ST-RRT* path and the minimum-snap trajectory smoothed inside it (OSQP).

References (keys refer to docs/references.md): [Zhou24] §3.2 — "reformulated" minimum snap, whose
variables are physical positions (not polynomial coefficients) so the corridor is a constraint on
them; [Mellinger11] — minimum snap; [Stellato20] — the QP solver.

**Tube.** The path of :func:`agents.planners.st_rrt.st_rrt_star` is cut at the trajectory's sample
times t_k = t₀ + k·h: each cut point is a node of the path (it lies on a checked edge) and carries
the ball of its clearance at t_k (:meth:`SpaceTimeField.clearance`: no grown body enters it *at
that instant*). A ball is used only at its own node's time — sample k is held in node k's ball —
so nothing has to be shrunk for the bodies' motion over a span. The raw path holds every sample
at its ball's centre, so the problem below is always feasible without the acceleration bound.

**Smoothing** (the discrete counterpart of minimum snap on a fixed time grid)::

    min_p   w_snap Σ_k ‖Δ⁴p_k‖² + w_accel Σ_k ‖Δ²p_k‖² + w_start ‖p₁ − p₀ − v₀ h‖²
    s.t.    p₀ = start;  p_{K−2} = p_{K−1} = p_K = goal        (arrive at rest, relative)
            C (p_k − c_k) ≤ r_k · e,  k = 0 … K                (inscribed polytope of ball k)
            |Δ²p_k| ≤ a_lim h²  per axis                       (optional, dropped if infeasible)

with Δ the forward difference over samples, c_k / r_k the ball's centre / radius and C, e the
facets of a polytope inscribed in the unit ball (the ``"lattice"`` kind of
:func:`agents.planners.polytopes.inscribed_polytope`: a regular polygon in 2D, 26 facets in 3D),
so the linear constraints are conservative. Positions
are scaled by ℓ = max_accel·h² for the solver. Each solved sample is then pulled radially into its
ball (a solver-tolerance correction), so the result lies in the tube exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from agents.planners.polytopes import inscribed_polytope
from agents.planners.spacetime import SpaceTimeField

__all__ = [
    "SmoothParams",
    "Trajectory",
    "Tube",
    "build_tube",
    "smooth_in_tube",
]

_SOLVED = (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)


@dataclass(frozen=True)
class SmoothParams:
    """Tunables of :func:`smooth_in_tube`.

    Attributes:
        w_snap: weight of the squared fourth difference (snap).
        w_accel: weight of the squared second difference (acceleration).
        w_start: weight of the mismatch with the chaser's velocity at the start.
        w_spine: weight of the squared distance from each ball's centre (the raw path): keeps
            the problem strictly convex, which the solver needs to converge quickly.
        accel_fraction: per-axis acceleration bound as a fraction of max_accel / sqrt(dim).
        facets: facets of the 2D polygon inscribed in each ball (3D uses 26).
        hold_steps: samples at the goal after the arrival (≥ 3: at rest at the end).
        max_iter: OSQP iteration limit per attempt.
    """

    w_snap: float = 1.0
    w_accel: float = 0.05
    w_start: float = 50.0
    w_spine: float = 0.1
    accel_fraction: float = 0.5
    facets: int = 16
    hold_steps: int = 3
    max_iter: int = 3000

    def __post_init__(self) -> None:
        for name in ("w_snap", "w_accel", "w_start", "w_spine"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if self.w_snap + self.w_accel <= 0:
            raise ValueError("w_snap + w_accel must be > 0")
        if not 0 < self.accel_fraction <= 1:
            raise ValueError(f"accel_fraction must be in (0, 1], got {self.accel_fraction!r}")
        if not (isinstance(self.facets, int) and self.facets >= 4):
            raise ValueError(f"facets must be an integer >= 4, got {self.facets!r}")
        if not (isinstance(self.hold_steps, int) and self.hold_steps >= 3):
            raise ValueError(f"hold_steps must be an integer >= 3, got {self.hold_steps!r}")
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")


@dataclass(frozen=True)
class Tube:
    """Balls along a space-time path, one per sample time.

    Attributes:
        times: (K+1,) sample times t₀ + k·h (s).
        centres: (K+1, dim) path nodes at those times (m, planning frame).
        radii: (K+1,) each node's clearance at its time (m), at least 0.
        step: h (s).
    """

    times: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    step: float


@dataclass(frozen=True)
class Trajectory:
    """A smoothed trajectory on the tube's time grid.

    Attributes:
        success: whether the QP was solved (else the raw path is returned).
        times: (K+1,) sample times (s).
        positions: (K+1, dim) positions (m, planning frame).
        velocities: (K+1, dim) velocities (m/s) by differences; zero at the end.
        tube: the tube the positions lie in.
        info: "accel_bounded" (whether the acceleration bound held), OSQP status.
    """

    success: bool
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    tube: Tube
    info: dict[str, Any] = field(default_factory=dict)


def build_tube(
    field: SpaceTimeField, times: np.ndarray, positions: np.ndarray, hold_steps: int = 3
) -> Tube:
    """Cut a path (node ``times`` (s) increasing from ``field.t0``, ``positions`` (m)) at the
    grid t₀ + k·h (h = ``field.h``) up to ``hold_steps`` samples past its arrival, and give
    every cut point its clearance ball (radius clipped at 0; after the arrival the goal point
    is held)."""
    times = np.asarray(times, float)
    pts = np.asarray(positions, float)
    h = field.h
    count = math.ceil((times[-1] - times[0]) / h - 1e-9) + hold_steps + 1
    grid = times[0] + h * np.arange(count)
    centres = np.stack([np.interp(grid, times, pts[:, i]) for i in range(pts.shape[1])], 1)
    radii = np.maximum(field.clearance(centres, grid), 0.0)
    return Tube(grid, centres, radii, h)


def _difference(count: int, order: int) -> sp.csr_matrix:
    """(count − order, count) forward-difference operator of the given order."""
    op: sp.csr_matrix | sp.csc_matrix | sp.bsr_matrix = sp.identity(count, format="csr")
    for _ in range(order):
        m = op.shape[0]
        op = (sp.eye(m - 1, m, k=1) - sp.eye(m - 1, m)) @ op
    return sp.csr_matrix(op)


def smooth_in_tube(
    tube: Tube,
    start_velocity: np.ndarray,
    max_accel: float,
    params: SmoothParams | None = None,
) -> Trajectory:
    """Minimum-snap positions on the tube's grid, each inside its ball (see the module).

    Args:
        tube: the balls (from :func:`build_tube`); its first centre is the start, its last
            ``hold_steps`` centres the goal.
        start_velocity: (dim,) the chaser's velocity (m/s, planning frame) now.
        max_accel: thrust limit (m/s²), for the scale and the acceleration bound.
        params: tunables.

    Returns:
        A :class:`Trajectory`; if OSQP fails even without the acceleration bound, the raw path
        (the tube's centres) with ``success=False``.
    """
    p = params or SmoothParams()
    if not (math.isfinite(max_accel) and max_accel > 0):
        raise ValueError(f"max_accel must be finite and > 0 m/s², got {max_accel!r}")
    c, r, h = tube.centres, tube.radii, tube.step
    count, d = c.shape
    ell = max_accel * h * h
    cs = c / ell
    v0 = np.asarray(start_velocity, float).reshape(d) * h / ell
    n = count * d
    eye_d = sp.identity(d, format="csr")

    def axiswise(op: sp.spmatrix) -> sp.csr_matrix:
        return sp.csr_matrix(sp.kron(op, eye_d))

    cost = sp.csr_matrix((n, n))
    if count > 4 and p.w_snap > 0:
        d4 = axiswise(_difference(count, 4))
        cost = cost + p.w_snap * (d4.T @ d4)
    d2 = axiswise(_difference(count, 2))
    cost = cost + p.w_accel * (d2.T @ d2)
    first = axiswise(_difference(count, 1)[:1])  # p₁ − p₀
    cost = cost + p.w_start * (first.T @ first) + p.w_spine * sp.identity(n)
    q = -p.w_start * (first.T @ v0) - p.w_spine * cs.reshape(-1)
    P = sp.triu(2.0 * cost, format="csc")
    q = 2.0 * q

    polytope = inscribed_polytope(d, p.facets, "lattice")
    normals, offsets = polytope.normals, polytope.offsets
    facet = sp.kron(sp.identity(count), sp.csr_matrix(normals))  # rows (k, f)
    facet_u = (np.einsum("fd,kd->kf", normals, cs) + (r / ell)[:, None] * offsets).reshape(-1)
    pin_rows = [0, count - 3, count - 2, count - 1]
    pin = sp.kron(sp.identity(count, format="csr")[pin_rows], eye_d)
    pin_v = cs[pin_rows].reshape(-1)
    a_lim = p.accel_fraction * max_accel / math.sqrt(d) * h * h / ell
    blocks: list[sp.spmatrix] = [facet, pin]
    lower = [np.full(facet.shape[0], -np.inf), pin_v]
    upper = [facet_u, pin_v]
    info: dict[str, Any] = {}
    solution = None
    for bounded in (True, False):
        a_blocks, lo, hi = list(blocks), list(lower), list(upper)
        if bounded:
            a_blocks.append(d2)
            lo.append(np.full(d2.shape[0], -a_lim))
            hi.append(np.full(d2.shape[0], a_lim))
        # scipy-stubs type vstack's format= for sparse arrays only, not sparse matrices
        constraints = sp.vstack(a_blocks, format="csc")  # type: ignore[call-overload]
        solver = osqp.OSQP()
        solver.setup(
            P, q, constraints, np.concatenate(lo), np.concatenate(hi),
            verbose=False, polishing=True, eps_abs=1e-4, eps_rel=1e-4, max_iter=p.max_iter,
        )  # fmt: skip
        res = solver.solve(raise_error=False)
        info = {"status": str(res.info.status), "accel_bounded": bounded}
        if res.info.status_val in _SOLVED and res.x is not None and np.all(np.isfinite(res.x)):
            solution = res.x.reshape(count, d) * ell
            break
    if solution is None:
        pos, ok = c.copy(), False
    else:
        off = solution - c
        norm = np.linalg.norm(off, axis=1)
        scale = np.where(norm > r, r / np.maximum(norm, 1e-300), 1.0)
        pos, ok = c + off * scale[:, None], True
    vel = np.zeros_like(pos)
    vel[1:-1] = (pos[2:] - pos[:-2]) / (2 * h)
    vel[0] = (pos[1] - pos[0]) / h
    return Trajectory(ok, tube.times.copy(), pos, vel, tube, info)
