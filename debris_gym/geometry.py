"""Geometry queries on one debris field: clearance, nearest points, swept contacts, lidar.

One meaning of *clearance* everywhere: the signed distance (m) from a point to a body's surface,
negative inside. Bodies are indexed targets first, then obstacles (as :attr:`Scenario.bodies`);
2D bodies are circles or convex polygons, 3D bodies spheres.

:class:`FieldGeometry` is a view of one field through the compiled geometry the envs step with:
a :class:`~debris_gym.batch_geometry.FieldBatch` holding that single field answers clearance and
lidar (the same loops, so a planner and the env agree on every gap to the last bit), and
:mod:`debris_gym.geometry_kernels` adds what only planners ask: nearest surface points with
their normals, and where along a path each body is first touched. There is no second
implementation in the library; the tests hold this one to an independent oracle (pymunk in 2D,
closed forms for spheres: ``tests/geometry_oracle.py``).

Queries take many points per call where they can (``signed_distance``, ``nearest_points``):
each call into compiled code has a fixed cost, which a planner asking thousands of times per
decision pays once per batch instead of once per point.
"""

from __future__ import annotations

import math

import numpy as np

from debris_gym.batch_geometry import FieldBatch
from debris_gym.geometry_kernels import first_contacts, nearest_points
from debris_gym.scenario import Scenario


def geometry_now(
    previous: FieldGeometry | None, scenario: Scenario, time: float, inflate: float
) -> FieldGeometry:
    """The :class:`FieldGeometry` of ``scenario`` at ``time`` (s; 0 for a frozen field)
    inflated by ``inflate`` (m): ``previous`` when it is that one already, else a new one (the
    cache of the envs' and views' ``geometry``)."""
    t = time if scenario.moving else 0.0
    if (
        previous is not None
        and previous.time == t
        and previous.scenario is scenario
        and previous.inflate == inflate
    ):
        return previous
    return FieldGeometry(scenario, inflate=inflate, time=t)


