"""Geometry of many debris fields at once, as padded numpy arrays (for the native vector env).

:class:`FieldBatch` holds N fields with the same number of bodies B (targets first, then
obstacles, as :attr:`Scenario.bodies`). Its queries take one point or one path per field and
answer for every body of every field in a handful of array operations, with no Python loop over
fields or bodies. They give the same answers as :class:`debris_gym.geometry.FieldGeometry` (numpy
clearance with the same formulas, pymunk swept checks); ``tests/test_vector_env.py`` holds the
two together.

Storage is compact: polygon data exists only for the bodies from ``polygon_start`` on (targets
are never polygons), five numbers per polygon edge (the start vertex relative to the body centre,
the edge vector, and 1 / its squared length; the outward normal is (e_y, −e_x) / |e|). Polygons
are padded to ``max_vertices`` by repeating their first edge, which changes none of the answers.
The edge arrays keep the vertex axis in front of the field axes, so that reductions over a
polygon's edges run along a long leading axis (numpy is slow at reducing short trailing ones).
"""

from __future__ import annotations

import numpy as np

from debris_gym.geometry import distance
from debris_gym.scenario import Scenario

# components of FieldBatch.edges
_VX, _VY, _EX, _EY, _INV = range(5)
_N_COMPONENTS = 5

_CHUNK = 64
"""Most fields whose edge arrays are built in one set of array operations."""


