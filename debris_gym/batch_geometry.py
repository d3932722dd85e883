"""Geometry of many debris fields at once, as padded numpy arrays (for the native vector env).

:class:`FieldBatch` holds N fields with the same number of bodies B (targets first, then
obstacles, as :attr:`Scenario.bodies`). Its queries take one point or one path per field and
answer for every body of every field in a handful of array operations, with no Python loop over
fields or bodies. They give the same answers as :class:`debris_gym.geometry.FieldGeometry` (numpy
clearance, pymunk swept checks); ``tests/test_vector_env.py`` holds the two together.

Polygons (2D) are padded to ``max_vertices`` with zero-length edges at their first vertex, which
change neither the inside test nor the smallest edge distance.
"""

from __future__ import annotations

import numpy as np

from debris_gym.scenario import Scenario


class FieldBatch:
    """N fields of B bodies each.

    Args:
        num: number of fields N.
        n_bodies: bodies per field B.
        dim: 2 or 3.
        max_vertices: most polygon vertices (2D).
    """

    def __init__(self, num: int, n_bodies: int, dim: int, max_vertices: int = 8) -> None:
        self.num, self.n_bodies, self.dim = num, n_bodies, dim
        v = max_vertices if dim == 2 else 1
        self.max_vertices = v
        self.centers = np.zeros((num, n_bodies, dim))
        self.radii = np.ones((num, n_bodies))
        self.is_polygon = np.zeros((num, n_bodies), dtype=bool)
        self.edge_start = np.zeros((num, n_bodies, v, 2))
        self.edge_vec = np.zeros((num, n_bodies, v, 2))
        self.edge_inv_len2 = np.zeros((num, n_bodies, v))
        self.edge_normal = np.zeros((num, n_bodies, v, 2))
        self.inradius = np.ones((num, n_bodies))  # largest centred disc inside each body
        self.any_polygon = False

    def load(self, i: int, scenario: Scenario) -> None:
        """Put ``scenario``'s bodies into slot ``i``."""
        bodies = scenario.bodies
        if len(bodies) != self.n_bodies or scenario.dim != self.dim:
            raise ValueError(
                f"field has {len(bodies)} bodies in {scenario.dim}D; this batch holds "
                f"{self.n_bodies} bodies in {self.dim}D"
            )
        self.centers[i] = scenario.body_positions(0.0)
        self.radii[i] = [b.radius for b in bodies]
        self.is_polygon[i] = [b.is_polygon for b in bodies]
        self.inradius[i] = self.radii[i]
        for j, body in enumerate(bodies):
            if not body.is_polygon:
                continue
            verts = np.asarray(body.vertices, dtype=float) + np.asarray(body.position)
            m = len(verts)
            if m > self.max_vertices:
                raise ValueError(f"polygon has {m} vertices; the batch allows {self.max_vertices}")
            edges = np.roll(verts, -1, axis=0) - verts
            normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
            normals /= np.linalg.norm(normals, axis=1, keepdims=True)
            self.edge_start[i, j, :m] = verts
            self.edge_vec[i, j, :m] = edges
            self.edge_inv_len2[i, j, :m] = 1.0 / (edges * edges).sum(axis=1)
            self.edge_normal[i, j, :m] = normals
            # distance from the centre to the nearest edge line (the centre is inside the polygon)
            centre_depth = ((np.asarray(body.position) - verts) * normals).sum(axis=1)
            self.inradius[i, j] = max(float(-centre_depth.max()), 0.0)
            self.edge_start[i, j, m:] = verts[0]
            self.edge_vec[i, j, m:] = 0.0
            self.edge_inv_len2[i, j, m:] = 0.0
            self.edge_normal[i, j, m:] = normals[0]
        self.any_polygon = bool(self.is_polygon.any())

    # --- clearance ----------------------------------------------------------------------------

    def gaps(
        self,
        points: np.ndarray,
        rows: np.ndarray | None = None,
        nearest: int | None = None,
        skip: int = 0,
    ) -> np.ndarray:
        """Signed distance (m) from each field's point to its bodies, shape (len(rows), B).

        Args:
            points: (N, dim) one point per field, or (len(rows), dim) with ``rows``.
            rows: fields to answer for (default: all).
            nearest: if given, polygon distances are exact only where they can matter for the
                ``nearest`` closest bodies from index ``skip`` on (and for bodies before ``skip``);
                elsewhere the value is a lower bound (the bounding-circle distance). Circles and
                spheres are always exact. Bodies are culled with [lower, upper] bounds from the
                bounding and inscribed circles, so the ``nearest`` smallest values and their order
                are the exact ones.
            skip: see ``nearest`` (e.g. the number of targets).
        """
        idx = slice(None) if rows is None else rows
        centers, radii = self.centers[idx], self.radii[idx]
        diff = centers - points[:, None, :]
        dist = np.sqrt((diff * diff).sum(axis=2))
        out = dist - radii
        if not self.any_polygon:
            return out
        poly = self.is_polygon[idx]
        if nearest is not None and out.shape[1] - skip > nearest:
            upper = dist[:, skip:] - self.inradius[idx][:, skip:]
            bound = np.partition(upper, nearest - 1, axis=1)[:, nearest - 1]
            needed = out <= bound[:, None]
            needed[:, :skip] = True
            poly = poly & needed
        r, c = np.nonzero(poly)
        if r.size:
            field_rows = r if rows is None else np.asarray(rows)[r]
            out[r, c] = self._polygon_gaps(points[r], field_rows, c)
        return out

    def _polygon_gaps(self, pts: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Exact signed distance of points (C, 2) to polygons (rows, cols), shape (C,)."""
        start = self.edge_start[rows, cols]  # (C, V, 2)
        edge = self.edge_vec[rows, cols]
        normal = self.edge_normal[rows, cols]
        dx = pts[:, None, 0] - start[..., 0]
        dy = pts[:, None, 1] - start[..., 1]
        t = (dx * edge[..., 0] + dy * edge[..., 1]) * self.edge_inv_len2[rows, cols]
        np.clip(t, 0.0, 1.0, out=t)
        cx = dx - t * edge[..., 0]
        cy = dy - t * edge[..., 1]
        edge_dist = np.sqrt((cx * cx + cy * cy).min(axis=1))
        depth = (dx * normal[..., 0] + dy * normal[..., 1]).max(axis=1)
        return np.where(depth > 0.0, edge_dist, depth)

    # --- swept collision ----------------------------------------------------------------------

    def touched(self, paths: np.ndarray, start_gaps: np.ndarray, inflate: float) -> np.ndarray:
        """Which bodies each field's polyline touches (inflated by ``inflate``), shape (N, B).

        Args:
            paths: (N, K+1, dim) positions along each field's step (m).
            start_gaps: :meth:`gaps` at ``paths[:, 0]``.
            inflate: distance added to every body (the chaser radius, m).
        """
        out = np.zeros((self.num, self.n_bodies), dtype=bool)
        rel = paths[:, 1:] - paths[:, :1]
        reach = np.sqrt((rel * rel).sum(axis=2).max(axis=1)) + inflate
        rows, cols = np.nonzero(start_gaps <= reach[:, None])  # broad phase
        if rows.size == 0:
            return out
        a = paths[rows, :-1]  # (C, K, dim) segment starts
        b = paths[rows, 1:]
        poly = self.is_polygon[rows, cols]
        hit = np.zeros(rows.size, dtype=bool)
        circ = ~poly
        if circ.any():
            centre = self.centers[rows[circ], cols[circ]][:, None, :]
            d = _point_segment_distance(centre, a[circ], b[circ])  # (Cc, K)
            hit[circ] = (d <= self.radii[rows[circ], cols[circ]][:, None] + inflate).any(axis=1)
        if poly.any():
            hit[poly] = self._segments_touch_polygons(
                a[poly], b[poly], rows[poly], cols[poly], inflate
            )
        out[rows[hit], cols[hit]] = True
        return out

    def _segments_touch_polygons(self, a, b, rows, cols, inflate: float) -> np.ndarray:
        """Does any of the K segments a→b (C, K, 2) come within ``inflate`` of its polygon?"""
        start = self.edge_start[rows, cols][:, None]  # (C, 1, V, 2)
        edge = self.edge_vec[rows, cols][:, None]
        normal = self.edge_normal[rows, cols][:, None]
        p, q = a[:, :, None, :], b[:, :, None, :]  # (C, K, 1, 2)
        # an end point inside the polygon
        inside_a = (((p - start) * normal).sum(-1)).max(axis=2) <= 0.0
        inside_b = (((q - start) * normal).sum(-1)).max(axis=2) <= 0.0
        # the segment crosses an edge (proper or touching intersection)
        seg = q - p
        end = start + edge
        d1 = _cross(seg, start - p)
        d2 = _cross(seg, end - p)
        d3 = _cross(edge, p - start)
        d4 = _cross(edge, q - start)
        real_edge = self.edge_inv_len2[rows, cols][:, None] > 0.0
        crosses = ((d1 * d2 <= 0.0) & (d3 * d4 <= 0.0) & real_edge).any(axis=2)
        touching = inside_a | inside_b | crosses
        if inflate > 0.0:
            # distance between the segment and the edges: end points to edges, vertices to segment
            dist = np.minimum(
                _point_segment_distance(p, start, end).min(axis=2),
                _point_segment_distance(q, start, end).min(axis=2),
            )
            dist = np.minimum(dist, _point_segment_distance(start, p, q).min(axis=2))
            touching |= dist <= inflate
        return touching.any(axis=1)

    # --- lidar --------------------------------------------------------------------------------

    def lidar(self, origins: np.ndarray, directions: np.ndarray, max_range: float) -> np.ndarray:
        """Range (m) along each ray to the first surface, capped at ``max_range``, (N, R).

        Args:
            origins: (N, dim) sensor positions (m).
            directions: (R, dim) unit ray directions.
            max_range: sensor range (m).
        """
        rel = self.centers - origins[:, None, :]  # (N, B, dim)
        proj = np.einsum("rd,nbd->nrb", directions, rel)  # along-ray distance of closest approach
        perp2 = (rel * rel).sum(axis=2)[:, None, :] - proj * proj
        r2 = (self.radii * self.radii)[:, None, :]
        half = np.sqrt(np.maximum(r2 - perp2, 0.0))
        entry = proj - half
        hit = (perp2 <= r2) & (proj + half >= 0.0)
        circle_range = np.where(hit, np.maximum(entry, 0.0), np.inf)
        if self.any_polygon:
            circle_range = np.where(
                self.is_polygon[:, None, :], self._lidar_polygons(origins, directions), circle_range
            )
        return np.minimum(circle_range.min(axis=2), max_range)

    def _lidar_polygons(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Ray → convex polygon entry distance (0 from inside, inf if missed), (N, R, B)."""
        start = self.edge_start[:, None]  # (N, 1, B, V, 2)
        edge = self.edge_vec[:, None]
        o = origins[:, None, None, None, :]
        d = directions[None, :, None, None, :]  # (1, R, 1, 1, 2)
        denom = _cross(d, edge)  # (N, R, B, V)
        w = start - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = _cross(w, edge) / denom  # along the ray
            s = _cross(w, d) / denom  # along the edge
        valid = (denom != 0.0) & (s >= 0.0) & (s <= 1.0) & (t >= 0.0)
        valid &= self.edge_inv_len2[:, None] > 0.0
        entry = np.where(valid, t, np.inf).min(axis=3)
        normal = self.edge_normal[:, None]
        inside = (((o - start) * normal).sum(-1)).max(axis=3) <= 0.0  # (N, 1, B)
        return np.where(inside, 0.0, entry)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """z-component of the 2D cross product over the last axis."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p to segments a→b (broadcast over leading axes; last axis = dim)."""
    ab = b - a
    ap = p - a
    len2 = (ab * ab).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(len2 > 0.0, (ap * ab).sum(-1) / len2, 0.0)
    t = np.clip(t, 0.0, 1.0)
    gap = ap - t[..., None] * ab
    return np.sqrt((gap * gap).sum(-1))
