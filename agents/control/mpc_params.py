"""The MPC tracker's parameters, its solution record and the thrust set its QP uses.

Plain data and one geometric helper for :mod:`agents.control.mpc` (the tracker itself); kept
apart so the tracker module reads as the QP and its solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from agents.planners.polytopes import inscribed_polytope

__all__ = ["MPCParams", "MPCSolution", "thrust_polytope"]


# --------------------------------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MPCParams:
    """Tunables of :class:`MPCTracker`.

    Weights are dimensionless: position errors are measured in ℓ = max_accel·dt² (m; 5 m on the
    default env), velocity errors in max_accel·dt (m/s), thrust as a fraction of max_accel.

    Attributes:
        horizon: prediction horizon N (steps); [APF-MPC] uses 20.
        w_position: weight of the squared position error per step.
        w_velocity: weight of the squared velocity error per step.
        w_terminal: multiplier of both tracking weights at the last step of the horizon.
        w_effort: λ1, weight of ‖ũ_k‖² (control effort, [APF-MPC] eq. 8).
        w_smooth: λ2, weight of ‖ũ_k − ũ_{k−1}‖² (smoothness, [APF-MPC] eq. 8), including the
            change from the previously applied command to the first move.
        keepout_margin: clearance (m) kept between the chaser's surface and every body; None:
            0.002 × the world size (2 m on the 1 km fields, 0.04 on the 20-unit paper field).
        keepout_per_step: keep-out bodies per linearisation point (nearest first); each gives a
            half-space on two consecutive predicted positions, so 2·this many rows per step.
            0 disables the keep-out constraints.
        teammates_per_step: keep-out spheres per linearisation point for the other chasers of a
            swarm (on their predicted tracks: :mod:`agents.planners.teammates`), nearest first,
            2·this many more rows per step; used only by an agent flying one chaser of a team
            (a view with ``teammates``); 0 ignores the teammates.
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
    teammates_per_step: int = 3
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
        if not (
            isinstance(self.teammates_per_step, int)
            and not isinstance(self.teammates_per_step, bool)
            and self.teammates_per_step >= 0
        ):
            raise ValueError(
                f"teammates_per_step must be an integer >= 0, got {self.teammates_per_step!r}"
            )
        if not (self.slack_linear > 0 and self.slack_quadratic > 0):
            raise ValueError("slack_linear and slack_quadratic must be > 0")
        if not (isinstance(self.thrust_facets, int) and self.thrust_facets >= 4):
            raise ValueError(f"thrust_facets must be an integer >= 4, got {self.thrust_facets!r}")
        if not (self.eps_abs > 0 and self.eps_rel >= 0 and self.max_iter >= 1):
            raise ValueError("eps_abs must be > 0, eps_rel >= 0 and max_iter >= 1")


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


def thrust_polytope(dim: int, model: str, facets: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Half-spaces C ũ ≤ h (ũ = u / max_accel) of the thrust set used by the QP.

    Returns:
        ``(C (F, dim), h (F,))``: the box |ũ_i| ≤ 1, or the ``"lattice"`` polytope inscribed
        in the unit ball (:func:`agents.planners.polytopes.inscribed_polytope`: the
        ``facets``-gon in 2D; the 26 cube face/edge/corner normals in 3D).
    """
    if model == "box":
        eye = np.eye(dim)
        return np.vstack([eye, -eye]), np.ones(2 * dim)
    if model != "ball":
        raise ValueError(f"thrust_model must be 'ball' or 'box', got {model!r}")
    polytope = inscribed_polytope(dim, facets, "lattice")
    return polytope.normals, polytope.offsets
