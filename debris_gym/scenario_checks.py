"""The rules a debris field must satisfy: the one place scenarios are checked.

Two levels, both raising ``ValueError`` that names the offending key (as a path such as
``targets[2].radius`` or ``obstacles[0].vertices``), its value and what is allowed:

* :func:`check_values` — every value on its own, run by ``Scenario.__post_init__`` (so on every
  construction, the generators' too; O(bodies · vertices)): types and shapes, finite numbers,
  radii, convex polygons, body counts, and the physical parameters inside the env's option
  ranges (:data:`debris_gym.config.OPTIONS`).
* :func:`check_layout` — the geometry of the world, run when a scenario comes from outside the
  library (``Scenario.from_dict`` / ``load`` and :func:`debris_gym.scenario.as_scenario`, the
  entry of every pinned field into an env): world size, every body inside the bounds, no two
  bodies overlapping, the dock inside the bounds and clear of every body at t = 0. It reads body
  positions only through ``Scenario.body_positions(t)`` at the times it is given, so a field
  whose bodies move can be checked over a horizon by passing more times.

Units are SI: m, s, rad/s, m/s². ``docs/validation.md`` ("Scenarios") lists every rule.
"""

from __future__ import annotations

import itertools
import math
import numbers
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from debris_gym.config import OPTIONS, Option

if TYPE_CHECKING:  # the scenario module imports this one
    from debris_gym.scenario import Scenario

__all__ = [
    "MAX_WORLD_COORDINATE",
    "MIN_WORLD_SIZE",
    "MOTION_MODELS",
    "body_names",
    "check_dock_clear",
    "check_layout",
    "check_polygon",
    "check_values",
    "number",
    "vector",
]

MIN_WORLD_SIZE = float(OPTIONS["field_size"].low)
"""Shortest allowed edge of the world box (m), the env's smallest ``field_size``.

Rewards and observations are scaled by L = half the world's largest edge: in a world of a few
metres one step's progress term reaches thousands, and the env's default capture zone (5 m) is
larger than the world itself."""

MAX_WORLD_COORDINATE = float(OPTIONS["field_size"].high)
"""Largest allowed |bound| (m): the world lies within the env's largest ``field_size`` of the
LVLH origin (the reference orbit), where the linear CWH model holds."""

MOTION_MODELS = ("frozen", "cwh")
"""Debris motion models a scenario may declare: ``"frozen"`` (every body fixed in LVLH, the v0
world) and ``"cwh"`` (every body on unforced CWH motion from its ``velocity``, the v1 world)."""

MAX_SPIN = 1.0
"""Largest tumble rate |spin| (rad/s) of a body: a turn every 6 s, faster than any debris
tumble worth flying beside."""

RELATIVE_TOLERANCE = 1e-9
"""Rounding allowance of the geometric comparisons, relative to the lengths compared."""

_PAIR_BLOCK = 256
"""Bodies per block of the pairwise overlap test (bounds its temporaries to ~B · 256 numbers)."""


# --- single values ------------------------------------------------------------------------------


def number(
    value: Any, key: str, *, low: float | None = None, high: float | None = None, unit: str = ""
) -> float:
    """``value`` as a finite float within ``[low, high]``, else ``ValueError`` naming ``key``.

    Booleans and strings are not numbers here (``"5"`` would otherwise pass as 5.0).
    """
    allowed = _interval(low, high, unit)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{key} must be a number, got {_show(value)}; allowed: {allowed}")
    try:
        out = float(value)
    except OverflowError:  # an int beyond float range
        out = math.inf
    if not math.isfinite(out):
        raise ValueError(f"{key} must be finite, got {_show(value)}; allowed: {allowed}")
    if (low is not None and out < low) or (high is not None and out > high):
        raise ValueError(f"{key}={out!r}{_unit(unit)} is out of range; allowed: {allowed}")
    return out


def _show(value: Any) -> str:
    """``repr(value)``, cut short (a 400-digit integer is still named, not printed whole)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def vector(value: Any, dim: int, key: str, unit: str = "m") -> tuple[float, ...]:
    """``value`` as ``dim`` finite floats, else ``ValueError`` naming ``key`` (or ``key[i]``)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{key} must be a list of {dim} numbers ({unit}), got {_show(value)}")
    if len(value) != dim:
        raise ValueError(
            f"{key} must have {dim} components ({unit}), got {len(value)}: {_show(value)}"
        )
    return tuple(number(v, f"{key}[{i}]", unit=unit) for i, v in enumerate(value))


