"""Body geometry for :mod:`debris_gym.envs.rendering`: what to draw of each body, and where.

Two jobs, both pure numpy (matplotlib's ``Path`` is imported only when paths are built):

- Huge bodies (:func:`outline`): a body far wider than the view is drawn as its part near the
  view, because Agg's work to draw a circle grows with its radius in pixels.
- Moving bodies (``Scenario.motion == "cwh"``): :class:`MovingBodies` gives every body's outline
  at any time, as matplotlib paths in one 2D projection, :func:`orbit_paths` samples each
  body's relative-orbit path (the closed ellipse of a drift-free body) over a window of time,
  and :func:`label_glyphs` gives the target numbers as shapes cheap to redraw.

Positions in m, times in s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from debris_gym.dynamics import discretize
from debris_gym.scenario import Scenario

CLIP_SPAN = 4.0
"""A body wider than this many view spans is drawn as its part near the view (:func:`outline`).

Agg flattens a circle's Bézier curves by subdividing them until each piece is under a pixel's
tolerance: the work grows with the radius in pixels, and at ~1e12 px (an obstacle of 1e15 m in a
1 km view) a single draw runs for minutes. Bodies up to this size are drawn whole (every body of
a checked scenario lies inside the bounds, so well below it); larger ones are replaced by a
polygon of bounded size that matches them to far below a pixel inside the view."""

ARC_POINTS = 256
"""Points along the arc of a clipped disc (the arc inside the view is at most ~6 view spans
long, so at most ~12 px apart on a 480 px panel, where the chord error stays below 0.01 px)."""

ORBIT_SAMPLES = 128
"""Straight pieces of one body's drawn path per window (:func:`orbit_paths`). On a 480 px panel
an ellipse as wide as the world (240 px half-axis) is then within 0.1 px of the true curve."""


def outline(
    centre: np.ndarray, radius: float, vertices: np.ndarray | None, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray | None:
    """What to draw of one body in the view box ``[lo, hi]`` (2-vectors, m).

    Returns ``None`` to draw the body whole (a circle of ``radius`` at ``centre``, or its polygon
    ``vertices`` in world coordinates), otherwise the polygon (k, 2) to draw instead: the body's
    part inside the view box grown by one view span on every side, so the cut edges stay off
    screen. An empty (0, 2) array means nothing of the body is near the view. Only bodies wider
    than :data:`CLIP_SPAN` view spans are cut (see there why).
    """
    span = float(np.max(hi - lo))
    box_lo, box_hi = lo - span, hi + span
    if vertices is None:
        if not radius > CLIP_SPAN * span:
            return None
        return _clipped_disc(centre, radius, box_lo, box_hi)
    extent = float(np.max(vertices.max(axis=0) - vertices.min(axis=0)))
    if not extent > CLIP_SPAN * span:
        return None
    return _clip_polygon(vertices, box_lo, box_hi)


def _clipped_disc(centre: np.ndarray, radius: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """A disc far larger than the box ``[lo, hi]``, cut to the box (polygon vertices, m).

    Worked in a frame at the box centre with axis u pointing away from the disc's centre and w
    across it, where the disc's edge is a = sqrt(r² − b²) − D, written as
    (r − D) − b² / (r + sqrt(r² − b²)) so that no two huge numbers are subtracted but r − D
    (which is as precise as the inputs allow).
    """
    mid = (lo + hi) / 2.0
    half = float(np.hypot(*((hi - lo) / 2.0)))  # the box lies within this distance of mid
    offset = mid - centre
    dist = float(np.hypot(*offset))
    gap = dist - radius  # first: dist ± half would round back to dist beside a huge radius
    if gap + half <= 0.0:  # the disc covers the box
        return np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]], dtype=float)
    if gap - half >= 0.0:  # the disc misses the box
        return np.zeros((0, 2))
    u = offset / dist  # dist > radius - half > 0: the centre is far outside the box
    w = np.array([-u[1], u[0]])
    b = np.linspace(-half, half, ARC_POINTS)
    a = -gap - b * b / (radius + np.sqrt(radius * radius - b * b))
    far = min(float(a.min()), -half) - half  # behind the box, on the disc's side
    a = np.concatenate([a, [far, far]])
    b = np.concatenate([b, [half, -half]])
    return mid + a[:, None] * u + b[:, None] * w


def _clip_polygon(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """A convex polygon cut to the box ``[lo, hi]`` (Sutherland–Hodgman), (k, 2) vertices."""
    out = np.asarray(points, dtype=float)
    for axis in (0, 1):
        for limit, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            if len(out) == 0:
                return np.zeros((0, 2))
            inside = sign * (out[:, axis] - limit) >= 0.0
            kept = []
            for k in range(len(out)):
                p, q = out[k], out[(k + 1) % len(out)]
                if inside[k]:
                    kept.append(p)
                if inside[k] != inside[(k + 1) % len(out)]:
                    kept.append(_cut(p, q, axis, limit))
            out = np.array(kept).reshape(-1, 2)
    return out


def _cut(p: np.ndarray, q: np.ndarray, axis: int, limit: float) -> np.ndarray:
    """Where segment pq crosses the line ``coordinate[axis] = limit``, interpolated from the end
    nearer to that line: the ends of a huge body's edge may lie 1e20 m apart, and interpolating
    from the far end would lose the crossing in rounding."""
    if abs(p[axis] - limit) > abs(q[axis] - limit):
        p, q = q, p
    point = p + (limit - p[axis]) / (q[axis] - p[axis]) * (q - p)
    point[axis] = limit
    return point


def label_glyphs(count: int, style: dict[str, Any]) -> list[Any]:
    """Outlines of the numbers 0 … count − 1 in points from a body's centre, set like a text
    annotation of ``style`` (its ``xytext`` offset in points, ``fontsize``, ``fontweight``). A
    moving field redraws its target labels on every frame, and filling a few glyph outlines costs
    a small part of laying out and drawing text."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    prop = FontProperties(size=style["fontsize"], weight=style["fontweight"])
    return [TextPath(style["xytext"], str(i), prop=prop) for i in range(count)]


