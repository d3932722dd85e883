"""Swept contact checks: which bodies a path touches during a step (compiled, per field).

The chaser's step is sampled at the collision sub-steps and the chords between the samples are
swept against every body, inflated by the chaser's radius: :func:`path_touches` for bodies at
rest (the v0 world), :func:`moving_path_touches` for bodies on CWH motion (in relative
coordinates, each body's own motion subtracted sub-step by sub-step; on request a turning
polygon's turn is followed in pieces short enough to stay within :data:`TURN_TOLERANCE`). Both
take the arrays of :class:`~debris_gym.batch_geometry.FieldBatch` and are inlined into the
compiled step (:mod:`debris_gym.mission_step`); :meth:`FieldBatch.touched
<debris_gym.batch_geometry.FieldBatch.touched>` runs the first over a batch. Polygon vertices
are stored as :class:`~debris_gym.batch_geometry.FieldBatch` describes (relative vertex, edge
vector). No gymnasium import.
"""

from __future__ import annotations

import math

from debris_gym.jit import inlined, kernel


@inlined
def polygon_edge(verts, v, cx, cy):
    """Edge v of a polygon: absolute start (x0, y0) and the stored edge vector (ex, ey)."""
    return verts[v, 0] + cx, verts[v, 1] + cy, verts[v, 2], verts[v, 3]


@inlined
def _point_segment_distance(p, a, b, dim):
    """Distance from point p to segment a→b (1-D arrays of length ``dim``)."""
    len2 = 0.0
    dot = 0.0
    for k in range(dim):
        ab = b[k] - a[k]
        len2 += ab * ab
        dot += (p[k] - a[k]) * ab
    t = dot / len2 if len2 > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    s = 0.0
    for k in range(dim):
        g = (p[k] - a[k]) - t * (b[k] - a[k])
        s += g * g
    return math.sqrt(s)


@inlined
def _segment_distance_2d(px, py, ax, ay, bx, by):
    """Distance from (px, py) to the segment (ax, ay) → (bx, by)."""
    abx = bx - ax
    aby = by - ay
    apx = px - ax
    apy = py - ay
    len2 = abx * abx + aby * aby
    t = (apx * abx + apy * aby) / len2 if len2 > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    gx = apx - t * abx
    gy = apy - t * aby
    return math.sqrt(gx * gx + gy * gy)


@inlined
def _segment_touches_polygon(ax, ay, bx, by, cx, cy, verts, m, inflate):
    """Does the segment a→b come within ``inflate`` of the convex polygon (see
    :func:`polygon_gap` for ``cx, cy, verts, m``)?"""
    inside_a = -math.inf
    inside_b = -math.inf
    sx_ = bx - ax
    sy_ = by - ay
    for v in range(m):
        x0, y0, ex, ey = polygon_edge(verts, v, cx, cy)
        # end points on the inner side of every edge: inside
        inside_a = max(inside_a, (ax - x0) * ey - (ay - y0) * ex)
        inside_b = max(inside_b, (bx - x0) * ey - (by - y0) * ex)
        # the segment crosses this edge (proper or touching intersection)
        x1 = x0 + ex
        y1 = y0 + ey
        d1 = sx_ * (y0 - ay) - sy_ * (x0 - ax)
        d2 = sx_ * (y1 - ay) - sy_ * (x1 - ax)
        d3 = ex * (ay - y0) - ey * (ax - x0)
        d4 = ex * (by - y0) - ey * (bx - x0)
        if d1 * d2 <= 0.0 and d3 * d4 <= 0.0:
            return True
        if inflate > 0.0:
            # segment-to-edge distance: end points to the edge, the edge's start to the segment
            if (
                _segment_distance_2d(ax, ay, x0, y0, x1, y1) <= inflate
                or _segment_distance_2d(bx, by, x0, y0, x1, y1) <= inflate
                or _segment_distance_2d(x0, y0, ax, ay, bx, by) <= inflate
            ):
                return True
    return inside_a <= 0.0 or inside_b <= 0.0