def _option(key: str, value: Any, name: str | None = None) -> float:
    """A scenario value checked against the env option ``key`` of :data:`OPTIONS`."""
    opt: Option = OPTIONS[key]
    return number(value, name or key, low=opt.low, high=opt.high, unit=opt.unit)


def _interval(low: float | None, high: float | None, unit: str) -> str:
    if low is None and high is None:
        return f"a finite number{f' ({unit})' if unit else ''}"
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    return f"[{lo}, {hi}]{_unit(unit)}"


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""


# --- polygons -----------------------------------------------------------------------------------


def check_polygon(vertices: Any, radius: float | None, key: str) -> tuple[tuple[float, float], ...]:
    """Check one 2D polygon and return its vertices as float pairs.

    Rules: at least 3 finite vertices (m, relative to the body's position), strictly convex and
    counter-clockwise (every turn to the left), simple (the boundary winds once around: a
    pentagram turns left at every corner but winds twice), and, when ``radius`` is given, equal
    to the vertices' circumradius about the position (their largest distance from it) within
    :data:`RELATIVE_TOLERANCE`.
    """
    if isinstance(vertices, np.ndarray):
        vertices = vertices.tolist()
    if not isinstance(vertices, (list, tuple)):
        raise ValueError(f"{key} must be a list of [x, y] vertices (m), got {vertices!r}")
    if len(vertices) < 3:
        raise ValueError(f"{key}: a polygon needs at least 3 vertices, got {len(vertices)}")
    pts = tuple(vector(v, 2, f"{key}[{k}]") for k, v in enumerate(vertices))
    xy = np.asarray(pts)
    left, turns, circumradius = _polygon_shapes(xy, np.array([len(pts)]))
    if left[0] < len(pts):
        k = int(left[0])
        raise ValueError(
            f"{key} must form a strictly convex, counter-clockwise polygon; the turn at vertex "
            f"{k} ({list(pts[k])!r} m) is not to the left"
        )
    if turns[0] != 1:
        raise ValueError(
            f"{key} winds {turns[0]} times around its inside; a convex polygon winds once "
            "(is it a star whose turns are all left?)"
        )
    if radius is not None and not _radius_matches(np.array([radius]), circumradius)[0]:
        raise ValueError(
            f"{key.rsplit('.', 1)[0]}.radius={radius!r} m disagrees with the circumradius of "
            f"its vertices, {float(circumradius[0])!r} m (largest vertex distance from the "
            "position); give that value or leave radius out to derive it"
        )
    return pts


def _polygon_shapes(xy: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, ...]:
    """The shape rules of P polygons at once, vertices (sum(counts), 2) one polygon after another.

    Returns ``(first, turns, circumradius)`` per polygon: the first vertex whose turn is not
    strictly to the left (``counts`` if none), the winding number of the boundary (round(total
    turning / 2π)), and the largest vertex distance from the body's position (m). Turns are
    measured on vertices scaled by the polygon's size, so huge coordinates do not overflow.
    """
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    poly = np.repeat(np.arange(len(counts)), counts)
    index = np.arange(len(xy))
    following = index + 1
    following[starts + counts - 1] = starts  # the last vertex turns into the first
    size = np.maximum.reduceat(np.abs(xy).max(axis=1), starts)
    unit = xy / np.where(size > 0.0, size, 1.0)[poly, None]
    edges = unit[following] - unit
    ahead = edges[following]
    cross = edges[:, 0] * ahead[:, 1] - edges[:, 1] * ahead[:, 0]
    dot = edges[:, 0] * ahead[:, 0] + edges[:, 1] * ahead[:, 1]
    # the turn between edge k (vertex k -> k+1) and edge k+1 happens at vertex k+1
    bad = np.where(cross > RELATIVE_TOLERANCE, counts[poly], following - starts[poly])
    first = np.minimum.reduceat(bad, starts)
    turns = np.rint(np.add.reduceat(np.arctan2(cross, dot), starts) / (2.0 * math.pi))
    circumradius = np.maximum.reduceat(np.hypot(xy[:, 0], xy[:, 1]), starts)
    return first, turns.astype(np.int64), circumradius


