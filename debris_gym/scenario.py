"""The debris field as plain, frozen, JSON-serialisable data.

A :class:`Scenario` holds everything that defines one field: the world bounds, the dock, the
targets to rendezvous with, the other debris, and the physical parameters (mean motion, step
length, thrust limit). Generators that build random fields live in :mod:`debris_gym.generators`;
queries on the geometry live in :mod:`debris_gym.geometry`.

Units are SI throughout: positions in m, velocities in m/s, mean motion in rad/s, time in s,
acceleration in m/s².

Debris motion: wave-1 fields are *frozen* in the LVLH frame (``motion="frozen"``): every body keeps
its initial position. Under CWH that is exact only for n = 0 (or a body on the V-bar, x = 0); it is
the simplifying assumption of the source papers. :meth:`Scenario.body_positions` is the one place a
body's position at time t comes from, so natural CWH motion can be added without touching callers.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from debris_gym.files import write_atomic

MOTION_MODELS = ("frozen",)
"""Debris motion models a scenario may declare."""


def _vec(values: Sequence[float], dim: int, name: str) -> tuple[float, ...]:
    out = tuple(float(v) for v in values)
    if len(out) != dim:
        raise ValueError(f"{name} must have {dim} components, got {len(out)}")
    if not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name} must be finite, got {out}")
    return out


@dataclass(frozen=True)
class Body:
    """One piece of debris (a target or an obstacle).

    Attributes:
        position: centre (m), length ``dim``.
        radius: circle / sphere radius (m); for a polygon, its bounding (circum-)radius.
        velocity: initial velocity in LVLH (m/s); zero for frozen fields.
        vertices: 2D convex polygon vertices relative to ``position`` (m), counter-clockwise;
            ``None`` for a circle or sphere.
    """

    position: tuple[float, ...]
    radius: float
    velocity: tuple[float, ...] = ()
    vertices: tuple[tuple[float, float], ...] | None = None

    @property
    def is_polygon(self) -> bool:
        """True for a 2D convex polygon, False for a circle / sphere."""
        return self.vertices is not None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        out: dict[str, Any] = {
            "position": list(self.position),
            "radius": self.radius,
            "velocity": list(self.velocity),
        }
        if self.vertices is not None:
            out["vertices"] = [list(v) for v in self.vertices]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any], dim: int) -> Body:
        """Inverse of :meth:`to_dict`; validates shapes and values."""
        unknown = set(data) - {"position", "radius", "velocity", "vertices"}
        if unknown:
            raise ValueError(f"unknown body keys {sorted(unknown)}")
        position = _vec(data["position"], dim, "body position")
        velocity = _vec(data.get("velocity", [0.0] * dim), dim, "body velocity")
        vertices = data.get("vertices")
        if vertices is not None:
            if dim != 2:
                raise ValueError("polygon vertices are only allowed in 2D scenarios")
            vertices = tuple(_vec(v, 2, "polygon vertex") for v in vertices)
        radius = float(data["radius"]) if "radius" in data else _circumradius(vertices)
        return cls(position=position, radius=radius, velocity=velocity, vertices=vertices)


def _circumradius(vertices: Sequence[Sequence[float]] | None) -> float:
    if not vertices:
        raise ValueError("a body needs a radius or polygon vertices")
    return float(max(math.hypot(v[0], v[1]) for v in vertices))


def _validate_convex_ccw(vertices: tuple[tuple[float, float], ...]) -> None:
    pts = np.asarray(vertices)
    if len(pts) < 3:
        raise ValueError(f"a polygon needs at least 3 vertices, got {len(pts)}")
    edges = np.roll(pts, -1, axis=0) - pts
    cross = (
        edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, 0)[:, 0]
    )
    if not np.all(cross > 0):
        raise ValueError("polygon vertices must form a strictly convex, counter-clockwise polygon")


@dataclass(frozen=True)
class Scenario:
    """One debris field with its physical parameters.

    Attributes:
        dim: 2 (in-plane) or 3.
        bounds: per-axis ``(low, high)`` limits of the world (m); leaving them ends an episode.
        dock: dock position (m): where the chaser starts and, if required, returns.
        targets: debris to rendezvous with.
        obstacles: debris to avoid.
        mean_motion: reference-orbit mean motion n (rad/s); 0 is the double integrator.
        dt: decision step length (s).
        max_accel: thrust limit (m/s²) per axis ("box") or in norm ("ball").
        motion: debris motion model; ``"frozen"`` (fixed in LVLH) is the only one.
        name: free-form label, e.g. the preset or generator it came from.
    """

    dim: int
    bounds: tuple[tuple[float, float], ...]
    dock: tuple[float, ...]
    targets: tuple[Body, ...]
    obstacles: tuple[Body, ...] = ()
    mean_motion: float = 0.0
    dt: float = 1.0
    max_accel: float = 1.0
    motion: str = "frozen"
    name: str = ""
    _cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False, hash=False)

    def __post_init__(self) -> None:
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {self.dim!r}")
        if len(self.bounds) != self.dim or any(lo >= hi for lo, hi in self.bounds):
            raise ValueError(f"bounds must be {self.dim} (low, high) pairs with low < high")
        _vec(self.dock, self.dim, "dock")
        if not self.targets:
            raise ValueError("a scenario needs at least one target")
        for kind, bodies in (("target", self.targets), ("obstacle", self.obstacles)):
            for i, body in enumerate(bodies):
                _vec(body.position, self.dim, f"{kind} {i} position")
                if len(body.velocity) not in (0, self.dim):
                    raise ValueError(f"{kind} {i} velocity must have {self.dim} components")
                if not (math.isfinite(body.radius) and body.radius > 0):
                    raise ValueError(f"{kind} {i} radius must be > 0 m, got {body.radius}")
                if body.vertices is not None:
                    if self.dim != 2:
                        raise ValueError(f"{kind} {i}: polygons are only allowed in 2D")
                    _validate_convex_ccw(body.vertices)
                if self.motion == "frozen" and any(v != 0.0 for v in body.velocity):
                    raise ValueError(f"{kind} {i}: a frozen field needs zero body velocities")
        for i, t in enumerate(self.targets):
            if t.vertices is not None:
                raise ValueError(f"target {i}: targets must be circles or spheres")
        if not (math.isfinite(self.mean_motion) and self.mean_motion >= 0):
            raise ValueError(f"mean_motion must be >= 0 rad/s, got {self.mean_motion!r}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be > 0 s, got {self.dt!r}")
        if not (math.isfinite(self.max_accel) and self.max_accel > 0):
            raise ValueError(f"max_accel must be > 0 m/s², got {self.max_accel!r}")
        if self.motion not in MOTION_MODELS:
            raise ValueError(f"motion must be one of {MOTION_MODELS}, got {self.motion!r}")

    # --- derived data -------------------------------------------------------------------------

    @property
    def bodies(self) -> tuple[Body, ...]:
        """Targets first, then obstacles: the index order every geometry query uses."""
        return self.targets + self.obstacles

    @property
    def low(self) -> np.ndarray:
        """Lower world bound per axis (m)."""
        return np.array([lo for lo, _ in self.bounds])

    @property
    def high(self) -> np.ndarray:
        """Upper world bound per axis (m)."""
        return np.array([hi for _, hi in self.bounds])

    @property
    def size(self) -> float:
        """Largest extent of the world (m)."""
        return float(np.max(self.high - self.low))

    def body_positions(self, t: float = 0.0) -> np.ndarray:
        """Centres (m) of all bodies (targets first) at time ``t`` (s), shape (n_bodies, dim).

        The single source of body motion. For ``motion="frozen"`` bodies stay where they are.
        """
        del t  # frozen: positions do not depend on time
        cached = self._cache.get("positions")
        if cached is None:
            cached = np.array([b.position for b in self.bodies], dtype=float)
            cached.setflags(write=False)
            self._cache["positions"] = cached
        return cached

    # --- serialisation ------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (lists and numbers only)."""
        return {
            "dim": self.dim,
            "bounds": [list(b) for b in self.bounds],
            "dock": list(self.dock),
            "targets": [b.to_dict() for b in self.targets],
            "obstacles": [b.to_dict() for b in self.obstacles],
            "mean_motion": self.mean_motion,
            "dt": self.dt,
            "max_accel": self.max_accel,
            "motion": self.motion,
            "name": self.name,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scenario:
        """Build and validate a scenario from :meth:`to_dict` output (or hand-written JSON)."""
        known = {
            "dim",
            "bounds",
            "dock",
            "targets",
            "obstacles",
            "mean_motion",
            "dt",
            "max_accel",
            "motion",
            "name",
        }
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown scenario keys {sorted(unknown)}; allowed: {sorted(known)}")
        dim = data["dim"]
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {dim!r}")
        return cls(
            dim=dim,
            bounds=tuple((float(lo), float(hi)) for lo, hi in data["bounds"]),
            dock=_vec(data["dock"], dim, "dock"),
            targets=tuple(Body.from_dict(b, dim) for b in data["targets"]),
            obstacles=tuple(Body.from_dict(b, dim) for b in data.get("obstacles", [])),
            mean_motion=float(data.get("mean_motion", 0.0)),
            dt=float(data.get("dt", 1.0)),
            max_accel=float(data.get("max_accel", 1.0)),
            motion=str(data.get("motion", "frozen")),
            name=str(data.get("name", "")),
        )

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the scenario as JSON, atomically (a crash never leaves a half-written file)."""
        write_atomic(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scenario:
        """Read a scenario written by :meth:`save`."""
        with open(path) as fh:
            return cls.from_dict(json.load(fh))


def as_scenario(value: Scenario | dict[str, Any] | str | os.PathLike[str]) -> Scenario:
    """Accept a Scenario, its dict form, or a path to its JSON file."""
    if isinstance(value, Scenario):
        return value
    if isinstance(value, dict):
        return Scenario.from_dict(value)
    if isinstance(value, (str, os.PathLike)):
        return Scenario.load(value)
    raise TypeError(f"scenario must be a Scenario, dict or path, got {type(value).__name__}")
