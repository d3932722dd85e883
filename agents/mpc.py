"""Linear MPC path tracker on the exact discretised CWH model, solved as a sparse QP with OSQP.

References:
    * Seed paper 000 (hybrid APF–MPC multi-target debris rendezvous), §IV: horizon N = 20 and the
      cost of eq. 8 — tracking error + λ1 ‖u‖² (control effort) + λ2 ‖Δu‖² (smoothness).
    * B. Stellato et al., "OSQP: an operator splitting solver for quadratic programs", Math. Prog.
      Comp. 12, 2020 — the QP solver (``import osqp``).

The problem solved at every decision (condensed form: the states are eliminated with the exact
zero-order-hold model x_{k+1} = Φ x_k + Γ u_k from :func:`debris_gym.dynamics.discretize`, the
only copy of the dynamics)::

    min_{ũ, s}  Σ_{k=1..N} c_k (w_p ‖(p_k − r_k)/ℓ‖² + w_v ‖(v_k − ṙ_k)/(a dt)‖²)
                + λ1 Σ_k ‖ũ_k‖² + λ2 Σ_k ‖ũ_k − ũ_{k−1}‖² + Σ_k (ρ_q s_k² + ρ_l s_k)
    s.t.        ũ_k in the thrust set (hard),            k = 0 … N−1
                n_j·(p_k − q_j) + ℓ s_k ≥ R + m_j,       keep-out half-spaces, s_k ≥ 0

in normalised units: thrust ũ = u / a (a = max_accel, m/s²), position errors in ℓ = a·dt² (m),
velocity errors in a·dt (m/s); c_k = 1, except c_N = w_terminal; ũ_{−1} is the previously applied
command. Thrust sets: "box" is |ũ_i| ≤ 1 per axis; "ball" is a polytope inscribed in the unit
ball — the regular ``thrust_facets``-gon (default 16 edges, inner radius cos(π/16) ≈ 0.981) in
2D, and in 3D the 26 half-spaces normal to the faces, edges and corners of the cube, offset so
every vertex lies on the unit sphere (inner radius ≈ 0.886). So every commanded acceleration is
inside the env's thrust limit and never clipped.

Keep-out: the debris field is convex bodies. Around each point p̂ of the previously predicted
trajectory (the last solution shifted one step, propagated from the current state) the
``keepout_per_step`` nearest bodies give supporting half-spaces n·(p − q) ≥ R + m (q: nearest
surface point, n: outward normal, R: chaser radius, m: margin), which contain no point of the
body. Each half-space found at p̂_k is imposed on both p_k and p_{k+1}, so the straight chord
between consecutive predicted positions is clear of that body too (the true arc strays from the
chord by at most a·dt²/8 ≈ 0.6 m on the default env, inside the margin). One slack per step, with
a large linear + quadratic penalty, keeps the QP feasible; if OSQP still fails the tracker brakes.

The QP is set up once per tracker (one scenario and one parameter set) with a fixed sparsity
pattern; every decision only calls ``update(q=, l=, u=, Ax=)`` and warm-starts from the previous
primal and dual solution shifted by one step.

:class:`PathReference` turns a waypoint path into the time-parametrised reference the tracker
follows: positions and tangent velocities over the horizon from a speed profile that respects a
cruise speed, the path's curvature and a braking distance to a stop at the path's end.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.spatial import HalfspaceIntersection

from agents.base import ClassicalAgent
from agents.mission import Goal, MissionPlan
from agents.planning import PlanResult
from debris_gym.dynamics import discretize
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

__all__ = [
    "MPCParams",
    "MPCPathAgent",
    "MPCSolution",
    "MPCTracker",
    "PathReference",
    "ReferenceParams",
    "thrust_polytope",
]

_OK_STATUS = {
    osqp.SolverStatus.OSQP_SOLVED,
    osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
    osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
}


# --------------------------------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MPCParams:
    """Tunables of :class:`MPCTracker`.

    Weights are dimensionless: position errors are measured in ℓ = max_accel·dt² (m; 5 m on the
    default env), velocity errors in max_accel·dt (m/s), thrust as a fraction of max_accel.

    Attributes:
        horizon: prediction horizon N (steps); seed 000 uses 20.
        w_position: weight of the squared position error per step.
        w_velocity: weight of the squared velocity error per step.
        w_terminal: multiplier of both tracking weights at the last step of the horizon.
        w_effort: λ1, weight of ‖ũ_k‖² (control effort, seed 000 eq. 8).
        w_smooth: λ2, weight of ‖ũ_k − ũ_{k−1}‖² (smoothness, seed 000 eq. 8), including the
            change from the previously applied command to the first move.
        keepout_margin: clearance (m) kept between the chaser's surface and every body; None:
            0.002 × the world size (2 m on the 1 km fields, 0.04 on the 20-unit paper field).
        keepout_per_step: keep-out bodies per linearisation point (nearest first); each gives a
            half-space on two consecutive predicted positions, so 2·this many rows per step.
            0 disables the keep-out constraints.
        slack_linear: ρ_l, linear penalty per unit of slack (slack in units of ℓ); makes the
            penalty exact (zero slack whenever the constraints are feasible).
        slack_quadratic: ρ_q, quadratic penalty per squared unit of slack.
        thrust_facets: half-planes of the 2D polygon approximating the thrust disc ("ball"); 3D
            always uses the 26-facet polytope.
        eps_abs: OSQP absolute tolerance (on the normalised problem).
        eps_rel: OSQP relative tolerance.
        max_iter: OSQP iteration limit per solve.
    """

    horizon: int = 20
    w_position: float = 1.0
    w_velocity: float = 4.0
    w_terminal: float = 5.0
    w_effort: float = 2.0
    w_smooth: float = 4.0
    keepout_margin: float | None = None
    keepout_per_step: int = 3
    slack_linear: float = 1.0e3
    slack_quadratic: float = 1.0e2
    thrust_facets: int = 16
    eps_abs: float = 1.0e-3
    eps_rel: float = 1.0e-3
    max_iter: int = 4000

    def __post_init__(self) -> None:
        if not (isinstance(self.horizon, int) and self.horizon >= 1):
            raise ValueError(f"horizon must be an integer >= 1, got {self.horizon!r}")
        for name in ("w_position", "w_velocity", "w_terminal", "w_effort", "w_smooth"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if self.w_effort + self.w_smooth <= 0:
            raise ValueError("w_effort + w_smooth must be > 0 (the QP must be strictly convex)")
        margin = self.keepout_margin
        if margin is not None and not (math.isfinite(margin) and margin >= 0):
            raise ValueError(f"keepout_margin must be >= 0 m, got {self.keepout_margin!r}")
        if not (isinstance(self.keepout_per_step, int) and self.keepout_per_step >= 0):
            raise ValueError(
                f"keepout_per_step must be an integer >= 0, got {self.keepout_per_step!r}"
            )
        if not (self.slack_linear > 0 and self.slack_quadratic > 0):
            raise ValueError("slack_linear and slack_quadratic must be > 0")
        if not (isinstance(self.thrust_facets, int) and self.thrust_facets >= 4):
            raise ValueError(f"thrust_facets must be an integer >= 4, got {self.thrust_facets!r}")
        if not (self.eps_abs > 0 and self.eps_rel >= 0 and self.max_iter >= 1):
            raise ValueError("eps_abs must be > 0, eps_rel >= 0 and max_iter >= 1")


@dataclass(frozen=True)
class ReferenceParams:
    """Speed profile of :class:`PathReference` (accelerations as fractions of max_accel).

    Attributes:
        cruise_speed: top speed along the path (m/s); None derives it from the field: the speed
            that needs a braking distance of 1/20 of the world size, sqrt(2·a_brake·size/20)
            (1.3 m/s on the default env).
        brake_fraction: a_brake / max_accel, the deceleration the profile plans with.
        accel_fraction: a_accel / max_accel, the acceleration ramp from the current speed.
        lateral_fraction: a_lat / max_accel, the largest centripetal acceleration in bends
            (v ≤ sqrt(a_lat / κ)).
        end_speed: creep speed (m/s) added to the braking profile, so the reference reaches the
            path's end in finite time; keep it below the capture speed.
        bend_window: distance (m) over which the path's turning angle is measured for the curvature
            κ ≈ angle / window; None: max(2·max_accel·dt², 1 % of the world size) (10 m on the
            1 km fields, 0.2 on the 20-unit paper field).
    """

    cruise_speed: float | None = None
    brake_fraction: float = 0.35
    accel_fraction: float = 0.5
    lateral_fraction: float = 0.3
    end_speed: float = 0.1
    bend_window: float | None = None

    def __post_init__(self) -> None:
        if self.cruise_speed is not None and not self.cruise_speed > 0:
            raise ValueError(f"cruise_speed must be > 0 m/s or None, got {self.cruise_speed!r}")
        for name in ("brake_fraction", "accel_fraction", "lateral_fraction"):
            value = getattr(self, name)
            if not 0 < value <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {value!r}")
        if not self.end_speed >= 0:
            raise ValueError(f"end_speed must be >= 0 m/s, got {self.end_speed!r}")
        if self.bend_window is not None and not self.bend_window > 0:
            raise ValueError(f"bend_window must be > 0 m or None, got {self.bend_window!r}")


@dataclass
class MPCSolution:
    """One solved MPC problem.

    Attributes:
        controls: (N, dim) planned accelerations (m/s²); the first one is the command.
        states: (N, 2·dim) predicted states after each control [m, m/s].
        status: OSQP status string, or "fallback" when the QP was not usable.
        iterations: OSQP iterations.
        slack: largest keep-out violation the QP accepted (m), 0 when every half-space holds.
        solve_time: wall time of the OSQP solve (s).
        ok: whether the controls come from a usable QP solution.
        dual: OSQP's dual vector (for a warm start), None when not ``ok``.
    """

    controls: np.ndarray
    states: np.ndarray
    status: str
    iterations: int
    slack: float
    solve_time: float
    ok: bool
    dual: np.ndarray | None = None


# --------------------------------------------------------------------------------------------------
# reference
# --------------------------------------------------------------------------------------------------


class PathReference:
    """A waypoint path with a speed profile, sampled as a reference over the MPC horizon.

    The path is resampled at a uniform spacing. Speed limit at arc length s (m)::

        v(s) = min(v_cruise, sqrt(a_lat / κ(s)), sqrt(2 a_brake (S_bend − s)) …) + end_speed

    computed by a backward pass over the samples (so the chaser can always brake with a_brake
    for the next bend and to a stop at the end, S), then clipped to the cruise speed. The
    reference over the horizon starts at the chaser's projection on the path and advances with
    speed min(v(s), v₀ + a_accel t), v₀ the chaser's speed along the path; reference velocities
    follow the (smoothed) path tangent, and are zero once the end is reached.

    Args:
        waypoints: (K, dim) path (m), start first; K = 1 is a hold point.
        max_accel: thrust limit (m/s²).
        dt: step length (s).
        params: speed profile.
        world_size: world extent (m), for the default cruise speed.
    """

    def __init__(
        self,
        waypoints: np.ndarray,
        *,
        max_accel: float,
        dt: float,
        params: ReferenceParams | None = None,
        world_size: float = 1000.0,
    ) -> None:
        params = params or ReferenceParams()
        pts = np.asarray(waypoints, dtype=float)
        if pts.ndim != 2 or pts.shape[0] < 1 or not np.all(np.isfinite(pts)):
            raise ValueError(f"waypoints must be a finite (K, dim) array, got shape {pts.shape}")
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9
        pts = pts[keep]
        self.dim = pts.shape[1]
        self.dt = float(dt)
        self.a_brake = params.brake_fraction * max_accel
        self.a_accel = params.accel_fraction * max_accel
        a_lat = params.lateral_fraction * max_accel
        self.end_speed = float(params.end_speed)
        self.cruise = (
            params.cruise_speed
            if params.cruise_speed is not None
            else math.sqrt(2.0 * self.a_brake * world_size / 20.0)
        )
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(cum[-1])
        ell = max_accel * dt * dt
        spacing = max(ell / 5.0, self.length / 4000.0, 1e-9)
        count = max(2, math.ceil(self.length / spacing) + 1)
        s = np.linspace(0.0, self.length, count)
        if self.length > 0:
            self.points = np.stack([np.interp(s, cum, pts[:, i]) for i in range(self.dim)], 1)
        else:
            self.points = np.repeat(pts[:1], count, axis=0)
        self.s = s
        self.spacing = float(s[1] - s[0]) if self.length > 0 else spacing
        window = (
            params.bend_window
            if params.bend_window is not None
            else max(2.0 * ell, 0.01 * world_size)
        )
        m = max(1, round(window / max(self.spacing, 1e-12)))
        idx = np.arange(count)
        ahead = self.points[np.minimum(idx + m, count - 1)]
        behind = self.points[np.maximum(idx - m, 0)]
        tangent = ahead - behind
        norm = np.linalg.norm(tangent, axis=1, keepdims=True)
        self.tangents = np.where(norm > 1e-12, tangent / np.maximum(norm, 1e-12), 0.0)
        d_in = self.points - behind
        d_out = ahead - self.points
        n_in = np.linalg.norm(d_in, axis=1)
        n_out = np.linalg.norm(d_out, axis=1)
        cos = np.einsum("ij,ij->i", d_in, d_out) / np.maximum(n_in * n_out, 1e-300)
        angle = np.where((n_in > 1e-12) & (n_out > 1e-12), np.arccos(np.clip(cos, -1, 1)), 0.0)
        kappa = angle / max(m * self.spacing, 1e-12)
        vlim = np.minimum(self.cruise, np.sqrt(a_lat / np.maximum(kappa, 1e-12)))
        # Backward pass: from every sample the chaser can brake to every later limit and to rest.
        profile = np.empty(count)
        profile[-1] = 0.0
        two_a_ds = 2.0 * self.a_brake * self.spacing
        for i in range(count - 2, -1, -1):
            profile[i] = min(vlim[i], math.sqrt(profile[i + 1] ** 2 + two_a_ds))
        self.profile = np.minimum(profile + self.end_speed, max(self.cruise, self.end_speed))
        self._profile_list = self.profile.tolist()
        self._back = ell  # the projection moves back at most this far (m)
        self.progress = 0
        self.deviation = 0.0

    @property
    def end(self) -> np.ndarray:
        """The path's last point (m)."""
        return self.points[-1].copy()

    def project(self, position: np.ndarray, lookahead: float) -> tuple[int, float]:
        """Nearest sample to ``position`` at or ahead of the current progress (minus a little).

        Args:
            position: (dim,) chaser position (m).
            lookahead: how far ahead (m) along the path to search.

        Returns:
            ``(index, distance (m))``; also stored as :attr:`progress` / :attr:`deviation`.
        """
        back = max(2, round(self._back / self.spacing))
        lo = max(0, self.progress - back)
        hi = min(len(self.s), self.progress + max(2, math.ceil(lookahead / self.spacing)) + 1)
        diff = self.points[lo:hi] - position
        dist2 = np.einsum("ij,ij->i", diff, diff)
        k = int(np.argmin(dist2))
        self.progress = lo + k
        self.deviation = math.sqrt(float(dist2[k]))
        return self.progress, self.deviation

    def horizon(self, state: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Reference positions and velocities for the next ``steps`` steps.

        Args:
            state: chaser state [position (m), velocity (m/s)].
            steps: horizon length N.

        Returns:
            ``(positions (N, dim) [m], velocities (N, dim) [m/s])`` at t = dt, 2 dt, …, N dt.
        """
        d = self.dim
        pos, vel = state[:d], state[d:]
        if self.length == 0.0:  # a hold point
            self.project(pos, lookahead=0.0)
            return np.repeat(self.points[:1], steps, axis=0), np.zeros((steps, d))
        speed = math.sqrt(float(vel @ vel))
        self.project(pos, lookahead=3.0 * (speed + self.cruise) * self.dt + 10 * self.spacing)
        i0 = self.progress
        s = float(self.s[i0])
        v = max(0.0, float(vel @ self.tangents[i0]))
        ds, length, last = self.spacing, self.length, len(self.s) - 1
        prof = self._profile_list
        substeps = 4
        h = self.dt / substeps
        out_s = np.empty(steps)
        out_v = np.empty(steps)
        for k in range(steps):
            for _ in range(substeps):
                x = s / ds
                j = min(int(x), last - 1)
                f = x - j
                limit = prof[j] + (prof[j + 1] - prof[j]) * f if j >= 0 else prof[0]
                v = min(limit, v + self.a_accel * h)
                s = min(length, s + v * h)
            out_s[k] = s
            out_v[k] = 0.0 if s >= length else v
        ref_pos = np.stack([np.interp(out_s, self.s, self.points[:, i]) for i in range(d)], 1)
        idx = np.minimum(np.rint(out_s / max(ds, 1e-300)).astype(int), last)
        ref_vel = self.tangents[idx] * out_v[:, None]
        return ref_pos, ref_vel


# --------------------------------------------------------------------------------------------------
# tracker
# --------------------------------------------------------------------------------------------------


def thrust_polytope(dim: int, model: str, facets: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Half-spaces C ũ ≤ h (ũ = u / max_accel) of the thrust set used by the QP.

    Returns:
        ``(C (F, dim), h (F,))``: the box |ũ_i| ≤ 1, or a polytope inscribed in the unit ball
        (16-gon in 2D by default; the 26 cube face/edge/corner normals in 3D).
    """
    if model == "box":
        eye = np.eye(dim)
        return np.vstack([eye, -eye]), np.ones(2 * dim)
    if model != "ball":
        raise ValueError(f"thrust_model must be 'ball' or 'box', got {model!r}")
    if dim == 2:
        ang = 2.0 * np.pi * np.arange(facets) / facets
        normals = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        return normals, np.full(facets, math.cos(math.pi / facets))
    dirs = [np.array(s, dtype=float) for s in itertools.product((-1, 0, 1), repeat=3) if any(s)]
    normals = np.array([v / np.linalg.norm(v) for v in dirs])
    halfspaces = np.hstack([normals, -np.ones((len(normals), 1))])
    radius = np.linalg.norm(HalfspaceIntersection(halfspaces, np.zeros(3)).intersections, axis=1)
    return normals, np.full(len(normals), 1.0 / float(radius.max()))


class MPCTracker:
    """Tracks a reference trajectory with a linear MPC on the exact CWH model (OSQP, sparse QP).

    Args:
        scenario: the field (mean motion, dt, max_accel, dim, bodies for the keep-out).
        params: MPC tunables.
        thrust_model: "ball" or "box", as the env's ``thrust_model``.
        chaser_radius: chaser radius (m), added to every keep-out distance.
        geometry: the field's :class:`FieldGeometry` (built, not inflated, if omitted).
    """

    def __init__(
        self,
        scenario: Scenario,
        params: MPCParams | None = None,
        *,
        thrust_model: str = "ball",
        chaser_radius: float = 0.0,
        geometry: FieldGeometry | None = None,
    ) -> None:
        self.params = p = params or MPCParams()
        self.scenario = scenario
        self.dim = d = scenario.dim
        self.thrust_model = thrust_model
        self.chaser_radius = float(chaser_radius)
        self.geometry = geometry if geometry is not None else FieldGeometry(scenario)
        self.model = discretize(scenario.mean_motion, scenario.dt, d)
        self.max_accel = a = float(scenario.max_accel)
        self.dt = float(scenario.dt)
        self.ell = a * self.dt**2
        self.N = p.horizon
        self.keepout_margin = (
            p.keepout_margin if p.keepout_margin is not None else 0.002 * scenario.size
        )
        self._build_prediction()
        self._facets, self._facet_h = thrust_polytope(d, thrust_model, p.thrust_facets)
        self.M = p.keepout_per_step if self.geometry.n_bodies else 0
        self.M = min(self.M, self.geometry.n_bodies)
        self._build_qp()
        self.stats: dict[str, Any] = {"solves": 0, "fallbacks": 0, "slack_steps": 0, "iters": []}
        self.reset()

    # --- construction -------------------------------------------------------------------------

    def _build_prediction(self) -> None:
        """Condensed prediction X = Sx x0 + Su U over the horizon (physical units)."""
        d, N = self.dim, self.N
        ad, bd = self.model.ad, self.model.bd
        nx = 2 * d
        sx = np.zeros((N, nx, nx))
        su = np.zeros((N, nx, N, d))
        power = np.eye(nx)
        for k in range(N):
            power = ad @ power
            sx[k] = power
            # x_{k+1} = Φ x_k + Γ u_k  ⇒  block (k, j) = Φ^{k−j} Γ for j ≤ k
            if k > 0:
                su[k, :, :k] = np.einsum("ab,bjc->ajc", ad, su[k - 1, :, :k])
            su[k, :, k] = bd
        self._sx = sx  # (N, 2d, 2d)
        self._su = su.reshape(N, nx, N * d)  # (N, 2d, N·d), u in m/s²

    def _build_qp(self) -> None:
        p, d, N, a, ell = self.params, self.dim, self.N, self.max_accel, self.ell
        nu = N * d
        nz = nu + N
        self._nu, self._nz = nu, nz
        # tracking weights on the stacked state (physical units), per step and component
        wpos = p.w_position / ell**2
        wvel = p.w_velocity / (a * self.dt) ** 2
        w = np.empty((N, 2 * d))
        w[:, :d], w[:, d:] = wpos, wvel
        w[-1] *= p.w_terminal
        self._w = w
        su_s = self._su.reshape(N * 2 * d, nu) * a  # maps ũ to the stacked state
        self._su_s = su_s
        hess = su_s.T @ (w.reshape(-1)[:, None] * su_s)
        hess += p.w_effort * np.eye(nu)
        diff = np.eye(nu) - np.eye(nu, k=-d)  # rows: ũ_k − ũ_{k−1} (ũ_{−1} in the linear term)
        hess += p.w_smooth * diff.T @ diff
        hess = 0.5 * (hess + hess.T)
        P = sp.block_diag(
            [sp.csc_matrix(2.0 * hess), sp.identity(N) * (2.0 * p.slack_quadratic)], format="csc"
        )
        self._P = sp.triu(P, format="csc")

        rows, cols, vals = [], [], []
        lower, upper = [], []
        r = 0
        # thrust rows: C ũ_k ≤ h
        F = len(self._facet_h)
        for k in range(N):
            for f in range(F):
                for i in range(d):
                    if self._facets[f, i] != 0.0:
                        rows.append(r)
                        cols.append(k * d + i)
                        vals.append(self._facets[f, i])
                lower.append(-np.inf)
                upper.append(self._facet_h[f])
                r += 1
        self._n_thrust = r
        # keep-out rows: 2M per step k (positions p_{k+1}), coefficients on ũ_0..ũ_k and s_k
        M2 = 2 * self.M
        self._ko_start = len(vals)
        ko_mask = np.zeros((N, M2, nu), dtype=bool)
        for k in range(N):
            for _ in range(M2):
                for c in range((k + 1) * d):
                    rows.append(r)
                    cols.append(c)
                    vals.append(1.0)
                rows.append(r)
                cols.append(nu + k)
                vals.append(1.0)
                lower.append(-np.inf)
                upper.append(np.inf)
                r += 1
            ko_mask[k, :, : (k + 1) * d] = True
        self._ko_mask = ko_mask
        self._n_keepout = N * M2
        # slack rows: s_k ≥ 0
        for k in range(N):
            rows.append(r)
            cols.append(nu + k)
            vals.append(1.0)
            lower.append(0.0)
            upper.append(np.inf)
            r += 1
        self._m = r
        coo_vals = np.array(vals)
        # Map from our entry order to OSQP's CSC data order (fixed sparsity pattern).
        ids = np.arange(1, len(vals) + 1, dtype=float)
        A = sp.csc_matrix((ids, (np.array(rows), np.array(cols))), shape=(r, nz))
        A.sort_indices()
        self._perm = A.data.astype(np.int64) - 1
        A = sp.csc_matrix((coo_vals[self._perm], A.indices, A.indptr), shape=(r, nz))
        self._a_vals = coo_vals
        self._l = np.array(lower)
        self._u = np.array(upper)
        # position part of the prediction in normalised units, for the keep-out coefficients
        gp = self._su[:, :d, :] * (a / ell)  # (N, d, nu)
        self._gp = gp
        # flat index of every keep-out control coefficient in _a_vals
        flat = []
        pos = self._ko_start
        for k in range(N):
            for _ in range(M2):
                n_c = (k + 1) * d
                flat.append(np.arange(pos, pos + n_c))
                pos += n_c + 1
        self._ko_ctrl_idx = np.concatenate(flat) if flat else np.zeros(0, dtype=np.int64)
        self._q = np.zeros(nz)
        self._q[nu:] = p.slack_linear
        self._solver = osqp.OSQP()
        self._solver.setup(
            self._P,
            self._q,
            A,
            self._l,
            self._u,
            verbose=False,
            polishing=False,
            warm_starting=True,
            eps_abs=p.eps_abs,
            eps_rel=p.eps_rel,
            max_iter=p.max_iter,
        )

    # --- state --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget the warm start and the last command (new episode or new reference)."""
        self._last_u: np.ndarray = np.zeros(self.dim)  # normalised
        self._guess: np.ndarray | None = None  # (N, d) normalised
        self._y: np.ndarray | None = None
        self.last_solution: MPCSolution | None = None

    # --- prediction ---------------------------------------------------------------------------

    def predict(self, state: np.ndarray, controls: np.ndarray) -> np.ndarray:
        """States (N, 2·dim) after applying ``controls`` (N, dim) [m/s²] from ``state``."""
        x0 = np.asarray(state, dtype=float)
        u = np.asarray(controls, dtype=float).reshape(-1)
        return np.einsum("kab,b->ka", self._sx, x0) + np.einsum("kac,c->ka", self._su, u)

    # --- keep-out -----------------------------------------------------------------------------

    def _halfspaces(
        self, points: np.ndarray, margins: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Supporting half-spaces n·p ≥ b of the nearest bodies around each point.

        Args:
            points: (P, dim) linearisation points (m).
            margins: (n_bodies,) required distance (m) from each surface (∞ skips a body).

        Returns:
            ``(normals (P, M, dim), offsets (P, M) [m], valid (P, M))``.
        """
        geom, M, d = self.geometry, self.M, self.dim
        gaps = geom.signed_distance(points)  # (P, B)
        score = gaps - np.where(np.isfinite(margins), margins, -np.inf)[None]
        score = np.where(np.isfinite(margins)[None], score, np.inf)
        if M < score.shape[1]:
            nearest = np.argpartition(score, M - 1, axis=1)[:, :M]
        else:
            nearest = np.tile(np.arange(score.shape[1]), (len(points), 1))
        valid = np.isfinite(np.take_along_axis(score, nearest, axis=1))
        centres = geom.centers[nearest]  # (P, M, d)
        radii = geom.radii[nearest]
        diff = points[:, None, :] - centres
        dist = np.linalg.norm(diff, axis=2)
        normals = diff / np.maximum(dist, 1e-12)[..., None]
        surface = centres + radii[..., None] * normals
        poly = geom.is_polygon[nearest] & valid
        if poly.any():
            shapes = geom.shapes
            for i, j in zip(*np.nonzero(poly), strict=True):
                info = shapes[nearest[i, j]].point_query((float(points[i, 0]), float(points[i, 1])))
                g = np.array([info.gradient.x, info.gradient.y])
                normals[i, j] = g / max(float(np.linalg.norm(g)), 1e-12)
                surface[i, j] = (info.point.x, info.point.y)
        offsets = np.einsum("pmd,pmd->pm", normals, surface) + margins[nearest]
        del d
        return normals, np.where(valid, offsets, -np.inf), valid

    # --- solving ------------------------------------------------------------------------------

    def body_margins(self, overrides: Mapping[int, float] | None = None) -> np.ndarray:
        """Keep-out distance (m) from each body's surface: chaser radius + margin, or override.

        ``overrides`` maps a body index to its own margin (m, beyond the chaser radius);
        ``math.inf`` leaves a body out of the keep-out entirely.
        """
        margins = np.full(self.geometry.n_bodies, self.chaser_radius + self.keepout_margin)
        for index, margin in (overrides or {}).items():
            margins[index] = math.inf if math.isinf(margin) else self.chaser_radius + margin
        return margins

    def solve(
        self,
        state: np.ndarray,
        ref_pos: np.ndarray,
        ref_vel: np.ndarray,
        *,
        u_prev: np.ndarray | None = None,
        guess: np.ndarray | None = None,
        dual_guess: np.ndarray | None = None,
        margins: Mapping[int, float] | None = None,
    ) -> MPCSolution:
        """Solve one MPC problem (the tracker's warm-start state is left alone).

        Args:
            state: current state [position (m), velocity (m/s)], shape (2·dim,).
            ref_pos: (N, dim) reference positions at steps 1..N (m).
            ref_vel: (N, dim) reference velocities (m/s).
            u_prev: previously applied acceleration (m/s²) for the first Δu term; zero if None.
            guess: (N, dim) accelerations (m/s²) to warm-start from and to linearise the
                keep-out around; None: a cold start (zeros), linearised around the reference.
            dual_guess: OSQP dual vector to warm-start with (None: zeros).
            margins: per-body keep-out margin overrides (see :meth:`body_margins`).
        """
        p, d, N, a, ell = self.params, self.dim, self.N, self.max_accel, self.ell
        x0 = np.asarray(state, dtype=float)
        ref = np.concatenate([np.asarray(ref_pos, float), np.asarray(ref_vel, float)], axis=1)
        if ref.shape != (N, 2 * d):
            raise ValueError(f"reference must be (N={N}, dim={d}) positions and velocities")
        free = np.einsum("kab,b->ka", self._sx, x0)  # (N, 2d) zero-control prediction
        u_prev_n = np.zeros(d) if u_prev is None else np.asarray(u_prev, float) / a
        err = (free - ref).reshape(-1)
        q = self._q
        q[: self._nu] = 2.0 * (self._su_s.T @ (self._w.reshape(-1) * err))
        q[:d] -= 2.0 * p.w_smooth * u_prev_n
        lower, upper = self._l, self._u
        guess_n = None if guess is None else np.asarray(guess, float).reshape(N, d) / a
        if self.M:
            if guess_n is None:
                lin = ref[:, :d]
            else:
                lin = free[:, :d] + np.einsum(
                    "kdc,c->kd", self._su[:, :d, :], guess_n.reshape(-1) * a
                )
            points = np.vstack([x0[:d], lin])  # p̂_0 … p̂_N
            normals, offsets, _ = self._halfspaces(points, self.body_margins(margins))
            # step k (position p_{k+1}): half-spaces of p̂_{k+1} (own) and of p̂_k (previous)
            n_rows = np.concatenate([normals[1:], normals[:-1]], axis=1)  # (N, 2M, d)
            b_rows = np.concatenate([offsets[1:], offsets[:-1]], axis=1)  # (N, 2M)
            coef = np.einsum("kmd,kdc->kmc", n_rows, self._gp)  # (N, 2M, nu)
            self._a_vals[self._ko_ctrl_idx] = coef[self._ko_mask]
            base = np.einsum("kmd,kd->km", n_rows, free[:, :d])  # n·(free position)
            lo = (b_rows - base) / ell
            s0 = self._n_thrust
            lower[s0 : s0 + N * 2 * self.M] = np.where(np.isfinite(lo), lo, -np.inf).reshape(-1)
        solver = self._solver
        if self.M:
            solver.update(q=q, l=lower, u=upper, Ax=self._a_vals[self._perm])
        else:
            solver.update(q=q, l=lower, u=upper)
        x_ws = np.zeros(self._nz)
        if guess_n is not None:
            x_ws[: self._nu] = guess_n.reshape(-1)
        y_ws = np.zeros(self._m) if dual_guess is None else dual_guess
        solver.warm_start(x=x_ws, y=y_ws)
        t0 = time.perf_counter()
        res = solver.solve(raise_error=False)
        elapsed = time.perf_counter() - t0
        status_val = res.info.status_val
        x = res.x
        ok = status_val in _OK_STATUS and x is not None and np.all(np.isfinite(x))
        if ok:
            un = x[: self._nu].reshape(N, d)
            slack = float(np.max(x[self._nu :], initial=0.0)) * ell
            dual = res.y.copy()
        else:
            un = np.zeros((N, d))
            slack = math.inf
            dual = None
        controls = self.project_thrust(un) * a
        states = free + (self._su @ controls.reshape(-1))
        return MPCSolution(
            controls=controls,
            states=states,
            status=str(res.info.status),
            iterations=int(res.info.iter),
            slack=max(slack, 0.0),
            solve_time=elapsed,
            ok=bool(ok),
            dual=dual,
        )

    def project_thrust(self, un: np.ndarray) -> np.ndarray:
        """Pull normalised controls (…, dim) back into the thrust set (solver tolerance)."""
        un = np.asarray(un, dtype=float)
        if self.thrust_model == "box":
            return np.clip(un, -1.0, 1.0)
        excess = (un @ self._facets.T) / self._facet_h  # ≤ 1 inside the polytope
        scale = np.maximum(excess.max(axis=-1, initial=0.0), 1.0)
        return un / scale[..., None]

    def command(
        self,
        state: np.ndarray,
        ref_pos: np.ndarray,
        ref_vel: np.ndarray,
        margins: Mapping[int, float] | None = None,
    ) -> np.ndarray:
        """The acceleration (m/s²) to apply now: the first move of the MPC solution.

        Warm-starts from the previous solution shifted by one step (primal and dual), penalises
        the change from the last command, and brakes (thrust against the velocity) if the QP
        fails.
        """
        guess = None
        dual = None
        if self._guess is not None:
            guess = np.vstack([self._guess[1:], self._guess[-1:]]) * self.max_accel
            if self._y is not None:
                dual = self._shift_dual(self._y)
        sol = self.solve(
            state,
            ref_pos,
            ref_vel,
            u_prev=self._last_u * self.max_accel,
            guess=guess,
            dual_guess=dual,
            margins=margins,
        )
        self.stats["solves"] += 1
        self.stats["iters"].append(sol.iterations)
        if sol.ok:
            if sol.slack > 0.1 * self.keepout_margin:
                self.stats["slack_steps"] += 1
            self._guess = sol.controls / self.max_accel
            self._y = sol.dual
            accel = sol.controls[0]
        else:
            self.stats["fallbacks"] += 1
            accel = self.brake(state)
            self._guess = None
            self._y = None
        self.last_solution = sol
        self._last_u = accel / self.max_accel
        return accel

    def _shift_dual(self, y: np.ndarray) -> np.ndarray:
        """Shift the dual vector one step forward in every per-step block."""
        out = y.copy()
        N = self.N
        for start, size in (
            (0, self._n_thrust),
            (self._n_thrust, self._n_keepout),
            (self._n_thrust + self._n_keepout, N),
        ):
            if size == 0:
                continue
            block = out[start : start + size].reshape(N, -1)
            block[:-1] = block[1:].copy()
        return out

    def brake(self, state: np.ndarray) -> np.ndarray:
        """Acceleration (m/s²) that kills the velocity as fast as the thrust set allows."""
        d = self.dim
        vel = np.asarray(state, float)[d:]
        want = -vel / self.dt / self.max_accel
        return self.project_thrust(want) * self.max_accel


# --------------------------------------------------------------------------------------------------
# planner + tracker agents
# --------------------------------------------------------------------------------------------------


class MPCPathAgent(ClassicalAgent):
    """Base of the planner + MPC-tracker baselines (APF-MPC, A*): plan a path per goal, track it.

    For each goal of the :class:`~agents.mission.MissionPlan` (an approach point next to the
    next uncaptured target, then the dock) a subclass's :meth:`plan_path` gives a waypoint path
    from the chaser's position; :class:`PathReference` turns it into a reference and
    :class:`MPCTracker` flies it. The path is re-planned when the goal changes (a capture) or
    when the chaser strays farther than ``replan_distance`` from it. At the path's end the
    reference stops at the approach point, so the tracker holds there until the env counts the
    capture. The goal target keeps a smaller keep-out margin (a quarter of the capture depth) so
    the approach point stays reachable.

    Args:
        env: the DebrisGym env.
        mpc: tracker parameters (shared by every subclass, so comparisons are of planners).
        reference: speed-profile parameters; ``end_speed`` is capped at 0.3 × capture speed.
        ordering: target visiting order, "shortest", "polygon" or "nearest" (the env's own
            current goal; see :class:`MissionPlan`).
        replan_distance: deviation from the path (m) that triggers a re-plan; None: 2 % of the
            world size.
        stall_steps: re-plan when the chaser has not advanced along the path (short of its end)
            for this many steps.

    Attributes:
        tracker: the episode's :class:`MPCTracker` (its ``stats``: solves, QP fallbacks to
            braking, steps that needed keep-out slack, OSQP iterations).
        stats: per-episode planner counters: plans, replans (deviation), stall_replans,
            plan_failures, plan_time (s), plus the subclass's own.
        path_log: the waypoint path of every plan this episode (m).
        decision_times: wall time (s) of every :meth:`act` call since the agent was built.
    """

    name = "mpc-path"

    def __init__(
        self,
        env: Any,
        mpc: MPCParams | None = None,
        reference: ReferenceParams | None = None,
        *,
        ordering: str = "shortest",
        replan_distance: float | None = None,
        stall_steps: int = 60,
    ) -> None:
        super().__init__(env)
        self.mpc_params = mpc or MPCParams()
        cfg = self.env.config
        reference = reference or ReferenceParams()
        self.reference_params = dataclasses.replace(
            reference, end_speed=min(reference.end_speed, 0.3 * cfg.capture_speed)
        )
        self.ordering = ordering
        self.replan_distance = replan_distance
        self.stall_steps = stall_steps
        self.tracker: MPCTracker | None = None
        self.stats: dict[str, Any] = {}
        self.decision_times: list[float] = []

    # --- hooks --------------------------------------------------------------------------------

    def prepare(self, scenario: Scenario) -> None:
        """Per-scenario planner set-up (e.g. a grid); called by :meth:`plan`."""

    def plan_path(self, start: np.ndarray, goal: Goal) -> PlanResult:
        """A collision-free path (m) from ``start`` to ``goal.point``."""
        raise NotImplementedError

    # --- ClassicalAgent -----------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.mission = MissionPlan(scenario, cfg, self.ordering)
        self.geometry = FieldGeometry(scenario)
        self.tracker = MPCTracker(
            scenario,
            self.mpc_params,
            thrust_model=cfg.thrust_model,
            chaser_radius=cfg.chaser_radius,
            geometry=self.geometry,
        )
        self._replan_distance = (
            self.replan_distance if self.replan_distance is not None else 0.02 * scenario.size
        )
        self._goal_key: tuple | None = None
        self._goal: Goal | None = None
        self._ref: PathReference | None = None
        self._margins: dict[int, float] = {}
        self.stats = {
            "plans": 0,
            "replans": 0,
            "stall_replans": 0,
            "plan_failures": 0,
            "plan_time": 0.0,
        }
        self.path_log: list[np.ndarray] = []
        self.prepare(scenario)

    def act(self) -> np.ndarray:
        t0 = time.perf_counter()
        env, d = self.env, self.env.dim
        state = env.chaser_state
        pos = state[:d]
        captured = env.captured
        key = tuple(bool(c) for c in captured)
        goal = None
        if self.mission.nearest:  # the env's goal can change without a capture
            goal = self.mission.current_goal(captured, pos)
            key += (None if goal is None else goal.index,)
        if key != self._goal_key:
            self._goal_key = key
            self._goal = goal or self.mission.current_goal(captured, pos)
            self.tracker.reset()
            self._new_path(pos)
        elif self._ref is not None and self._ref.deviation > self._replan_distance:
            self.stats["replans"] += 1
            self._new_path(pos)
        elif self._ref is not None and self._stalled():
            self.stats["stall_replans"] += 1
            self._new_path(pos)
        if self._ref is None:  # nothing left to do: hold still
            accel = self.tracker.brake(state)
        else:
            ref_pos, ref_vel = self._ref.horizon(state, self.tracker.N)
            accel = self.tracker.command(state, ref_pos, ref_vel, margins=self._margins)
        action = self.accel_to_action(accel)
        self.decision_times.append(time.perf_counter() - t0)
        return action

    def _stalled(self) -> bool:
        """No progress along the path, short of its end, for ``stall_steps`` decisions."""
        ref = self._ref
        if ref.progress > self._best_progress:
            self._best_progress = ref.progress
            self._since_progress = 0
            return False
        self._since_progress += 1
        near_end = (len(ref.s) - 1 - ref.progress) * ref.spacing <= 2.0 * self.tracker.ell
        return not near_end and self._since_progress >= self.stall_steps

    def _new_path(self, pos: np.ndarray) -> None:
        goal = self._goal
        if goal is None:
            self._ref = None
            return
        cfg, scen = self.env.config, self.env.scenario
        self._margins = {goal.index: 0.25 * cfg.capture_radius} if goal.kind == "target" else {}
        t0 = time.perf_counter()
        result = self.plan_path(pos, goal)
        self.stats["plan_time"] += time.perf_counter() - t0
        self.stats["plans"] += 1
        waypoints = result.waypoints
        if not result.success:
            self.stats["plan_failures"] += 1
            # Keep what the planner found and finish with a straight hop to the goal: the
            # tracker's keep-out constraints guard it.
            waypoints = np.vstack([waypoints, goal.point[None]])
        self.path_log.append(np.asarray(waypoints))
        self._best_progress = 0
        self._since_progress = 0
        self._ref = PathReference(
            waypoints,
            max_accel=scen.max_accel,
            dt=scen.dt,
            params=self.reference_params,
            world_size=scen.size,
        )