def off_view(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """A small triangle one view span beyond the lower-left corner: the stand-in drawn for a body
    nowhere near the view, so that every body keeps its one shape (colours are per shape)."""
    return np.repeat(lo[None] - (hi - lo), 3, axis=0)


# --- moving bodies ------------------------------------------------------------------------------


def path_window(scenario: Scenario) -> float:
    """Length (s) of the stretch of each body's motion drawn as its path.

    One orbit period 2π/n for n > 0: a drift-free body's whole relative-orbit ellipse. For
    n = 0 (straight-line motion) the time the fastest body takes to cross the world; ``inf``
    when nothing moves (no paths to draw).
    """
    n = scenario.mean_motion
    if n > 0.0:
        return 2.0 * math.pi / n
    speeds = np.linalg.norm(scenario.initial_body_states()[:, scenario.dim :], axis=1)
    fastest = float(speeds.max()) if speeds.size else 0.0
    return scenario.size / fastest if fastest > 0.0 else math.inf


def orbit_paths(scenario: Scenario, start: float, duration: float) -> np.ndarray:
    """Every body's positions (m) at :data:`ORBIT_SAMPLES` + 1 evenly spaced times from
    ``start`` to ``start + duration`` (s): shape (n_bodies, samples, dim), targets first.

    Starts from ``scenario.body_states(start)`` (the exact state-transition matrix) and steps
    with the exact transition over one sample spacing, whose rounding stays ~1e-13 of the
    positions over a window.
    """
    dim = scenario.dim
    states = np.array(scenario.body_states(start), dtype=float)
    step = discretize(scenario.mean_motion, duration / ORBIT_SAMPLES, dim).ad.T
    out = np.empty((states.shape[0], ORBIT_SAMPLES + 1, dim))
    out[:, 0] = states[:, :dim]
    for k in range(1, ORBIT_SAMPLES + 1):
        states = states @ step
        out[:, k] = states[:, :dim]
    return out


class MovingBodies:
    """The bodies of a scenario drawn where they are at any time, as matplotlib paths.

    Positions come from ``scenario.body_positions(t)``; a 2D polygon is its ``vertices`` turned
    by ``scenario.body_angles(t)`` (the rotation ``Scenario.body_vertices`` applies, done here
    for all polygons at once). Bodies wide enough to need :func:`outline` are found once, from
    their size, so the per-frame work for ordinary bodies is a translation of a stored shape.

    Args:
        scenario: the field (any motion; a frozen one simply stays put).
        span: the smallest view span (m) the paths will be drawn for, for :data:`CLIP_SPAN`.
    """

    def __init__(self, scenario: Scenario, span: float) -> None:
        from matplotlib.path import Path

        self._path = Path
        self._circle = Path.unit_circle()
        self.scenario = scenario
        bodies = scenario.bodies
        self.radii = np.array([b.radius for b in bodies], dtype=float)
        self.local = [None if b.vertices is None else np.asarray(b.vertices, float) for b in bodies]
        # outline() measures a circle by its radius and a polygon by its extent, which its
        # circumscribed circle bounds by 2·radius whatever the attitude.
        width = np.where([v is None for v in self.local], 1.0, 2.0) * self.radii
        self.huge = width > CLIP_SPAN * span

    def at(self, time: float) -> tuple[np.ndarray, list[np.ndarray | None]]:
        """Centres (n_bodies, dim) and world-coordinate polygon vertices (None for circles and
        spheres) of every body at ``time`` (s)."""
        scenario = self.scenario
        centres = np.asarray(scenario.body_positions(time), dtype=float)
        angles = scenario.body_angles(time)
        vertices: list[np.ndarray | None] = []
        for b, local in enumerate(self.local):
            if local is None:
                vertices.append(None)
                continue
            c, s = math.cos(angles[b]), math.sin(angles[b])
            vertices.append(centres[b] + local @ np.array([[c, s], [-s, c]]))
        return centres, vertices

    def paths(
        self,
        indices: range,
        centres: np.ndarray,
        vertices: list[np.ndarray | None],
        h: int,
        v: int,
        lo: np.ndarray,
        hi: np.ndarray,
    ) -> list[Any]:
        """Matplotlib paths (data coordinates of the projection onto axes ``h`` across and ``v``
        up) of the bodies ``indices``, from :meth:`at`'s output, for the view box ``[lo, hi]``."""
        path, circle = self._path, self._circle
        out = []
        for b in indices:
            centre = centres[b, [h, v]]
            poly = vertices[b]
            if poly is not None:
                poly = poly[:, [h, v]]
            if self.huge[b]:
                shape = outline(centre, float(self.radii[b]), poly, lo, hi)
                if shape is not None:
                    if len(shape) == 0:
                        shape = off_view(lo, hi)
                    out.append(path(np.vstack([shape, shape[:1]]), closed=True))
                    continue
            if poly is None:
                out.append(path(circle.vertices * self.radii[b] + centre, circle.codes))
            else:
                out.append(path(np.vstack([poly, poly[:1]]), closed=True))
        return out
