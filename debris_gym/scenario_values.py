"""The rules of single values in a scenario: numbers, vectors, polygons, and their limits.

Every function raises ``ValueError`` naming the key it is given (a path such as
``targets[2].radius``), the value and what is allowed. :mod:`debris_gym.scenario_checks` applies
them to whole scenarios; :class:`~debris_gym.body.Body` to one body's dict. Units are SI: m, s,
rad/s, m/s².
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from debris_gym.config import OPTIONS

__all__ = [
    "MAX_SPIN",
    "MAX_VERTICES",
    "MAX_WORLD_COORDINATE",
    "MIN_WORLD_SIZE",
    "MOTION_MODELS",
    "RELATIVE_TOLERANCE",
    "check_polygon",
    "interval",
    "known_keys",
    "mapping",
    "number",
    "pair",
    "polygon_shapes",
    "radius_matches",
    "sequence",
    "show",
    "vector",
]

MIN_WORLD_SIZE = float(OPTIONS["field_size"].limits()[0])
"""Shortest allowed edge of the world box (m), the env's smallest ``field_size``.

Rewards and observations are scaled by L = half the world's largest edge: in a world of a few
metres one step's progress term reaches thousands, and the env's default capture zone (5 m) is
larger than the world itself."""

MAX_WORLD_COORDINATE = float(OPTIONS["field_size"].limits()[1])
"""Largest allowed |bound| (m): the world lies within the env's largest ``field_size`` of the
LVLH origin (the reference orbit), where the linear CWH model holds."""

MOTION_MODELS = ("frozen", "cwh")
"""Debris motion models a scenario may declare: ``"frozen"`` (every body fixed in LVLH, the v0
world) and ``"cwh"`` (every body on unforced CWH motion from its ``velocity``, the v1 world)."""

MAX_SPIN = 1.0
"""Largest tumble rate |spin| (rad/s) of a body: a turn every 6 s, faster than any debris
tumble worth flying beside."""

MAX_VERTICES = 64
"""Most vertices of one polygon: a hand-modelled debris outline needs far fewer (generated ones
have 3 to 7); the bound keeps a pinned field's geometry, and the time to check it, bounded."""

RELATIVE_TOLERANCE = 1e-9
"""Rounding allowance of the geometric comparisons, relative to the lengths compared."""


def show(value: Any) -> str:
    """``repr(value)``, cut short (a 5 000-digit integer is still named, not printed whole)."""
    try:
        text = repr(value)
    except ValueError:  # an int past Python's digit limit for str(): name its size instead
        return f"an integer of about {int(value).bit_length() * 0.30103:.0f} digits"
    return text if len(text) <= 60 else text[:57] + "..."


def number(
    value: Any, key: str, *, low: float | None = None, high: float | None = None, unit: str = ""
) -> float:
    """``value`` as a finite float within ``[low, high]``, else ``ValueError`` naming ``key``.

    Booleans and strings are not numbers here (``"5"`` would otherwise pass as 5.0).
    """
    allowed = interval(low, high, unit)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{key} must be a number, got {show(value)}; allowed: {allowed}")
    try:
        out = float(value)
    except OverflowError:  # an int beyond float range
        out = math.inf
    if not math.isfinite(out):
        raise ValueError(f"{key} must be finite, got {show(value)}; allowed: {allowed}")
    if (low is not None and out < low) or (high is not None and out > high):
        raise ValueError(f"{key}={out!r}{_unit(unit)} is out of range; allowed: {allowed}")
    return out


