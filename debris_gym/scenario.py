"""The debris field as plain, frozen, JSON-serialisable data.

A :class:`Scenario` holds everything that defines one field: the world bounds, the dock, the
targets to rendezvous with, the other debris, and the physical parameters (mean motion, step
length, thrust limit). Generators that build random fields live in :mod:`debris_gym.generators`;
queries on the geometry live in :mod:`debris_gym.geometry`.

Units are SI throughout: positions in m, velocities in m/s, mean motion in rad/s, time in s,
acceleration in m/s².

Debris motion (``Scenario.motion``): in a ``"cwh"`` field (the v1 world) every body moves on
unforced CWH motion from its initial LVLH state (``position``, ``velocity``), propagated exactly
with the state-transition matrix, and a 2D polygon keeps an inertially fixed attitude (it turns at
−n in LVLH) plus its own tumble rate ``spin``. In a ``"frozen"`` field (the v0 world) every body
keeps its initial position, which under CWH is exact only for n = 0 or a body at rest on the V-bar
(x = 0). :meth:`Scenario.body_states` and :meth:`Scenario.body_angles` are the one place a body's
state and attitude at time t come from.

Checks (:mod:`debris_gym.scenario_checks`, listed in ``docs/validation.md``): every value is
checked when a :class:`Scenario` is built; the layout of the world (size, bodies inside the bounds
and apart, the dock clear) when a scenario comes from outside the library — :meth:`from_dict`,
:meth:`load` and :func:`as_scenario`, through which every pinned field enters an env.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from debris_gym.dynamics import discretize
from debris_gym.files import write_atomic
from debris_gym.scenario_checks import (
    MOTION_MODELS,
    check_layout,
    check_polygon,
    check_values,
    number,
    vector,
)

__all__ = ["MOTION_MODELS", "Body", "Scenario", "as_scenario"]

REQUIRED_KEYS = ("dim", "bounds", "dock", "targets", "mean_motion", "dt", "max_accel")
"""Keys a scenario dict / JSON file must have: the physical parameters too, since a saved field is
flown with its own physics (an absent ``dt`` must not silently mean 1 s)."""

OPTIONAL_KEYS = {"obstacles": (), "motion": "frozen", "name": ""}
"""Keys a scenario dict may leave out, with the value they then take."""

BODY_KEYS = ("position", "radius", "velocity", "vertices", "spin")
"""Keys of one body's dict; ``position`` always, ``radius`` unless ``vertices`` give it."""


def _sequence(value: Any, key: str, what: str) -> list[Any] | tuple[Any, ...]:
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{key} must be a list of {what}, got {value!r}")
    return value


