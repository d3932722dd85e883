"""Artificial potential field (APF, [Khatib86]): potentials and forces, the local-minimum test,
and a gradient-descent path planner (the agent that flies the gradient is
:class:`agents.policies.apf.APFAgent`).

References (keys refer to docs/references.md):
    * [Khatib86] — the FIRAS repulsive potential.
    * [Choset05] ch. 4 (eq. 4.2-4.6) — quadratic attraction with a conic switch far away, repulsion
      U = ½η(1/d − 1/d₀)² for d ≤ d₀ with gradient −η(1/d − 1/d₀)(1/d²)∇d.
    * [APF-MPC] eq. 1-6 — the same potentials, descent with step ε = 0.01 for 400 steps per
      segment, influence distance 1 (:meth:`APFParams.paper`).
    * [An23] eq. 2-5 and the local-minimum test eq. 14 (:func:`is_local_minimum`); its RRT escape
      lives in :mod:`agents.planners.rrt`.
    * [Ge00] — optional goal shielding of the repulsion (``goal_shield``), which removes the
      "goal non-reachable with obstacles nearby" equilibrium.

Forces are minus potential gradients. In the agent they are accelerations (m/s²), so ``k_att`` is
in 1/s² and ``k_rep`` in m⁴/s²; the planner only uses the force direction (or ε·force, the [APF-MPC]
rule), so there only the ratio of the gains matters. Clearance ``d`` to a body is its signed
distance (``FieldGeometry.gaps_and_normals``) minus ``inflate`` (the chaser's radius) minus the
safety ``margin``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.planners.result import PlanResult
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

# --- tunables: defaults for the LEO field (1 km, max_accel 0.05 m/s², dt 10 s) -------------------

LEO_LENGTH = 1000.0
"""Field size (m) the default parameters are tuned for; :meth:`APFParams.for_scenario` scales."""

LEO_ACCEL = 0.05
"""Thrust limit (m/s²) the default parameters are tuned for."""

MIN_CLEARANCE_FRACTION = 1e-3
"""Clearances below this fraction of d₀ are clamped (the repulsion stays finite, very large)."""

VirtualPoint = tuple[np.ndarray, float]
"""A virtual repulsive point: (position (m), influence radius (m))."""


@dataclass(frozen=True)
class APFParams:
    """Potential-field parameters (SI units; defaults for the 1 km LEO field).

    The LEO defaults: the attraction saturates at ζ·d* = 0.02 m/s² (0.4 of the thrust limit);
    η makes the repulsion equal to that at 10 m clearance; d₀ = 60 m is about twice the stopping
    distance (one step of lag included) from the agent's cruise speed of about 1.2 m/s.

    Attributes:
        k_att: attractive gain ζ (1/s²): force −ζ(x − g) inside ``d_star``.
        d_star: quadratic → conic switch distance (m); beyond it the attraction has the constant
            magnitude ζ·d_star. ``inf`` = quadratic everywhere ([APF-MPC]).
        k_rep: repulsive gain η (m⁴/s²).
        d0: influence distance d₀ (m): bodies farther than this do not repel.
        margin: safety margin (m) added to every body on top of ``inflate``.
        goal_shield: [Ge00] goal shielding radius r_g (m): repulsion is multiplied by
            ρ_g²/(ρ_g² + r_g²), ρ_g the distance to the goal, so it vanishes at the goal. 0 = off.
        step_size: planner step (m): the length of each normalised step, or ε of the gradient
            rule ``x ← x + ε F`` when ``normalized_step`` is False.
        normalized_step: True: steps of fixed length along the force ([An23]); False: the
            plain gradient rule of [APF-MPC].
        max_steps: planner step limit per segment.
        goal_tol: the planner has arrived within this distance of the goal (m).
        stall_window: steps over which progress toward the goal is measured.
        stall_progress: smallest decrease of the goal distance over ``stall_window`` steps that
            still counts as progress (m); None = 0.1 · stall_window · step_size.
        balance_tol: eq. 14 force balance ‖F_att + F_rep‖ < balance_tol · ‖F_att‖.
        opposed_cos: eq. 14 angle test cos∠(F_att, F_rep) < opposed_cos.
    """

    k_att: float = 2.0e-3
    d_star: float = 10.0
    k_rep: float = 24.0
    d0: float = 60.0
    margin: float = 2.0
    goal_shield: float = 0.0
    step_size: float = 2.0
    normalized_step: bool = True
    max_steps: int = 3000
    goal_tol: float = 1.0
    stall_window: int = 30
    stall_progress: float | None = None
    balance_tol: float = 0.5
    opposed_cos: float = -0.9

    def __post_init__(self) -> None:
        positive = ("k_att", "d_star", "d0", "step_size", "goal_tol")
        for name in positive:
            value = getattr(self, name)
            if not value > 0 or math.isnan(value):
                raise ValueError(f"APFParams.{name} must be > 0, got {value!r}")
        for name in ("k_rep", "margin", "goal_shield"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"APFParams.{name} must be finite and >= 0, got {value!r}")
        if self.max_steps < 1 or self.stall_window < 1:
            raise ValueError("APFParams.max_steps and stall_window must be >= 1")
        if not (self.balance_tol > 0 and -1.0 <= self.opposed_cos <= 1.0):
            raise ValueError("APFParams.balance_tol must be > 0 and opposed_cos in [-1, 1]")

    @property
    def progress_tol(self) -> float:
        """Smallest goal-distance decrease (m) over ``stall_window`` steps that is progress."""
        if self.stall_progress is not None:
            return self.stall_progress
        return 0.1 * self.stall_window * self.step_size

    @classmethod
    def paper(cls) -> APFParams:
        """The [APF-MPC] planner: U_att = ‖x − g‖² (ζ = 2, no conic part), influence distance 1,
        x ← x − ε∇U with ε = 0.01 for at most 400 steps per segment (unit-less 20 × 20 world).

        The paper does not print its repulsion factor α; 0.05 keeps its 20 × 20 field's paths
        clear of the unit-size spheres.
        """
        return cls(
            k_att=2.0,
            d_star=math.inf,
            k_rep=0.05,
            d0=1.0,
            margin=0.0,
            step_size=0.01,
            normalized_step=False,
            max_steps=400,
            goal_tol=0.05,
            stall_window=40,
            stall_progress=1e-3,
        )

    def scaled(self, length: float, accel: float) -> APFParams:
        """The same field shape for a world ``length`` times larger and thrust ``accel`` times
        stronger (lengths × length, k_att × accel/length, k_rep × accel·length³)."""
        return dataclasses.replace(
            self,
            k_att=self.k_att * accel / length,
            d_star=self.d_star * length,
            k_rep=self.k_rep * accel * length**3,
            d0=self.d0 * length,
            margin=self.margin * length,
            goal_shield=self.goal_shield * length,
            step_size=self.step_size * length,
            goal_tol=self.goal_tol * length,
            stall_progress=None if self.stall_progress is None else self.stall_progress * length,
        )

    @classmethod
    def for_scenario(cls, scenario: Scenario, **overrides: Any) -> APFParams:
        """Defaults scaled from the LEO field to ``scenario`` (its size and thrust limit)."""
        base = cls(**overrides)
        return base.scaled(scenario.size / LEO_LENGTH, scenario.max_accel / LEO_ACCEL)


# --- potentials and forces ------------------------------------------------------------------------


def attractive_potential(x: np.ndarray, goal: np.ndarray, params: APFParams) -> float:
    """U_att (m²/s²): ½ζρ² for ρ ≤ d*, ζd*ρ − ½ζd*² beyond (ρ = ‖x − goal‖)."""
    rho = float(np.linalg.norm(np.asarray(x, float) - goal))
    if rho <= params.d_star:
        return 0.5 * params.k_att * rho * rho
    return params.k_att * params.d_star * (rho - 0.5 * params.d_star)


def attractive_force(x: np.ndarray, goal: np.ndarray, params: APFParams) -> np.ndarray:
    """F_att = −∇U_att: −ζ(x − g) inside d*, −ζd*(x − g)/ρ beyond (m/s²)."""
    diff = np.asarray(x, float) - np.asarray(goal, float)
    rho = math.sqrt(float(diff @ diff))
    if rho <= params.d_star:
        return -params.k_att * diff
    return -params.k_att * params.d_star * diff / rho


def _body_terms(
    gaps: np.ndarray, normals: np.ndarray, params: APFParams, active: np.ndarray, inflate: float
) -> tuple[float, np.ndarray]:
    """Σ U_rep,i and Σ F_rep,i over the bodies within d₀ (no goal shielding)."""
    d = gaps - inflate - params.margin
    near = active & (d <= params.d0)
    if not near.any():
        return 0.0, np.zeros(normals.shape[1])
    dn = np.maximum(d[near], MIN_CLEARANCE_FRACTION * params.d0)
    excess = 1.0 / dn - 1.0 / params.d0
    potential = 0.5 * params.k_rep * float((excess * excess).sum())
    force = (params.k_rep * excess / (dn * dn)) @ normals[near]
    return potential, force


def _virtual_terms(
    x: np.ndarray, virtual: Iterable[VirtualPoint], params: APFParams
) -> tuple[float, np.ndarray]:
    """Σ U and Σ F of virtual repulsive points ([An23] §3), each with its own radius."""
    potential, force = 0.0, np.zeros(len(x))
    for point, radius in virtual:
        diff = x - point
        dist = math.sqrt(float(diff @ diff))
        if dist >= radius:
            continue
        dn = max(dist, MIN_CLEARANCE_FRACTION * radius)
        excess = 1.0 / dn - 1.0 / radius
        potential += 0.5 * params.k_rep * excess * excess
        if dist > 0.0:
            force += params.k_rep * excess / (dn * dn) * diff / dist
    return potential, force


def repulsion(
    x: np.ndarray,
    gaps: np.ndarray,
    normals: np.ndarray,
    params: APFParams,
    active: np.ndarray,
    inflate: float,
    goal: np.ndarray | None,
    virtual: Sequence[VirtualPoint],
) -> tuple[float, np.ndarray]:
    """Total repulsive potential (m²/s²) and force (m/s²) at ``x``, with Ge-Cui goal shielding
    when enabled.

    Args:
        x: position (m).
        gaps: signed distance (m) from ``x`` to each body, un-inflated.
        normals: (n_bodies, dim) unit outward normals at ``x`` (∇ of each gap).
        params: gains and distances.
        active: (n_bodies,) which bodies repel (:func:`active_mask`).
        inflate: distance (m) added to every body, e.g. the chaser's radius.
        goal: the goal (m), used only when ``params.goal_shield`` > 0.
        virtual: extra repulsive points (position, influence radius).
    """
    potential, force = _body_terms(gaps, normals, params, active, inflate)
    if virtual:
        pv, fv = _virtual_terms(x, virtual, params)
        potential, force = potential + pv, force + fv
    if params.goal_shield > 0.0 and goal is not None and potential > 0.0:
        # U = s(ρ_g)·U₀ with s = ρ_g²/(ρ_g² + r²): F = s·F₀ − U₀∇s, ∇s = 2r²(x − g)/(ρ_g² + r²)².
        diff = x - goal
        rho2 = float(diff @ diff)
        r2 = params.goal_shield**2
        s = rho2 / (rho2 + r2)
        grad_s = 2.0 * r2 * diff / (rho2 + r2) ** 2
        force = s * force - potential * grad_s
        potential = s * potential
    return potential, force


def active_mask(n_bodies: int, ignore: Iterable[int]) -> np.ndarray:
    """(n_bodies,) booleans: True for every body that repels, False for the ``ignore``d ones."""
    mask = np.ones(n_bodies, dtype=bool)
    for i in ignore:
        mask[int(i)] = False
    return mask


def repulsive_field(
    x: np.ndarray,
    geometry: FieldGeometry,
    params: APFParams,
    ignore: Iterable[int] = (),
    *,
    inflate: float = 0.0,
    goal: np.ndarray | None = None,
    virtual: Sequence[VirtualPoint] = (),
) -> tuple[float, np.ndarray]:
    """(U_rep, F_rep) at ``x``: U_rep = Σᵢ ½η(1/dᵢ − 1/d₀)² over bodies with clearance dᵢ ≤ d₀
    (m²/s²) and F_rep = −∇U_rep = Σᵢ η(1/dᵢ − 1/d₀)(1/dᵢ²)∇dᵢ (m/s²), ∇dᵢ the unit normal from
    ``FieldGeometry.gaps_and_normals``.

    Args:
        x: position (m).
        geometry: the field's geometry (its own ``inflate`` is not used).
        params: gains and distances.
        ignore: body indices (targets first, then obstacles) that do not repel.
        inflate: distance (m) added to every body, e.g. the chaser's radius.
        goal: the goal (m), needed only when ``params.goal_shield`` > 0.
        virtual: extra repulsive points (position, influence radius).
    """
    x = np.asarray(x, float)
    gaps, normals = geometry.gaps_and_normals(x)
    active = active_mask(geometry.n_bodies, ignore)
    goal_arr = None if goal is None else np.asarray(goal, float)
    return repulsion(x, gaps, normals, params, active, inflate, goal_arr, virtual)


def total_force(
    x: np.ndarray,
    goal: np.ndarray,
    geometry: FieldGeometry,
    params: APFParams,
    ignore: Iterable[int] = (),
    *,
    inflate: float = 0.0,
    virtual: Sequence[VirtualPoint] = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F_total, F_att, F_rep) at ``x`` (m/s²): [APF-MPC] eq. 6, [An23] eq. 6."""
    x = np.asarray(x, float)
    goal = np.asarray(goal, float)
    gaps, normals = geometry.gaps_and_normals(x)
    active = active_mask(geometry.n_bodies, ignore)
    f_att = attractive_force(x, goal, params)
    f_rep = repulsion(x, gaps, normals, params, active, inflate, goal, virtual)[1]
    return f_att + f_rep, f_att, f_rep