def vector(value: Any, dim: int, key: str, unit: str = "m") -> tuple[float, ...]:
    """``value`` as ``dim`` finite floats, else ``ValueError`` naming ``key`` (or ``key[i]``)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{key} must be a list of {dim} numbers ({unit}), got {show(value)}")
    if len(value) != dim:
        raise ValueError(
            f"{key} must have {dim} components ({unit}), got {len(value)}: {show(value)}"
        )
    return tuple(number(v, f"{key}[{i}]", unit=unit) for i, v in enumerate(value))


def pair(value: Any, key: str, unit: str = "m") -> tuple[float, float]:
    """``value`` as two finite floats (a 2D point, a ``[low, high]`` range), else ``ValueError``
    naming ``key``."""
    first, second = vector(value, 2, key, unit)
    return first, second


def sequence(value: Any, key: str, what: str) -> list[Any] | tuple[Any, ...]:
    """``value`` if it is a list or tuple, else ``ValueError`` naming ``key``."""
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{key} must be a list of {what}, got {show(value)}")
    return value


def mapping(value: Any, key: str) -> Mapping[str, Any]:
    """``value`` if it is a dict whose keys are all strings, else ``ValueError`` naming ``key``
    (and the first key that is not a string: a JSON object's keys always are)."""
    if not isinstance(value, Mapping):
        raise ValueError(f"{key} must be a dict (a JSON object), got {type(value).__name__}")
    for name in value:
        if not isinstance(name, str):
            raise ValueError(
                f"{key} has a key {show(name)} of type {type(name).__name__}; keys must be "
                "strings (as in a JSON object)"
            )
    return value


def known_keys(
    value: Any,
    key: str,
    allowed: Sequence[str],
    *,
    also: str = "",
    unknown: str = "{key} has unknown key(s) {names}; allowed: {allowed}",
) -> Mapping[str, Any]:
    """``value`` if it is a dict whose keys are all in ``allowed``, else ``ValueError`` naming
    ``key`` and the allowed keys. ``also``: what else is accepted, appended to the message for
    a value that is not a dict (such as ``" or a MissionStart"``); ``unknown``: the message
    for keys outside ``allowed``, a template of ``{key}``, ``{names}`` (the unknown keys,
    sorted) and ``{allowed}``."""
    among = ", ".join(allowed)
    if not isinstance(value, Mapping):
        raise ValueError(
            f"{key} must be a dict with keys among {among}{also}, got {type(value).__name__}"
        )
    names = sorted(set(value) - set(allowed), key=str)
    if names:
        raise ValueError(unknown.format(key=key, names=names, allowed=among))
    return value


def interval(low: float | None, high: float | None, unit: str) -> str:
    """``[low, high] unit`` as the error messages write an allowed range."""
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

    Rules: 3 to :data:`MAX_VERTICES` finite vertices (m, relative to the body's position),
    strictly convex and counter-clockwise (every turn to the left), simple (the boundary winds
    once around: a pentagram turns left at every corner but winds twice), and, when ``radius``
    is given, equal to the vertices' circumradius about the position (their largest distance
    from it) within :data:`RELATIVE_TOLERANCE`.
    """
    if isinstance(vertices, np.ndarray):
        vertices = vertices.tolist()
    if not isinstance(vertices, (list, tuple)):
        raise ValueError(f"{key} must be a list of [x, y] vertices (m), got {show(vertices)}")
    if not 3 <= len(vertices) <= MAX_VERTICES:
        raise ValueError(
            f"{key} has {len(vertices)} vertices; allowed: 3 to {MAX_VERTICES} per polygon"
        )
    pts = tuple(pair(v, f"{key}[{k}]") for k, v in enumerate(vertices))
    xy = np.asarray(pts)
    left, turns, circumradius = polygon_shapes(xy, np.array([len(pts)]))
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
    if radius is not None and not radius_matches(np.array([radius]), circumradius)[0]:
        raise ValueError(
            f"{key.rsplit('.', 1)[0]}.radius={radius!r} m disagrees with the circumradius of "
            f"its vertices, {float(circumradius[0])!r} m (largest vertex distance from the "
            "position); give that value or leave radius out to derive it"
        )
    return pts


def polygon_shapes(xy: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, ...]:
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


def radius_matches(radius: np.ndarray, circumradius: np.ndarray) -> np.ndarray:
    """``math.isclose(radius, circumradius, rel_tol=RELATIVE_TOLERANCE)``, element-wise."""
    return np.abs(radius - circumradius) <= RELATIVE_TOLERANCE * np.maximum(
        np.abs(radius), np.abs(circumradius)
    )
