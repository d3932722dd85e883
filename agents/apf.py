"""Artificial potential field (APF): Khatib's potentials, a gradient-descent path planner, and an
agent that flies the potential gradient under CWH dynamics.

References:
    * O. Khatib, "Real-time obstacle avoidance for manipulators and mobile robots", IJRR 5(1),
      1986 — the FIRAS repulsive potential.
    * H. Choset et al., *Principles of Robot Motion*, MIT Press 2005, ch. 4 (eq. 4.2-4.6):
      quadratic attraction with a conic switch far away, repulsion
      U = ½η(1/d − 1/d₀)² for d ≤ d₀ with gradient −η(1/d − 1/d₀)(1/d²)∇d.
    * Seed paper 000 (APF-MPC debris rendezvous) eq. 1-6: the same potentials, descent with step
      ε = 0.01 for 400 steps per segment, influence distance 1 (:meth:`APFParams.paper`).
    * Seed paper 003 (improved APF) eq. 2-5 and the local-minimum test eq. 14
      (:func:`is_local_minimum`); its RRT escape lives in :mod:`agents.apf_rrt`.
    * S. S. Ge, Y. J. Cui, "New potential functions for mobile robot path planning", IEEE T-RA
      16(5), 2000 — optional goal shielding of the repulsion (``goal_shield``), which removes the
      "goal non-reachable with obstacles nearby" equilibrium.

Forces are minus potential gradients. In the agent they are accelerations (m/s²), so ``k_att`` is
in 1/s² and ``k_rep`` in m⁴/s²; the planner only uses the force direction (or ε·force, the paper's
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

from agents.base import ClassicalAgent
from agents.mission import Goal, MissionPlan
from agents.planning import PlanResult
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
            magnitude ζ·d_star. ``inf`` = quadratic everywhere (seed 000).
        k_rep: repulsive gain η (m⁴/s²).
        d0: influence distance d₀ (m): bodies farther than this do not repel.
        margin: safety margin (m) added to every body on top of ``inflate``.
        goal_shield: Ge-Cui goal shielding radius r_g (m): repulsion is multiplied by
            ρ_g²/(ρ_g² + r_g²), ρ_g the distance to the goal, so it vanishes at the goal. 0 = off.
        step_size: planner step (m): the length of each normalised step, or ε of the gradient
            rule ``x ← x + ε F`` when ``normalized_step`` is False.
        normalized_step: True: steps of fixed length along the force (seed 003); False: the
            plain gradient rule of seed 000.
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
        """Seed 000's planner: U_att = ‖x − g‖² (ζ = 2, no conic part), influence distance 1,
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
    """Σ U and Σ F of virtual repulsive points (seed 003 §3), each with its own radius."""
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


def _repulsion(
    x: np.ndarray,
    gaps: np.ndarray,
    normals: np.ndarray,
    params: APFParams,
    active: np.ndarray,
    inflate: float,
    goal: np.ndarray | None,
    virtual: Sequence[VirtualPoint],
) -> tuple[float, np.ndarray]:
    """Total repulsive potential and force, with Ge-Cui goal shielding when enabled."""
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


def _active_mask(n_bodies: int, ignore: Iterable[int]) -> np.ndarray:
    mask = np.ones(n_bodies, dtype=bool)
    for i in ignore:
        mask[int(i)] = False
    return mask