def is_local_minimum(f_att: np.ndarray, f_rep: np.ndarray, params: APFParams) -> bool:
    """[An23] eq. 14: the forces nearly cancel and nearly oppose each other.

    Balance: ‖F_att + F_rep‖ < balance_tol·‖F_att‖ — the paper's |‖F_att‖ − ‖F_rep‖| / ‖F_att‖
    < 0.5 taken on the vector sum, which implies it (triangle inequality). Angle:
    cos∠(F_att, F_rep) < opposed_cos (−0.9 in the paper).
    """
    fa = float(np.linalg.norm(f_att))
    fr = float(np.linalg.norm(f_rep))
    if fa <= 0.0 or fr <= 0.0:
        return False
    balanced = float(np.linalg.norm(f_att + f_rep)) < params.balance_tol * fa
    opposed = float(f_att @ f_rep) / (fa * fr) < params.opposed_cos
    return balanced and opposed


def is_held_back(f_att: np.ndarray, f_rep: np.ndarray, params: APFParams) -> bool:
    """[An23] eq. 14 with its balance test one-sided, for a moving field: the repulsion is
    nearly opposite the attraction, cos∠(F_att, F_rep) < opposed_cos, and at least
    (1 − balance_tol) as strong, ‖F_rep‖ ≥ (1 − balance_tol)·‖F_att‖, with no upper bound (a body
    closing in on the chaser pushes it back harder than the goal pulls)."""
    fa = float(np.linalg.norm(f_att))
    fr = float(np.linalg.norm(f_rep))
    if fa <= 0.0 or fr <= 0.0:
        return False
    strong = fr >= (1.0 - params.balance_tol) * fa
    opposed = float(f_att @ f_rep) / (fa * fr) < params.opposed_cos
    return strong and opposed


