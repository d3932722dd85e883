"""Spherical expansion: a graph of body-free spheres and the shortest chain of them to a goal.

Reference: [Bandyopadhyay17] Alg. 1, "Spherical Expansion step" (single-agent form; keys refer to
docs/references.md). Every node is a point X with the radius r of the largest sphere around it
that touches no body (``MinDistObs``): the library's clearance
(:meth:`debris_gym.geometry.FieldGeometry.signed_distance`) minus the chaser's radius and its
safety margin, and never past the world's bounds. The graph grows like an RRT whose step adapts
to the free space: a sample X_rand is drawn in the bounds, the nearest node found, and the new
node is X_rand itself if it lies inside that node's sphere, otherwise the point of the sphere's
surface nearest X_rand (``Steer``). Two nodes are joined when their spheres overlap, so the
straight segment between the centres stays in the union of the two spheres; the cost of an edge
is the distance between the centres, stretched where a sphere is small (:func:`edge_cost`). The
shortest chain start → goal (Dijkstra, :func:`scipy.sparse.csgraph.dijkstra`) is the corridor
the sequential convex programme (:mod:`agents.planners.scp`) keeps its trajectory in.

An edge needs a little more than touching spheres: ``d ≤ κ (r_v + r_w) − min_overlap``, with κ
the inner-radius factor of the polytope the SCP puts inside each sphere (1 for exact spheres), so
that the two polytopes share a point and the SCP can cross from one sphere into the next.

Everything here is a pure function of the field; randomness comes from the generator passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from debris_gym.geometry import FieldGeometry

__all__ = [
    "ExpansionParams",
    "SphereChain",
    "SphereGraph",
    "chain_waypoints",
    "edge_cost",
    "expand_spheres",
    "joinable",
    "node_radii",
    "shortest_chain",
    "thin_chain",
]


@dataclass(frozen=True)
class ExpansionParams:
    """Tunables of :func:`expand_spheres`.

    Attributes:
        max_nodes: largest number of nodes (start and goal included) before giving up.
        extra_nodes: nodes added after start and goal first connect, so the shortest chain can
            improve ([Bandyopadhyay17]: optimal as the samples tend to infinity).
        goal_bias: probability (0 … 1) that a sample is the goal itself.
        min_radius: smallest sphere radius (m) a new node may have; smaller ones are dropped.
        min_overlap: how far (m) two spheres must overlap beyond the polytope factor to be joined.
        polytope_factor: κ in (0, 1], the inner-radius factor of the polytope inside each
            sphere that the trajectory optimiser uses (1: exact spheres).
        narrow_cost: ρ (m) of the edge cost d·(1 + ρ / min(r_v, r_w)) (:func:`edge_cost`);
            0: plain centre distance.
    """

    max_nodes: int = 400
    extra_nodes: int = 60
    goal_bias: float = 0.1
    min_radius: float = 1.0
    min_overlap: float = 0.5
    polytope_factor: float = 1.0
    narrow_cost: float = 2.0

    def __post_init__(self) -> None:
        if not (isinstance(self.max_nodes, int) and self.max_nodes >= 2):
            raise ValueError(f"max_nodes must be an integer >= 2, got {self.max_nodes!r}")
        if not (isinstance(self.extra_nodes, int) and self.extra_nodes >= 0):
            raise ValueError(f"extra_nodes must be an integer >= 0, got {self.extra_nodes!r}")
        if not (math.isfinite(self.goal_bias) and 0.0 <= self.goal_bias <= 1.0):
            raise ValueError(f"goal_bias must be in [0, 1], got {self.goal_bias!r}")
        if not (math.isfinite(self.min_radius) and self.min_radius > 0.0):
            raise ValueError(f"min_radius must be > 0 m, got {self.min_radius!r}")
        if not (math.isfinite(self.min_overlap) and self.min_overlap >= 0.0):
            raise ValueError(f"min_overlap must be >= 0 m, got {self.min_overlap!r}")
        if not (math.isfinite(self.polytope_factor) and 0.0 < self.polytope_factor <= 1.0):
            raise ValueError(f"polytope_factor must be in (0, 1], got {self.polytope_factor!r}")
        if not (math.isfinite(self.narrow_cost) and self.narrow_cost >= 0.0):
            raise ValueError(f"narrow_cost must be >= 0 m, got {self.narrow_cost!r}")


@dataclass(frozen=True)
class SphereGraph:
    """The spherical-expansion graph.

    Attributes:
        centers: (K, dim) node positions (m); node 0 is the start, node 1 the goal.
        radii: (K,) radius (m) of each node's body-free sphere (clearance minus margins).
        adjacency: (K, K) sparse matrix; entry (v, w) > 0 is the cost (m, centre distance) of
            the edge v → w (symmetric).
        connected: whether start and goal are joined by a chain of edges.
        samples: samples drawn.
    """

    centers: np.ndarray
    radii: np.ndarray
    adjacency: csr_matrix
    connected: bool
    samples: int

    @property
    def n_nodes(self) -> int:
        """Number of nodes K."""
        return len(self.radii)


@dataclass(frozen=True)
class SphereChain:
    """The shortest chain of overlapping spheres from start to goal.

    Attributes:
        success: whether a chain exists.
        nodes: node indices in the graph, start first and goal last (empty on failure).
        centers: (m, dim) sphere centres (m) in chain order.
        radii: (m,) sphere radii (m).
        cost: chain cost (m): the sum of its edge costs.
        info: diagnostics (nodes, samples).
    """

    success: bool
    nodes: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    cost: float
    info: dict = field(default_factory=dict)


def node_radii(
    geometry: FieldGeometry,
    points: np.ndarray,
    margins: np.ndarray,
    low: np.ndarray | None = None,
    high: np.ndarray | None = None,
) -> np.ndarray:
    """``MinDistObs``: radius (m) of the largest body-free sphere around each point.

    The radius is the smallest over the bodies of (signed distance to the body − that body's
    margin), and over the axes of the distance to each wall of the bounds; negative when the
    point is inside a body's margin.

    Args:
        geometry: the field's geometry (bodies where they are for this plan).
        points: (M, dim) or (dim,) positions (m).
        margins: (n_bodies,) distance (m) each body's surface must be kept from the sphere
            (the chaser's radius plus its safety margin).
        low, high: (dim,) world bounds (m); None: unbounded.
    """
    pts = np.asarray(points, dtype=float)
    single = pts.ndim == 1
    pts = pts.reshape(-1, geometry.dim)
    radius = np.full(len(pts), np.inf)
    if geometry.n_bodies:
        gaps = geometry.signed_distance(pts) - np.asarray(margins, dtype=float)[None]
        radius = gaps.min(axis=1)
    if low is not None and high is not None:
        walls = np.minimum(pts - np.asarray(low)[None], np.asarray(high)[None] - pts).min(axis=1)
        radius = np.minimum(radius, walls)
    return radius[0] if single else radius


class _UnionFind:
    """Connected components of the growing graph (path halving, union by size)."""

    def __init__(self) -> None:
        self.parent: list[int] = []
        self.size: list[int] = []

    def add(self) -> None:
        self.parent.append(len(self.parent))
        self.size.append(1)

    def find(self, a: int) -> int:
        parent = self.parent
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return
        if self.size[ra] < self.size[rb]:
            ra, rb = rb, ra
        self.parent[rb] = ra
        self.size[ra] += self.size[rb]


def joinable(
    dist: np.ndarray, r_a: np.ndarray | float, r_b: np.ndarray | float, params: ExpansionParams
) -> np.ndarray:
    """Whether two spheres of radii ``r_a`` and ``r_b`` (m) whose centres are ``dist`` (m)
    apart overlap enough to be joined by an edge: ``d ≤ κ (r_a + r_b) − min_overlap``."""
    return dist <= params.polytope_factor * (r_a + r_b) - params.min_overlap


def joined(
    centers: np.ndarray, radii: np.ndarray, i: int, others: np.ndarray, params: ExpansionParams
) -> np.ndarray:
    """Mask over ``others`` of the nodes whose spheres overlap node ``i``'s enough to join."""
    dist = np.linalg.norm(centers[others] - centers[i], axis=1)
    return joinable(dist, radii[others], radii[i], params)


def expand_spheres(
    geometry: FieldGeometry,
    start: np.ndarray,
    goal: np.ndarray,
    margins: np.ndarray,
    rng: np.random.Generator,
    params: ExpansionParams | None = None,
    *,
    low: np.ndarray,
    high: np.ndarray,
    start_radius: float | None = None,
    goal_radius: float | None = None,
) -> SphereGraph:
    """Grow the spherical-expansion graph from ``start`` until it reaches ``goal``.

    Args:
        geometry: the field's geometry (a frozen field, or a snapshot of a moving one).
        start, goal: (dim,) positions (m).
        margins: (n_bodies,) keep-out distance (m) per body surface (see :func:`node_radii`).
        rng: the generator every sample is drawn from.
        params: tunables.
        low, high: (dim,) bounds the samples are drawn in and the spheres stay inside (m).
        start_radius, goal_radius: radius (m) to give the start / goal sphere instead of
            :func:`node_radii` (e.g. when the chaser already sits inside a margin); clipped at 0.

    Returns:
        The graph; :attr:`SphereGraph.connected` says whether start and goal are joined.
    """
    params = params or ExpansionParams()
    d = geometry.dim
    start = np.asarray(start, dtype=float).reshape(d)
    goal = np.asarray(goal, dtype=float).reshape(d)
    low = np.asarray(low, dtype=float)
    high = np.asarray(high, dtype=float)
    margins = np.asarray(margins, dtype=float)
    if margins.shape != (geometry.n_bodies,):
        raise ValueError(f"margins must have one entry per body ({geometry.n_bodies})")
    centers = np.empty((params.max_nodes, d))
    radii = np.empty(params.max_nodes)
    centers[:2] = start, goal
    radii[:2] = node_radii(geometry, centers[:2], margins, low, high)
    if start_radius is not None:
        radii[0] = start_radius
    if goal_radius is not None:
        radii[1] = goal_radius
    radii[:2] = np.maximum(radii[:2], 0.0)
    rows: list[int] = []
    cols: list[int] = []
    components = _UnionFind()
    components.add()
    components.add()
    if joined(centers, radii, 1, np.array([0]), params)[0]:
        rows.append(0)
        cols.append(1)
        components.union(0, 1)
    count, samples, extra = 2, 0, -1
    budget = 20 * params.max_nodes  # samples that land inside a margin are redrawn
    while count < params.max_nodes and samples < budget and extra != 0:
        samples += 1
        if rng.random() < params.goal_bias:
            sample = goal
        else:
            sample = low + rng.random(d) * (high - low)
        offsets = centers[:count] - sample
        dist2 = np.einsum("ij,ij->i", offsets, offsets)
        dist2[1] = np.inf  # the goal is reached, not grown from
        near = int(np.argmin(dist2))
        gap = math.sqrt(float(dist2[near]))
        if gap <= radii[near]:
            new = sample.copy()
        else:  # the point of the nearest sphere's surface closest to the sample
            new = centers[near] + (sample - centers[near]) * (radii[near] / gap)
        if np.min(np.linalg.norm(centers[:count] - new, axis=1)) < 1e-6:
            # the sample is a node already (the goal, drawn again while its small sphere is not
            # yet joined): place the new node half-way to it, which closes the gap step by step
            new = 0.5 * (centers[near] + sample)
            if np.min(np.linalg.norm(centers[:count] - new, axis=1)) < 1e-6:
                continue
        radius = float(node_radii(geometry, new, margins, low, high))
        if radius < params.min_radius:
            continue
        centers[count], radii[count] = new, radius
        components.add()
        mask = joined(centers, radii, count, np.arange(count), params)
        for other in np.flatnonzero(mask):
            rows.append(int(other))
            cols.append(count)
            components.union(int(other), count)
        count += 1
        if extra > 0:
            extra -= 1
        elif extra < 0 and components.find(0) == components.find(1):
            extra = params.extra_nodes
    centers, radii = centers[:count].copy(), radii[:count].copy()
    r = np.array(rows + cols, dtype=np.int64)
    c = np.array(cols + rows, dtype=np.int64)
    cost = edge_cost(centers[r], radii[r], centers[c], radii[c], params.narrow_cost)
    # a zero-length edge would vanish from the sparse matrix: keep it as a tiny cost
    adjacency = csr_matrix((np.maximum(cost, 1e-9), (r, c)), shape=(count, count))
    return SphereGraph(
        centers=centers,
        radii=radii,
        adjacency=adjacency,
        connected=components.find(0) == components.find(1),
        samples=samples,
    )


def edge_cost(
    c1: np.ndarray, r1: np.ndarray, c2: np.ndarray, r2: np.ndarray, narrow: float
) -> np.ndarray:
    """``EdgeCost``: centre distance (m) stretched by ``1 + narrow / min(r1, r2)``, so a chain
    squeezes through small spheres only when it saves length (a narrow corridor leaves the
    trajectory little room and needs many points)."""
    dist = np.linalg.norm(np.asarray(c1) - np.asarray(c2), axis=-1)
    return dist * (1.0 + narrow / np.maximum(np.minimum(r1, r2), 1e-9))


def shortest_chain(graph: SphereGraph, source: int = 0, target: int = 1) -> SphereChain:
    """``MinPath``: the least-cost chain of spheres from node ``source`` to node ``target``
    (Dijkstra on the edge costs)."""
    # scipy-stubs type indices as an array, but an int is allowed (1-D results)
    dist, pred = dijkstra(  # type: ignore[call-overload]
        graph.adjacency, indices=source, return_predecessors=True
    )
    info = {"nodes": graph.n_nodes, "samples": graph.samples}
    d = graph.centers.shape[1]
    if not np.isfinite(dist[target]):
        empty = np.zeros((0, d))
        return SphereChain(False, np.zeros(0, dtype=np.int64), empty, np.zeros(0), math.inf, info)
    nodes = [target]
    while nodes[-1] != source:
        nodes.append(int(pred[nodes[-1]]))
    order = np.array(nodes[::-1], dtype=np.int64)
    return SphereChain(
        success=True,
        nodes=order,
        centers=graph.centers[order].copy(),
        radii=graph.radii[order].copy(),
        cost=float(dist[target]),
        info=info,
    )


def thin_chain(chain: SphereChain, params: ExpansionParams) -> SphereChain:
    """The chain with the spheres it can skip left out: from each kept sphere, the farthest
    later one it could be joined to by an edge (:func:`joinable`) comes next.

    Every kept sphere is one of the chain's and every kept pair overlaps as a graph edge needs,
    so the corridor stays inside the original one. A time allocation gives the trajectory at
    least one step per sphere; a chain that converges on its goal in many tiny steps (an
    expansion grown toward a goal a few metres away) would otherwise stretch a short hop over
    many steps, whose slow reference the tracker cannot tell from station keeping.

    Returns:
        the thinned chain, its cost the sum of its edge costs (:func:`edge_cost`); a failed
        chain or one of two spheres or fewer unchanged.
    """
    c, r = chain.centers, chain.radii
    if not chain.success or len(r) <= 2:
        return chain
    keep, i, last = [0], 0, len(r) - 1
    while i < last:
        later = np.arange(i + 1, last + 1)
        ok = joinable(np.linalg.norm(c[later] - c[i], axis=1), r[later], r[i], params)
        # the next sphere stays a candidate: the chain joined it to this one already
        i = int(later[ok][-1]) if ok.any() else i + 1
        keep.append(i)
    index = np.asarray(keep, dtype=np.int64)
    cost = edge_cost(c[index[:-1]], r[index[:-1]], c[index[1:]], r[index[1:]], params.narrow_cost)
    return SphereChain(
        True, chain.nodes[index], c[index].copy(), r[index].copy(), float(cost.sum()), chain.info
    )


def lens_point(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float) -> np.ndarray:
    """A point (m) in both spheres: the middle of their overlap on the line of centres."""
    offset = c2 - c1
    dist = float(np.linalg.norm(offset))
    if dist < 1e-12:
        return c1.copy()
    lo = max(dist - r2, 0.0)
    hi = min(r1, dist)
    return c1 + offset * (0.5 * (lo + hi) / dist)


def chain_waypoints(chain: SphereChain, factor: float = 1.0) -> np.ndarray:
    """The polyline start → lens points → goal through a chain (m), one segment per sphere.

    Consecutive waypoints lie in a common sphere (shrunk by ``factor``), so every segment does.
    """
    c, r = chain.centers, chain.radii * factor
    points = [c[0]]
    for j in range(len(r) - 1):
        points.append(lens_point(c[j], r[j], c[j + 1], r[j + 1]))
    points.append(c[-1])
    return np.array(points)