def _radius_matches(radius: np.ndarray, circumradius: np.ndarray) -> np.ndarray:
    """``math.isclose(radius, circumradius, rel_tol=RELATIVE_TOLERANCE)``, element-wise."""
    return np.abs(radius - circumradius) <= RELATIVE_TOLERANCE * np.maximum(
        np.abs(radius), np.abs(circumradius)
    )


# --- the whole scenario, value by value ---------------------------------------------------------


def check_values(scenario: Scenario) -> None:
    """Every value of ``scenario`` on its own (see the module docstring); ``ValueError`` if not.

    Raises:
        ValueError: naming the key path, the value and what is allowed.
    """
    dim = scenario.dim
    integral = isinstance(dim, numbers.Integral) and not isinstance(dim, (bool, np.bool_))
    if not integral or dim not in (2, 3):
        raise ValueError(f"dim must be the integer 2 or 3, got {dim!r}")
    bounds = scenario.bounds
    if not isinstance(bounds, (list, tuple)) or len(bounds) != dim:
        raise ValueError(f"bounds must be {dim} [low, high] pairs (m), got {bounds!r}")
    for axis, pair in enumerate(bounds):
        lo, hi = vector(pair, 2, f"bounds[{axis}]")
        if not lo < hi:
            raise ValueError(f"bounds[{axis}]={[lo, hi]!r} m must have low < high")
    vector(scenario.dock, dim, "dock")
    counts = (("targets", "n_targets"), ("obstacles", "n_obstacles"))
    for kind, option in counts:
        bodies = getattr(scenario, kind)
        if not isinstance(bodies, tuple):
            raise ValueError(f"{kind} must be a tuple of Body, got {type(bodies).__name__}")
        opt = OPTIONS[option]
        if not opt.low <= len(bodies) <= opt.high:
            raise ValueError(
                f"{kind} has {len(bodies)} bodies; allowed: {opt.describe()} (the env's {option})"
            )
    if not _bodies_pass(scenario):  # the fast screen found something: find and name it
        radius_min = {"targets": "target_radius_min", "obstacles": "obstacle_radius_min"}
        for kind, _ in counts:
            min_radius = float(OPTIONS[radius_min[kind]].low)
            for i, body in enumerate(getattr(scenario, kind)):
                _check_body(body, dim, f"{kind}[{i}]", min_radius, scenario.motion)
                if kind == "targets" and body.vertices is not None:
                    raise ValueError(f"targets[{i}].vertices: targets must be circles or spheres")
    _option("mean_motion", scenario.mean_motion)
    _option("dt", scenario.dt)
    _option("max_accel", scenario.max_accel)
    if scenario.motion not in MOTION_MODELS:
        raise ValueError(f"motion must be one of {MOTION_MODELS}, got {scenario.motion!r}")
    if not isinstance(scenario.name, str):
        raise ValueError(f"name must be a string, got {scenario.name!r}")


_PLAIN = (float, int)
"""Number types the fast screen accepts as they are (``bool`` is a type of its own here)."""


def _plain(values: Any) -> bool:
    return all(type(v) in _PLAIN for v in values)


def _bodies_pass(scenario: Scenario) -> bool:
    """Whether every body passes :func:`_check_body`, checked as arrays (a random field's
    thousands of bodies are built on every reset). True only if every rule holds; False sends
    :func:`check_values` through the bodies one by one, which names the first fault (and
    accepts what this screen left to it, such as numpy scalars)."""
    from debris_gym.scenario import Body  # here: the scenario module imports this one

    dim = scenario.dim
    bodies = scenario.bodies
    if not all(type(b) is Body for b in bodies):
        return False
    if any(b.vertices is not None for b in scenario.targets):
        return False
    if not all(type(b.velocity) is tuple for b in bodies):
        return False
    positions = [b.position for b in bodies]
    velocities = [b.velocity for b in bodies if b.velocity]
    radii = [b.radius for b in bodies]
    if not (
        all(type(p) is tuple and len(p) == dim for p in positions)
        and all(type(v) is tuple and len(v) == dim for v in velocities)
        and _plain(itertools.chain.from_iterable(positions))
        and _plain(itertools.chain.from_iterable(velocities))
        and _plain(radii)
    ):
        return False
    try:
        return _body_arrays_pass(scenario, positions, velocities, radii)
    except OverflowError:  # an int beyond float range: the slow path names it
        return False