class FieldGeometry:
    """Geometry of one :class:`Scenario` with its bodies where they are at ``time``.

    Args:
        scenario: the field.
        inflate: distance (m) added to every body (e.g. the chaser's radius) by the swept checks
            :meth:`first_hit` and :meth:`touched`; distances are never inflated.
        time: the instant (s since the episode began) whose body positions and polygon
            attitudes the queries see (:meth:`Scenario.body_states`); a frozen field is the
            same at every time. The queries treat the bodies as standing still there.

    Attributes:
        centers: (B, dim) body centres (m).
        radii: (B,) body radii (m; a polygon's circumradius).
        is_polygon: (B,) True for 2D convex polygons.
        batch: the one-field :class:`~debris_gym.batch_geometry.FieldBatch` behind the queries.
    """

    def __init__(self, scenario: Scenario, inflate: float = 0.0, time: float = 0.0) -> None:
        if not (math.isfinite(inflate) and inflate >= 0):
            raise ValueError(f"inflate must be >= 0 m, got {inflate!r}")
        if not (math.isfinite(time) and time >= 0):
            raise ValueError(f"time must be finite and >= 0 s, got {time!r}")
        self.time = float(time)
        self.scenario = scenario
        self.dim = scenario.dim
        self.inflate = float(inflate)
        bodies = scenario.bodies
        self.n_bodies = len(bodies)
        most = max((len(b.vertices) for b in bodies if b.vertices is not None), default=3)
        self.batch = FieldBatch(1, self.n_bodies, self.dim, max_vertices=most)
        self.batch.load(0, scenario, self.time if scenario.moving else 0.0)
        self.centers = self.batch.centers[0]
        self.radii = self.batch.radii[0]
        self.is_polygon = self.batch.is_polygon[0]
        self._field = (
            self.centers,
            self.radii,
            self.batch.polygon_start,
            self.batch.n_vertices[0],
            self.batch.vertices[0],
        )
        self._zeros = np.zeros(1, dtype=np.int64)

    def _rows(self, count: int) -> np.ndarray:
        """``count`` references to the batch's only row (a reused array)."""
        if self._zeros.size < count:
            self._zeros = np.zeros(max(count, 2 * self._zeros.size), dtype=np.int64)
        return self._zeros[:count]

    # --- clearance ----------------------------------------------------------------------------

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (m) from each point to each body surface, negative inside.

        Args:
            points: (M, dim) or (dim,) positions (m).

        Returns:
            (M, n_bodies) array, or (n_bodies,) for a single point. Not inflated.
        """
        pts = np.asarray(points, dtype=float)
        single = pts.ndim == 1
        pts = pts.reshape(-1, self.dim)
        out = self.batch.gaps(pts, self._rows(pts.shape[0]))
        return out[0] if single else out

    def point_gaps(self, point: np.ndarray) -> np.ndarray:
        """Signed distance (m) from one point (dim,) to every body, shape (n_bodies,)."""
        return self.batch.gaps(np.reshape(point, (1, self.dim)), self._rows(1))[0]

    def clearance(self, point: np.ndarray) -> float:
        """Smallest signed distance (m) from ``point`` to any body surface (+inf if none)."""
        if self.n_bodies == 0:
            return math.inf
        return float(self.point_gaps(point).min())

    def nearest_points(
        self, points: np.ndarray, first: int = 0, last: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest surface point of each body to each point, with the distance's gradient.

        Args:
            points: (M, dim) positions (m).
            first, last: answer for bodies ``first … last − 1`` (default: all).

        Returns:
            ``(gaps (M, K), normals (M, K, dim), surface (M, K, dim))`` for K = last − first:
            signed distances (m), unit gradients of the distances (pointing away from the
            body: the direction that increases clearance fastest), nearest surface points (m).
        """
        last = self.n_bodies if last is None else last
        if not 0 <= first <= last <= self.n_bodies:
            raise ValueError(f"bodies [{first}, {last}) must lie in [0, {self.n_bodies}]")
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, self.dim)
        k = last - first
        gaps = np.empty((pts.shape[0], k))
        normals = np.empty((pts.shape[0], k, self.dim))
        surface = np.empty((pts.shape[0], k, self.dim))
        nearest_points(pts, first, last, *self._field, gaps, normals, surface)
        return gaps, normals, surface

    def gaps_and_normals(self, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (m) from one point to every body and the unit gradient of each.

        The gradient points away from the body (the direction that increases clearance
        fastest): what a repulsive potential needs.

        Returns:
            ``(gaps (n_bodies,), normals (n_bodies, dim))``.
        """
        gaps, normals, _ = self.nearest_points(np.reshape(point, (1, self.dim)))
        return gaps[0], normals[0]

    # --- swept checks -------------------------------------------------------------------------

    def _touched_mask(self, path: np.ndarray, start_gaps: np.ndarray | None) -> np.ndarray:
        """(B,) True for the bodies the polyline ``path`` touches (the batch's contact test)."""
        path = np.ascontiguousarray(path, dtype=float)
        if start_gaps is None:
            start_gaps = self.point_gaps(path[0])
        return self.batch.touched(
            path.reshape(1, -1, self.dim), np.reshape(start_gaps, (1, -1)), self.inflate
        )[0]

    def first_hit(self, path: np.ndarray, start_gaps: np.ndarray | None = None) -> int:
        """Index of the first body the polyline ``path`` touches (inflated), or -1.

        The path (K+1, dim) is swept segment by segment, so a step that crosses a body between
        its end points is caught; a body the path starts in is touched at once. Of several
        bodies touched, the one met earliest along the path.

        Args:
            path: (K+1, dim) positions (m).
            start_gaps: :meth:`point_gaps` of ``path[0]`` if already known (saves a query);
                +inf for a body leaves it out of the check.
        """
        if self.n_bodies == 0:
            return -1
        if start_gaps is None:
            start_gaps = self.point_gaps(np.asarray(path, dtype=float)[0])
        hit = np.flatnonzero(self._touched_mask(path, start_gaps))
        if hit.size <= 1:
            return int(hit[0]) if hit.size else -1
        segment = np.empty(self.n_bodies, dtype=np.int64)
        alpha = np.empty(self.n_bodies)
        first_contacts(
            np.ascontiguousarray(path, dtype=float),
            np.ascontiguousarray(start_gaps, dtype=float),
            self.inflate,
            *self._field,
            segment,
            alpha,
        )
        # a body the contact test touched but the ranking missed (a graze at rounding level)
        # ranks last
        segment = np.where(segment[hit] >= 0, segment[hit], np.iinfo(np.int64).max)
        return int(hit[np.lexsort((alpha[hit], segment))[0]])

    def touched(self, path: np.ndarray, start_gaps: np.ndarray | None = None) -> list[int]:
        """Indices (ascending) of every body the polyline ``path`` touches (inflated).

        Same sweep as :meth:`first_hit`, but it keeps going after the first contact, so a path
        that brushes one body and then enters another reports both.
        """
        if self.n_bodies == 0:
            return []
        return [int(i) for i in np.flatnonzero(self._touched_mask(path, start_gaps))]

    # --- lidar --------------------------------------------------------------------------------

    def lidar(self, origin: np.ndarray, directions: np.ndarray, max_range: float) -> np.ndarray:
        """Distance (m) along each unit direction to the first surface, capped at ``max_range``.

        Args:
            origin: (dim,) sensor position (m).
            directions: (R, dim) unit vectors.
            max_range: sensor range (m).
        """
        return self.batch.lidar(np.reshape(origin, (1, self.dim)), directions, max_range)[0]


def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance over the last axis of two broadcastable arrays (m).

    One array operation per axis instead of a reduction over a short last axis (which numpy does
    slowly): ``sqrt((a₀ − b₀)² + (a₁ − b₁)² [+ (a₂ − b₂)²])``, summed in that order.
    """
    sq: np.ndarray | None = None
    for axis in range(a.shape[-1]):
        delta = a[..., axis] - b[..., axis]
        delta *= delta
        sq = delta if sq is None else np.add(sq, delta, out=sq)
    if sq is None:
        raise ValueError(f"distance needs points with at least one axis, got shape {a.shape}")
    return np.sqrt(sq, out=sq)


def lidar_directions(dim: int, n_rays: int) -> np.ndarray:
    """Evenly spread unit ray directions: a circle fan in 2D, a Fibonacci sphere in 3D."""
    if n_rays < 1:
        raise ValueError(f"n_rays must be >= 1, got {n_rays!r}")
    if dim == 2:
        ang = 2.0 * np.pi * np.arange(n_rays) / n_rays
        return np.stack([np.cos(ang), np.sin(ang)], axis=1)
    k = np.arange(n_rays) + 0.5
    z = 1.0 - 2.0 * k / n_rays
    phi = np.pi * (1.0 + 5**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
