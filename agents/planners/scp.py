"""Sequential convex programming of a fuel-optimal trajectory through a chain of spheres.

Reference: [Bandyopadhyay17] Problem 1 (eq. 3–10) and its appendix (eq. 17–20); keys refer to
docs/references.md. Given a chain of overlapping body-free spheres
(:mod:`agents.planners.spherical_expansion`), find states x[0 … T] and thrusts u[0 … T−1] that

    minimise    Σ_k c(u[k]) Δ                                   (fuel, eq. 3)
    subject to  x[0] = the chaser's state                       (eq. 4)
                p[T] = goal, ṗ[T] = goal velocity               (eq. 5)
                p[k] inside its assigned sphere(s)              (eq. 6–8)
                u[k] in the thrust set                          (eq. 9)
                x[k+1] = Φ x[k] + Γ u[k]                        (eq. 10)

What is kept and what differs from the paper:

* dynamics: the paper linearises a general model and discretises it with a zero-order hold (eq.
  17–20). CWH motion is already linear and time-invariant, so F[k] = Φ, G[k] = Γ and H[k] = 0 are
  the exact ZOH matrices of :func:`debris_gym.dynamics.discretize` (the env's own model), and no
  linearisation is iterated;
* fuel c(u): the env's Δv rate. "box" thrusters spend Σ|u_i| (an L1 norm, written with one slack
  per axis: s ≥ ±u_i); a "ball" engine spends ‖u‖, written with one slack per step above the
  projections of u on F evenly spread directions (s ≥ n_i·u), which is ‖u‖ to within a factor
  cos(π/F) in 2D. A small quadratic term (``regularisation``) makes the optimum unique;
* spheres: OSQP [Stellato20] has no second-order cones, so every sphere ‖p − c‖ ≤ r is replaced
  by a polytope inscribed in it (the ``"fibonacci"`` kind of
  :func:`agents.planners.polytopes.inscribed_polytope`; its vertices lie on the sphere, so inside
  the polytope ⇒ inside the sphere: conservative). The thrust ball likewise;
* sphere assignment: the paper puts p[2ℓ] in the intersection of spheres ℓ and ℓ+1 and p[2ℓ+1]
  in sphere ℓ+1, so T is fixed by the chain length. Here T comes from a time allocation (the
  chain's length at a cruise speed plus the time to reach that speed and stop) and the points are
  given to the spheres in order, each sphere at least one point: point k belongs to sphere σ(k),
  σ non-decreasing in steps of at most one, and a point whose successor moves on to the next
  sphere lies in both. Then both ends of every chord p[k] → p[k+1] lie in one sphere, and so
  does the chord (spheres are convex);
* sequential part: since the dynamics are exact, what the iterations move is the assignment:
  after each solve the points are re-assigned to the furthest sphere of the chain that holds
  them, and the programme is solved again while the cost falls; if a programme is infeasible
  the time allocation grows (× ``time_growth``) and it is tried again.

The chord between two consecutive points is the straight line; the true arc under constant thrust
and CWH drift strays from it by about a·Δ²/8 (m), which the caller's safety margin covers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.optimize import linprog

from agents.planners.polytopes import inscribed_polytope
from debris_gym.dynamics import DiscreteModel, discretize

__all__ = ["SCPParams", "SCPResult", "assign_points", "scp_trajectory"]

_OK = {osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE}


def _polytope(dim: int, facets: int) -> tuple[np.ndarray, float]:
    """(normals (F, dim), h) of the SCP's polytope inscribed in the unit ball."""
    polytope = inscribed_polytope(dim, facets, "fibonacci")
    return polytope.normals, polytope.offset


_TOLERANCE = 1.0e-3
"""Distance (m) every sphere polytope is pulled in by, so the solver's tolerance and the
re-propagation of the states from the thrusts cannot carry a point past its sphere."""