class FieldBatch:
    """N fields of B bodies each.

    Args:
        num: number of fields N.
        n_bodies: bodies per field B.
        dim: 2 or 3.
        max_vertices: most polygon vertices (2D); grows when a field with more is loaded.
        polygon_start: first body index that may be a polygon (e.g. the number of targets).

    Attributes:
        centers: (N, B, dim) body centres (m).
        radii: (N, B) bounding radii (m).
        inradius: (N, B) radius of a disc about the centre inside each body (m): the radius
            for circles and spheres, a hair under the largest such disc for polygons.
        is_polygon: (N, B) True for 2D convex polygons.
        n_vertices: (N, P) vertex counts of bodies ``polygon_start …`` (0: not a polygon).
        edges: (5, V, N, P) per polygon edge: start vertex relative to the centre (x, y), edge
            vector (x, y) (m), 1 / squared edge length (1/m²); zero for non-polygons.
    """

    def __init__(
        self, num: int, n_bodies: int, dim: int, max_vertices: int = 7, polygon_start: int = 0
    ) -> None:
        if not 0 <= polygon_start <= n_bodies:
            raise ValueError(f"polygon_start must be in [0, {n_bodies}], got {polygon_start}")
        self.num, self.n_bodies, self.dim = num, n_bodies, dim
        self.polygon_start = polygon_start if dim == 2 else n_bodies
        p = n_bodies - self.polygon_start
        self.max_vertices = max_vertices if dim == 2 else 0
        self.centers = np.zeros((num, n_bodies, dim))
        self.radii = np.ones((num, n_bodies))
        self.inradius = np.ones((num, n_bodies))
        self.is_polygon = np.zeros((num, n_bodies), dtype=bool)
        self.n_vertices = np.zeros((num, p), dtype=np.int16)
        self.edges = np.zeros((_N_COMPONENTS, self.max_vertices, num, p))
        self.any_polygon = False

    # --- loading ------------------------------------------------------------------------------

    def load(self, i: int, scenario: Scenario) -> None:
        """Put ``scenario``'s bodies into slot ``i``."""
        self.load_scenario(np.array([i]), scenario)

    def load_scenario(self, rows: np.ndarray, scenario: Scenario) -> None:
        """Put ``scenario``'s bodies into every slot of ``rows``."""
        bodies = scenario.bodies
        if len(bodies) != self.n_bodies or scenario.dim != self.dim:
            raise ValueError(
                f"field has {len(bodies)} bodies in {scenario.dim}D; this batch holds "
                f"{self.n_bodies} bodies in {self.dim}D"
            )
        ps = self.polygon_start
        if any(b.is_polygon for b in bodies[:ps]):
            raise ValueError(f"bodies before index {ps} must be circles in this batch")
        polys = bodies[ps:]
        v = max([self.max_vertices, *(len(b.vertices) for b in polys if b.is_polygon)])
        vertices = np.zeros((1, len(polys), v, 2))
        counts = np.zeros((1, len(polys)), dtype=np.int64)
        for j, body in enumerate(polys):
            if body.is_polygon:
                m = len(body.vertices)
                vertices[0, j, :m] = body.vertices
                counts[0, j] = m
        k = len(rows)
        self.load_arrays(
            rows,
            np.broadcast_to(scenario.body_positions(0.0), (k, *self.centers.shape[1:])),
            np.broadcast_to([b.radius for b in bodies], (k, self.n_bodies)),
            np.broadcast_to(vertices, (k, *vertices.shape[1:])),
            np.broadcast_to(counts, (k, len(polys))),
        )

    def load_arrays(
        self,
        rows: np.ndarray,
        centers: np.ndarray,
        radii: np.ndarray,
        vertices: np.ndarray,
        n_vertices: np.ndarray,
    ) -> None:
        """Put K fields given as arrays into the slots ``rows`` (no Python loop over bodies).

        Args:
            rows: (K,) slot indices.
            centers: (K, B, dim) body centres (m).
            radii: (K, B) radii (m).
            vertices: (K, P, V', 2) vertices of bodies ``polygon_start …`` relative to their
                centres (m), counter-clockwise; slots past a polygon's count are ignored.
            n_vertices: (K, P) vertex counts, 0 for circles / spheres.
        """
        rows = np.asarray(rows)
        self.centers[rows] = centers
        self.radii[rows] = radii
        self.inradius[rows] = radii
        if self.dim != 2:
            return
        ps = self.polygon_start
        if vertices.shape[2] > self.max_vertices:
            self._grow_vertices(vertices.shape[2])
        counts = np.asarray(n_vertices)
        poly = counts > 0
        self.is_polygon[rows, :ps] = False
        self.is_polygon[rows, ps:] = poly
        self.n_vertices[rows] = counts
        if vertices.shape[2]:
            for i in range(0, len(rows), _CHUNK):  # in chunks: bounded temporaries
                part = slice(i, i + _CHUNK)
                records, inradius = _edge_records(
                    vertices[part], counts[part], centers[part, ps:], self.max_vertices
                )
                self.edges[:, :, rows[part]] = records
                self.inradius[rows[part], ps:] = np.where(poly[part], inradius, radii[part, ps:])
        else:
            self.edges[:, :, rows] = 0.0
        self.any_polygon = bool(self.is_polygon.any())

    def _grow_vertices(self, v: int) -> None:
        """Make room for polygons of ``v`` vertices (the new slots repeat each first edge)."""
        old = self.edges
        extra = np.repeat(old[:, :1], v - old.shape[1], axis=1)
        self.edges = np.concatenate([old, extra], axis=1)
        self.max_vertices = v

    def vertex_arrays(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Field ``i``'s polygon vertices relative to their centres (P, V, 2) and counts (P,)."""
        return self.edges[_VX : _VY + 1, :, i].transpose(2, 1, 0), self.n_vertices[i]

    def _records(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Edge arrays (5, V, C) of polygons (rows, cols) with *absolute* start vertices (m).

        The start is computed as vertex + centre, exactly as :class:`FieldGeometry` does.
        """
        p = self.n_bodies - self.polygon_start
        flat = rows * p + (cols - self.polygon_start)
        rec = self.edges.reshape(_N_COMPONENTS, self.max_vertices, -1).take(flat, axis=2)
        centres = self.centers.reshape(-1, self.dim).take(rows * self.n_bodies + cols, axis=0)
        rec[_VX] += centres[:, 0]
        rec[_VY] += centres[:, 1]
        return rec

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
        if rows is None:
            centers, radii, field_rows = self.centers, self.radii, None
        else:
            rows = np.asarray(rows)
            centers, radii, field_rows = self.centers[rows], self.radii[rows], rows
        dist = distance(centers, points[:, None, :])
        out = dist - radii
        if not self.any_polygon:
            return out
        poly = self.is_polygon if rows is None else self.is_polygon[rows]
        if nearest is not None and out.shape[1] - skip > nearest:
            inradius = self.inradius if rows is None else self.inradius[rows]
            upper = dist[:, skip:] - inradius[:, skip:]
            bound = np.partition(upper, nearest - 1, axis=1)[:, nearest - 1]
            needed = out <= bound[:, None]
            needed[:, :skip] = True
            poly = poly & needed
        flat = np.flatnonzero(poly)
        if flat.size:
            r, c = np.divmod(flat, self.n_bodies)
            body_rows = r if field_rows is None else field_rows[r]
            out.reshape(-1)[flat] = self._polygon_gaps(points[r], body_rows, c)
        return out

    def _polygon_gaps(self, pts: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Exact signed distance of points (C, 2) to polygons (rows, cols), shape (C,).

        Outside: the distance to the nearest edge; inside: minus the depth. The same formula,
        operation for operation, as :meth:`FieldGeometry.point_gaps`.
        """
        rec = self._records(rows, cols)  # (5, V, C)
        ex, ey, inv = rec[_EX], rec[_EY], rec[_INV]
        dx = np.subtract(pts[:, 0], rec[_VX], out=rec[_VX])
        dy = np.subtract(pts[:, 1], rec[_VY], out=rec[_VY])
        t = dx * ex
        t += dy * ey
        t *= inv
        np.clip(t, 0.0, 1.0, out=t)
        cx = dx - t * ex
        cy = dy - t * ey
        cx *= cx
        cy *= cy
        cx += cy
        edge_dist = np.sqrt(cx.min(axis=0))
        depth = dx * ey
        depth -= dy * ex
        depth *= np.sqrt(inv)
        depth = depth.max(axis=0)
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
        reach = distance(paths[:, 1:], paths[:, :1]).max(axis=1) + inflate
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
        rec = self._records(rows, cols).transpose(2, 1, 0)[:, None]  # (C, 1, V, 5)
        start = rec[..., _VX : _VY + 1]
        edge = rec[..., _EX : _EY + 1]
        p, q = a[:, :, None, :], b[:, :, None, :]  # (C, K, 1, 2)
        # an end point inside the polygon (on the inner side of every edge)
        inside_a = _cross(p - start, edge).max(axis=2) <= 0.0
        inside_b = _cross(q - start, edge).max(axis=2) <= 0.0
        # the segment crosses an edge (proper or touching intersection)
        seg = q - p
        end = start + edge
        d1 = _cross(seg, start - p)
        d2 = _cross(seg, end - p)
        d3 = _cross(edge, p - start)
        d4 = _cross(edge, q - start)
        crosses = ((d1 * d2 <= 0.0) & (d3 * d4 <= 0.0)).any(axis=2)
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
            ps = self.polygon_start
            circle_range[:, :, ps:] = np.where(
                self.is_polygon[:, None, ps:],
                self._lidar_polygons(origins, directions),
                circle_range[:, :, ps:],
            )
        return np.minimum(circle_range.min(axis=2), max_range)

    def _lidar_polygons(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Ray → convex polygon entry distance (0 from inside, inf if missed), (N, R, P)."""
        rec = self.edges.transpose(2, 3, 1, 0)[:, None]  # (N, 1, P, V, 5)
        centres = self.centers[:, None, self.polygon_start :, None, :]
        start = rec[..., _VX : _VY + 1] + centres  # (N, 1, P, V, 2)
        edge = rec[..., _EX : _EY + 1]
        o = origins[:, None, None, None, :]
        d = directions[None, :, None, None, :]  # (1, R, 1, 1, 2)
        denom = _cross(d, edge)  # (N, R, P, V)
        w = start - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = _cross(w, edge) / denom  # along the ray
            s = _cross(w, d) / denom  # along the edge
        valid = (denom != 0.0) & (s >= 0.0) & (s <= 1.0) & (t >= 0.0)
        entry = np.where(valid, t, np.inf).min(axis=3)
        inside = _cross(o - start, edge).max(axis=3) <= 0.0  # (N, 1, P)
        return np.where(inside, 0.0, entry)


def _edge_records(
    vertices: np.ndarray, counts: np.ndarray, centers: np.ndarray, v_out: int
) -> tuple[np.ndarray, np.ndarray]:
    """Edge arrays (5, v_out, K, P) and inscribed radii (K, P) of K × P polygons.

    Args:
        vertices: (K, P, V, 2) vertices relative to the centres (m), V <= v_out.
        counts: (K, P) vertex counts (0: not a polygon; its arrays are zero).
        centers: (K, P, 2) centres (m).
        v_out: vertex slots per polygon.
    """
    k, p, v = vertices.shape[:3]
    if v < v_out:
        vertices = np.concatenate([vertices, np.zeros((k, p, v_out - v, 2))], axis=2)
    j = np.arange(v_out)
    real = j < counts[..., None]  # (K, P, v_out)
    absolute = vertices + centers[:, :, None, :]  # as FieldGeometry: vertex + position
    following = np.where(j + 1 < counts[..., None], j + 1, 0)
    edge = np.take_along_axis(absolute, following[..., None], axis=2) - absolute
    ex, ey = edge[..., 0], edge[..., 1]
    with np.errstate(divide="ignore"):
        inv_len2 = 1.0 / (ex * ex + ey * ey)
    records = np.stack([vertices[..., 0], vertices[..., 1], ex, ey, inv_len2])  # (5, K, P, V)
    records = np.where(real, records, records[..., :1])  # padding: the first edge again
    records[:, counts == 0] = 0.0
    # depth of the centre behind each edge line (the centre is inside the polygon)
    start = records[_VX : _VY + 1].transpose(1, 2, 3, 0) + centers[:, :, None]  # (K, P, V, 2)
    rel = centers[:, :, None, :] - start
    depth = (rel[..., 0] * records[_EY] - rel[..., 1] * records[_EX]) * np.sqrt(records[_INV])
    inradius = np.maximum(-depth.max(axis=-1), 0.0) * (1.0 - 1e-9)  # never above the true one
    return records.transpose(0, 3, 1, 2), inradius


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