def _mapping(value: Any, key: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ValueError(f"{key} must be a dict (a JSON object), got {type(value).__name__}")
    return value


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
        data = _mapping(data, key)
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
        motion: debris motion model: ``"cwh"`` (unforced CWH motion, the v1 world) or
            ``"frozen"`` (fixed in LVLH, the v0 world); see the module docstring.
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
    # derived data, fresh for every object (init=False: dataclasses.replace must not share it)
    _cache: dict[str, Any] = field(
        default_factory=dict, init=False, compare=False, repr=False, hash=False
    )

    def __post_init__(self) -> None:
        check_values(self)

    def check_layout(self) -> Scenario:
        """Check the world's geometry (bounds, bodies inside and apart, dock clear); return self.

        Every scenario from outside the library passes here (:meth:`from_dict`, :meth:`load`,
        :func:`as_scenario`); the rules are in :mod:`debris_gym.scenario_checks`. The result is
        remembered per object, so pinning the same scenario on every reset checks it once.

        Raises:
            ValueError: naming the offending key, its value and what is allowed.
        """
        if not self._cache.get("layout_checked"):
            check_layout(self)
            self._cache["layout_checked"] = True
        return self

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

    @property
    def moving(self) -> bool:
        """True when the bodies move (``motion="cwh"``)."""
        return self.motion == "cwh"

    def initial_body_states(self) -> np.ndarray:
        """(n_bodies, 2·dim) position (m) and velocity (m/s) of every body at t = 0, targets
        first (read-only; velocities zero in a frozen field)."""
        cached = self._cache.get("states")
        if cached is None:
            dim = self.dim
            cached = np.zeros((len(self.bodies), 2 * dim))
            for b, body in enumerate(self.bodies):
                cached[b, :dim] = body.position
                if body.velocity and self.moving:
                    cached[b, dim:] = body.velocity
            cached.setflags(write=False)
            self._cache["states"] = cached
        return cached

    def body_states(self, t: float = 0.0) -> np.ndarray:
        """(n_bodies, 2·dim) position (m) and velocity (m/s) of every body at time ``t`` (s).

        The single source of body motion: exact unforced CWH motion for ``motion="cwh"``
        (the state-transition matrix of :func:`debris_gym.dynamics.discretize`), the initial
        positions at rest for ``"frozen"``.
        """
        states = self.initial_body_states()
        if t == 0.0 or not self.moving:
            return states
        return states @ discretize(self.mean_motion, float(t), self.dim).ad.T

    def body_positions(self, t: float = 0.0) -> np.ndarray:
        """Centres (m) of all bodies (targets first) at time ``t`` (s), shape (n_bodies, dim)."""
        if t == 0.0 or not self.moving:
            cached = self._cache.get("positions")
            if cached is None:
                cached = np.array([b.position for b in self.bodies], dtype=float)
                cached.setflags(write=False)
                self._cache["positions"] = cached
            return cached
        return self.body_states(t)[:, : self.dim]

    def body_rates(self) -> np.ndarray:
        """(n_bodies,) turn rate (rad/s) of every body's attitude in LVLH: ``spin − n`` (an
        inertially fixed body turns at −n in the rotating frame); 0 in a frozen field."""
        if not self.moving:
            return np.zeros(len(self.bodies))
        return np.array([b.spin for b in self.bodies], dtype=float) - self.mean_motion

    def body_angles(self, t: float = 0.0) -> np.ndarray:
        """(n_bodies,) angle (rad, counter-clockwise) each body has turned through in LVLH
        since t = 0: polygon ``b`` at time ``t`` is its ``vertices`` rotated by it."""
        return self.body_rates() * float(t)

    def body_vertices(self, b: int, t: float = 0.0) -> np.ndarray | None:
        """Polygon ``b``'s vertices (m, world coordinates) at time ``t`` (s), or None for a
        circle / sphere."""
        vertices = self.bodies[b].vertices
        if vertices is None:
            return None
        angle = float(self.body_angles(t)[b])
        c, s = math.cos(angle), math.sin(angle)
        rel = np.asarray(vertices, dtype=float) @ np.array([[c, s], [-s, c]])
        return self.body_positions(t)[b] + rel

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
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """Build and check a scenario from :meth:`to_dict` output (or hand-written JSON).

        Required keys: :data:`REQUIRED_KEYS`; optional: :data:`OPTIONAL_KEYS`. Runs every rule of
        :mod:`debris_gym.scenario_checks`, values and layout.

        Raises:
            ValueError: naming the missing, unknown or invalid key (e.g. ``targets[2].radius``).
        """
        data = _mapping(data, "scenario")
        unknown = sorted(set(data) - set(REQUIRED_KEYS) - set(OPTIONAL_KEYS))
        if unknown:
            allowed = sorted([*REQUIRED_KEYS, *OPTIONAL_KEYS])
            raise ValueError(f"unknown scenario keys {unknown}; allowed: {allowed}")
        missing = [k for k in REQUIRED_KEYS if k not in data]
        if missing:
            raise ValueError(
                f"scenario is missing key(s) {missing}; required: {list(REQUIRED_KEYS)} (a "
                "scenario is flown with its own mean_motion, dt and max_accel, so they must be "
                "given)"
            )
        dim = data["dim"]
        if isinstance(dim, bool) or not isinstance(dim, int) or dim not in (2, 3):
            raise ValueError(f"dim must be the integer 2 or 3, got {dim!r}")
        bounds = _sequence(data["bounds"], "bounds", f"{dim} [low, high] pairs (m)")
        if len(bounds) != dim:
            raise ValueError(f"bounds must be dim={dim} [low, high] pairs (m), got {len(bounds)}")
        bodies = {}
        for kind in ("targets", "obstacles"):
            items = _sequence(data.get(kind, ()), kind, "body dicts")
            bodies[kind] = tuple(
                Body.from_dict(b, dim, f"{kind}[{i}]") for i, b in enumerate(items)
            )
        for key in ("motion", "name"):
            if not isinstance(data.get(key, ""), str):
                raise ValueError(f"{key} must be a string, got {data[key]!r}")
        scenario = cls(
            dim=dim,
            bounds=tuple(vector(pair, 2, f"bounds[{a}]") for a, pair in enumerate(bounds)),
            dock=vector(data["dock"], dim, "dock"),
            targets=bodies["targets"],
            obstacles=bodies["obstacles"],
            mean_motion=number(data["mean_motion"], "mean_motion", unit="rad/s"),
            dt=number(data["dt"], "dt", unit="s"),
            max_accel=number(data["max_accel"], "max_accel", unit="m/s²"),
            motion=data.get("motion", OPTIONAL_KEYS["motion"]),
            name=data.get("name", OPTIONAL_KEYS["name"]),
        )
        return scenario.check_layout()

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the scenario as JSON, atomically (a crash never leaves a half-written file)."""
        write_atomic(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scenario:
        """Read and check a scenario written by :meth:`save` (or by hand).

        Raises:
            ValueError: the file is not UTF-8 JSON (naming the file, line and column) or its
                scenario breaks a rule (naming the file and the key).
            OSError: the file cannot be read.
        """
        name = os.fspath(path)
        with open(path, encoding="utf-8") as fh:
            try:
                text = fh.read()
            except UnicodeDecodeError as exc:
                raise ValueError(f"scenario file {name!r} is not UTF-8 text: {exc}") from exc
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(
                f"scenario file {name!r} is not valid JSON: {exc.msg} at line "
                f"{exc.lineno}, column {exc.colno}"
            ) from exc
        except RecursionError as exc:
            raise ValueError(f"scenario file {name!r} nests too deeply") from exc
        try:
            return cls.from_dict(data)
        except ValueError as exc:
            raise ValueError(f"scenario file {name!r}: {exc}") from exc


def as_scenario(value: Scenario | Mapping[str, Any] | str | os.PathLike[str]) -> Scenario:
    """Accept a Scenario, its dict form, or a path to its JSON file; every rule is checked.

    This is how a pinned field enters an env (``reset(options={"scenario": ...})``), so a
    hand-built :class:`Scenario` gets its layout checked here too.

    Raises:
        ValueError: ``value`` is none of those, or breaks a rule (naming the key).
    """
    if isinstance(value, Scenario):
        return value.check_layout()
    if isinstance(value, Mapping):
        return Scenario.from_dict(value)
    if isinstance(value, (str, os.PathLike)):
        return Scenario.load(value)
    raise ValueError(
        f"scenario must be a Scenario, its dict form or a path to its JSON file, got "
        f"{type(value).__name__}"
    )
