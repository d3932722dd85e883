"""RRT, and the APF planner that escapes local minima with an RRT and virtual repulsive points
(the agent that does the same in flight is :class:`agents.policies.apf_rrt.APFRRTAgent`).

The escape follows [An23] §2.2 and §3 (keys refer to docs/references.md):

1. detect a local minimum — the forces balance, ‖F_att + F_rep‖ < 0.5‖F_att‖ (which implies the
   paper's |‖F_att‖ − ‖F_rep‖| / ‖F_att‖ < 0.5), and are nearly opposite,
   cos∠(F_att, F_rep) < −0.9 (eq. 14) — here also required: no progress toward the goal over a
   window (the chaser really is stuck, not passing by a saddle);
2. grow an RRT (§2.2 steps 1-4: random samples, nearest node, fixed-step extension, resample on
   collision, stop when the goal can be joined) from the stuck point to the goal;
3. add a virtual repulsive point to the repulsive field, at the stall point (the paper leaves its
   placement vague; at the minimum it turns the trap into a hill), follow the RRT path out of the
   trap, and continue with APF; the virtual points are cleared when the goal is reached.

The RRT path is left at its first waypoint that is both outside the virtual point's influence and
closer to the goal than the stall point (the "leave" rule of the Bug planners, [Lumelsky87]); if
no waypoint qualifies, the RRT path is followed to the goal. RRT collision checks are swept
(:meth:`FieldGeometry.touched`) on the field inflated by ``inflate`` + ``RRTParams.clearance``
(``APFParams.margin`` if no path keeps that clearance). The tree itself is [LaValle98]'s RRT.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.planners.apf import LEO_LENGTH, APFParams, Descent, VirtualPoint
from agents.planners.result import PlanResult
from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Scenario

# --- tunables (LEO defaults) ---------------------------------------------------------------------


@dataclass(frozen=True)
class RRTParams:
    """RRT escape parameters (SI units; defaults for the 1 km LEO field).

    Attributes:
        expand_dist: tree extension step (m).
        goal_sample_rate: share of samples drawn at the goal.
        max_iter: samples before the search gives up.
        shortcut_iters: random shortcut attempts on the found path.
        max_escapes: escapes allowed per goal before giving up.
        virtual_radius: influence radius (m) of a virtual repulsive point; capped at half the
            stall point's distance to the goal so the goal is never shielded.
        waypoint_tol: the agent has reached an RRT waypoint within this distance (m).
        clearance: margin (m) the RRT keeps from the bodies (on top of the chaser's radius), so
            the repulsion lets the chaser reach its waypoints; the APF ``margin`` if that fails.
        route_repulsion: scale of the bodies' repulsion while the agent follows an RRT route
            (the route is collision-checked and the closing-speed limits stay in force).
        local_pad: the first half of the samples come from the start-goal box grown by this
            (m) plus half the start-goal distance; the rest from the whole world.
    """

    expand_dist: float = 25.0
    goal_sample_rate: float = 0.2
    max_iter: int = 3000
    shortcut_iters: int = 60
    max_escapes: int = 10
    virtual_radius: float = 60.0
    waypoint_tol: float = 10.0
    clearance: float = 12.0
    local_pad: float = 150.0
    route_repulsion: float = 0.25

    def __post_init__(self) -> None:
        if not (self.clearance >= 0 and self.local_pad >= 0 and self.route_repulsion >= 0):
            raise ValueError("RRTParams.clearance, local_pad and route_repulsion must be >= 0")
        for name in ("expand_dist", "virtual_radius", "waypoint_tol"):
            if not getattr(self, name) > 0:
                raise ValueError(f"RRTParams.{name} must be > 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.goal_sample_rate <= 1.0:
            raise ValueError("RRTParams.goal_sample_rate must be in [0, 1]")
        if self.max_iter < 1 or self.shortcut_iters < 0 or self.max_escapes < 0:
            raise ValueError("RRTParams.max_iter must be >= 1, shortcut_iters/max_escapes >= 0")

    def scaled(self, length: float) -> RRTParams:
        """The same search for a world ``length`` times larger."""
        return RRTParams(
            expand_dist=self.expand_dist * length,
            goal_sample_rate=self.goal_sample_rate,
            max_iter=self.max_iter,
            shortcut_iters=self.shortcut_iters,
            max_escapes=self.max_escapes,
            virtual_radius=self.virtual_radius * length,
            waypoint_tol=self.waypoint_tol * length,
            clearance=self.clearance * length,
            local_pad=self.local_pad * length,
            route_repulsion=self.route_repulsion,
        )

    @classmethod
    def for_scenario(cls, scenario: Scenario, **overrides: Any) -> RRTParams:
        """Defaults scaled from the LEO field to ``scenario``'s size."""
        return cls(**overrides).scaled(scenario.size / LEO_LENGTH)


# --- collision checks -------------------------------------------------------------------------


class EdgeChecker:
    """Swept collision checks of straight segments against the inflated field.

    Bodies are inflated by ``inflate + margin``; the ``ignore``d bodies (the goal target, whose
    approach point lies inside its margin) only by ``inflate``, so a path may end next to them but
    never enters them.

    Args:
        scenario: the field.
        inflate: the chaser's radius (m).
        margin: safety margin (m) on top of ``inflate``.
        ignore: body indices checked without the margin.
    """

    def __init__(
        self, scenario: Scenario, inflate: float, margin: float, ignore: Iterable[int] = ()
    ) -> None:
        self.safe = FieldGeometry(scenario, inflate=inflate + margin)
        self.ignore = {int(i) for i in ignore}
        self.physical = FieldGeometry(scenario, inflate=inflate) if self.ignore else None
        self.low = scenario.low + inflate
        self.high = scenario.high - inflate

    def free(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the segment a → b touches no (inflated) body and stays inside the bounds."""
        if np.any(b <= self.low) or np.any(b >= self.high):
            return False
        path = np.stack([a, b])
        gaps = self.safe.point_gaps(a)  # un-inflated: shared by both geometries
        hits = set(self.safe.touched(path, gaps))
        if hits - self.ignore:
            return False
        if not hits or self.physical is None:  # (no ignored bodies: no physical geometry)
            return True
        return not self.ignore.intersection(self.physical.touched(path, gaps))

    def path_free(self, waypoints: np.ndarray) -> bool:
        """Whether every segment of the polyline is free."""
        return all(self.free(a, b) for a, b in zip(waypoints[:-1], waypoints[1:]))


# --- RRT --------------------------------------------------------------------------------------


def rrt_path(
    checker: EdgeChecker,
    start: np.ndarray,
    goal: np.ndarray,
    rng: np.random.Generator,
    params: RRTParams | None = None,
) -> PlanResult:
    """Grow an RRT from ``start`` until ``goal`` can be joined by a free segment ([An23] §2.2),
    then shorten the path (random shortcuts, then greedy line-of-sight pruning).

    Samples are drawn first from the box around start and goal grown by ``params.local_pad``
    (m); after half of ``params.max_iter`` from the whole world.

    Args:
        checker: collision checks (and the world bounds).
        start, goal: positions (m).
        rng: the random generator (the only source of randomness).
        params: search parameters.

    Returns:
        :class:`PlanResult` with waypoints start … goal on success; ``info["nodes"]`` = tree size.
    """
    params = RRTParams() if params is None else params
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    pad = params.local_pad + 0.5 * float(np.linalg.norm(goal - start))
    local_low = np.maximum(np.minimum(start, goal) - pad, checker.low)
    local_high = np.minimum(np.maximum(start, goal) + pad, checker.high)
    nodes = np.empty((params.max_iter + 2, len(start)))
    nodes[0] = start
    parents = [-1]
    count = 1
    found = -1
    if checker.free(start, goal):
        nodes[1] = goal
        parents.append(0)
        count, found = 2, 1
    for it in range(params.max_iter if found < 0 else 0):
        if rng.random() < params.goal_sample_rate:
            sample = goal
        elif it < params.max_iter // 2:
            sample = rng.uniform(local_low, local_high)
        else:
            sample = rng.uniform(checker.low, checker.high)
        offsets = sample - nodes[:count]
        dist = np.einsum("ij,ij->i", offsets, offsets)
        near = int(np.argmin(dist))
        length = math.sqrt(float(dist[near]))
        if length == 0.0:
            continue
        new = nodes[near] + offsets[near] * (min(params.expand_dist, length) / length)
        if not checker.free(nodes[near], new):
            continue  # step 3: resample on collision
        nodes[count] = new
        parents.append(near)
        count += 1
        if float(np.linalg.norm(goal - new)) <= params.expand_dist and checker.free(new, goal):
            nodes[count] = goal
            parents.append(count - 1)
            found = count
            count += 1
            break
    if found < 0:
        return PlanResult(False, start[None], 0.0, {"nodes": count})
    chain = []
    k = found
    while k >= 0:
        chain.append(nodes[k].copy())
        k = parents[k]
    waypoints = shortcut(np.asarray(chain[::-1]), checker, rng, params.shortcut_iters)
    return PlanResult(True, waypoints, PlanResult.path_length(waypoints), {"nodes": count})


def shortcut(
    waypoints: np.ndarray, checker: EdgeChecker, rng: np.random.Generator, iters: int
) -> np.ndarray:
    """Shorten a free polyline: ``iters`` random shortcuts (two random waypoints joined directly
    when the segment is free), then greedy pruning (from each kept waypoint, jump to the farthest
    one in free line of sight)."""
    path = list(waypoints)
    for _ in range(iters):
        if len(path) < 3:
            break
        i, j = sorted(rng.choice(len(path), size=2, replace=False).tolist())
        if j - i >= 2 and checker.free(path[i], path[j]):
            path = path[: i + 1] + path[j:]
    kept = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not checker.free(path[i], path[j]):
            j -= 1
        kept.append(path[j])
        i = j
    return np.asarray(kept)


def exit_index(
    waypoints: np.ndarray, stall: np.ndarray, goal: np.ndarray, radius: float, progress: float
) -> int:
    """Index of the first RRT waypoint from which APF takes over: outside the virtual point's
    influence ``radius`` and closer to the goal than the stall point by ``progress`` (m);
    the last index (the goal) if none is."""
    stall_gap = float(np.linalg.norm(goal - stall))
    for k in range(1, len(waypoints)):
        w = waypoints[k]
        if (
            float(np.linalg.norm(w - stall)) >= radius
            and float(np.linalg.norm(goal - w)) < stall_gap - progress
        ):
            return k
    return len(waypoints) - 1


def densify(waypoints: np.ndarray, spacing: float) -> np.ndarray:
    """Insert points so that no segment is longer than ``spacing`` (m); drops the first point."""
    out: list[np.ndarray] = []
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / spacing))
        out.extend(a + (b - a) * (k / n) for k in range(1, n + 1))
    return np.asarray(out).reshape(-1, waypoints.shape[1])


def virtual_point(stall: np.ndarray, goal: np.ndarray, rrt: RRTParams) -> VirtualPoint:
    """The virtual repulsive point at ``stall``, its radius capped at half the goal distance."""
    radius = min(rrt.virtual_radius, 0.5 * float(np.linalg.norm(goal - stall)))
    return np.array(stall, dtype=float), max(radius, 1e-9)


# --- the planner -------------------------------------------------------------------------------


def apf_rrt_path(
    scenario: Scenario,
    start: np.ndarray,
    goal: np.ndarray,
    params: APFParams | None = None,
    *,
    inflate: float = 0.0,
    geometry: FieldGeometry | None = None,
    ignore: Iterable[int] = (),
    rng: np.random.Generator | None = None,
    rrt: RRTParams | None = None,
) -> PlanResult:
    """APF descent that escapes local minima with an RRT and virtual repulsive points.

    Arguments as :func:`agents.planners.apf.apf_path`, plus:

    Args:
        rng: random generator for the RRT (default: ``numpy.random.default_rng(0)``).
        rrt: RRT parameters; default :meth:`RRTParams.for_scenario`.

    Returns:
        :class:`PlanResult`; ``info``: ``escapes`` (RRT escapes used), ``virtual_points`` (their
        positions, m), ``stall_points``, ``rrt_nodes`` (total tree size), ``steps``,
        ``stalled``/``stall_reason`` (why it finally failed, if it did), ``min_clearance``.
    """
    ignore = tuple(int(i) for i in ignore)
    descent, points = Descent.from_start(
        scenario, start, goal, params, inflate=inflate, geometry=geometry, ignore=ignore
    )
    params, geometry, goal = descent.params, descent.geometry, descent.goal
    rrt = RRTParams.for_scenario(scenario) if rrt is None else rrt
    rng = np.random.default_rng(0) if rng is None else rng
    checkers: dict[tuple, EdgeChecker] = {}
    info: dict[str, Any] = {"escapes": 0, "stall_points": [], "rrt_nodes": 0}
    status = "max_steps"
    while len(points) - 1 < params.max_steps:
        budget = params.max_steps - (len(points) - 1)
        status, stall, _ = descent.run(points, budget)
        if status == "arrived" or stall is None or info["escapes"] >= rrt.max_escapes:
            break
        escape = escape_route(
            geometry, points[-1], goal, inflate, ignore, params, rrt, rng, checkers
        )
        info["rrt_nodes"] += escape.info["nodes"]
        if not escape.success:
            status = "rrt_failed"
            break
        info["escapes"] += 1
        info["stall_points"].append(stall)
        vp = virtual_point(stall, goal, rrt)
        descent.virtual.append(vp)
        k = exit_index(escape.waypoints, stall, goal, vp[1], params.progress_tol)
        points.extend(densify(escape.waypoints[: k + 1], _route_spacing(params)))
        if k == len(escape.waypoints) - 1:
            status = "arrived"
            break
    waypoints = np.asarray(points)
    success = status == "arrived"
    info.update(
        steps=len(points) - 1,
        stalled=not success and status != "max_steps",
        stall_reason=None if success else status,
        virtual_points=[vp[0] for vp in descent.virtual],
        min_clearance=float((geometry.signed_distance(waypoints) - inflate).min(initial=math.inf)),
    )
    return PlanResult(success, waypoints, PlanResult.path_length(waypoints), info)


def _route_spacing(params: APFParams) -> float:
    """Spacing (m) of followed RRT waypoints: the APF step (100 ε for the [APF-MPC] rule)."""
    return params.step_size if params.normalized_step else 100.0 * params.step_size


def escape_route(
    geometry: FieldGeometry,
    start: np.ndarray,
    goal: np.ndarray,
    inflate: float,
    ignore: tuple[int, ...],
    params: APFParams,
    rrt: RRTParams,
    rng: np.random.Generator,
    checkers: dict[tuple, EdgeChecker],
) -> PlanResult:
    """RRT from ``start`` to ``goal`` keeping ``rrt.clearance`` from the bodies, or, if that
    fails, ``params.margin``; a margin is shrunk to half the start's clearance when the start
    already sits inside it. ``checkers`` caches the collision checkers per (ignore, margin)."""
    gaps = np.delete(geometry.point_gaps(start), list(ignore)) - inflate
    start_clear = float(gaps.min()) if gaps.size else math.inf
    nodes = 0
    found = PlanResult(False, np.asarray(start, float)[None], 0.0)
    for wanted in dict.fromkeys((max(rrt.clearance, params.margin), params.margin)):
        margin = round(min(wanted, max(0.5 * start_clear, 0.0)), 9)
        key = (ignore, margin)
        if key not in checkers:
            checkers[key] = EdgeChecker(geometry.scenario, inflate, margin, ignore)
        found = rrt_path(checkers[key], start, goal, rng, rrt)
        nodes += found.info["nodes"]
        if found.success:
            break
    return PlanResult(found.success, found.waypoints, found.cost, {"nodes": nodes})


__all__ = [
    "EdgeChecker",
    "RRTParams",
    "apf_rrt_path",
    "densify",
    "escape_route",
    "exit_index",
    "rrt_path",
    "shortcut",
    "virtual_point",
]