def _body_arrays_pass(scenario: Scenario, positions: list, velocities: list, radii: list) -> bool:
    """The array part of :func:`_bodies_pass`, on values already known to be plain numbers."""
    dim, bodies = scenario.dim, scenario.bodies
    if not np.isfinite(np.array(positions, dtype=float)).all():
        return False
    if velocities:
        speeds = np.array(velocities, dtype=float)
        if not np.isfinite(speeds).all():
            return False
        if scenario.motion == "frozen" and np.any(speeds != 0.0):
            return False
    spins = [b.spin for b in bodies]
    if not (_plain(spins) and all(abs(w) <= MAX_SPIN for w in spins)):
        return False
    if scenario.motion == "frozen" and any(spins):
        return False
    low = np.where(
        np.arange(len(bodies)) < len(scenario.targets),
        OPTIONS["target_radius_min"].low,
        OPTIONS["obstacle_radius_min"].low,
    )
    r = np.array(radii, dtype=float)
    if not (np.isfinite(r).all() and np.all(r >= low)):
        return False
    polygons = [b for b in scenario.obstacles if b.vertices is not None]
    if not polygons:
        return True
    if dim != 2:
        return False
    shapes = [b.vertices for b in polygons]
    counts = np.array([len(v) for v in shapes])
    if not (
        all(type(v) is tuple for v in shapes)
        and np.all(counts >= 3)
        and all(type(p) is tuple and len(p) == 2 for v in shapes for p in v)
        and _plain(itertools.chain.from_iterable(itertools.chain.from_iterable(shapes)))
    ):
        return False
    xy = np.array(list(itertools.chain.from_iterable(shapes)), dtype=float)
    if not np.isfinite(xy).all():
        return False
    first, turns, circumradius = _polygon_shapes(xy, counts)
    radius = np.array([b.radius for b in polygons], dtype=float)
    matches = _radius_matches(radius, circumradius)
    return bool(np.all(first == counts) and np.all(turns == 1) and matches.all())


def _check_body(body: Any, dim: int, key: str, min_radius: float, motion: str) -> None:
    from debris_gym.scenario import Body  # here: the scenario module imports this one

    if not isinstance(body, Body):
        raise ValueError(f"{key} must be a Body, got {type(body).__name__}")
    vector(body.position, dim, f"{key}.position")
    if not isinstance(body.velocity, (list, tuple, np.ndarray)) or len(body.velocity) not in (
        0,
        dim,
    ):
        raise ValueError(f"{key}.velocity must have {dim} components (m/s), got {body.velocity!r}")
    velocity = vector(body.velocity, len(body.velocity), f"{key}.velocity", "m/s")
    if motion == "frozen" and any(v != 0.0 for v in velocity):
        raise ValueError(
            f"{key}.velocity={list(velocity)!r} m/s: a frozen field (motion='frozen') needs zero "
            "body velocities"
        )
    spin = number(body.spin, f"{key}.spin", low=-MAX_SPIN, high=MAX_SPIN, unit="rad/s")
    if motion == "frozen" and spin != 0.0:
        raise ValueError(
            f"{key}.spin={spin!r} rad/s: a frozen field (motion='frozen') has no tumbling bodies"
        )
    number(body.radius, f"{key}.radius", low=min_radius, unit="m")
    if body.vertices is not None:
        if dim != 2:
            raise ValueError(f"{key}.vertices: polygons are only allowed in 2D scenarios")
        check_polygon(body.vertices, body.radius, f"{key}.vertices")


# --- the layout of the world --------------------------------------------------------------------


def body_names(scenario: Scenario) -> list[str]:
    """Key path of every body in :attr:`Scenario.bodies` order (targets first)."""
    return [f"targets[{i}]" for i in range(len(scenario.targets))] + [
        f"obstacles[{i}]" for i in range(len(scenario.obstacles))
    ]