@inlined
def _chords_touch_polygon(points, cx, cy, verts, m, inflate):
    """Does the polyline ``points`` (K+1, 2) come within ``inflate`` of the convex polygon (see
    :func:`_segment_touches_polygon`) along any of its chords?"""
    for k in range(points.shape[0] - 1):
        if _segment_touches_polygon(
            points[k, 0], points[k, 1], points[k + 1, 0], points[k + 1, 1], cx, cy, verts, m,
            inflate,
        ):  # fmt: skip
            return True
    return False


@inlined
def path_reach(path):
    """Largest distance (m) from ``path[0]`` to a later point of the polyline ``path`` (K+1,
    dim): the path lies in that ball around its start (the broad phase of the swept checks)."""
    reach2 = 0.0
    for k in range(1, path.shape[0]):
        s = 0.0
        for a in range(path.shape[1]):
            d = path[k, a] - path[0, a]
            s += d * d
        reach2 = max(reach2, s)
    return math.sqrt(reach2)


@inlined
def path_touches(
    path, start_gaps, inflate, i, centers, radii, polygon_start, n_vertices, vertices, out
):
    """Which bodies of field ``i`` the polyline ``path`` (K+1, dim) touches, into ``out`` (B,).

    ``start_gaps`` (B,) are the gaps at ``path[0]`` (the broad phase); bodies are inflated by
    ``inflate`` (m).
    """
    n_points, dim = path.shape
    reach = path_reach(path) + inflate
    for b in range(centers.shape[1]):
        out[b] = False
        if not start_gaps[b] <= reach:  # broad phase
            continue
        j = b - polygon_start
        m = n_vertices[i, j] if dim == 2 and j >= 0 else 0
        if m:
            out[b] = _chords_touch_polygon(
                path, centers[i, b, 0], centers[i, b, 1], vertices[i, j], m, inflate
            )
        else:
            limit = radii[i, b] + inflate
            for k in range(n_points - 1):
                if _point_segment_distance(centers[i, b], path[k], path[k + 1], dim) <= limit:
                    out[b] = True
                    break


@inlined
def _origin_segment_distance(rel, k, dim):
    """Distance (m) from the origin to the segment ``rel[k]`` → ``rel[k + 1]``."""
    len2 = 0.0
    dot = 0.0
    for a in range(dim):
        ab = rel[k + 1, a] - rel[k, a]
        len2 += ab * ab
        dot -= rel[k, a] * ab
    t = dot / len2 if len2 > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    s = 0.0
    for a in range(dim):
        g = rel[k, a] + t * (rel[k + 1, a] - rel[k, a])
        s += g * g
    return math.sqrt(s)


TURN_TOLERANCE = 0.01
"""How far (m) the chords of the swept turn check may stray from the path they stand for in a
turning polygon's frame: the order of the sampled path's own chord error at the default step
(``docs/environments.md``, "Collisions are continuous"), a hundredth of the default chaser."""


@inlined
def turn_pieces(angle, far, length, tolerance):
    """Pieces to cut one sub-step into so that, in a frame turning by ``angle`` (rad) over it,
    the chords between the pieces' ends stay within ``tolerance`` (m) of the turned path.

    The path is a segment of ``length`` (m) within ``far`` (m) of the turn's centre; seen from
    the turning frame it is q(t) = R(−ωt)·p(t), whose second derivative is at most
    ω²·far + 2·|ω|·|ṗ|, and a chord strays from a curve by at most h²/8 times that over a piece
    of duration h: α²·far/8 + α·(length / pieces)/4 for a piece turning by α = angle / pieces,
    so pieces ≥ √(|angle|·(|angle|·far/8 + length/4) / tolerance).
    """
    a = abs(angle)
    need = math.sqrt(a * (a * far / 8.0 + length / 4.0) / tolerance)
    return max(1, math.ceil(need))


