"""The rules a debris field must satisfy: the one place scenarios are checked.

Three levels, each raising ``ValueError`` that names the offending key (as a path such as
``targets[2].radius`` or ``obstacles[0].vertices``), its value and what is allowed:

* :func:`check_values` — every value on its own, run by ``Scenario.__post_init__`` (so on every
  construction, the generators' too; O(bodies · vertices)): types and shapes, finite numbers,
  radii, convex polygons, body counts, and the physical parameters inside the env's option
  ranges (:data:`debris_gym.config.OPTIONS`). The single values' rules are
  :mod:`debris_gym.scenario_values`.
* :func:`check_layout` — the geometry of the world at t = 0, run when a scenario comes from
  outside the library (``Scenario.from_dict`` / ``load`` and
  :func:`debris_gym.scenario.as_scenario`, the entry of every pinned field into an env): world
  size, every body inside the bounds, no two bodies overlapping, the dock inside the bounds and
  clear of every body, and in a moving field every body's speed within
  :func:`max_body_speed`.
* the motion over an episode, :mod:`debris_gym.horizon_checks`, when an env pins a moving
  field.

Units are SI: m, s, rad/s, m/s². ``docs/validation.md`` ("Scenarios") lists every rule.
"""

from __future__ import annotations

import itertools
import numbers
from typing import Any, Protocol

import numpy as np

from debris_gym.body import Body
from debris_gym.config import OPTIONS
from debris_gym.scenario_values import (
    MAX_SPIN,
    MAX_VERTICES,
    MAX_WORLD_COORDINATE,
    MIN_WORLD_SIZE,
    MOTION_MODELS,
    RELATIVE_TOLERANCE,
    check_polygon,
    interval,
    number,
    polygon_shapes,
    radius_matches,
    vector,
)
from debris_gym.sweep_prune import overlapping_intervals

__all__ = [
    "BODY_COUNTS",
    "MAX_SPIN",
    "MAX_VERTICES",
    "MAX_WORLD_COORDINATE",
    "MIN_WORLD_SIZE",
    "MOTION_MODELS",
    "ScenarioFields",
    "body_names",
    "check_count",
    "check_dock_clear",
    "check_layout",
    "check_polygon",
    "check_values",
    "max_body_speed",
    "number",
    "vector",
]

BODY_COUNTS = {"targets": "n_targets", "obstacles": "n_obstacles"}
"""Body list → the env option whose range bounds its length (:func:`check_count`)."""

_PAIR_BLOCK = 256
"""Bodies per block of the pairwise overlap test (bounds its temporaries to ~B · 256 numbers)."""


class ScenarioFields(Protocol):
    """What the rules read of a scenario: :class:`debris_gym.scenario.Scenario` is one (that
    module imports this one, so the rules name the fields they read rather than the class)."""

    @property
    def dim(self) -> int: ...
    @property
    def bounds(self) -> tuple[tuple[float, float], ...]: ...
    @property
    def dock(self) -> tuple[float, ...]: ...
    @property
    def targets(self) -> tuple[Body, ...]: ...
    @property
    def obstacles(self) -> tuple[Body, ...]: ...
    @property
    def mean_motion(self) -> float: ...
    @property
    def dt(self) -> float: ...
    @property
    def max_accel(self) -> float: ...
    @property
    def motion(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def bodies(self) -> tuple[Body, ...]: ...
    @property
    def low(self) -> np.ndarray: ...
    @property
    def high(self) -> np.ndarray: ...
    @property
    def size(self) -> float: ...
    def body_positions(self, t: float = 0.0) -> np.ndarray: ...


# --- the whole scenario, value by value ---------------------------------------------------------


def check_count(kind: str, count: int) -> None:
    """``count`` bodies in the list ``kind`` ("targets" or "obstacles") are allowed, else
    ``ValueError`` naming the list and the env option that bounds it (checked before a single
    body is built)."""
    option = BODY_COUNTS[kind]
    opt = OPTIONS[option]
    low, high = opt.limits()
    if not low <= count <= high:
        raise ValueError(
            f"{kind} has {count} bodies; allowed: {opt.describe()} (the env's {option})"
        )


def check_values(scenario: ScenarioFields) -> None:
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
    for kind in BODY_COUNTS:
        bodies = getattr(scenario, kind)
        if not isinstance(bodies, tuple):
            raise ValueError(f"{kind} must be a tuple of Body, got {type(bodies).__name__}")
        check_count(kind, len(bodies))
    if not _bodies_pass(scenario):  # the fast screen found something: find and name it
        radius_min = {"targets": "target_radius_min", "obstacles": "obstacle_radius_min"}
        for kind in BODY_COUNTS:
            min_radius = float(OPTIONS[radius_min[kind]].limits()[0])
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


def _option(key: str, value: Any) -> float:
    """A scenario value checked against the env option ``key`` of :data:`OPTIONS`."""
    opt = OPTIONS[key]
    return number(value, key, low=opt.low, high=opt.high, unit=opt.unit)


_PLAIN = (float, int)
"""Number types the fast screen accepts as they are (``bool`` is a type of its own here)."""


def _plain(values: Any) -> bool:
    return all(type(v) in _PLAIN for v in values)


def _bodies_pass(scenario: ScenarioFields) -> bool:
    """Whether every body passes :func:`_check_body`, checked as arrays (a random field's
    thousands of bodies are built on every reset). True only if every rule holds; False sends
    :func:`check_values` through the bodies one by one, which names the first fault (and
    accepts what this screen left to it, such as numpy scalars)."""
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


def _body_arrays_pass(
    scenario: ScenarioFields, positions: list, velocities: list, radii: list
) -> bool:
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
        OPTIONS["target_radius_min"].limits()[0],
        OPTIONS["obstacle_radius_min"].limits()[0],
    )
    r = np.array(radii, dtype=float)
    if not (np.isfinite(r).all() and np.all(r >= low)):
        return False
    polygons = [b for b in scenario.obstacles if b.vertices is not None]
    if not polygons:
        return True
    if dim != 2:
        return False
    shapes = [b.vertices for b in polygons if b.vertices is not None]
    counts = np.array([len(v) for v in shapes])
    if not (
        all(type(v) is tuple for v in shapes)
        and np.all(counts >= 3)
        and np.all(counts <= MAX_VERTICES)
        and all(type(p) is tuple and len(p) == 2 for v in shapes for p in v)
        and _plain(itertools.chain.from_iterable(itertools.chain.from_iterable(shapes)))
    ):
        return False
    xy = np.array(list(itertools.chain.from_iterable(shapes)), dtype=float)
    if not np.isfinite(xy).all():
        return False
    first, turns, circumradius = polygon_shapes(xy, counts)
    radius = np.array([b.radius for b in polygons], dtype=float)
    matches = radius_matches(radius, circumradius)
    return bool(np.all(first == counts) and np.all(turns == 1) and matches.all())


