"""Compiled queries of one field that planners need beyond the envs' clearance and contacts.

:class:`debris_gym.geometry.FieldGeometry` answers clearance, swept contacts and lidar with the
batch's own loops (:class:`~debris_gym.batch_geometry.FieldBatch`); the two queries here are the
ones the batch has no use for:

- :func:`nearest_points`: the nearest surface point of each body, the signed distance and its
  unit gradient (the repulsion of an artificial potential field, the keep-out half-planes of the
  MPC tracker).
- :func:`first_contacts`: where along a polyline each inflated body is first touched (which body
  a planner's path meets first; whether it meets one at all is the batch's contact test).

Both take the arrays of one field as :class:`~debris_gym.batch_geometry.FieldBatch` stores a
row: ``centers`` (B, dim) body centres (m), ``radii`` (B,) (m), ``polygon_start`` the first body
that may be a polygon, ``n_vertices`` (P,) vertex counts of bodies ``polygon_start …`` (0: not a
polygon), ``vertices`` (P, V, 4) each vertex relative to its body centre and the edge vector to
the next vertex (m), counter-clockwise.

The nearest point of a polygon is computed with the arithmetic of Chipmunk2D's point query
(pymunk's engine, the tests' oracle; edges walked from the lowest-x vertex, the order of its
convex hull; each edge's closest point measured from the edge's end): the gradients, which an
APF agent integrates over hundreds of steps, are then the same to the last bit as the oracle's.
"""

from __future__ import annotations

import math

from debris_gym.jit import inlined, kernel
from debris_gym.swept_contacts import path_reach

GRADIENT_EPSILON = 1e-5
"""Distance (m) below which the direction from the surface point is too short to normalise: the
gradient is then the nearest edge's outward normal (polygons) or the last axis (round bodies)."""

_TINY = 2.2250738585072014e-308
"""Smallest normal double, added to an edge length before dividing (a zero-length edge gives a
zero normal instead of NaN)."""


# --- nearest surface point ----------------------------------------------------------------------


@inlined
def _round_nearest(point, center, radius, dim, normal, surface):
    """Signed distance (m) from ``point`` to a circle / sphere; its unit gradient into ``normal``
    and the nearest surface point into ``surface`` (dim,)."""
    s = 0.0
    for k in range(dim):
        d = point[k] - center[k]
        s += d * d
    dist = math.sqrt(s)
    scale = radius / dist if dist > 0.0 else radius
    inv = 1.0 / dist
    for k in range(dim):
        d = point[k] - center[k]
        surface[k] = center[k] + d * scale
        if dist > GRADIENT_EPSILON:
            normal[k] = d * inv
        else:
            normal[k] = 1.0 if k == dim - 1 else 0.0
    return dist - radius


@inlined
def _polygon_nearest(px, py, cx, cy, verts, m, normal, surface):
    """Signed distance (m) from (px, py) to a convex polygon (centre cx, cy; ``m`` vertices
    ``verts`` relative to it); the unit gradient into ``normal`` (2,), the nearest boundary point
    into ``surface`` (2,)."""
    first = 0  # the lowest x, then the lowest y: where the oracle's convex hull starts
    for v in range(1, m):
        x, y = verts[v, 0] + cx, verts[v, 1] + cy
        fx, fy = verts[first, 0] + cx, verts[first, 1] + cy
        if x < fx or (x == fx and y < fy):
            first = v
    last = (first + m - 1) % m
    ax, ay = verts[last, 0] + cx, verts[last, 1] + cy  # start of the current edge
    best = math.inf
    qx = qy = 0.0  # nearest boundary point so far
    best_nx = best_ny = 0.0  # outward unit normal of its edge
    outside = False
    for i in range(m):
        v = (first + i) % m
        bx, by = verts[v, 0] + cx, verts[v, 1] + cy  # end of the current edge
        ex, ey = bx - ax, by - ay
        scale = 1.0 / (math.sqrt(ex * ex + ey * ey) + _TINY)
        nx, ny = ey * scale, -ex * scale
        if nx * (px - bx) + ny * (py - by) > 0.0:
            outside = True
        # nearest point of the edge, as a fraction of the way from its end back to its start
        dx, dy = ax - bx, ay - by
        t = (dx * (px - bx) + dy * (py - by)) / (dx * dx + dy * dy)
        t = max(0.0, min(t, 1.0))
        sx, sy = bx + dx * t, by + dy * t
        gx, gy = px - sx, py - sy
        dist = math.sqrt(gx * gx + gy * gy)
        if dist < best:
            best, qx, qy, best_nx, best_ny = dist, sx, sy, nx, ny
        ax, ay = bx, by
    signed = best if outside else -best
    inv = 1.0 / signed
    surface[0], surface[1] = qx, qy
    if best > GRADIENT_EPSILON:
        normal[0], normal[1] = (px - qx) * inv, (py - qy) * inv
    else:
        normal[0], normal[1] = best_nx, best_ny
    return signed