@inlined
def _turning_chords_touch_polygon(rel, c, s, ch, sh, angle, verts, m, radius, inflate):
    """Does the relative path ``rel`` (K+1, 2; LVLH, polygon centre at the origin) come within
    ``inflate`` of the convex polygon ``verts`` (``m`` vertices, bounding radius ``radius``) while
    the polygon turns (attitude ``c, s`` at ``rel[0]``; ``ch, sh`` and ``angle`` (rad) the turn of
    one sub-step)?

    Between sub-steps the relative position moves along the chord (as for every body) while the
    polygon keeps turning: each chord is cut into :func:`turn_pieces` pieces whose ends are turned
    by the polygon's attitude at their instant, so that the pieces stay within
    :data:`TURN_TOLERANCE` of the turned chord. A chord farther than ``radius + inflate`` from the
    origin is skipped whole (distances to the centre do not change with the turn).
    """
    reach = radius + inflate
    for k in range(rel.shape[0] - 1):
        cn = c * ch - s * sh  # the attitude at the chord's end
        sn = s * ch + c * sh
        if _origin_segment_distance(rel, k, 2) <= reach:
            x0, y0 = rel[k, 0], rel[k, 1]
            dx, dy = rel[k + 1, 0] - x0, rel[k + 1, 1] - y0
            far = max(math.hypot(x0, y0), math.hypot(x0 + dx, y0 + dy))
            pieces = turn_pieces(angle, far, math.hypot(dx, dy), TURN_TOLERANCE)
            cp, sp = math.cos(angle / pieces), math.sin(angle / pieces)
            ax, ay = c * x0 + s * y0, c * y0 - s * x0
            cq, sq = c, s
            for p in range(1, pieces + 1):
                if p == pieces:
                    cq, sq = cn, sn
                else:
                    cq, sq = cq * cp - sq * sp, sq * cp + cq * sp
                f = p / pieces
                x, y = x0 + f * dx, y0 + f * dy
                bx, by = cq * x + sq * y, cq * y - sq * x
                if _segment_touches_polygon(ax, ay, bx, by, 0.0, 0.0, verts, m, inflate):
                    return True
                ax, ay = bx, by
        c, s = cn, sn
    return False


