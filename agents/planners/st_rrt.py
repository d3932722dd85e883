"""Tube-ST-RRT*: space-time RRT*-Connect among moving bodies, with a collision-free tube.

References (keys refer to docs/references.md): [Zhou24] Algorithm 1 (Tube-ST-RRT*) and
Algorithm 2 (conditional sampling), which build on ST-RRT* [Grothe22].

The planner searches position × time, in a planning frame (:class:`SpaceTimeField`: LVLH, or the
goal target's frame, where the goal is a fixed point), for the earliest arrival at the goal:

* **states** are (position, time) pairs; an edge is a straight space-time segment that goes
  forward in time at a speed at most ``max_speed`` (the velocity cone);
* **conditional sampling** (Alg. 2): a position is drawn uniformly in a box around start and
  goal, then a time between the earliest it can be reached from the start and the latest from
  which a sampled goal can still be reached, both at ``max_speed``;
* **progressive goal region**: goal states are the goal point at sampled arrival times; the time
  range they are drawn from starts at ``initial_range`` × the least arrival time and grows by
  ``range_factor`` whenever a batch of ``batch_size`` samples has been added without a
  solution; while the newest slice of time is filled, a sample falls in the older region with
  the probability of that region's share of the range (so the density evens out);
* **nearest / steer / rewire** in space-time: the distance sqrt(‖Δp‖² + (v_max·Δt)²), finite
  only along the velocity cone (forward in time for the start tree, backward for the goal tree);
  steering stops at ``steer_range`` along that line (keeping its speed). A node's cost is its
  arrival time, which its own time fixes, so rewiring minimises the secondary cost, the path
  length (a fuel proxy), among ``rewire_neighbours`` near nodes;
* **bidirectional connection** (RRT*-Connect): the start tree and a goal tree whose roots are the
  goal states swap roles every iteration; a new node tries to reach the other tree with steps of
  ``steer_range``; a connection is a solution whose cost is the goal state's time. After one,
  the time range is capped at that time, samples come from the known region only and nodes that
  cannot beat it are pruned;
* **tube**: every node carries the radius of the largest ball about it, at its own time, that no
  (grown) body enters (FindMaxRadius; :meth:`SpaceTimeField.clearance`). A node's ball is only
  used at the node's own time — the smoothing (:mod:`agents.planners.tube`) cuts the path at its
  sample times so every sample gets a node of its own, at its own time — so no ball has to hold
  over a time span. Edges are checked exactly against the moving bodies
  (:meth:`SpaceTimeField.edge_clear`).

The planner is a pure function of its inputs and the generator it is handed: the same seed gives
the same path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.planners.spacetime import SpaceTimeField

__all__ = ["STRRTParams", "STRRTResult", "st_rrt_star"]


@dataclass(frozen=True)
class STRRTParams:
    """Tunables of :func:`st_rrt_star` (SI units).

    Attributes:
        max_speed: v_max, the largest speed (m/s) of an edge in the planning frame.
        steer_range: d, the longest step (space-time metric, m) of an extension.
        goal_probability: p_goal, the chance per iteration of sampling a new goal state.
        batch_size: samples added before the goal time range grows (first batch).
        range_factor: growth factor of the time range (over the least arrival time).
        initial_range: first time range, as a multiple of the least arrival time ‖g − s‖/v_max.
        max_iterations: iteration budget (the termination condition ptc).
        improve_iterations: iterations kept on after the first solution to improve it.
        rewire_neighbours: near nodes considered for parent choice and rewiring.
        connect_steps: extension steps a connection attempt may take.
        horizon: latest arrival considered (s after the start).
        sample_padding: margin (m) of the sampling box around start and goal.
        bounds_margin: distance (m) every node keeps from the world bounds (LVLH).
    """

    max_speed: float = 1.0
    steer_range: float = 200.0
    goal_probability: float = 0.1
    batch_size: int = 60
    range_factor: float = 1.5
    initial_range: float = 1.6
    max_iterations: int = 600
    improve_iterations: int = 60
    rewire_neighbours: int = 8
    connect_steps: int = 8
    horizon: float = 4000.0
    sample_padding: float = 200.0
    bounds_margin: float = 10.0

    def __post_init__(self) -> None:
        positive = ("max_speed", "steer_range", "horizon", "range_factor", "initial_range")
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if not 0.0 < self.goal_probability <= 1.0:
            raise ValueError(f"goal_probability must be in (0, 1], got {self.goal_probability!r}")
        if self.range_factor <= 1.0:
            raise ValueError(f"range_factor must be > 1, got {self.range_factor!r}")
        if self.initial_range < 1.0:
            raise ValueError(f"initial_range must be >= 1, got {self.initial_range!r}")
        counts = (
            ("batch_size", 1),
            ("max_iterations", 1),
            ("improve_iterations", 0),
            ("rewire_neighbours", 1),
            ("connect_steps", 1),
        )
        for name, least in counts:
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= least):
                raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
        for name in ("sample_padding", "bounds_margin"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0 m, got {value!r}")


@dataclass(frozen=True)
class STRRTResult:
    """The outcome of :func:`st_rrt_star`.

    Attributes:
        success: whether ``positions`` reaches the goal.
        times: (K,) node times (s), strictly increasing, start first.
        positions: (K, dim) node positions (m, planning frame); the last is the goal on success.
        radii: (K,) each node's ball radius (m): its clearance at its own time.
        arrival: the goal's arrival time (s), inf without a solution.
        info: iterations, nodes, goal states, time range, first-solution iteration.
    """

    success: bool
    times: np.ndarray
    positions: np.ndarray
    radii: np.ndarray
    arrival: float
    info: dict[str, Any] = field(default_factory=dict)


class _Tree:
    """One search tree: nodes in arrays, parent links and path-length costs.

    ``sign`` is +1 for the start tree (edges run forward in time, parent → child) and −1 for the
    goal tree (its roots are goal states; edges run backward in time from parent to child).
    """

    def __init__(self, dim: int, sign: int, capacity: int = 512) -> None:
        self.sign = sign
        self.pos = np.empty((capacity, dim))
        self.time = np.empty(capacity)
        self.cost = np.empty(capacity)
        self.radius = np.empty(capacity)
        self.parent = np.empty(capacity, dtype=np.int64)
        self.alive = np.zeros(capacity, dtype=bool)
        self.children: list[list[int]] = []
        self.size = 0

    def add(self, pos: np.ndarray, t: float, radius: float, parent: int, cost: float) -> int:
        if self.size == len(self.time):
            grow = len(self.time)
            self.pos = np.concatenate([self.pos, np.empty_like(self.pos[:grow])])
            for name in ("time", "cost", "radius", "parent", "alive"):
                arr = getattr(self, name)
                setattr(self, name, np.concatenate([arr, np.zeros_like(arr[:grow])]))
        i = self.size
        self.pos[i], self.time[i], self.radius[i] = pos, t, radius
        self.parent[i], self.cost[i], self.alive[i] = parent, cost, True
        self.children.append([])
        if parent >= 0:
            self.children[parent].append(i)
        self.size += 1
        return i

    def metric(self, pos: np.ndarray, t: float, speed: float) -> np.ndarray:
        """Space-time distance from every node to (pos, t); inf outside the velocity cone."""
        n = self.size
        dp = np.linalg.norm(self.pos[:n] - pos, axis=1)
        dt = (t - self.time[:n]) * self.sign  # > 0: (pos, t) lies on the tree's side in time
        ok = self.alive[:n] & (dt > 0) & (dp <= speed * dt * (1 + 1e-9))
        return np.where(ok, np.sqrt(dp * dp + (speed * dt) ** 2), np.inf)

    def reparent(self, i: int, parent: int, cost: float) -> None:
        old = int(self.parent[i])
        if old >= 0:
            self.children[old].remove(i)
        self.children[parent].append(i)
        self.parent[i] = parent
        delta = cost - self.cost[i]
        stack = [i]
        while stack:  # the subtree's path lengths all change by the same amount
            j = stack.pop()
            self.cost[j] += delta
            stack.extend(self.children[j])

    def path(self, i: int) -> list[int]:
        """Node indices from ``i`` to its root."""
        out = [i]
        while self.parent[out[-1]] >= 0:
            out.append(int(self.parent[out[-1]]))
        return out


class _Search:
    """State of one Tube-ST-RRT* search (Algorithm 1's bookkeeping B and both trees)."""

    def __init__(
        self,
        field: SpaceTimeField,
        start: np.ndarray,
        goal: np.ndarray,
        params: STRRTParams,
        rng: np.random.Generator,
    ) -> None:
        self.f, self.p, self.rng = field, params, rng
        self.start, self.goal = start, goal
        self.t0 = field.t0
        self.v = params.max_speed
        self.t_least = self.t0 + float(np.linalg.norm(goal - start)) / self.v
        self.t_cap = min(self.t0 + params.horizon, field.t_end)
        span = max(self.t_least - self.t0, field.h)
        self.range_lo = self.t0  # the newest slice of goal times is [range_lo, range_hi]
        self.range_hi = min(self.t0 + params.initial_range * span, self.t_cap)
        self.batch_size = params.batch_size
        self.in_batch = 0
        self.batch_probability = 1.0
        self.goals_old: list[float] = []  # goal times sampled before the last expansion
        self.goals_new: list[float] = []
        self.best = math.inf
        self.best_pair: tuple[int, int] | None = None
        self.first_solution: int | None = None
        pad = params.sample_padding
        self.box_lo = np.minimum(start, goal) - pad
        self.box_hi = np.maximum(start, goal) + pad
        d = field.dim
        self.trees = (_Tree(d, +1), _Tree(d, -1))
        r0 = float(field.clearance(start[None], np.array([self.t0]))[0])
        self.trees[0].add(start, self.t0, r0, -1, 0.0)

    # --- Algorithm 1's parts ------------------------------------------------------------------

    def update_goal_region(self) -> None:
        """Grow the time range once a batch is full and no solution is known."""
        if self.in_batch < self.batch_size or self.best < math.inf:
            return
        if self.range_hi >= self.t_cap:
            return
        old_span = self.range_hi - self.t0
        new_hi = min(self.t0 + (self.range_hi - self.t0) * self.p.range_factor, self.t_cap)
        self.range_lo, self.range_hi = self.range_hi, new_hi
        self.goals_old.extend(self.goals_new)
        self.goals_new = []
        self.batch_probability = old_span / (new_hi - self.t0)
        self.batch_size = max(1, math.ceil(self.batch_size * self.p.range_factor))
        self.in_batch = 0

    def sample_goal(self) -> None:
        """A goal state: the goal point at a time drawn from the newest slice of the range.

        An attempt that finds none (the slice is empty or the goal is blocked then) counts
        toward the batch, so a range without a usable goal state grows.
        """
        lo = max(self.range_lo, self.t_least)
        hi = min(self.range_hi, self.best)
        if hi <= lo:
            self.in_batch += 1
            return
        t = float(self.rng.uniform(lo, hi))
        r = float(self.f.clearance(self.goal[None], np.array([t]))[0])
        if r < 0:
            self.in_batch += 1
            return
        self.trees[1].add(self.goal, t, r, -1, 0.0)
        (self.goals_new if self.range_lo > self.t0 else self.goals_old).append(t)

    def _max_valid_time(self, q: np.ndarray, goals: list[float]) -> float:
        """Latest time from which one of ``goals`` is reachable from ``q`` at v_max."""
        if not goals:
            return -math.inf
        return max(goals) - float(np.linalg.norm(self.goal - q)) / self.v

    def sample_conditionally(self) -> tuple[np.ndarray, float] | None:
        """Algorithm 2: a position, then a time inside both velocity cones."""
        for _ in range(20):
            q = self.rng.uniform(self.box_lo, self.box_hi)
            t_min = self.t0 + float(np.linalg.norm(q - self.start)) / self.v
            if self.rng.random() <= self.batch_probability:
                t_lb, t_ub = t_min, self._max_valid_time(q, self.goals_old + self.goals_new)
            else:
                t_lb = max(t_min, self._max_valid_time(q, self.goals_old))
                t_ub = self._max_valid_time(q, self.goals_new)
            t_ub = min(t_ub, self.best)
            if t_ub > t_lb:
                return q, float(self.rng.uniform(t_lb, t_ub))
        return None

    def _steer(
        self, tree: _Tree, i: int, q: np.ndarray, t: float, dist: float
    ) -> tuple[np.ndarray, float]:
        """Move from node ``i`` toward (q, t) by at most the steer range (same speed)."""
        if dist <= self.p.steer_range:
            return q, t
        frac = self.p.steer_range / dist
        return tree.pos[i] + frac * (q - tree.pos[i]), float(
            tree.time[i] + frac * (t - tree.time[i])
        )

    def _valid_node(self, q: np.ndarray, t: float) -> float | None:
        """The node's ball radius, or None when (q, t) is not a usable state."""
        if t > self.t_cap:
            return None
        r, inside = self.f.node(q, t, self.p.bounds_margin)
        return r if inside and r >= 0 else None

    def _edge(self, tree: _Tree, i: int, q: np.ndarray, t: float) -> bool:
        return self.f.edge_clear(tree.pos[i], float(tree.time[i]), q, t)

    def extend(self, tree: _Tree, q: np.ndarray, t: float) -> int | None:
        """Nearest, steer, motion check, choose parent and rewire (RRT*); the new node or None."""
        dist = tree.metric(q, t, self.v)
        i = int(np.argmin(dist)) if dist.size else -1
        if i < 0 or not math.isfinite(dist[i]):
            return None
        q_new, t_new = self._steer(tree, i, q, t, float(dist[i]))
        r_new = self._valid_node(q_new, t_new)
        if r_new is None:
            return None
        near_d = tree.metric(q_new, t_new, self.v)
        order = [
            int(j)
            for j in np.argsort(near_d)[: self.p.rewire_neighbours]
            if math.isfinite(near_d[j])
        ]
        if i not in order:
            order.append(i)
        lengths = np.linalg.norm(tree.pos[order] - q_new, axis=1)
        ranked = sorted(zip(tree.cost[order] + lengths, order, strict=True))
        parent, cost = -1, math.inf
        for c, j in ranked:  # cheapest parent whose edge is clear
            if self._edge(tree, j, q_new, t_new):
                parent, cost = j, float(c)
                break
        if parent < 0:
            return None
        new = tree.add(q_new, t_new, r_new, parent, cost)
        self._rewire(tree, new)
        self.in_batch += 1
        return new

    def _rewire(self, tree: _Tree, new: int) -> None:
        """Hang near later nodes (earlier, in the goal tree) from ``new`` when that is shorter."""
        n, sign = tree.size, tree.sign
        q, t = tree.pos[new], tree.time[new]
        dt = (tree.time[:n] - t) * sign
        dp = np.linalg.norm(tree.pos[:n] - q, axis=1)
        ok = tree.alive[:n] & (dt > 0) & (dp <= self.v * dt)
        ok &= tree.cost[new] + dp < tree.cost[:n] - 1e-9
        cand = np.flatnonzero(ok)
        if cand.size == 0:
            return
        metric = np.sqrt(dp[cand] ** 2 + (self.v * dt[cand]) ** 2)
        for j in cand[np.argsort(metric)][: self.p.rewire_neighbours]:
            if tree.parent[j] < 0:
                continue  # a goal tree's root stays a root
            if self.f.edge_clear(q, float(t), tree.pos[j], float(tree.time[j])):
                tree.reparent(int(j), new, float(tree.cost[new] + dp[j]))

    def connect(self, other: _Tree, q: np.ndarray, t: float) -> int | None:
        """Extend ``other`` toward (q, t) until it reaches it (the node) or is trapped."""
        for _ in range(self.p.connect_steps):
            new = self.extend(other, q, t)
            if new is None:
                return None
            if other.time[new] == t and np.array_equal(other.pos[new], q):
                return new
        return None

    def record(self, a_tree: int, a_node: int, b_node: int) -> None:
        """A connection: keep it when its goal state is earlier (or as early and shorter)."""
        start_node, goal_node = (a_node, b_node) if a_tree == 0 else (b_node, a_node)
        root = self.trees[1].path(goal_node)[-1]
        arrival = float(self.trees[1].time[root])
        shorter = self.best_pair is not None and self._length(start_node, goal_node) < self._length(
            *self.best_pair
        )
        if arrival < self.best or (arrival == self.best and shorter):
            self.best = arrival
            self.best_pair = (start_node, goal_node)
            self.batch_probability = 1.0
            self.prune()

    def _length(self, start_node: int, goal_node: int) -> float:
        return float(self.trees[0].cost[start_node] + self.trees[1].cost[goal_node])

    def prune(self) -> None:
        """Drop nodes that cannot be on a path arriving before the best one."""
        s, g = self.trees
        n = s.size
        late = s.time[:n] + np.linalg.norm(s.pos[:n] - self.goal, axis=1) / self.v > self.best
        s.alive[:n] &= ~late
        s.alive[0] = True
        g.alive[: g.size] &= g.time[: g.size] <= self.best
        self.goals_old = [t for t in self.goals_old if t <= self.best]
        self.goals_new = [t for t in self.goals_new if t <= self.best]

    def solution(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, g = self.trees
        if self.best_pair is None:
            raise RuntimeError("no solution found yet")
        a, b = self.best_pair
        first = s.path(a)[::-1]
        second = g.path(b)[1:]  # b is the same state as a
        times = np.concatenate([s.time[first], g.time[second]])
        pos = np.vstack([s.pos[first], g.pos[second]])
        radii = np.concatenate([s.radius[first], g.radius[second]])
        return times, pos, radii


def st_rrt_star(
    field: SpaceTimeField,
    start: np.ndarray,
    goal: np.ndarray,
    params: STRRTParams | None = None,
    rng: np.random.Generator | None = None,
) -> STRRTResult:
    """Tube-ST-RRT* ([Zhou24] Alg. 1) from ``start`` at ``field.t0`` to ``goal``, earliest arrival.

    Args:
        field: the moving bodies in the planning frame over the planning window.
        start: (dim,) start position (m, planning frame) at time ``field.t0``.
        goal: (dim,) goal point (m, planning frame); any arrival time is a goal state.
        params: tunables.
        rng: the random generator (its state advances); None: ``default_rng(0)``.

    Returns:
        An :class:`STRRTResult`; on failure the start node alone and ``success=False``.
    """
    params = params or STRRTParams()
    rng = rng if rng is not None else np.random.default_rng(0)
    start = np.asarray(start, float).reshape(field.dim)
    goal = np.asarray(goal, float).reshape(field.dim)
    search = _Search(field, start, goal, params, rng)
    s_tree, g_tree = search.trees
    a = 0  # which tree extends this iteration (Swap(T_a, T_b))
    iteration = 0
    for iteration in range(1, params.max_iterations + 1):
        if search.first_solution is not None:
            if iteration - search.first_solution > params.improve_iterations:
                break
        search.update_goal_region()
        if g_tree.size == 0 or params.goal_probability > rng.random():
            search.sample_goal()
        sample = search.sample_conditionally()
        if sample is not None and g_tree.size:
            q, t = sample
            tree, other = search.trees[a], search.trees[1 - a]
            new = search.extend(tree, q, t)
            if new is not None:
                hit = search.connect(other, tree.pos[new].copy(), float(tree.time[new]))
                if hit is not None:
                    search.record(a, new, hit)
                    if search.first_solution is None:
                        search.first_solution = iteration
        a = 1 - a
    info = {
        "iterations": iteration,
        "nodes": s_tree.size + g_tree.size,
        "goal_states": int(np.sum(g_tree.parent[: g_tree.size] < 0)),
        "time_range": search.range_hi - field.t0,
        "first_solution": search.first_solution,
    }
    if search.best_pair is None:
        return STRRTResult(
            False, np.array([field.t0]), start[None].copy(), s_tree.radius[:1].copy(), math.inf,
            info,
        )  # fmt: skip
    times, pos, radii = search.solution()
    return STRRTResult(True, times, pos, radii, float(times[-1]), info)