@kernel
def nearest_points(
    points, first, last, centers, radii, polygon_start, n_vertices, vertices, gaps, normals,
    surface,
):  # fmt: skip
    """Nearest surface point of bodies ``first … last − 1`` to each point.

    Args:
        points: (M, dim) positions (m).
        first, last: the body range answered.
        centers, radii, polygon_start, n_vertices, vertices: the field (module docstring).
        gaps: out (M, last − first) signed distances (m), negative inside.
        normals: out (M, last − first, dim) unit gradients of the distances (pointing away
            from the body).
        surface: out (M, last − first, dim) nearest surface points (m).
    """
    dim = centers.shape[1]
    for r in range(points.shape[0]):
        p = points[r]
        for b in range(first, last):
            o = b - first
            j = b - polygon_start
            m = n_vertices[j] if dim == 2 and j >= 0 else 0
            if m:
                gaps[r, o] = _polygon_nearest(
                    p[0], p[1], centers[b, 0], centers[b, 1], vertices[j], m, normals[r, o],
                    surface[r, o],
                )  # fmt: skip
            else:
                gaps[r, o] = _round_nearest(
                    p, centers[b], radii[b], dim, normals[r, o], surface[r, o]
                )


# --- first contact along a path ---------------------------------------------------------------


@inlined
def _ball_entry(a, b, center, reach, dim):
    """Fraction t ∈ [0, ∞) along a→b where it enters the ball of radius ``reach`` about
    ``center`` coming from outside; ``inf`` if it never does (t > 1: beyond b)."""
    qa = 0.0  # |b − a|²
    qb = 0.0  # (a − c)·(b − a)
    qc = 0.0  # |a − c|² − reach²
    for k in range(dim):
        d = b[k] - a[k]
        f = a[k] - center[k]
        qa += d * d
        qb += f * d
        qc += f * f
    qc -= reach * reach
    if qb >= 0.0:  # closest approach at or before a: moving away or standing still
        return math.inf
    if qc <= 0.0:  # on the surface (a rounding away from outside), heading in
        return 0.0
    det = qb * qb - qa * qc
    if det < 0.0:
        return math.inf
    return qc / (-qb + math.sqrt(det))  # the smaller root, without cancellation


@inlined
def _clip(t_in, t_out, num, den):
    """Narrow [t_in, t_out] to the part of a segment a + t·d on the inner side of one line
    n·(x − x₀) ≤ c, given num = c − n·(a − x₀) and den = n·d (Cyrus-Beck)."""
    if den == 0.0:
        if num < 0.0:  # parallel and outside
            return 1.0, 0.0
    elif den < 0.0:
        t_in = max(t_in, num / den)
    else:
        t_out = min(t_out, num / den)
    return t_in, t_out