@inlined
def moving_path_touches(
    path, matrix_t, reach_position, reach_velocity, start_gaps, inflate, i, centers, velocities,
    radii, polygon_start, n_vertices, vertices, attitude, turns, swept_turns, rel, out,
):  # fmt: skip
    """Which moving bodies of field ``i`` the chaser touches during a step, into ``out`` (B,).

    Relative coordinates: a free body's state obeys CW as the chaser's does, so the chaser's
    position relative to body b at every sub-step is its sampled position ``path`` (K+1, dim)
    minus the body's, the body's coming from the same exact sub-step matrix ``matrix_t``
    (its first 2·dim rows, see :attr:`~debris_gym.mission_data.Rules.step_matrix_t`) applied to
    the body's state at the step's start (``centers``, ``velocities``). Consecutive relative
    positions are swept as chords against the body at the origin: a circle / sphere of its
    radius, or a polygon in its own frame (``attitude`` at the start; ``turns[i, j]`` the turn
    of a step and of a sub-step, see :class:`~debris_gym.mission_data.Field`). With
    ``swept_turns`` False the relative positions are turned back by the polygon's attitude at
    each sub-step only and joined by straight chords (the v0 / v1 check); with it True each
    chord is followed through the polygon's turn in pieces
    (:func:`_turning_chords_touch_polygon`). Bodies are inflated by ``inflate`` (m).

    Broad phase: the relative path stays within ``reach(chaser) + reach(body)`` of its start,
    where a body's reach over the step is at most ``reach_position`` · |position| +
    ``reach_velocity`` · |velocity| (the largest 2-norms of the position blocks of Φ(t) − I and
    Φ(t) at the sub-steps; the vectors' 1-norms, which are no smaller, stand in for theirs);
    with ``swept_turns`` a polygon's surface also moves by at most r·min(|Δθ|, 2) as it turns
    by Δθ over the step (r its bounding radius: a point at r from the centre moves a chord of
    2r·sin(|Δθ|/2)); bodies whose gap at the start (``start_gaps``) is larger are skipped.
    ``rel`` is (K+1, dim) scratch.
    """
    n_points, dim = path.shape
    reach = path_reach(path) + inflate
    swept = swept_turns and dim == 2 and turns.shape[1] > 0
    for b in range(centers.shape[1]):
        out[b] = False
        # 1-norms bound the 2-norms from above: a looser bound that needs no square root;
        # the axes written out (dim is not known at compile time: a loop over them compiles
        # to far more than two or three additions)
        pos1 = abs(centers[i, b, 0]) + abs(centers[i, b, 1])
        vel1 = abs(velocities[i, b, 0]) + abs(velocities[i, b, 1])
        if dim == 3:
            pos1 += abs(centers[i, b, 2])
            vel1 += abs(velocities[i, b, 2])
        bound = reach_position * pos1 + reach_velocity * vel1
        j = b - polygon_start
        polygon = dim == 2 and j >= 0
        if swept:
            # a turning polygon's pad without a branch on the body's kind (which changes from
            # body to body, so a branch mispredicts): the others add 0, which changes nothing
            jj = max(j, 0)
            turning = 1.0 if (j >= 0) & (n_vertices[i, jj] != 0) else 0.0
            bound += turning * (radii[i, b] * min(abs(turns[i, jj, 4]), 2.0))
        if not start_gaps[b] <= reach + bound:  # broad phase
            continue
        m = n_vertices[i, j] if polygon else 0  # read past the broad phase: most bodies stop there
        for a in range(dim):
            rel[0, a] = path[0, a] - centers[i, b, a]
        for k in range(1, n_points):
            for a in range(dim):
                col = (k - 1) * dim + a
                p = 0.0
                for q in range(dim):
                    p += centers[i, b, q] * matrix_t[q, col]
                    p += velocities[i, b, q] * matrix_t[dim + q, col]
                rel[k, a] = path[k, a] - p
        if m and swept_turns:
            out[b] = _turning_chords_touch_polygon(
                rel, attitude[i, j, 0], attitude[i, j, 1], turns[i, j, 2], turns[i, j, 3],
                turns[i, j, 5], vertices[i, j], m, radii[i, b], inflate,
            )  # fmt: skip
        elif m:
            # turn every relative position back into the polygon's loaded frame
            c, s = attitude[i, j, 0], attitude[i, j, 1]
            ch, sh = turns[i, j, 2], turns[i, j, 3]
            for k in range(n_points):
                x, y = rel[k, 0], rel[k, 1]
                rel[k, 0] = c * x + s * y
                rel[k, 1] = c * y - s * x
                c, s = c * ch - s * sh, s * ch + c * sh
            out[b] = _chords_touch_polygon(rel, 0.0, 0.0, vertices[i, j], m, inflate)
        else:
            limit = radii[i, b] + inflate
            for k in range(n_points - 1):
                if _origin_segment_distance(rel, k, dim) <= limit:
                    out[b] = True
                    break


@inlined
def pair_distance(path_a, path_b):
    """Closest approach (m, centre to centre) of two chasers flying the sampled paths
    ``path_a`` and ``path_b`` (K + 1, dim) over one step: the smallest distance from the origin
    to the chords of their relative path (both are free CW bodies under constant thrust, so
    their relative motion is sampled at the same sub-steps exactly as a chaser's relative to a
    body, :func:`~debris_gym.swept_contacts.moving_path_touches`)."""
    n_points, dim = path_a.shape
    best = math.inf
    for k in range(n_points - 1):
        len2 = 0.0
        dot = 0.0
        for a in range(dim):
            r0 = path_a[k, a] - path_b[k, a]
            ab = path_a[k + 1, a] - path_b[k + 1, a] - r0
            len2 += ab * ab
            dot -= r0 * ab
        t = dot / len2 if len2 > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        d2 = 0.0
        for a in range(dim):
            r0 = path_a[k, a] - path_b[k, a]
            g = r0 + t * (path_a[k + 1, a] - path_b[k + 1, a] - r0)
            d2 += g * g
        best = min(best, d2)
    return math.sqrt(best)


@kernel
def touched_bodies(
    paths, start_gaps, inflate, centers, radii, polygon_start, n_vertices, vertices, out
):  # fmt: skip
    """:func:`path_touches` for every field i of a batch: ``out[i, b]`` is True for each body b
    the polyline ``paths[i]`` touches (inflated by ``inflate``, m)."""
    for i in range(paths.shape[0]):
        path_touches(
            paths[i], start_gaps[i], inflate, i, centers, radii, polygon_start, n_vertices,
            vertices, out[i],
        )  # fmt: skip
