"""Geometry queries on a debris field: clearance, swept collision checks, lidar.

One meaning of *clearance* everywhere: the signed distance (m) from a point to a body's surface,
negative inside. Bodies are indexed targets first, then obstacles (as :attr:`Scenario.bodies`).

2D fields live in a :class:`pymunk.Space` (circles and convex polygons as static shapes); its
segment queries do the narrow phase of swept collision checks and the lidar. Batched numpy
formulas give the signed distances used on every step (one vectorised call for all bodies instead
of one pymunk call per body); ``tests/test_geometry.py`` holds the two to the same answers. 3D
fields are spheres, handled in numpy.
"""

from __future__ import annotations

import math

import numpy as np

from debris_gym.scenario import Scenario


class FieldGeometry:
    """Pre-computed geometry of one :class:`Scenario` (frozen bodies).

    Args:
        scenario: the field.
        inflate: distance (m) added to every body (e.g. the chaser's radius) for collision checks.
    """

    def __init__(self, scenario: Scenario, inflate: float = 0.0) -> None:
        if not (math.isfinite(inflate) and inflate >= 0):
            raise ValueError(f"inflate must be >= 0 m, got {inflate!r}")
        self.scenario = scenario
        self.dim = scenario.dim
        self.inflate = float(inflate)
        bodies = scenario.bodies
        self.n_bodies = len(bodies)
        self.centers = np.array(scenario.body_positions(0.0), dtype=float).reshape(-1, self.dim)
        self.radii = np.array([b.radius for b in bodies], dtype=float)
        self.is_polygon = np.array([b.is_polygon for b in bodies], dtype=bool)
        self.circle_idx = np.flatnonzero(~self.is_polygon)
        self.polygon_idx = np.flatnonzero(self.is_polygon)
        self._build_polygons([bodies[i] for i in self.polygon_idx])
        self._circle_axes = [self.centers[self.circle_idx, k].copy() for k in range(self.dim)]
        self._circle_radii = self.radii[self.circle_idx].copy()
        self._space = None
        self._shapes: list = []

    # --- construction -------------------------------------------------------------------------

    def _build_polygons(self, polys: list) -> None:
        """Pad polygons to a common vertex count and pre-compute edges and outward normals."""
        n_poly = len(polys)
        vmax = max((len(b.vertices) for b in polys), default=3)
        verts = np.zeros((n_poly, vmax, 2))
        normals = np.zeros((n_poly, vmax, 2))
        nxt = np.zeros((n_poly, vmax, 2))
        for k, body in enumerate(polys):
            v = np.asarray(body.vertices, dtype=float) + np.asarray(body.position)
            m = len(v)
            following = np.roll(v, -1, axis=0)
            edges = following - v
            nrm = np.stack([edges[:, 1], -edges[:, 0]], axis=1)  # outward for CCW order
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            verts[k, :m], nxt[k, :m], normals[k, :m] = v, following, nrm
            # Padding: zero-length edges at the first vertex with the first edge's normal. They
            # change neither the inside test nor the smallest edge distance.
            verts[k, m:], nxt[k, m:], normals[k, m:] = v[0], v[0], nrm[0]
        self.poly_verts = verts
        self.poly_next = nxt
        self.poly_edges = self.poly_next - verts
        self.poly_edge_len2 = np.maximum(
            np.einsum("pvi,pvi->pv", self.poly_edges, self.poly_edges), 1e-300
        )
        self.poly_normals = normals
        self.poly_offsets = np.einsum("pvi,pvi->pv", normals, verts)
        # Flat per-edge arrays (no padding) for the single-point fast path.
        counts = [len(b.vertices) for b in polys]
        keep = (
            np.concatenate([np.arange(c) + k * vmax for k, c in enumerate(counts)]).astype(int)
            if polys
            else np.zeros(0, dtype=int)
        )
        # (the same arrays and formulas as debris_gym.batch_geometry.FieldBatch)
        self._edge_start = verts.reshape(-1, 2)[keep].T.copy()  # (2, E)
        self._edge_vec = self.poly_edges.reshape(-1, 2)[keep].T.copy()
        ex, ey = self._edge_vec
        self._edge_inv_len2 = 1.0 / (ex * ex + ey * ey)
        self._edge_inv_len = np.sqrt(self._edge_inv_len2)
        self._edge_first = np.cumsum([0, *counts[:-1]]).astype(np.intp)

    @property
    def space(self):
        """The pymunk space holding the 2D bodies (built on first use)."""
        if self.dim != 2:
            raise ValueError("a pymunk space exists only for 2D fields")
        if self._space is None:
            import pymunk

            space = pymunk.Space()
            shapes = []
            for i, body in enumerate(self.scenario.bodies):
                if body.is_polygon:
                    pts = [
                        (p[0] + body.position[0], p[1] + body.position[1]) for p in body.vertices
                    ]
                    shape = pymunk.Poly(space.static_body, pts)
                else:
                    shape = pymunk.Circle(space.static_body, body.radius, tuple(body.position))
                shape.body_index = i
                shapes.append(shape)
            space.add(*shapes)
            self._space = space
            self._shapes = shapes
        return self._space

    @property
    def shapes(self) -> list:
        """pymunk shapes in body order (2D only)."""
        _ = self.space
        return self._shapes

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
        out = np.empty((pts.shape[0], self.n_bodies))
        if self.circle_idx.size:
            diff = pts[:, None, :] - self.centers[None, self.circle_idx, :]
            out[:, self.circle_idx] = (
                np.sqrt(np.einsum("mbi,mbi->mb", diff, diff)) - self.radii[self.circle_idx]
            )
        if self.polygon_idx.size:
            out[:, self.polygon_idx] = self._polygon_signed_distance(pts)
        return out[0] if single else out

    def point_gaps(self, point: np.ndarray) -> np.ndarray:
        """Signed distance (m) from one point (dim,) to every body: the per-step fast path.

        Same answer as :meth:`signed_distance` for a single point, with fewer numpy calls.
        """
        out = np.empty(self.n_bodies)
        ci = self.circle_idx
        if ci.size:
            sq = None
            for axis in range(self.dim):
                diff = self._circle_axes[axis] - point[axis]
                sq = diff * diff if sq is None else sq + diff * diff
            out[ci] = np.sqrt(sq) - self._circle_radii
        if self.polygon_idx.size:
            dx = point[0] - self._edge_start[0]
            dy = point[1] - self._edge_start[1]
            ex, ey = self._edge_vec
            t = dx * ex
            t += dy * ey
            t *= self._edge_inv_len2
            np.clip(t, 0.0, 1.0, out=t)
            cx = dx - t * ex
            cy = dy - t * ey
            edge = np.sqrt(np.minimum.reduceat(cx * cx + cy * cy, self._edge_first))
            # depth behind each edge line: (d × e) / |e| = d · outward unit normal
            plane = dx * ey
            plane -= dy * ex
            plane *= self._edge_inv_len
            depth = np.maximum.reduceat(plane, self._edge_first)
            # outside (depth > 0): distance to the nearest edge; inside: minus the depth
            out[self.polygon_idx] = (
                edge if (depth > 0.0).all() else np.where(depth > 0.0, edge, depth)
            )
        return out

    def gaps_and_normals(self, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (m) to every body and the unit gradient of each distance.

        The gradient points away from the body (the direction that increases clearance fastest):
        what a repulsive potential needs. 2D uses pymunk's nearest-point queries; 3D, spheres in
        numpy.

        Returns:
            ``(gaps (n_bodies,), normals (n_bodies, dim))``.
        """
        point = np.asarray(point, dtype=float)
        if self.dim == 2:
            gaps = np.empty(self.n_bodies)
            normals = np.empty((self.n_bodies, 2))
            p = (float(point[0]), float(point[1]))
            for i, shape in enumerate(self.shapes):
                info = shape.point_query(p)
                gaps[i] = info.distance
                normals[i] = info.gradient
            return gaps, normals
        diff = point - self.centers
        dist = np.linalg.norm(diff, axis=1)
        normals = diff / np.maximum(dist, 1e-12)[:, None]
        return dist - self.radii, normals

    def _polygon_signed_distance(self, pts: np.ndarray) -> np.ndarray:
        """Exact signed distance of points (M, 2) to the convex polygons, shape (M, P)."""
        rel = pts[:, None, None, :] - self.poly_verts[None]  # (M, P, V, 2)
        t = np.einsum("mpvi,pvi->mpv", rel, self.poly_edges) / self.poly_edge_len2
        np.clip(t, 0.0, 1.0, out=t)
        closest = rel - t[..., None] * self.poly_edges[None]
        edge_dist = np.sqrt(np.einsum("mpvi,mpvi->mpv", closest, closest)).min(axis=2)
        plane = np.einsum("mi,pvi->mpv", pts, self.poly_normals) - self.poly_offsets[None]
        depth = plane.max(axis=2)
        return np.where(depth > 0.0, edge_dist, depth)

    def clearance(self, point: np.ndarray) -> float:
        """Smallest signed distance (m) from ``point`` to any body surface (+inf if none)."""
        if self.n_bodies == 0:
            return math.inf
        return float(self.signed_distance(point).min())

    # --- swept collision ----------------------------------------------------------------------

    def _candidates(self, path: np.ndarray, start_gaps: np.ndarray | None) -> np.ndarray:
        """Broad phase: bodies the polyline could touch.

        The whole path lies in the ball around ``path[0]`` of radius R = max_k |path[k] − path[0]|,
        so only bodies whose gap at ``path[0]`` is at most R + inflate can be touched.
        """
        if start_gaps is None:
            start_gaps = self.point_gaps(path[0])
        rel = path[1:] - path[0]
        reach = math.sqrt(float((rel * rel).sum(axis=1).max())) + self.inflate
        return np.flatnonzero(start_gaps <= reach)

    def first_hit(self, path: np.ndarray, start_gaps: np.ndarray | None = None) -> int:
        """Index of the first body the polyline ``path`` touches (inflated), or -1.

        The path (K+1, dim) is swept segment by segment, so a step that crosses a body between
        its end points is caught. Narrow phase: pymunk segment queries (2D) or the exact
        segment-sphere distance (3D).

        Args:
            path: (K+1, dim) positions (m) along the step.
            start_gaps: :meth:`point_gaps` of ``path[0]`` if already known (saves a query).
        """
        if self.n_bodies == 0:
            return -1
        near = self._candidates(path, start_gaps)
        if near.size == 0:
            return -1
        for k in range(path.shape[0] - 1):
            hits = self._segment_hits(path[k], path[k + 1], near)
            if hits:
                return min(hits, key=lambda item: item[1])[0]
        return -1

    def touched(self, path: np.ndarray, start_gaps: np.ndarray | None = None) -> list[int]:
        """Indices (ascending) of every body the polyline ``path`` touches (inflated).

        Same sweep as :meth:`first_hit`, but it keeps going after the first contact, so a path
        that brushes one body and then enters another reports both.
        """
        if self.n_bodies == 0:
            return []
        near = self._candidates(path, start_gaps)
        found: set[int] = set()
        for k in range(path.shape[0] - 1):
            if near.size == 0:
                break
            found.update(i for i, _ in self._segment_hits(path[k], path[k + 1], near))
        return sorted(found)

    def _segment_hits(self, a: np.ndarray, b: np.ndarray, candidates: np.ndarray) -> list:
        """(body index, alpha along the segment) for every candidate the segment a→b touches."""
        hits = []
        if self.dim == 2:
            shapes = self.shapes
            pa, pb = (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))
            for i in candidates:
                info = shapes[i].segment_query(pa, pb, self.inflate)
                if info is not None:
                    hits.append((int(i), info.alpha))
            return hits
        d = b - a
        seg_len2 = float(d @ d)
        for i in candidates:
            rel = self.centers[i] - a
            t = 0.0 if seg_len2 == 0.0 else min(1.0, max(0.0, float(rel @ d) / seg_len2))
            gap = rel - t * d
            if math.sqrt(float(gap @ gap)) <= self.radii[i] + self.inflate:
                hits.append((int(i), t))
        return hits

    # --- lidar --------------------------------------------------------------------------------

    def lidar(self, origin: np.ndarray, directions: np.ndarray, max_range: float) -> np.ndarray:
        """Distance (m) along each unit direction to the first surface, capped at ``max_range``.

        Args:
            origin: (dim,) sensor position (m).
            directions: (R, dim) unit vectors.
            max_range: sensor range (m).
        """
        origin = np.asarray(origin, dtype=float)
        if self.dim == 2:
            import pymunk

            space = self.space
            flt = pymunk.ShapeFilter()
            start = (float(origin[0]), float(origin[1]))
            out = np.full(len(directions), max_range)
            for r, d in enumerate(directions):
                end = (start[0] + d[0] * max_range, start[1] + d[1] * max_range)
                info = space.segment_query_first(start, end, 0.0, flt)
                if info is not None:
                    out[r] = info.alpha * max_range
            return out
        return self._lidar_spheres(origin, directions, max_range)

    def _lidar_spheres(self, origin: np.ndarray, directions: np.ndarray, max_range: float):
        if self.n_bodies == 0:
            return np.full(len(directions), max_range)
        rel = self.centers - origin  # (B, 3)
        proj = directions @ rel.T  # (R, B) distance along the ray to the closest approach
        perp2 = np.einsum("bi,bi->b", rel, rel)[None, :] - proj**2
        half = np.sqrt(np.maximum(self.radii[None, :] ** 2 - perp2, 0.0))
        entry = proj - half
        inside = perp2 <= self.radii[None, :] ** 2
        entry = np.where(inside & (proj + half >= 0.0), np.maximum(entry, 0.0), np.inf)
        return np.minimum(entry.min(axis=1), max_range)


def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance over the last axis of two broadcastable arrays (m).

    One array operation per axis instead of a reduction over a short last axis (which numpy does
    slowly): ``sqrt((a₀ − b₀)² + (a₁ − b₁)² [+ (a₂ − b₂)²])``, summed in that order.
    """
    sq = None
    for axis in range(a.shape[-1]):
        delta = a[..., axis] - b[..., axis]
        delta *= delta
        sq = delta if sq is None else np.add(sq, delta, out=sq)
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
