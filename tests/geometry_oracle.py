"""Independent geometry of a debris field: the oracle the library's geometry is tested against.

Nothing here shares code with :mod:`debris_gym`: 2D fields are built in a :class:`pymunk.Space`
(circles and convex polygons as static shapes) and asked pymunk's own point, segment and ray
queries; 3D fields are spheres, answered with closed forms in plain numpy. One body at a time,
one point at a time: slow and plain on purpose.

Same conventions as :class:`debris_gym.geometry.FieldGeometry`: bodies are indexed targets first,
then obstacles; a distance is signed (m, negative inside); swept checks inflate every body by
``inflate`` (m) and count a path that starts in a body as touching it.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from debris_gym.scenario import Scenario


class OracleField:
    """One :class:`Scenario` (bodies at their t = 0 positions), queried through pymunk / numpy.

    Args:
        scenario: the field.
        inflate: distance (m) added to every body by :meth:`touched` and :meth:`first_hit`.
    """

    def __init__(self, scenario: Scenario, inflate: float = 0.0) -> None:
        self.scenario = scenario
        self.dim = scenario.dim
        self.inflate = float(inflate)
        self.centers = np.array([b.position for b in scenario.bodies], dtype=float)
        self.radii = np.array([b.radius for b in scenario.bodies], dtype=float)
        self.space = pymunk.Space() if self.dim == 2 else None
        self.shapes: list[pymunk.Shape] = []
        if self.space is not None:
            for i, body in enumerate(scenario.bodies):
                x, y = body.position
                if body.is_polygon:
                    corners = [(vx + x, vy + y) for vx, vy in body.vertices]
                    shape = pymunk.Poly(self.space.static_body, corners)
                else:
                    shape = pymunk.Circle(self.space.static_body, body.radius, (x, y))
                shape.body_index = i
                self.shapes.append(shape)
            self.space.add(*self.shapes)

    # --- points -------------------------------------------------------------------------------

    def nearest(self, point) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distances (B,), unit gradients (B, dim) and nearest surface points (B, dim)."""
        p = np.asarray(point, dtype=float)
        if self.dim == 2:
            infos = [s.point_query((float(p[0]), float(p[1]))) for s in self.shapes]
            return (
                np.array([q.distance for q in infos]),
                np.array([tuple(q.gradient) for q in infos]).reshape(-1, 2),
                np.array([tuple(q.point) for q in infos]).reshape(-1, 2),
            )
        rel = p - self.centers
        length = np.sqrt((rel**2).sum(axis=1))
        unit = rel / length[:, None]
        return length - self.radii, unit, self.centers + self.radii[:, None] * unit

    def signed_distance(self, points) -> np.ndarray:
        """Signed distance (m) from each point (M, dim) to each body, shape (M, B)."""
        pts = np.asarray(points, dtype=float).reshape(-1, self.dim)
        return np.array([self.nearest(p)[0] for p in pts]).reshape(len(pts), len(self.radii))

    def point_gaps(self, point) -> np.ndarray:
        """Signed distance (m) from one point to every body, shape (B,)."""
        return self.nearest(point)[0]

    # --- swept checks -------------------------------------------------------------------------

    def segment_contacts(self, a, b) -> dict[int, float]:
        """Bodies the segment a→b touches (inflated) → fraction along it where contact begins."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if self.dim == 2:
            hits = {}
            for i, shape in enumerate(self.shapes):
                info = shape.segment_query(tuple(a), tuple(b), self.inflate)
                if info is not None:
                    hits[i] = info.alpha
            return hits
        hits = {}
        d = b - a
        for i, (c, r) in enumerate(zip(self.centers, self.radii)):
            t = _sphere_contact(a - c, d, r + self.inflate)
            if t is not None:
                hits[i] = t
        return hits

    def touched(self, path, start_gaps=None) -> list[int]:
        """Indices (ascending) of every body the polyline ``path`` (K+1, dim) touches.

        ``start_gaps`` is accepted for the library's signature and not used.
        """
        found: set[int] = set()
        for a, b in zip(path[:-1], path[1:]):
            found.update(self.segment_contacts(a, b))
        return sorted(found)

    def first_hit(self, path) -> int:
        """Index of the body the polyline ``path`` touches first, or -1."""
        for a, b in zip(path[:-1], path[1:]):
            hits = self.segment_contacts(a, b)
            if hits:
                return min(hits, key=lambda i: (hits[i], i))
        return -1

    # --- lidar --------------------------------------------------------------------------------

    def lidar(self, origin, directions, max_range: float) -> np.ndarray:
        """Range (m) along each unit direction to the first surface, capped at ``max_range``."""
        o = np.asarray(origin, dtype=float)
        out = np.full(len(directions), float(max_range))
        for k, d in enumerate(np.asarray(directions, dtype=float)):
            if self.dim == 2:
                end = tuple(o + d * max_range)
                info = self.space.segment_query_first(tuple(o), end, 0.0, pymunk.ShapeFilter())
                if info is not None:
                    out[k] = info.alpha * max_range
                continue
            for c, r in zip(self.centers, self.radii):
                t = _sphere_contact(o - c, d * max_range, r)
                if t is not None:
                    out[k] = min(out[k], t * max_range)
        return out


def _sphere_contact(rel: np.ndarray, d: np.ndarray, radius: float) -> float | None:
    """Smallest t ∈ [0, 1] with |rel + t·d| ≤ radius (``rel`` = start − centre), or None."""
    if rel @ rel <= radius * radius:
        return 0.0
    a, b, c = d @ d, 2.0 * (rel @ d), rel @ rel - radius * radius
    disc = b * b - 4.0 * a * c
    if a == 0.0 or disc < 0.0:
        return None
    t = (-b - math.sqrt(disc)) / (2.0 * a)
    return t if 0.0 <= t <= 1.0 else None
