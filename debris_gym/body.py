"""One piece of debris, a target or an obstacle, as plain frozen data (:class:`Body`).

A :class:`~debris_gym.scenario.Scenario` holds its bodies; this module is below it so that the
rules of a scenario (:mod:`debris_gym.scenario_checks`) can name the type they check. Positions
in m, velocities in m/s, spin in rad/s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from debris_gym.scenario_values import check_polygon, mapping, number, vector

__all__ = ["BODY_KEYS", "Body"]

BODY_KEYS = ("position", "radius", "velocity", "vertices", "spin")
"""Keys of one body's dict; ``position`` always, ``radius`` unless ``vertices`` give it."""


@dataclass(frozen=True)
class Body:
    """One piece of debris (a target or an obstacle).

    Attributes:
        position: centre (m), length ``dim``.
        radius: circle / sphere radius (m); for a polygon, its bounding (circum-)radius.
        velocity: initial velocity in LVLH (m/s) at t = 0; zero for frozen fields.
        vertices: 2D convex polygon vertices relative to ``position`` (m), counter-clockwise,
            at t = 0; ``None`` for a circle or sphere.
        spin: tumble rate (rad/s, counter-clockwise) of the body's attitude in the inertial
            frame; 0 keeps it inertially fixed. Turns 2D polygons only; 0 in frozen fields.
    """

    position: tuple[float, ...]
    radius: float
    velocity: tuple[float, ...] = ()
    vertices: tuple[tuple[float, float], ...] | None = None
    spin: float = 0.0

    @property
    def is_polygon(self) -> bool:
        """True for a 2D convex polygon, False for a circle / sphere."""
        return self.vertices is not None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        out: dict[str, Any] = {
            "position": list(self.position),
            "radius": self.radius,
            # a body built without a velocity is at rest: written as zeros, which from_dict reads
            "velocity": list(self.velocity) if self.velocity else [0.0] * len(self.position),
        }
        if self.vertices is not None:
            out["vertices"] = [list(v) for v in self.vertices]
        if self.spin:
            out["spin"] = self.spin
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], dim: int, key: str = "body") -> Body:
        """Inverse of :meth:`to_dict`; ``key`` (e.g. ``"targets[2]"``) prefixes error messages.

        ``radius`` may be left out of a polygon's dict: it is then the vertices' circumradius.

        Raises:
            ValueError: a missing, unknown or wrong-typed key, named as ``key.name``.
        """
        data = mapping(data, key)
        unknown = sorted(set(data) - set(BODY_KEYS))
        if unknown:
            raise ValueError(f"{key} has unknown keys {unknown}; allowed: {list(BODY_KEYS)}")
        if "position" not in data:
            raise ValueError(f"{key}.position is missing (the body's centre, {dim} numbers in m)")
        position = vector(data["position"], dim, f"{key}.position")
        velocity = vector(data.get("velocity", [0.0] * dim), dim, f"{key}.velocity", "m/s")
        radius = number(data["radius"], f"{key}.radius", unit="m") if "radius" in data else None
        vertices = data.get("vertices")
        if vertices is not None:
            if dim != 2:
                raise ValueError(f"{key}.vertices: polygons are only allowed in 2D scenarios")
            vertices = check_polygon(vertices, radius, f"{key}.vertices")
            if radius is None:
                radius = float(max(math.hypot(x, y) for x, y in vertices))
        if radius is None:
            raise ValueError(f"{key}.radius is missing (a circle or sphere needs its radius in m)")
        spin = number(data.get("spin", 0.0), f"{key}.spin", unit="rad/s")
        return cls(
            position=position, radius=radius, velocity=velocity, vertices=vertices, spin=spin
        )