def check_layout(scenario: Scenario, times: Sequence[float] = (0.0,)) -> None:
    """The world's geometry (see the module docstring); ``ValueError`` naming the key if not.

    Args:
        scenario: a scenario whose values passed :func:`check_values`.
        times: instants (s) at which the bodies must be inside the bounds and apart. The dock
            must be clear at the first of them only: a body whose later path crosses the start
            is a legitimate test case.
    """
    low, high = scenario.low, scenario.high
    for axis, (lo, hi) in enumerate(scenario.bounds):
        size = hi - lo
        if not MIN_WORLD_SIZE <= size <= MAX_WORLD_COORDINATE:
            raise ValueError(
                f"bounds[{axis}] spans {size!r} m; allowed: "
                f"{_interval(MIN_WORLD_SIZE, MAX_WORLD_COORDINATE, 'm')} (the env's field_size "
                "range: rewards and observations are scaled by half the world size)"
            )
        if max(abs(lo), abs(hi)) > MAX_WORLD_COORDINATE:
            raise ValueError(
                f"bounds[{axis}]={[lo, hi]!r} m reaches beyond ±{MAX_WORLD_COORDINATE:g} m of the "
                "LVLH origin (the reference orbit), where the linear CWH model stops holding"
            )
    dock = np.asarray(scenario.dock, dtype=float)
    if np.any(dock <= low) or np.any(dock >= high):
        raise ValueError(
            f"dock={list(scenario.dock)!r} m must be strictly inside the bounds "
            f"{[list(b) for b in scenario.bounds]!r} m"
        )
    names = body_names(scenario)
    radii = np.array([b.radius for b in scenario.bodies])
    for k, t in enumerate(times):
        centres = np.asarray(scenario.body_positions(t), dtype=float)
        _check_inside(scenario, centres, radii, names, t)
        _check_apart(scenario, centres, radii, names, t)
        if k == 0:
            _check_dock_clear(scenario, dock, centres, radii, names)


def _at(t: float) -> str:
    return "" if t == 0.0 else f" at t = {t:g} s"


def _outline(scenario: Scenario, b: int, centre: np.ndarray) -> np.ndarray | None:
    """Polygon vertices of body ``b`` in world coordinates (m), or None for a circle / sphere."""
    vertices = scenario.bodies[b].vertices
    return None if vertices is None else centre + np.asarray(vertices, dtype=float)


def _check_inside(scenario, centres, radii, names, t) -> None:
    low, high = scenario.low, scenario.high
    lows, highs = centres - radii[:, None], centres + radii[:, None]
    for b in np.flatnonzero(np.any(lows < low, axis=1) | np.any(highs > high, axis=1)).tolist():
        outline = _outline(scenario, b, centres[b])
        if outline is not None and np.all(outline >= low) and np.all(outline <= high):
            continue  # the bounding circle sticks out, the polygon itself does not
        raise ValueError(
            f"{names[b]} (position {centres[b].tolist()!r} m, radius {radii[b].item()!r} m) is not "
            f"inside the bounds {[list(p) for p in scenario.bounds]!r} m{_at(t)}; every body must "
            "lie wholly inside them"
        )


def _check_apart(scenario, centres, radii, names, t) -> None:
    """No two bodies overlap (touching is allowed).

    Candidate pairs come from sweep and prune: bodies sorted by where their bounding box starts
    along the axis of widest spread, each paired with those that start before it ends (a few per
    body in a random field, so ~B log B work rather than B²); then bounding circles / spheres,
    then the exact shapes for the pairs those flag. At most :data:`_PAIR_BLOCK` · B candidates
    are held at once, whatever the layout.
    """
    count = len(radii)
    if count < 2:
        return
    axis = int(np.argmax(np.ptp(centres, axis=0)))
    order = np.argsort(centres[:, axis] - radii, kind="stable")
    starts = (centres[:, axis] - radii)[order]
    ends = (centres[:, axis] + radii)[order]
    last = np.searchsorted(starts, ends, side="left")  # sorted bodies k+1 .. last-1 may meet k
    pending = np.maximum(last - np.arange(count) - 1, 0)
    budget = _PAIR_BLOCK * count
    k = 0
    while k < count:
        stop = k + max(1, int(np.searchsorted(np.cumsum(pending[k:]), budget, side="right")))
        rows = np.arange(k, min(stop, count))
        n_pairs = pending[rows]
        first = np.repeat(rows, n_pairs)
        offset = np.arange(n_pairs.sum()) - np.repeat(np.cumsum(n_pairs) - n_pairs, n_pairs)
        a, b = order[first], order[first + 1 + offset]
        delta = centres[a] - centres[b]
        dist = np.sqrt(np.einsum("ij,ij->i", delta, delta))
        close = np.flatnonzero(dist < (radii[a] + radii[b]) * (1.0 - RELATIVE_TOLERANCE))
        for m in close[np.lexsort((b[close], a[close]))].tolist():  # report in index order
            i, j = sorted((int(a[m]), int(b[m])))
            if _shapes_overlap(scenario, i, j, centres, radii):
                raise ValueError(
                    f"{names[i]} and {names[j]} overlap{_at(t)} (centres "
                    f"{centres[i].tolist()!r} and {centres[j].tolist()!r} m, {dist[m]:.6g} m "
                    f"apart, radii {radii[i].item()!r} and {radii[j].item()!r} m); bodies must "
                    "not overlap"
                )
        k = rows[-1] + 1