# --- the planner -------------------------------------------------------------------------------


class Descent:
    """Gradient descent on the total potential toward one goal; shared by the APF planners
    (:func:`apf_path`, :func:`agents.planners.rrt.apf_rrt_path`, which adds virtual points).

    Keeps the path collision-free by construction: a step never exceeds half the current physical
    clearance (clearance is 1-Lipschitz, so the segment cannot reach a body).
    """

    def __init__(
        self,
        geometry: FieldGeometry,
        params: APFParams,
        goal: np.ndarray,
        ignore: Iterable[int],
        inflate: float,
    ) -> None:
        self.geometry = geometry
        self.params = params
        self.goal = goal
        self.inflate = inflate
        self.active = active_mask(geometry.n_bodies, ignore)
        self.virtual: list[VirtualPoint] = []

    @classmethod
    def from_start(
        cls,
        scenario: Scenario,
        start: np.ndarray,
        goal: np.ndarray,
        params: APFParams | None,
        *,
        inflate: float,
        geometry: FieldGeometry | None,
        ignore: Iterable[int],
    ) -> tuple[Descent, list[np.ndarray]]:
        """A planner's descent from ``start`` to ``goal`` and its path so far (``[start]``);
        arguments as :func:`apf_path` (``params`` None: the LEO defaults; ``geometry`` None:
        built from ``scenario``).

        Raises:
            ValueError: ``start`` or ``goal`` is not a point of the scenario's dimension.
        """
        params = APFParams() if params is None else params
        geometry = FieldGeometry(scenario) if geometry is None else geometry
        x = np.asarray(start, dtype=float).copy()
        goal = np.asarray(goal, dtype=float)
        if x.shape != (scenario.dim,) or goal.shape != (scenario.dim,):
            raise ValueError(f"start and goal must have shape ({scenario.dim},)")
        return cls(geometry, params, goal, ignore, inflate), [x]

    def forces(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(F_att, F_rep, physical clearance (m)) at ``x``; ignored bodies count for clearance."""
        gaps, normals = self.geometry.gaps_and_normals(x)
        f_att = attractive_force(x, self.goal, self.params)
        f_rep = repulsion(
            x, gaps, normals, self.params, self.active, self.inflate, self.goal, self.virtual
        )[1]
        clearance = float(gaps.min()) - self.inflate if gaps.size else math.inf
        return f_att, f_rep, clearance

    def step(self, x: np.ndarray, force: np.ndarray, clearance: float) -> np.ndarray | None:
        """The next point, or None if the force vanishes or there is no room to move."""
        p = self.params
        norm = float(np.linalg.norm(force))
        if norm == 0.0 or not math.isfinite(norm) or clearance <= 0.0:
            return None
        length = p.step_size if p.normalized_step else p.step_size * norm
        to_goal = float(np.linalg.norm(self.goal - x))
        length = min(length, 0.5 * clearance, max(to_goal, p.goal_tol))
        return x + force * (length / norm)

    def arrived(self, x: np.ndarray, clearance: float) -> bool:
        """Within goal_tol of the goal, and the last hop onto the goal is collision-free."""
        gap = float(np.linalg.norm(self.goal - x))
        return gap <= self.params.goal_tol and gap < clearance

    def run(self, points: list[np.ndarray], budget: int) -> tuple[str, np.ndarray | None, float]:
        """Descend from ``points[-1]`` for at most ``budget`` steps, appending to ``points``.

        Returns:
            (status, stall point or None, smallest physical clearance (m) met). Status:
            "arrived" (the goal was appended), "local_minimum" / "no_progress" / "zero_force"
            (stalled), or "max_steps".
        """
        x = points[-1]
        dists = [float(np.linalg.norm(self.goal - x))]
        min_clear = math.inf
        for _ in range(budget):
            f_att, f_rep, clearance = self.forces(x)
            min_clear = min(min_clear, clearance)
            if self.arrived(x, clearance):
                if dists[-1] > 0.0:
                    points.append(self.goal.copy())
                return "arrived", None, min_clear
            reason = _stalled(dists, self.params, f_att, f_rep)
            nxt = self.step(x, f_att + f_rep, clearance)
            if reason is not None or nxt is None:
                tail = np.asarray(points[-min(len(points), 10) :])
                return reason or "zero_force", tail.mean(axis=0), min_clear
            x = nxt
            points.append(x)
            dists.append(float(np.linalg.norm(self.goal - x)))
        return "max_steps", None, min_clear


def _stalled(dists: list[float], params: APFParams, f_att, f_rep) -> str | None:
    """Why the descent is stuck, or None: eq. 14 + no progress over the window, or no
    progress at all over four windows (a limit cycle eq. 14 does not see)."""
    w = params.stall_window
    if len(dists) <= w:
        return None
    no_progress = dists[-1 - w] - dists[-1] < params.progress_tol
    if no_progress and is_local_minimum(f_att, f_rep, params):
        return "local_minimum"
    if len(dists) > 4 * w and min(dists[: -4 * w]) - min(dists[-4 * w :]) < params.progress_tol:
        return "no_progress"
    return None


def apf_path(
    scenario: Scenario,
    start: np.ndarray,
    goal: np.ndarray,
    params: APFParams | None = None,
    *,
    inflate: float = 0.0,
    geometry: FieldGeometry | None = None,
    ignore: Iterable[int] = (),
) -> PlanResult:
    """Plan a path from ``start`` to ``goal`` by descending the total potential.

    Each step moves ``params.step_size`` along the total force (or ε·F, the [APF-MPC] rule, when
    ``params.normalized_step`` is False), never more than half the clearance. Stops at the goal
    (success), after ``params.max_steps``, or when stalled in a local minimum ([An23] eq. 14 and
    no progress toward the goal over ``params.stall_window`` steps).

    Args:
        scenario: the field (frozen bodies).
        start: start position (m).
        goal: goal position (m), e.g. an approach point next to a target.
        params: potential and planner parameters; defaults to the LEO ones.
        inflate: distance (m) added to every body, e.g. the chaser's radius.
        geometry: a prebuilt :class:`FieldGeometry` of ``scenario`` (only its un-inflated distance
            queries are used); built if None.
        ignore: body indices (targets first) that do not repel — the goal target whose surface the
            approach point sits next to. They still bound the step, so the path never enters them.

    Returns:
        :class:`PlanResult`: waypoints (K, dim), start first, ending exactly at ``goal`` on
        success. ``info``: ``steps``, ``stalled``, ``stall_point`` (m, or None), ``stall_reason``,
        ``min_clearance`` (m, to the inflated bodies).
    """
    descent, points = Descent.from_start(
        scenario, start, goal, params, inflate=inflate, geometry=geometry, ignore=ignore
    )
    status, stall_point, min_clear = descent.run(points, descent.params.max_steps)
    stalled = stall_point is not None
    waypoints = np.asarray(points)
    info: dict[str, Any] = {
        "steps": len(points) - 1,
        "stalled": stalled,
        "stall_point": stall_point,
        "stall_reason": status if stalled else None,
        "min_clearance": min_clear,
    }
    return PlanResult(status == "arrived", waypoints, PlanResult.path_length(waypoints), info)


__all__ = [
    "MIN_CLEARANCE_FRACTION",
    "APFParams",
    "Descent",
    "VirtualPoint",
    "active_mask",
    "apf_path",
    "attractive_force",
    "attractive_potential",
    "is_held_back",
    "is_local_minimum",
    "repulsion",
    "repulsive_field",
    "total_force",
]
