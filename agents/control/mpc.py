"""Linear MPC path tracker on the exact discretised CWH model, solved as a sparse QP with OSQP.

References (keys refer to docs/references.md):
    * [APF-MPC] §IV — horizon N = 20 and the cost of eq. 8: tracking error + λ1 ‖u‖² (control
      effort) + λ2 ‖Δu‖² (smoothness).
    * [Stellato20] — the QP solver (``import osqp``).

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

Moving bodies (a ``motion="cwh"`` field, given as a :class:`~agents.planners.motion.FieldMotion`
and the current time): the keep-out is time-indexed. The half-spaces around p̂_k come from the
bodies where they will be at t + k·dt; a half-space found at p̂_k and carried to p_{k+1} moves
with its body (its offset shifted by n·(c(t_{k+1}) − c(t_k)), c the body's centre), so it holds
in the body's own frame at both ends of the chord. The chaser's motion relative to a body obeys
the same CWH law, so this is the static argument in each body's frame.

Moving spheres (a swarm's teammates on their predicted tracks, ``movers`` of :meth:`solve`;
:mod:`agents.planners.teammates`): a tracker built with ``movers=T`` has T more half-spaces
per linearisation point, from the T nearest spheres where they will be at t + k·dt, carried one
step on with their sphere like a moving body's. A tracker built with ``movers=0`` (a single
chaser) has exactly the QP above.

The QP is set up once per tracker (one scenario and one parameter set) with a fixed sparsity
pattern; every decision only calls ``update(q=, l=, u=, Ax=)`` and warm-starts from the previous
primal and dual solution shifted by one step.

The reference it tracks (positions and velocities over the horizon) comes from
:class:`agents.control.reference.PathReference`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from agents.control.mpc_params import MPCParams, MPCSolution, thrust_polytope
from agents.planners.motion import FieldMotion
from agents.planners.teammates import MovingSpheres, keepout_halfspaces
from debris_gym.dynamics import discretize
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

__all__ = ["MPCParams", "MPCSolution", "MPCTracker", "thrust_polytope"]

_OK_STATUS = {
    osqp.SolverStatus.OSQP_SOLVED,
    osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
    osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
}


# --------------------------------------------------------------------------------------------------
# tracker
# --------------------------------------------------------------------------------------------------


class MPCTracker:
    """Tracks a reference trajectory with a linear MPC on the exact CWH model (OSQP, sparse QP).

    Args:
        scenario: the field (mean motion, dt, max_accel, dim, bodies for the keep-out).
        params: MPC tunables.
        thrust_model: "ball" or "box", as the env's ``thrust_model``.
        chaser_radius: chaser radius (m), added to every keep-out distance.
        geometry: the field's :class:`FieldGeometry` (built, not inflated, if omitted).
        motion: the bodies' predicted motion; given for a moving field, the keep-out uses the
            bodies where they will be at each step of the horizon (``now`` of :meth:`solve`).
        movers: keep-out rows per step for spheres on predicted tracks given at every solve
            (a swarm's teammates, ``movers`` of :meth:`solve`), the nearest first; 0: none (the
            QP of a single chaser).
    """

    def __init__(
        self,
        scenario: Scenario,
        params: MPCParams | None = None,
        *,
        thrust_model: str = "ball",
        chaser_radius: float = 0.0,
        geometry: FieldGeometry | None = None,
        motion: FieldMotion | None = None,
        movers: int = 0,
    ) -> None:
        if isinstance(movers, bool) or not isinstance(movers, (int, np.integer)) or movers < 0:
            raise ValueError(f"movers must be an integer >= 0, got {movers!r}")
        self.params = p = params or MPCParams()
        self.motion = motion if motion is not None and motion.moving else None
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
        self.T = int(movers)
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
        # keep-out rows: 2(M + T) per step k (positions p_{k+1}), coefficients on ũ_0..ũ_k and
        # s_k; the bodies' M, then the movers' T, of p̂_{k+1} and of p̂_k
        M2 = 2 * (self.M + self.T)
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
        self, points: np.ndarray, margins: np.ndarray, geometry: FieldGeometry | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Supporting half-spaces n·p ≥ b of the nearest bodies around each point.

        Args:
            points: (P, dim) linearisation points (m).
            margins: (n_bodies,) required distance (m) from each surface (∞ skips a body).
            geometry: the bodies as they are for these points (default: the tracker's field).

        Returns:
            ``(normals (P, M, dim), offsets (P, M) [m], valid (P, M), bodies (P, M))``.
        """
        geom, M, d = geometry or self.geometry, self.M, self.dim
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
        if poly.any():  # a polygon's nearest point may be a vertex or on an edge
            rows, slots = np.nonzero(poly)
            bodies = nearest[rows, slots]
            _, body_normals, body_surface = geom.nearest_points(points)
            g = body_normals[rows, bodies]
            normals[rows, slots] = g / np.maximum(np.linalg.norm(g, axis=1), 1e-12)[:, None]
            surface[rows, slots] = body_surface[rows, bodies]
        offsets = np.einsum("pmd,pmd->pm", normals, surface) + margins[nearest]
        del d
        return normals, np.where(valid, offsets, -np.inf), valid, nearest

    def _moving_halfspaces(
        self, points: np.ndarray, margins: np.ndarray, t0: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Half-spaces around p̂_k (k = 0 … N) from the bodies where they are at t0 + k·dt, and
        each carried one step on with its body (see the module docstring).

        Returns:
            ``(normals (N+1, M, dim), offsets (N+1, M), carried offsets (N, M))``: the
            carried offsets are those of p̂_k's half-spaces moved to t0 + (k+1)·dt.
        """
        motion, dt = self.motion, self.dt
        if motion is None:
            raise RuntimeError("half-spaces that move with the bodies need the tracker's motion")
        k_pts = len(points)
        normals = np.empty((k_pts, self.M, self.dim))
        offsets = np.empty((k_pts, self.M))
        bodies = np.empty((k_pts, self.M), dtype=np.int64)
        centres = np.array([motion.positions(t0 + k * dt) for k in range(k_pts)])
        for k in range(k_pts):
            geom = motion.geometry(t0 + k * dt)
            nk, ok, _, bk = self._halfspaces(points[k : k + 1], margins, geom)
            normals[k], offsets[k], bodies[k] = nk[0], ok[0], bk[0]
        shift = centres[1:k_pts] - centres[: k_pts - 1]  # (N, B, dim)
        rows = np.arange(k_pts - 1)[:, None]
        moved = np.einsum("kmd,kmd->km", normals[:-1], shift[rows, bodies[:-1]])
        return normals, offsets, offsets[:-1] + moved

    def _with_movers(
        self,
        points: np.ndarray,
        movers: MovingSpheres | None,
        normals: np.ndarray,
        offsets: np.ndarray,
        carried: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bodies' half-spaces (normals (N+1, M, dim), offsets (N+1, M), carried (N, M))
        followed by the movers' (T per point, :func:`~agents.planners.teammates.
        keepout_halfspaces`; without movers, rows that bind nothing)."""
        movers = movers if movers is not None else MovingSpheres.none(self.N, self.dim)
        if movers.tracks.shape[1] < self.N + 1:
            raise ValueError(f"movers' tracks must hold N + 1 = {self.N + 1} positions or more")
        n_m, o_m, c_m = keepout_halfspaces(
            points, movers, self.chaser_radius, self.keepout_margin, self.T
        )
        return (
            np.concatenate([normals, n_m], axis=1),
            np.concatenate([offsets, o_m], axis=1),
            np.concatenate([carried, c_m], axis=1),
        )

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

    def reachable_margins(
        self, pos: np.ndarray, now: float, overrides: Mapping[int, float] | None = None
    ) -> dict[int, float]:
        """Keep-out margins (m beyond the chaser radius) the chaser at ``pos`` (m) already
        satisfies at time ``now`` (s): ``overrides`` (see :meth:`body_margins`), and for every
        body nearer than its margin the chaser's present surface clearance instead.

        A body the chaser is closer to than its keep-out (the target just captured, whose
        margin was a quarter of the capture depth while it was the goal, is a plain obstacle
        from the next decision on) would make the first steps infeasible if the full margin were
        asked at once, and the QP's slack (one per step, a finite penalty) would then also pay
        for violating the other half-spaces of those steps; the present clearance rises back to
        the full margin as the chaser moves off.
        """
        margins = dict(overrides or {})
        default = self.keepout_margin
        geometry = self.motion.geometry(now) if self.motion is not None else self.geometry
        gaps = geometry.signed_distance(pos) - self.chaser_radius
        for index in np.flatnonzero(gaps < default):
            own = margins.get(int(index), default)
            margins[int(index)] = min(own, max(float(gaps[index]), 0.0))
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
        now: float = 0.0,
        movers: MovingSpheres | None = None,
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
            now: the current time (s since the episode began): where the bodies of a moving
                field are (ignored for a frozen one).
            movers: spheres on predicted tracks (at least N + 1 positions from now) kept out
                like the bodies, the tracker's ``movers`` nearest per step; a mover nearer than
                the keep-out margin must only not come nearer than it is (as a body in
                :meth:`reachable_margins`). Ignored by a tracker built with ``movers=0``.
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
        movers = movers if self.T and movers is not None and movers.count else None
        if self.M or self.T:
            if guess_n is None and self.motion is None and movers is None:
                lin = ref[:, :d]
            elif guess_n is None:
                # Cold start in a moving field (a new goal): linearise around the coasting
                # prediction, which starts where the chaser is. The reference can leap ahead
                # along a new path, and half-spaces taken around it can exclude the chaser's own
                # neighbourhood when it sits beside a body (just after a capture), so no step
                # is feasible and the slack then buys a cut through that body. The same holds
                # beside a teammate.
                lin = free[:, :d]
            else:
                lin = free[:, :d] + np.einsum(
                    "kdc,c->kd", self._su[:, :d, :], guess_n.reshape(-1) * a
                )
            points = np.vstack([x0[:d], lin])  # p̂_0 … p̂_N
            if not self.M:
                normals, offsets = np.zeros((N + 1, 0, d)), np.zeros((N + 1, 0))
                carried = offsets[:-1]
            elif self.motion is None:
                normals, offsets, _, _ = self._halfspaces(points, self.body_margins(margins))
                carried = offsets[:-1]
            else:
                normals, offsets, carried = self._moving_halfspaces(
                    points, self.body_margins(margins), now
                )
            if self.T:
                normals, offsets, carried = self._with_movers(
                    points, movers, normals, offsets, carried
                )
            # step k (position p_{k+1}): half-spaces of p̂_{k+1} (own) and of p̂_k (previous)
            n_rows = np.concatenate([normals[1:], normals[:-1]], axis=1)  # (N, 2(M+T), d)
            b_rows = np.concatenate([offsets[1:], carried], axis=1)  # (N, 2(M+T))
            coef = np.einsum("kmd,kdc->kmc", n_rows, self._gp)  # (N, 2(M+T), nu)
            self._a_vals[self._ko_ctrl_idx] = coef[self._ko_mask]
            base = np.einsum("kmd,kd->km", n_rows, free[:, :d])  # n·(free position)
            lo = (b_rows - base) / ell
            s0 = self._n_thrust
            lower[s0 : s0 + self._n_keepout] = np.where(np.isfinite(lo), lo, -np.inf).reshape(-1)
        solver = self._solver
        if self.M or self.T:
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
        now: float = 0.0,
        movers: MovingSpheres | None = None,
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
            now=now,
            movers=movers,
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