def _check_body(body: Any, dim: int, key: str, min_radius: float, motion: str) -> None:
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


def body_names(scenario: ScenarioFields) -> list[str]:
    """Key path of every body in :attr:`Scenario.bodies` order (targets first)."""
    return [f"targets[{i}]" for i in range(len(scenario.targets))] + [
        f"obstacles[{i}]" for i in range(len(scenario.obstacles))
    ]


def max_body_speed(scenario: ScenarioFields) -> float:
    """Fastest a body of a moving field may be (m/s): the world's size per step (size / dt, the
    chaser's own limit: faster, it crosses the world in one step), or, about a fast orbit,
    2·n·size, twice the speed of the widest relative orbit that fits in the world (so every
    field the generators draw passes), whichever is larger."""
    return max(scenario.size / scenario.dt, 2.0 * scenario.mean_motion * scenario.size)


def check_layout(scenario: ScenarioFields) -> None:
    """The world's geometry at t = 0 and the bodies' speeds (see the module docstring);
    ``ValueError`` naming the key if not.

    Args:
        scenario: a scenario whose values passed :func:`check_values`.
    """
    low, high = scenario.low, scenario.high
    for axis, (lo, hi) in enumerate(scenario.bounds):
        size = hi - lo
        if not MIN_WORLD_SIZE <= size <= MAX_WORLD_COORDINATE:
            raise ValueError(
                f"bounds[{axis}] spans {size!r} m; allowed: "
                f"{interval(MIN_WORLD_SIZE, MAX_WORLD_COORDINATE, 'm')} (the env's field_size "
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
    centres = np.asarray(scenario.body_positions(0.0), dtype=float)
    _check_inside(scenario, centres, radii, names)
    _check_apart(scenario, centres, radii, names)
    _check_dock_clear(scenario, dock, centres, radii, names)
    if scenario.motion == "cwh":
        _check_speeds(scenario, names)


def _check_speeds(scenario: ScenarioFields, names: list[str]) -> None:
    """Every body's speed is at most :func:`max_body_speed`: with it, no reward term, contact
    test or observation meets a body that jumps across the world between two step ends."""
    limit = max_body_speed(scenario)
    velocities = np.array(
        [b.velocity if b.velocity else (0.0,) * scenario.dim for b in scenario.bodies],
        dtype=float,
    ).reshape(-1, scenario.dim)
    scale = np.abs(velocities).max(axis=1, initial=0.0)
    safe = np.where(scale > 0.0, scale, 1.0)
    speeds = scale * np.sqrt(((velocities / safe[:, None]) ** 2).sum(axis=1))  # no overflow
    fast = np.flatnonzero(~(speeds <= limit))
    if fast.size:
        b = int(fast[0])
        raise ValueError(
            f"{names[b]}.velocity={velocities[b].tolist()!r} m/s (speed {speeds[b]:.6g} m/s) is "
            f"too fast; allowed: speed <= {limit:.6g} m/s (max(size / dt, 2·n·size): the world's "
            f"size {scenario.size:g} m per step of {scenario.dt:g} s)"
        )


def _check_inside(scenario, centres, radii, names) -> None:
    low, high = scenario.low, scenario.high
    lows, highs = centres - radii[:, None], centres + radii[:, None]
    for b in np.flatnonzero(np.any(lows < low, axis=1) | np.any(highs > high, axis=1)).tolist():
        outline = _outline(scenario, b)
        if outline is not None and np.all(outline >= low) and np.all(outline <= high):
            continue  # the bounding circle sticks out, the polygon itself does not
        raise ValueError(
            f"{names[b]} (position {centres[b].tolist()!r} m, radius {radii[b].item()!r} m) is not "
            f"inside the bounds {[list(p) for p in scenario.bounds]!r} m; every body must lie "
            "wholly inside them"
        )


def _outline(scenario: ScenarioFields, b: int) -> np.ndarray | None:
    """Polygon vertices of body ``b`` in world coordinates at t = 0 (m), or None for a circle /
    sphere."""
    body = scenario.bodies[b]
    if body.vertices is None:
        return None
    return np.asarray(body.position, dtype=float) + np.asarray(body.vertices, dtype=float)


def _check_apart(scenario, centres, radii, names) -> None:
    """No two bodies overlap (touching is allowed).

    Candidate pairs come from sweep and prune: bodies sorted by where their bounding box starts
    along the axis of widest spread, each paired with those that start before it ends (a few per
    body in a random field, so ~B log B work rather than B²); then bounding circles / spheres,
    then the exact shapes for the pairs those flag. At most :data:`_PAIR_BLOCK` · B candidates
    are held at once, whatever the layout.
    """
    for i, j, dist in close_pairs(centres, radii):
        if _shapes_overlap(scenario, i, j, centres, radii):
            raise ValueError(
                f"{names[i]} and {names[j]} overlap (centres {centres[i].tolist()!r} and "
                f"{centres[j].tolist()!r} m, {dist:.6g} m apart, radii {radii[i].item()!r} and "
                f"{radii[j].item()!r} m); bodies must not overlap"
            )


def close_pairs(centres: np.ndarray, radii: np.ndarray):
    """Yield ``(i, j, distance)`` (i < j, ascending) for every pair of balls (centres (B, dim)
    and radii (B,), m) that overlap by more than rounding, found by sweep and prune."""
    count = len(radii)
    if count < 2:
        return
    axis = int(np.argmax(np.ptp(centres, axis=0)))
    starts, ends = centres[:, axis] - radii, centres[:, axis] + radii
    for a, b in overlapping_intervals(starts, ends, _PAIR_BLOCK * count, touching=False):
        delta = centres[a] - centres[b]
        dist = np.sqrt(np.einsum("ij,ij->i", delta, delta))
        close = np.flatnonzero(dist < (radii[a] + radii[b]) * (1.0 - RELATIVE_TOLERANCE))
        for m in close[np.lexsort((b[close], a[close]))].tolist():  # report in index order
            i, j = sorted((int(a[m]), int(b[m])))
            yield i, j, float(dist[m])


def _shapes_overlap(scenario, a: int, b: int, centres, radii) -> bool:
    """Whether bodies ``a`` and ``b``, whose bounding circles overlap, overlap themselves."""
    pa, pb = _outline(scenario, a), _outline(scenario, b)
    if pa is None and pb is None:
        return True
    if pa is None or pb is None:
        circle, poly = (a, b) if pa is None else (b, a)
        gap = _polygon_gap(scenario, poly, centres[circle])
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


def _polygon_gap(scenario: ScenarioFields, b: int, point: np.ndarray) -> float:
    """Signed distance (m) from ``point`` to the polygon of body ``b`` at t = 0, negative
    inside: the library's one geometry (:class:`~debris_gym.batch_geometry.FieldBatch`), the one
    the envs measure gaps with."""
    # imported here, not at the top: compiled code (numba) is loaded only when a polygon is
    # checked, so that `import debris_gym` stays free of it
    from debris_gym.batch_geometry import FieldBatch

    body = scenario.bodies[b]
    vertices = np.asarray(body.vertices, dtype=float)
    row = np.zeros(1, dtype=np.int64)
    batch = FieldBatch(1, 1, 2, max_vertices=len(vertices))
    batch.load_arrays(
        row,
        np.asarray(body.position, dtype=float).reshape(1, 1, 2),
        np.array([[body.radius]]),
        vertices[None, None],
        np.array([[len(vertices)]]),
    )
    return float(batch.gaps(np.reshape(point, (1, 2)), row)[0, 0])


def check_dock_clear(scenario: ScenarioFields, chaser_radius: float = 0.0) -> None:
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
        if scenario.bodies[b].vertices is not None and (
            _polygon_gap(scenario, b, dock) > chaser_radius
        ):
            continue
        within = (
            f"within the chaser radius {chaser_radius!r} m of" if chaser_radius else "inside or on"
        )
        raise ValueError(
            f"dock={list(scenario.dock)!r} m is {within} {names[b]} (position "
            f"{centres[b].tolist()!r} m, radius {radii[b].item()!r} m); the dock must be clear of "
            "every body at t = 0 (the episode would start in collision)"
        )