def repulsive_potential(
    x: np.ndarray,
    geometry: FieldGeometry,
    params: APFParams,
    ignore: Iterable[int] = (),
    *,
    inflate: float = 0.0,
    goal: np.ndarray | None = None,
    virtual: Sequence[VirtualPoint] = (),
) -> float:
    """U_rep = Σᵢ ½η(1/dᵢ − 1/d₀)² over bodies with clearance dᵢ ≤ d₀ (m²/s²).

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
    active = _active_mask(geometry.n_bodies, ignore)
    goal_arr = None if goal is None else np.asarray(goal, float)
    return _repulsion(x, gaps, normals, params, active, inflate, goal_arr, virtual)[0]


def repulsive_force(
    x: np.ndarray,
    geometry: FieldGeometry,
    params: APFParams,
    ignore: Iterable[int] = (),
    *,
    inflate: float = 0.0,
    goal: np.ndarray | None = None,
    virtual: Sequence[VirtualPoint] = (),
) -> np.ndarray:
    """F_rep = −∇U_rep = Σᵢ η(1/dᵢ − 1/d₀)(1/dᵢ²)∇dᵢ (m/s²); arguments as
    :func:`repulsive_potential`. ∇dᵢ is the unit normal from ``FieldGeometry.gaps_and_normals``.
    """
    x = np.asarray(x, float)
    gaps, normals = geometry.gaps_and_normals(x)
    active = _active_mask(geometry.n_bodies, ignore)
    goal_arr = None if goal is None else np.asarray(goal, float)
    return _repulsion(x, gaps, normals, params, active, inflate, goal_arr, virtual)[1]


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
    """(F_total, F_att, F_rep) at ``x`` (m/s²): seed 000 eq. 6, seed 003 eq. 6."""
    x = np.asarray(x, float)
    goal = np.asarray(goal, float)
    gaps, normals = geometry.gaps_and_normals(x)
    active = _active_mask(geometry.n_bodies, ignore)
    f_att = attractive_force(x, goal, params)
    f_rep = _repulsion(x, gaps, normals, params, active, inflate, goal, virtual)[1]
    return f_att + f_rep, f_att, f_rep


def is_local_minimum(f_att: np.ndarray, f_rep: np.ndarray, params: APFParams) -> bool:
    """Seed 003 eq. 14: the forces nearly cancel and nearly oppose each other.

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


# --- the planner -------------------------------------------------------------------------------