def _shapes_overlap(scenario, a: int, b: int, centres, radii) -> bool:
    """Whether bodies ``a`` and ``b``, whose bounding circles overlap, overlap themselves."""
    pa, pb = _outline(scenario, a, centres[a]), _outline(scenario, b, centres[b])
    if pa is None and pb is None:
        return True
    if pa is None or pb is None:
        circle, poly = (a, b) if pa is None else (b, a)
        gap = _polygon_gap(scenario, poly, centres[circle], centres[poly])
        return gap < radii[circle] * (1.0 - RELATIVE_TOLERANCE)
    return not _separated(pa, pb)


def _edge_normals(poly: np.ndarray) -> np.ndarray:
    """Outward (unnormalised) normals of a counter-clockwise polygon's edges."""
    edges = np.roll(poly, -1, axis=0) - poly
    return np.column_stack([edges[:, 1], -edges[:, 0]])


def _separated(pa: np.ndarray, pb: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons; touching counts as separated."""
    size = max(float(np.abs(pa).max()), float(np.abs(pb).max()), 1.0)
    for normals in (_edge_normals(pa), _edge_normals(pb)):
        norm = np.hypot(normals[:, 0], normals[:, 1])[:, None]
        axes = normals / norm
        proj_a, proj_b = pa @ axes.T, pb @ axes.T
        gap = np.maximum(
            proj_b.min(axis=0) - proj_a.max(axis=0), proj_a.min(axis=0) - proj_b.max(axis=0)
        )
        if np.any(gap >= -RELATIVE_TOLERANCE * size):
            return True
    return False


def _polygon_gap(scenario: Scenario, b: int, point: np.ndarray, centre: np.ndarray) -> float:
    """Signed distance (m) from ``point`` to the polygon of body ``b`` placed at ``centre``,
    negative inside: the library's one geometry (:class:`~debris_gym.geometry.FieldGeometry`),
    the one the envs measure gaps with."""
    from debris_gym.geometry import FieldGeometry  # it imports Scenario, which imports this

    shift = centre - np.asarray(scenario.bodies[b].position, dtype=float)
    return float(FieldGeometry(scenario).signed_distance(point - shift)[b])


def check_dock_clear(scenario: Scenario, chaser_radius: float = 0.0) -> None:
    """The dock is more than ``chaser_radius`` (m) from every body at t = 0, else ``ValueError``.

    :func:`check_layout` asks for a dock outside every body (``chaser_radius`` 0): a scenario
    knows no chaser. An env that starts its chaser at the dock can ask for its own radius, so
    that a chaser of that size does not start (or end its mission) touching debris.
    """
    dock = np.asarray(scenario.dock, dtype=float)
    centres = np.asarray(scenario.body_positions(0.0), dtype=float)
    radii = np.array([b.radius for b in scenario.bodies])
    _check_dock_clear(scenario, dock, centres, radii, body_names(scenario), chaser_radius)


def _check_dock_clear(scenario, dock, centres, radii, names, chaser_radius=0.0) -> None:
    dist = np.sqrt(((centres - dock) ** 2).sum(axis=1))
    for b in np.flatnonzero(dist <= radii + chaser_radius).tolist():
        outline = _outline(scenario, b, centres[b])
        if outline is not None and _polygon_gap(scenario, b, dock, centres[b]) > chaser_radius:
            continue
        within = (
            f"within the chaser radius {chaser_radius!r} m of" if chaser_radius else "inside or on"
        )
        raise ValueError(
            f"dock={list(scenario.dock)!r} m is {within} {names[b]} (position "
            f"{centres[b].tolist()!r} m, radius {radii[b].item()!r} m); the dock must be clear of "
            "every body at t = 0 (the episode would start in collision)"
        )