@dataclass(frozen=True)
class SCPParams:
    """Tunables of :func:`scp_trajectory`.

    Attributes:
        cruise_speed: speed (m/s) of the time allocation along the chain.
        accel_fraction: fraction of the thrust limit the time allocation speeds up and stops
            with (the planned thrust may use up to ``thrust_fraction``).
        thrust_fraction: fraction (0, 1] of the thrust limit the plan may use; the rest is left
            to the tracker for corrections.
        step: time step Δ (s) of the programme; None: the scenario's step.
        max_iterations: solves per time allocation (the first plus re-assignments).
        max_steps: largest number of steps T of a trajectory.
        time_growth: factor on the time allocation after an infeasible programme (> 1).
        max_growths: how often the allocation may grow before giving up.
        sphere_facets: facets of the polytope inside each sphere (2D; 3D uses 3× as many).
        thrust_facets: facets of the thrust-ball polytope and of the ‖u‖ epigraph (2D; 3D 3×).
        sphere_penalty: None: every point is held in its sphere (hard constraints; an
            infeasible programme grows the time allocation). A number ρ (m/s per m): the
            points may leave their spheres by e_k ≥ 0 (m) at a cost ρ·Σ e_k beside the fuel, so
            a programme always has a solution (a chaser already too fast to stay in its first
            sphere); ``info["violation"]`` reports the largest e_k (0 when the spheres hold).
        regularisation: weight of the quadratic term Σ‖u/a‖² beside the fuel (dimensionless).
        eps: OSQP absolute and relative tolerance.
        max_iter: OSQP iteration limit per solve.
    """

    cruise_speed: float = 1.0
    accel_fraction: float = 0.3
    thrust_fraction: float = 0.7
    step: float | None = None
    max_iterations: int = 3
    max_steps: int = 200
    time_growth: float = 1.4
    max_growths: int = 2
    sphere_facets: int = 16
    thrust_facets: int = 16
    sphere_penalty: float | None = None
    solver: str = "highs"
    regularisation: float = 0.1
    eps: float = 1.0e-3
    max_iter: int = 4000

    def __post_init__(self) -> None:
        for name in ("cruise_speed",):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0 m/s, got {value!r}")
        for name in ("accel_fraction", "thrust_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 1.0):
                raise ValueError(f"{name} must be in (0, 1], got {value!r}")
        if self.step is not None and not (math.isfinite(self.step) and self.step > 0):
            raise ValueError(f"step must be > 0 s or None, got {self.step!r}")
        for name in ("max_iterations", "max_steps", "max_iter"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not (isinstance(self.max_growths, int) and self.max_growths >= 0):
            raise ValueError(f"max_growths must be an integer >= 0, got {self.max_growths!r}")
        if not (math.isfinite(self.time_growth) and self.time_growth > 1.0):
            raise ValueError(f"time_growth must be > 1, got {self.time_growth!r}")
        for name in ("sphere_facets", "thrust_facets"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 4):
                raise ValueError(f"{name} must be an integer >= 4, got {value!r}")
        if not (math.isfinite(self.regularisation) and self.regularisation >= 0):
            raise ValueError(f"regularisation must be >= 0, got {self.regularisation!r}")
        penalty = self.sphere_penalty
        if penalty is not None and not (math.isfinite(penalty) and penalty > 0):
            raise ValueError(f"sphere_penalty must be > 0 or None, got {penalty!r}")
        if self.solver not in ("highs", "osqp"):
            raise ValueError(f"solver must be 'highs' or 'osqp', got {self.solver!r}")
        if not (math.isfinite(self.eps) and self.eps > 0):
            raise ValueError(f"eps must be > 0, got {self.eps!r}")

    def facets(self, dim: int) -> tuple[int, int]:
        """(sphere facets, thrust facets) for ``dim``."""
        scale = 1 if dim == 2 else 3
        return scale * self.sphere_facets, scale * self.thrust_facets


@dataclass(frozen=True)
class SCPResult:
    """A trajectory from :func:`scp_trajectory`.

    Attributes:
        success: whether a programme was solved.
        states: (T+1, 2·dim) positions (m) and velocities (m/s) at t = 0, Δ, …, TΔ.
        controls: (T, dim) accelerations (m/s²), each held over one step.
        step: Δ (s).
        assignment: (T+1,) index in the chain of the sphere each point belongs to.
        delta_v: Δv (m/s) of ``controls`` by the thrust model (‖u‖Δ or Σ|u_i|Δ).
        iterations: programmes solved.
        info: diagnostics (time allocations tried, statuses).
    """

    success: bool
    states: np.ndarray
    controls: np.ndarray
    step: float
    assignment: np.ndarray
    delta_v: float
    iterations: int
    info: dict = field(default_factory=dict)


def _repair(sigma: np.ndarray, spheres: int) -> np.ndarray | None:
    """Make an assignment start at 0, end at ``spheres − 1`` and rise by at most one per point;
    None when there are too few points."""
    out = np.clip(np.asarray(sigma, dtype=np.int64), 0, spheres - 1)
    out[0], out[-1] = 0, spheres - 1
    for k in range(1, len(out)):
        out[k] = min(max(out[k], out[k - 1]), out[k - 1] + 1)
    out[-1] = spheres - 1
    for k in range(len(out) - 2, -1, -1):
        out[k] = max(out[k], out[k + 1] - 1)
    if out[0] != 0:
        return None
    return out


def assign_points(positions: np.ndarray, waypoints: np.ndarray) -> np.ndarray | None:
    """Initial assignment: point k goes to the segment of the chain polyline it projects on.

    Args:
        positions: (T+1, dim) points spread along the polyline (m).
        waypoints: (m+1, dim) polyline start → lens points → goal; segment j lies in sphere j.

    Returns:
        (T+1,) sphere indices (see the module docstring), or None if T+1 < m.
    """
    seg = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    spheres = len(waypoints) - 1
    # arc length of each point = its distance along the polyline (they are laid on it)
    along = np.array([_arc(p, waypoints, cum) for p in positions])
    best = np.searchsorted(cum[1:-1], along, side="right")
    return _repair(best, spheres)


def _arc(point: np.ndarray, waypoints: np.ndarray, cum: np.ndarray) -> float:
    """Arc length (m) of the projection of ``point`` on the polyline."""
    a, b = waypoints[:-1], waypoints[1:]
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    t = np.clip(np.einsum("ij,ij->i", point - a, ab) / length2, 0.0, 1.0)
    dist = np.linalg.norm(a + t[:, None] * ab - point, axis=1)
    j = int(np.argmin(dist))
    return float(cum[j] + t[j] * math.sqrt(length2[j]))


def _profile(length: float, params: SCPParams, a: float, steps: int, dt: float) -> np.ndarray:
    """Arc lengths (m) at the T+1 points of a speed-up / cruise / stop profile over ``length``."""
    t_total = steps * dt
    times = np.arange(steps + 1) * dt
    # a symmetric trapezoid in time that covers the length exactly
    ramp = min(params.cruise_speed / (params.accel_fraction * a), 0.5 * t_total)
    v = length / max(t_total - ramp, 1e-9)
    s = np.where(
        times < ramp,
        0.5 * v / ramp * times**2,
        np.where(
            times > t_total - ramp,
            length - 0.5 * v / ramp * (t_total - times) ** 2,
            0.5 * v * ramp + v * (times - ramp),
        ),
    )
    return np.clip(s, 0.0, length)


def allocate_steps(
    waypoints: np.ndarray, speed0: float, max_accel: float, dt: float, params: SCPParams
) -> int:
    """Time allocation (steps): the polyline at the cruise speed, plus speeding up, stopping
    and killing the current speed ``speed0`` (m/s) at ``accel_fraction`` of the thrust."""
    length = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
    accel = params.accel_fraction * max_accel
    seconds = length / params.cruise_speed + 2.0 * params.cruise_speed / accel + speed0 / accel
    spheres = len(waypoints) - 1
    return int(min(max(math.ceil(seconds / dt), spheres, 2), params.max_steps))


def scp_trajectory(
    state: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
    goal_velocity: np.ndarray | None = None,
    *,
    mean_motion: float,
    dt: float,
    max_accel: float,
    thrust_model: str = "ball",
    params: SCPParams | None = None,
    waypoints: np.ndarray | None = None,
    steps: int | None = None,
) -> SCPResult:
    """A fuel-optimal trajectory from ``state`` to the last sphere's centre through the chain.

    Args:
        state: (2·dim,) start [position (m), velocity (m/s)]; the position should be the first
            sphere's centre (the spherical expansion's start node).
        centers: (m, dim) chain of sphere centres (m); the last one is the goal position.
        radii: (m,) sphere radii (m), > 0 (consecutive spheres must overlap).
        goal_velocity: (dim,) velocity (m/s) to arrive with; None: at rest.
        mean_motion: n (rad/s) of the CWH model (0: double integrator).
        dt: the scenario's step (s); the programme's step unless ``params.step`` is set.
        max_accel: thrust limit (m/s²).
        thrust_model: "ball" or "box", as the env's.
        params: tunables.
        waypoints: (m+1, dim) polyline through the chain for the first guess; None: start,
            lens points, goal.
        steps: number of steps T to arrive in (a final time fixed by an earlier plan); None:
            the time allocation of :func:`allocate_steps`. Grows like the allocation when the
            programme is infeasible.
    """
    from agents.planners.spherical_expansion import SphereChain, chain_waypoints

    params = params or SCPParams()
    if thrust_model not in ("ball", "box"):
        raise ValueError(f"thrust_model must be 'ball' or 'box', got {thrust_model!r}")
    if not (math.isfinite(max_accel) and max_accel > 0):
        raise ValueError(f"max_accel must be finite and > 0 m/s², got {max_accel!r}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    centers = np.asarray(centers, dtype=float)
    radii = np.asarray(radii, dtype=float)
    if centers.ndim != 2 or centers.shape[0] < 1 or radii.shape != (centers.shape[0],):
        raise ValueError("centers must be (m, dim) and radii (m,) with m >= 1")
    if not np.all(radii > 0):
        raise ValueError(f"radii must be > 0 m, got min {radii.min()!r}")
    d = centers.shape[1]
    x0 = np.asarray(state, dtype=float).reshape(2 * d)
    v_goal = np.zeros(d) if goal_velocity is None else np.asarray(goal_velocity, float)
    step = params.step if params.step is not None else float(dt)
    sphere_f, thrust_f = params.facets(d)
    if waypoints is None:
        chain = SphereChain(True, np.arange(len(radii)), centers, radii, 0.0)
        waypoints = chain_waypoints(chain)
    if steps is None:
        steps = allocate_steps(waypoints, float(np.linalg.norm(x0[d:])), max_accel, step, params)
    elif not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps must be an integer >= 1 or None, got {steps!r}")
    steps = int(min(max(steps, len(radii), 2), params.max_steps))
    tried: list[int] = []
    statuses: list[str] = []
    iterations = 0
    model = discretize(mean_motion, step, d)
    for _ in range(params.max_growths + 1):
        tried.append(steps)
        length = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
        arc = _profile(length, params, max_accel, steps, step)
        seg = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        guess = np.stack([np.interp(arc, cum, waypoints[:, i]) for i in range(d)], axis=1)
        sigma = assign_points(guess, waypoints)
        best: tuple[float, np.ndarray, np.ndarray, np.ndarray, float] | None = None
        for _ in range(params.max_iterations):
            if sigma is None:
                break
            solved = _solve(
                x0, v_goal, centers, radii, sigma, model, max_accel, thrust_model,
                params, sphere_f, thrust_f,
            )  # fmt: skip
            iterations += 1
            statuses.append(solved[0])
            if solved[1] is None:
                break
            fuel, states, controls, violation = solved[1]
            cost = fuel + (params.sphere_penalty or 0.0) * violation
            if best is not None and cost >= best[0] - 1e-6 * max(1.0, abs(best[0])):
                break
            best = (cost, states, controls, sigma, violation)
            new = _reassign(states[:, :d], sigma, centers, radii, sphere_f)
            if new is None or np.array_equal(new, sigma):
                break
            sigma = new
        if best is not None:
            _, states, controls, sigma, violation = best
            rate = (
                np.abs(controls).sum(axis=1)
                if thrust_model == "box"
                else np.linalg.norm(controls, axis=1)
            )
            return SCPResult(
                success=True,
                states=states,
                controls=controls,
                step=step,
                assignment=sigma,
                delta_v=float(rate.sum() * step),
                iterations=iterations,
                info={"steps_tried": tried, "statuses": statuses, "violation": violation},
            )
        steps = min(math.ceil(steps * params.time_growth), params.max_steps)
        if steps == tried[-1]:
            break
    return SCPResult(
        success=False,
        states=np.zeros((0, 2 * d)),
        controls=np.zeros((0, d)),
        step=step,
        assignment=np.zeros(0, dtype=np.int64),
        delta_v=math.inf,
        iterations=iterations,
        info={"steps_tried": tried, "statuses": statuses},
    )


def _reassign(
    positions: np.ndarray,
    sigma: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
    facets: int,
) -> np.ndarray | None:
    """Each point to the furthest sphere of the chain (no more than one past its predecessor's)
    whose polytope holds it and its predecessor; otherwise its old sphere."""
    normals, h = _polytope(positions.shape[1], facets)
    spheres = len(radii)

    def inside(point: np.ndarray, j: int) -> bool:
        return bool(np.all(normals @ (point - centers[j]) <= radii[j] * h + 1e-6))

    out = sigma.copy()
    for k in range(1, len(out)):
        prev = out[k - 1]
        if (
            prev + 1 < spheres
            and inside(positions[k], prev + 1)
            and inside(positions[k - 1], prev + 1)
        ):
            out[k] = prev + 1
        else:
            out[k] = max(prev, min(sigma[k], prev + 1))
    return _repair(out, spheres)


def _prediction(model: DiscreteModel, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Condensed prediction x[k] = Sx[k] x[0] + Su[k] u (k = 0 … T) of the exact ZOH model.

    Returns:
        ``(Sx (T+1, 2d, 2d), Su (T+1, 2d, T·d))``; u stacked step by step (m/s²).
    """
    ad, bd = model.ad, model.bd
    nx, d = bd.shape
    sx = np.empty((steps + 1, nx, nx))
    su = np.zeros((steps + 1, nx, steps * d))
    sx[0] = np.eye(nx)
    for k in range(steps):
        sx[k + 1] = ad @ sx[k]
        # x[k+1] = Φ x[k] + Γ u[k]: earlier inputs pass through Φ once more
        su[k + 1, :, : k * d] = ad @ su[k, :, : k * d]
        su[k + 1, :, k * d : (k + 1) * d] = bd
    return sx, su


def _solve(
    x0: np.ndarray,
    v_goal: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
    sigma: np.ndarray,
    model: DiscreteModel,
    max_accel: float,
    thrust_model: str,
    params: SCPParams,
    sphere_facets: int,
    thrust_facets: int,
) -> tuple[str, tuple[float, np.ndarray, np.ndarray, float] | None]:
    """One convex programme (a QP for OSQP) for a fixed assignment ``sigma``.

    Condensed: the states are eliminated with the exact model (x[k] = Sx[k] x[0] + Su[k] u), so
    the variables are the thrusts ũ = u / a and the fuel slacks (units of a). Returns
    ``(status, (Δv m/s, states, controls, largest sphere violation m))``, the second part None
    when not solved.
    """
    d = centers.shape[1]
    T = len(sigma) - 1
    a = max_accel
    step = model.dt
    ell = a * step * step  # position unit (m) of the scaled rows
    sx, su = _prediction(model, T)
    box = thrust_model == "box"
    n_slack = d if box else 1
    n_u, n_s = T * d, T * n_slack
    penalty = params.sphere_penalty
    soft = penalty is not None
    n_e = T - 1 if soft else 0  # one sphere violation (in ℓ) per inner point
    nz = n_u + n_s + n_e
    blocks: list[sp.spmatrix] = []
    lower: list[np.ndarray] = []
    upper: list[np.ndarray] = []

    def add(block, lo, hi) -> None:
        block = sp.csr_matrix(block)
        if block.shape[1] < nz:
            block = sp.hstack([block, sp.csr_matrix((block.shape[0], nz - block.shape[1]))])
        blocks.append(sp.csr_matrix(block))
        lower.append(np.asarray(lo, dtype=float))
        upper.append(np.asarray(hi, dtype=float))

    # the end state: position at the goal, velocity the goal's (position rows in ℓ, velocity
    # rows in a·Δ)
    unit = np.concatenate([np.full(d, ell), np.full(d, a * step)])
    goal_state = np.concatenate([centers[-1], v_goal])
    end = (goal_state - sx[T] @ x0) / unit
    add(np.hstack([su[T] * a / unit[:, None], np.zeros((2 * d, n_s))]), end, end)
    if box:
        thrust = sp.identity(n_u, format="csr")
        pad = sp.csr_matrix((n_u, n_s))
        add(sp.hstack([thrust, pad]), np.full(n_u, -params.thrust_fraction),
            np.full(n_u, params.thrust_fraction))  # fmt: skip
        for sign in (1.0, -1.0):  # s ≥ ±ũ per axis
            add(sp.hstack([sign * thrust, -sp.identity(n_s)]), np.full(n_u, -np.inf),
                np.zeros(n_u))  # fmt: skip
    else:
        # the epigraph s_k ≥ n·ũ_k of every facet n, with s_k ≤ thrust_fraction·h, holds ũ_k
        # in the thrust polytope as well: one row per facet and step, not two
        normals, h = _polytope(d, thrust_facets)
        per = sp.kron(sp.identity(T), sp.csr_matrix(normals), format="csr")
        rows = per.shape[0]
        ones = sp.kron(sp.identity(T), sp.csr_matrix(np.ones((thrust_facets, 1))), format="csr")
        add(sp.hstack([per, -ones]), np.full(rows, -np.inf), np.zeros(rows))
        add(sp.hstack([sp.csr_matrix((n_s, n_u)), sp.identity(n_s)]), np.full(n_s, -np.inf),
            np.full(n_s, params.thrust_fraction * h))  # fmt: skip
    # spheres: N (p[k] − c_j) ≤ r_j h − tolerance for each sphere point k must lie in
    normals, h = _polytope(d, sphere_facets)
    coef, bound, owner = [], [], []
    for k in range(1, T):
        holders = {int(sigma[k])}
        if sigma[k + 1] != sigma[k]:
            holders.add(int(sigma[k + 1]))
        free = sx[k, :d] @ x0
        gain = normals @ su[k, :d] * (a / ell)
        for j in holders:
            coef.append(gain)
            bound.append((radii[j] * h - _TOLERANCE + normals @ (centers[j] - free)) / ell)
            owner.append(np.full(len(normals), k - 1))
    if coef:
        rows_c = np.vstack(coef)
        n_rows = len(rows_c)
        block = sp.hstack([sp.csr_matrix(rows_c), sp.csr_matrix((n_rows, n_s))])
        if soft:  # N p − e_k ≤ bound: the violation e_k ≥ 0 is paid for in the objective
            who = np.concatenate(owner)
            block = sp.hstack([block, sp.csr_matrix((-np.ones(n_rows), (np.arange(n_rows), who)),
                                                    shape=(n_rows, n_e))])  # fmt: skip
        add(block, np.full(n_rows, -np.inf), np.concatenate(bound))
    if soft:
        add(sp.hstack([sp.csr_matrix((n_e, n_u + n_s)), sp.identity(n_e)]), np.zeros(n_e),
            np.full(n_e, np.inf))  # fmt: skip
    # scipy-stubs type vstack's format= for sparse arrays only, not sparse matrices
    A = sp.vstack(blocks, format="csc")  # type: ignore[call-overload]
    lo, hi = np.concatenate(lower), np.concatenate(upper)
    q = np.zeros(nz)
    q[n_u : n_u + n_s] = 1.0
    if penalty is not None:  # fuel is in units of a·Δ (m/s), violations in ℓ = a·Δ² (m)
        q[n_u + n_s :] = penalty * step
    if params.solver == "highs":
        status, z = _solve_lp(q, A, lo, hi)
    else:
        status, z = _solve_osqp(q, A, lo, hi, n_u, n_s + n_e, params)
    if z is None:
        return status, None
    res_x = z
    ctrl = res_x[:n_u].reshape(T, d) * a
    if box:
        ctrl = np.clip(ctrl, -params.thrust_fraction * a, params.thrust_fraction * a)
    else:  # pull any solver-tolerance excess back inside the thrust polytope
        tn, th = _polytope(d, thrust_facets)
        excess = (ctrl / a) @ tn.T / (params.thrust_fraction * th)
        ctrl = ctrl / np.maximum(excess.max(axis=1), 1.0)[:, None]
    # states from the exact model and the thrusts actually returned
    states = np.einsum("kab,b->ka", sx, x0) + np.einsum("kac,c->ka", su, ctrl.reshape(-1))
    rate = np.abs(ctrl).sum(axis=1) if box else np.linalg.norm(ctrl, axis=1)
    violation = float(np.max(res_x[n_u + n_s :], initial=0.0) * ell)
    return status, (float(rate.sum() * step), states, ctrl, violation)


def _solve_lp(
    q: np.ndarray, A: sp.csc_matrix, lo: np.ndarray, hi: np.ndarray
) -> tuple[str, np.ndarray | None]:
    """min qᵀz s.t. lo ≤ A z ≤ hi with HiGHS (:func:`scipy.optimize.linprog`)."""
    eq = lo == hi
    up = ~eq & np.isfinite(hi)
    down = ~eq & np.isfinite(lo)
    rows = A.tocsr()
    a_ub = sp.vstack([rows[np.flatnonzero(up)], -rows[np.flatnonzero(down)]], format="csr")
    b_ub = np.concatenate([hi[up], -lo[down]])
    # scipy-stubs type A_ub / A_eq as dense, but HiGHS takes sparse matrices
    res = linprog(  # type: ignore[call-overload]
        q, A_ub=a_ub, b_ub=b_ub, A_eq=rows[np.flatnonzero(eq)], b_eq=lo[eq],
        bounds=(None, None), method="highs",
    )  # fmt: skip
    if res.status != 0 or res.x is None:
        return str(res.message), None
    return "solved", res.x


def _solve_osqp(
    q: np.ndarray,
    A: sp.csc_matrix,
    lo: np.ndarray,
    hi: np.ndarray,
    n_u: int,
    n_s: int,
    params: SCPParams,
) -> tuple[str, np.ndarray | None]:
    """The same programme with OSQP, plus the quadratic ``regularisation`` on the thrusts."""
    P = sp.block_diag(
        [2.0 * params.regularisation * sp.identity(n_u), sp.csc_matrix((n_s, n_s))], format="csc"
    )
    solver = osqp.OSQP()
    solver.setup(
        sp.triu(P, format="csc"), q, A, lo, hi, verbose=False, polishing=True,
        eps_abs=params.eps, eps_rel=params.eps, max_iter=params.max_iter,
    )  # fmt: skip
    res = solver.solve(raise_error=False)
    status = str(res.info.status)
    if res.info.status_val not in _OK or res.x is None or not np.all(np.isfinite(res.x)):
        return status, None
    return status, res.x