class _Descent:
    """Gradient descent on the total potential toward one goal; shared by the APF planners.

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
        self.active = _active_mask(geometry.n_bodies, ignore)
        self.virtual: list[VirtualPoint] = []

    def forces(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(F_att, F_rep, physical clearance (m)) at ``x``; ignored bodies count for clearance."""
        gaps, normals = self.geometry.gaps_and_normals(x)
        f_att = attractive_force(x, self.goal, self.params)
        f_rep = _repulsion(
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
            if reason is None and nxt is None:
                reason = "zero_force"
            if reason is not None:
                tail = np.asarray(points[-min(len(points), 10) :])
                return reason, tail.mean(axis=0), min_clear
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

    Each step moves ``params.step_size`` along the total force (or ε·F, seed 000's rule, when
    ``params.normalized_step`` is False), never more than half the clearance. Stops at the goal
    (success), after ``params.max_steps``, or when stalled in a local minimum (seed 003 eq. 14 and
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
    params = APFParams() if params is None else params
    geometry = FieldGeometry(scenario) if geometry is None else geometry
    x = np.asarray(start, dtype=float).copy()
    goal = np.asarray(goal, dtype=float)
    if x.shape != (scenario.dim,) or goal.shape != (scenario.dim,):
        raise ValueError(f"start and goal must have shape ({scenario.dim},)")
    descent = _Descent(geometry, params, goal, ignore, inflate)
    points = [x]
    status, stall_point, min_clear = descent.run(points, params.max_steps)
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


# --- the agent ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class APFGuidance:
    """How :class:`APFAgent` turns the potential into thrust (SI units; LEO defaults).

    Attributes:
        damping: velocity damping k_d (1/s) in a = F − k_d v; the cruise speed is about
            ‖F_att‖max / k_d = k_att·d_star / k_d.
        brake_fraction: share β of the thrust limit the braking speed limits assume.
        stall_time: window (s) over which APF-RRT looks for a local minimum: no progress
            toward the goal, and the window-mean forces pass the eq. 14 test.
        stall_progress: goal-distance decrease (m) over ``stall_time`` that counts as progress.
    """

    damping: float = 0.0167
    brake_fraction: float = 0.5
    stall_time: float = 300.0
    stall_progress: float = 5.0

    def scaled(self, length: float, accel: float) -> APFGuidance:
        """Rescale for a world ``length`` times larger and thrust ``accel`` times stronger."""
        time = math.sqrt(length / accel)
        return dataclasses.replace(
            self,
            damping=self.damping / time,
            stall_time=self.stall_time * time,
            stall_progress=self.stall_progress * length,
        )

    @classmethod
    def for_scenario(cls, scenario: Scenario, **overrides: Any) -> APFGuidance:
        """Defaults scaled from the LEO field to ``scenario``."""
        base = cls(**overrides)
        return base.scaled(scenario.size / LEO_LENGTH, scenario.max_accel / LEO_ACCEL)


def braking_speed(distance: float, decel: float, dt: float) -> float:
    """Largest speed (m/s) from which a chaser that reacts one step late can still stop within
    ``distance`` (m) at deceleration ``decel`` (m/s²): v·dt + v²/(2·decel) = distance."""
    if distance <= 0.0:
        return 0.0
    lag = decel * dt
    return -lag + math.sqrt(lag * lag + 2.0 * decel * distance)


def cwh_accel(state: np.ndarray, n: float) -> np.ndarray:
    """The CWH acceleration of an uncontrolled chaser (m/s²): [3n²x + 2nẏ, −2nẋ(, −n²z)]."""
    d = len(state) // 2
    x, v = state[:d], state[d:]
    out = np.empty(d)
    out[0] = 3.0 * n * n * x[0] + 2.0 * n * v[1]
    out[1] = -2.0 * n * v[0]
    if d == 3:
        out[2] = -n * n * x[2]
    return out


def prioritised_sum(first: np.ndarray, second: np.ndarray, limit: float) -> np.ndarray:
    """``first`` + λ·``second`` with the largest λ ∈ [0, 1] that keeps the norm ≤ ``limit``
    (``first`` alone scaled down if it already exceeds it)."""
    n1 = float(np.linalg.norm(first))
    if n1 >= limit:
        return first * (limit / n1)
    total = first + second
    if float(total @ total) <= limit * limit:
        return total
    # ‖first + λ second‖ = limit: a λ² + b λ + c = 0 with the positive root.
    a = float(second @ second)
    b = 2.0 * float(first @ second)
    c = n1 * n1 - limit * limit
    lam = (-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)
    return first + min(max(lam, 0.0), 1.0) * second


class APFAgent(ClassicalAgent):
    """Flies the mission on the potential gradient ("apf").

    Each step, toward the current goal (the approach point of the next target, then the dock):

    * a_nom = F_att + F_rep − D·v: the APF force as an acceleration (the current goal target does
      not repel; every other body, captured targets included, does, with the chaser's radius and
      the margin added), damped so the chaser settles instead of orbiting. D is light along the
      motion and stiff along the normals of nearby bodies (see ``_damping``), so a stiff
      repulsion sampled every dt cannot set up a limit cycle;
    * a braking speed limit toward the goal, v ≤ √(2βa·ρ) (one step of lag included), so the
      chaser stops at the approach point well below the capture speed;
    * the same limit on the closing speed toward every nearby body and the world bounds, as
      constraints: braking now where a limit is already exceeded, and the APF term projected so
      that it cannot push a closing speed past its limit on the next step (a potential alone does
      not know the chaser's stopping distance);
    * the CWH acceleration [3n²x + 2nẏ, −2nẋ(, −n²z)] is cancelled, so the potential alone
      shapes the motion (the debris is frozen in LVLH).

    Braking and the CWH compensation take the thrust first; the APF term gets what is left of the
    thrust limit (:func:`prioritised_sum`). A local minimum stops the chaser for good: that is
    APF's known failure, which :class:`agents.apf_rrt.APFRRTAgent` repairs.

    Args:
        env: the DebrisGym env.
        params: potential parameters; default :meth:`APFParams.for_scenario` of each field.
        guidance: control gains; default :meth:`APFGuidance.for_scenario`.
        ordering: target order, "shortest", "polygon" or "nearest" (see :class:`MissionPlan`).
    """

    name = "apf"

    def __init__(
        self,
        env: Any,
        params: APFParams | None = None,
        guidance: APFGuidance | None = None,
        ordering: str = "shortest",
    ) -> None:
        super().__init__(env)
        self._fixed_params = params
        self._fixed_guidance = guidance
        self.ordering = ordering

    # --- episode set-up -------------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        cfg = self.env.config
        self.params = self._fixed_params or APFParams.for_scenario(scenario)
        self.guidance = self._fixed_guidance or APFGuidance.for_scenario(scenario)
        self.mission = MissionPlan(scenario, cfg, self.ordering)
        self.geometry = self.env.geometry
        self.inflate = cfg.chaser_radius
        self.goal_key: tuple | None = None
        self.virtual: list[VirtualPoint] = []

    # --- one step ------------------------------------------------------------------------------

    def current_goal(self, pos: np.ndarray) -> Goal | None:
        """The mission's current goal, or None when everything is done."""
        return self.mission.current_goal(self.env.captured, pos)

    def attractor(self, pos: np.ndarray, goal: Goal) -> np.ndarray:
        """The point the attractive field pulls toward (APF-RRT swaps in RRT waypoints)."""
        del pos
        return goal.point

    def act(self) -> np.ndarray:
        state = self.env.chaser_state
        d = self.env.dim
        pos, vel = state[:d], state[d:]
        goal = self.current_goal(pos)
        compensation = -cwh_accel(state, self.env.scenario.mean_motion)
        if goal is None:  # mission over: hold still
            accel = prioritised_sum(compensation, -vel / self.env.scenario.dt, self._limit())
            return self.accel_to_action(accel)
        key = (goal.kind, goal.index)
        if key != self.goal_key:
            self.goal_key = key
            self.on_new_goal(goal)
        ignore = () if goal.index is None else (goal.index,)
        aim = self.attractor(pos, goal)
        gaps, normals = self.geometry.gaps_and_normals(pos)
        active = _active_mask(self.geometry.n_bodies, ignore)
        f_att = attractive_force(pos, aim, self.params)
        f_rep = _repulsion(
            pos, gaps, normals, self.params, active, self.inflate, aim, self.active_virtual()
        )[1]
        f_rep *= self.repulsion_scale()
        self.observe_forces(pos, vel, goal, f_att, f_rep)
        nominal = f_att + f_rep + self._damping(pos, vel, aim, gaps, normals, active)
        nominal += self._goal_braking(pos, vel, aim)
        toward, allowed = self._closing_limits(pos, vel, gaps, normals, active)
        # brake now where the closing speed already exceeds the limit ...
        braking = np.minimum(allowed, 0.0) @ toward  # (negative) · toward: away
        # ... and keep the APF term from pushing any closing speed past its limit next step
        limit = self._limit()
        nominal *= min(1.0, limit / max(float(np.linalg.norm(nominal)), 1e-300))
        nominal = limit_closing(nominal, toward, np.maximum(allowed - toward @ braking, 0.0))
        safety = compensation + braking
        return self.accel_to_action(prioritised_sum(safety, nominal, limit))

    # --- hooks for APF-RRT ---------------------------------------------------------------------

    def on_new_goal(self, goal: Goal) -> None:
        """Called when the mission moves on to a new goal."""
        self.virtual = []

    def observe_forces(
        self, pos: np.ndarray, vel: np.ndarray, goal: Goal, f_att: np.ndarray, f_rep: np.ndarray
    ) -> None:
        """Called every step with the forces (APF-RRT watches for local minima here)."""

    def active_virtual(self) -> list[VirtualPoint]:
        """Virtual repulsive points in force now."""
        return self.virtual

    def repulsion_scale(self) -> float:
        """Scale of the repulsion now (APF-RRT weakens it on a collision-checked route)."""
        return 1.0

    # --- helpers -------------------------------------------------------------------------------

    def _limit(self) -> float:
        return self.env.scenario.max_accel

    def _decel(self) -> float:
        return self.guidance.brake_fraction * self.env.scenario.max_accel

    def _damping(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        aim: np.ndarray,
        gaps: np.ndarray,
        normals: np.ndarray,
        active: np.ndarray,
    ) -> np.ndarray:
        """Damping acceleration −D·v (m/s²).

        D = k_d·I, raised along the normal of every body whose repulsion has stiffness
        s = ∂F/∂d (1/s²) to max(2√s, 0.6·s·dt) — critical damping, and at least what keeps the
        sampled-data loop stable (a spring s under zero-order hold every dt needs damping
        c > s·dt/2) — and isotropically to 2√ζ inside d*. Eigenvalues are capped at 1.6/dt.
        Sliding along a surface stays lightly damped.
        """
        p = self.params
        dt = self.env.scenario.dt
        cap = 1.6 / dt
        base = self.guidance.damping
        if float(np.linalg.norm(aim - pos)) <= p.d_star:
            base = max(base, 2.0 * math.sqrt(p.k_att), 0.6 * p.k_att * dt)
        base = min(base, cap)
        d = gaps - self.inflate - p.margin
        near = np.flatnonzero(active & (d <= p.d0))
        if near.size == 0:
            return -base * vel
        dn = np.maximum(d[near], MIN_CLEARANCE_FRACTION * p.d0)
        stiffness = p.k_rep * (3.0 / dn**4 - 2.0 / (p.d0 * dn**3)).clip(0.0)
        wanted = np.maximum(2.0 * np.sqrt(stiffness), 0.6 * dt * stiffness)
        extra = (wanted - base).clip(0.0)
        if not extra.any():
            return -base * vel
        n = normals[near]
        matrix = base * np.eye(len(vel)) + (n.T * extra) @ n
        values, vectors = np.linalg.eigh(matrix)
        matrix = (vectors * np.minimum(values, cap)) @ vectors.T
        return -matrix @ vel

    def _goal_braking(self, pos: np.ndarray, vel: np.ndarray, aim: np.ndarray) -> np.ndarray:
        """Cuts the speed down to the braking limit for the distance left to the goal."""
        dt = self.env.scenario.dt
        speed = float(np.linalg.norm(vel))
        limit = braking_speed(float(np.linalg.norm(aim - pos)), self._decel(), dt)
        if speed <= limit or speed == 0.0:
            return np.zeros_like(vel)
        return -(speed - limit) / dt * vel / speed

    def _closing_limits(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        gaps: np.ndarray,
        normals: np.ndarray,
        active: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Closing-speed limits toward the bodies within d₀ and the world bounds.

        The closing speed toward a body after the next step must not exceed the speed from
        which the chaser can still stop (:func:`braking_speed`) before the body's margin. The
        goal target (not repelled) counts too: the chaser must stop a quarter of the capture
        depth short of its surface, inside the capture zone.

        Returns:
            (unit directions toward each body or bound (k, dim), the largest net acceleration
            along each (k,) (m/s²); negative means the chaser must brake now).
        """
        scen, dt = self.env.scenario, self.env.scenario.dt
        p = self.params
        decel = self._decel()
        buffer = np.where(active, p.margin, 0.25 * self.env.config.capture_radius)
        clear = gaps - self.inflate - buffer
        near = clear <= p.d0
        dirs = [-normals[near]]
        room = [clear[near]]
        low, high = scen.low + p.margin, scen.high - p.margin
        eye = np.eye(len(pos))
        for axis in range(len(pos)):
            for wall, sign in ((low[axis], -1.0), (high[axis], 1.0)):
                gap = sign * (wall - pos[axis])
                if gap <= p.d0:
                    dirs.append(sign * eye[axis][None])
                    room.append(np.array([gap]))
        toward = np.concatenate(dirs)
        lag = decel * dt
        limit = -lag + np.sqrt(lag * lag + 2.0 * decel * np.maximum(np.concatenate(room), 0.0))
        return toward, (limit - toward @ vel) / dt


def limit_closing(accel: np.ndarray, toward: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Remove from ``accel`` the part along each unit direction ``toward[i]`` beyond
    ``allowed[i]`` >= 0: a few rounds of projection onto the most violated half-space, then a
    uniform scale-down that makes every constraint hold (zero always does)."""
    out = np.array(accel, dtype=float)
    if toward.size == 0:
        return out
    for _ in range(8):
        excess = toward @ out - allowed
        worst = int(np.argmax(excess))
        if excess[worst] <= 1e-15:
            return out
        out -= excess[worst] * toward[worst]
    along = toward @ out
    over = along > allowed
    if over.any():
        out *= float(np.min(allowed[over] / along[over]))
    return out


__all__ = [
    "APFAgent",
    "APFGuidance",
    "APFParams",
    "apf_path",
    "attractive_force",
    "attractive_potential",
    "braking_speed",
    "cwh_accel",
    "is_local_minimum",
    "limit_closing",
    "prioritised_sum",
    "repulsive_force",
    "repulsive_potential",
    "total_force",
]