@inlined
def _polygon_entry(ax, ay, bx, by, cx, cy, verts, m, inflate):
    """Fraction t ∈ [0, ∞) along a→b where it enters a convex polygon inflated by ``inflate``
    (m) (centre cx, cy; ``m`` vertices ``verts``), from outside; ``inf`` if it never does.

    The inflated polygon is the union of the polygon, a strip of half-width ``inflate`` along
    each edge and a disc at each vertex; the entry into it is the earliest entry into any part.
    """
    dx, dy = bx - ax, by - ay
    t_in, t_out = 0.0, 1.0
    for v in range(m):  # the polygon: the inner side of every edge line
        x0, y0, ex, ey = verts[v, 0] + cx, verts[v, 1] + cy, verts[v, 2], verts[v, 3]
        t_in, t_out = _clip(t_in, t_out, -((ax - x0) * ey - (ay - y0) * ex), dx * ey - dy * ex)
    best = t_in if t_in <= t_out else math.inf
    if inflate > 0.0:
        a = (ax, ay)
        b = (bx, by)
        for v in range(m):
            x0, y0, ex, ey = verts[v, 0] + cx, verts[v, 1] + cy, verts[v, 2], verts[v, 3]
            best = min(best, _ball_entry(a, b, (x0, y0), inflate, 2))
            length2 = ex * ex + ey * ey
            scale = 1.0 / math.sqrt(length2)
            nx, ny = ey * scale, -ex * scale
            across = nx * (ax - x0) + ny * (ay - y0)  # a's offset from the edge line
            along = ex * (ax - x0) + ey * (ay - y0)
            speed = nx * dx + ny * dy
            run = ex * dx + ey * dy
            s_in, s_out = _clip(0.0, 1.0, inflate - across, speed)
            s_in, s_out = _clip(s_in, s_out, inflate + across, -speed)
            s_in, s_out = _clip(s_in, s_out, length2 - along, run)
            s_in, s_out = _clip(s_in, s_out, along, -run)
            if s_in <= s_out:
                best = min(best, s_in)
    return best


@kernel
def first_contacts(
    path, start_gaps, inflate, centers, radii, polygon_start, n_vertices, vertices, segment, alpha
):
    """Where the polyline ``path`` first touches each body inflated by ``inflate``.

    A body the path starts in or on (gap at ``path[0]`` at most ``inflate``) is touched at the
    start. Broad phase: the path lies within R = max_k |path[k] − path[0]| of its start, so
    bodies whose gap at the start exceeds R + ``inflate`` are skipped (a gap of +inf leaves a
    body out).

    Args:
        path: (K+1, dim) positions (m).
        start_gaps: (B,) signed distances (m) from ``path[0]`` to every body.
        inflate: distance (m) added to every body.
        centers, radii, polygon_start, n_vertices, vertices: the field (module docstring).
        segment: out (B,) index k of the first touching segment path[k] → path[k+1], −1 if
            none.
        alpha: out (B,) fraction along that segment where the contact begins, inf if none.
    """
    n_points, dim = path.shape
    reach = path_reach(path) + inflate
    for b in range(centers.shape[0]):
        segment[b] = -1
        alpha[b] = math.inf
        if not start_gaps[b] <= reach:
            continue
        if start_gaps[b] <= inflate:
            segment[b] = 0
            alpha[b] = 0.0
            continue
        j = b - polygon_start
        m = n_vertices[j] if dim == 2 and j >= 0 else 0
        for k in range(n_points - 1):
            if m:
                t = _polygon_entry(
                    path[k, 0], path[k, 1], path[k + 1, 0], path[k + 1, 1],
                    centers[b, 0], centers[b, 1], vertices[j], m, inflate,
                )  # fmt: skip
            else:
                t = _ball_entry(path[k], path[k + 1], centers[b], radii[b] + inflate, dim)
            if t <= 1.0:
                segment[b] = k
                alpha[b] = t
                break
