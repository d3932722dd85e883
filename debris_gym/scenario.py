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
and apart, the dock clear, moving bodies' speeds) when a scenario comes from outside the library
— :meth:`from_dict`, :meth:`load` and :func:`as_scenario`, through which every pinned field
enters an env; and a moving field's motion over the env's episode
(:meth:`Scenario.check_motion`, :mod:`debris_gym.horizon_checks`) when an env pins it.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from debris_gym.body import BODY_KEYS, Body
from debris_gym.config import OPTIONS
from debris_gym.dynamics import discretize
from debris_gym.files import write_atomic
from debris_gym.horizon_checks import describe, first_motion_fault
from debris_gym.scenario_checks import (
    BODY_COUNTS,
    MOTION_MODELS,
    body_names,
    check_count,
    check_layout,
    check_values,
)
from debris_gym.scenario_values import mapping, number, pair, sequence, show, vector

__all__ = ["BODY_KEYS", "MOTION_FAULTS", "MOTION_MODELS", "Body", "Scenario", "as_scenario"]

REQUIRED_KEYS = ("dim", "bounds", "dock", "targets", "mean_motion", "dt", "max_accel")
"""Keys a scenario dict / JSON file must have: the physical parameters too, since a saved field is
flown with its own physics (an absent ``dt`` must not silently mean 1 s)."""

OPTIONAL_KEYS = {"obstacles": (), "motion": "frozen", "name": "", "motion_faults": "refuse"}
"""Keys a scenario dict may leave out, with the value they then take."""

MOTION_FAULTS = ("refuse", "warn")
"""What an env does with a moving field whose bodies break the layout rules within its episode
(:meth:`Scenario.check_motion`): ``"refuse"`` it (``ValueError``, the default) or ``"warn"``
(fly it, with a ``UserWarning`` naming the first fault: the user asked for a field whose
targets may leave the world or whose bodies may pass through each other)."""

MAX_FILE_BYTES = 64 * 2**20
"""Largest scenario file read (bytes): the largest scenario (20 targets, 2 000 obstacles, every
one a 64-vertex polygon) takes under 10 MB as ``save`` writes it."""

MAX_OBJECTS = 1 + sum(int(OPTIONS[option].limits()[1]) for option in BODY_COUNTS.values())
"""Most JSON objects (``{...}``) a scenario file holds: the scenario and one per body. A file
with more is refused as soon as the parser meets one more, before it is read whole into Python
objects (a 1e6-body file would otherwise take tens of seconds and most of a gigabyte)."""


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
        motion_faults: what an env does when the bodies' motion breaks the layout rules within
            its episode (:meth:`check_motion`): ``"refuse"`` (the default) or ``"warn"``
            (:data:`MOTION_FAULTS`; moving fields only).
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
    motion_faults: str = "refuse"
    # derived data, fresh for every object (init=False: dataclasses.replace must not share it)
    _cache: dict[str, Any] = field(
        default_factory=dict, init=False, compare=False, repr=False, hash=False
    )

    def __post_init__(self) -> None:
        check_values(self)
        if self.motion_faults not in MOTION_FAULTS:
            raise ValueError(
                f"motion_faults must be one of {MOTION_FAULTS}, got {show(self.motion_faults)}"
            )
        if self.motion_faults != "refuse" and self.motion != "cwh":
            raise ValueError(
                f"motion_faults={self.motion_faults!r} applies to moving fields only "
                f"(motion='cwh'); this one has motion={self.motion!r}"
            )

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

    def check_motion(self, steps: int) -> Scenario:
        """Check a moving field over ``steps`` steps of its ``dt`` (an env's episode); return
        self.

        Every body, by its bounding circle / sphere, stays inside the bounds and no two bodies
        overlap at any instant of ``[0, steps · dt]`` (:mod:`debris_gym.horizon_checks`; exact
        to a relative 1e-9 of the world's size). A frozen field has nothing to check. The
        result is remembered per object (the longest horizon checked).

        Raises:
            ValueError: the first fault found, naming the bodies and the time — unless
                ``motion_faults`` is ``"warn"``, which gives a ``UserWarning`` instead.
        """
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise ValueError(f"steps must be a whole number >= 0, got {show(steps)}")
        if not self.moving or steps <= self._cache.get("motion_steps", -1):
            return self
        radii = np.array([b.radius for b in self.bodies])
        fault = first_motion_fault(
            self.initial_body_states(), radii, self.low, self.high, self.mean_motion, self.dt,
            int(steps),
        )  # fmt: skip
        if fault is not None:
            what = describe(fault, body_names(self), radii)
            horizon = f"within {int(steps)} steps of {self.dt:g} s (the env's episode)"
            if self.motion_faults == "refuse":
                raise ValueError(
                    f"{what}, {horizon}: a moving field's bodies must stay wholly inside the "
                    "bounds and apart (by their bounding circles / spheres) over the episode; "
                    "to fly it anyway, set the scenario's motion_faults='warn'"
                )
            warnings.warn(
                f"{what}, {horizon}; flown anyway (motion_faults='warn'): a target that leaves "
                "the world cannot be captured",
                UserWarning,
                stacklevel=2,
            )
        self._cache["motion_steps"] = int(steps)
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
            **({"motion_faults": self.motion_faults} if self.motion_faults != "refuse" else {}),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """Build and check a scenario from :meth:`to_dict` output (or hand-written JSON).

        Required keys: :data:`REQUIRED_KEYS`; optional: :data:`OPTIONAL_KEYS`. Runs every rule of
        :mod:`debris_gym.scenario_checks`, values and layout; the body counts first, before a
        single body is built.

        Raises:
            ValueError: naming the missing, unknown or invalid key (e.g. ``targets[2].radius``).
        """
        data = mapping(data, "scenario")
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
            raise ValueError(f"dim must be the integer 2 or 3, got {show(dim)}")
        bounds = sequence(data["bounds"], "bounds", f"{dim} [low, high] pairs (m)")
        if len(bounds) != dim:
            raise ValueError(f"bounds must be dim={dim} [low, high] pairs (m), got {len(bounds)}")
        items = {kind: sequence(data.get(kind, ()), kind, "body dicts") for kind in BODY_COUNTS}
        for kind, bodies in items.items():
            check_count(kind, len(bodies))
        built = {
            kind: tuple(Body.from_dict(b, dim, f"{kind}[{i}]") for i, b in enumerate(bodies))
            for kind, bodies in items.items()
        }
        for key in ("motion", "name", "motion_faults"):
            if not isinstance(data.get(key, ""), str):
                raise ValueError(f"{key} must be a string, got {show(data[key])}")
        scenario = cls(
            dim=dim,
            bounds=tuple(pair(low_high, f"bounds[{a}]") for a, low_high in enumerate(bounds)),
            dock=vector(data["dock"], dim, "dock"),
            targets=built["targets"],
            obstacles=built["obstacles"],
            mean_motion=number(data["mean_motion"], "mean_motion", unit="rad/s"),
            dt=number(data["dt"], "dt", unit="s"),
            max_accel=number(data["max_accel"], "max_accel", unit="m/s²"),
            motion=data.get("motion", OPTIONAL_KEYS["motion"]),
            name=data.get("name", OPTIONAL_KEYS["name"]),
            motion_faults=data.get("motion_faults", OPTIONAL_KEYS["motion_faults"]),
        )
        return scenario.check_layout()

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the scenario as JSON, atomically (a crash never leaves a half-written file)."""
        write_atomic(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scenario:
        """Read and check a scenario written by :meth:`save` (or by hand).

        A file is refused before it is read whole when it is larger than
        :data:`MAX_FILE_BYTES`, and while it is parsed once it holds more than
        :data:`MAX_OBJECTS` objects (bodies), so a huge file costs neither time nor memory.

        Raises:
            ValueError: naming the file: a directory, too large, not UTF-8 JSON (naming the line
                and column), a key twice in one object, or a scenario that breaks a rule
                (naming the key).
            OSError: the file cannot be read.
        """
        name = os.fspath(path)
        if os.path.isdir(path):
            raise ValueError(
                f"scenario path {name!r} is a directory; give the path of a scenario JSON file "
                "(Scenario.save writes one)"
            )
        with open(path, "rb") as fh:
            raw = _read_at_most(fh, MAX_FILE_BYTES)
        if raw is None:
            raise ValueError(
                f"scenario file {name!r} is larger than {MAX_FILE_BYTES // 2**20} MiB; a "
                f"scenario (at most {MAX_OBJECTS - 1} bodies) is far smaller"
            )
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"scenario file {name!r} is not UTF-8 text: {exc}") from exc
        try:
            data = _parse(text)
        except json.JSONDecodeError as exc:
            raise ValueError(
                f"scenario file {name!r} is not valid JSON: {exc.msg} at line "
                f"{exc.lineno}, column {exc.colno}"
            ) from exc
        except RecursionError as exc:
            raise ValueError(f"scenario file {name!r} nests too deeply") from exc
        except ValueError as exc:
            raise ValueError(f"scenario file {name!r}: {exc}") from exc
        try:
            return cls.from_dict(data)
        except ValueError as exc:
            raise ValueError(f"scenario file {name!r}: {exc}") from exc


def _read_at_most(fh: Any, limit: int) -> bytes | None:
    """The whole of the binary file ``fh``, or None if it holds more than ``limit`` bytes (a
    regular file is judged by its size before anything is read; a pipe or device is read in
    pieces and stops one byte past the limit)."""
    size = os.fstat(fh.fileno()).st_size
    if size > limit:
        return None
    pieces, total = [], 0
    while total <= limit:
        piece = fh.read(min(max(size + 1, 1 << 16), limit + 1 - total))
        if not piece:
            break
        pieces.append(piece)
        total += len(piece)
    return None if total > limit else b"".join(pieces)


def _parse(text: str) -> Any:
    """``json.loads(text)``, refusing (``ValueError``) a document of more than
    :data:`MAX_OBJECTS` objects as soon as the parser meets one more, and an object with a key
    twice; an integer too long for Python to convert becomes a :class:`_LongInteger`."""
    objects = 0

    def build(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        nonlocal objects
        objects += 1
        if objects > MAX_OBJECTS:
            limits = ", ".join(
                f"{kind} {OPTIONS[option].describe()}" for kind, option in BODY_COUNTS.items()
            )
            raise ValueError(
                f"targets and obstacles hold more than {MAX_OBJECTS - 1} bodies (JSON objects); "
                f"allowed: {limits} (the env's n_targets and n_obstacles)"
            )
        out = dict(pairs)
        if len(out) != len(pairs):
            seen: set[str] = set()
            for key, _ in pairs:
                if key in seen:
                    raise ValueError(
                        f"an object has the key {key!r} twice; each key may appear once"
                    )
                seen.add(key)
        return out

    return json.loads(text, object_pairs_hook=build, parse_int=_integer)


_MAX_DIGITS = 4000
"""Longest integer literal converted to an int (Python refuses more than 4 300 digits)."""


class _LongInteger(float):
    """A JSON integer too long to convert: ±inf as a number (so every rule refuses it as not
    finite, naming its key), shown as its length."""

    digits: int

    def __new__(cls, text: str) -> _LongInteger:
        out = super().__new__(cls, "-inf" if text.startswith("-") else "inf")
        out.digits = len(text.lstrip("-"))
        return out

    def __repr__(self) -> str:
        return f"a {self.digits}-digit integer"


def _integer(text: str) -> int | float:
    return int(text) if len(text) <= _MAX_DIGITS else _LongInteger(text)


def as_scenario(
    value: Scenario | Mapping[str, Any] | str | os.PathLike[str],
    *,
    horizon_steps: int | None = None,
) -> Scenario:
    """Accept a Scenario, its dict form, or a path to its JSON file; every rule is checked.

    This is how a pinned field enters an env (``reset(options={"scenario": ...})``), so a
    hand-built :class:`Scenario` gets its layout checked here too.

    Args:
        value: the field.
        horizon_steps: the env's episode in steps: a moving field's motion is checked over
            that many steps of its ``dt`` (:meth:`Scenario.check_motion`); None skips it.

    Raises:
        ValueError: ``value`` is none of those, or breaks a rule (naming the key).
    """
    if isinstance(value, Scenario):
        scenario = value.check_layout()
    elif isinstance(value, Mapping):
        scenario = Scenario.from_dict(value)
    elif isinstance(value, (str, os.PathLike)):
        scenario = Scenario.load(value)
    else:
        raise ValueError(
            f"scenario must be a Scenario, its dict form or a path to its JSON file, got "
            f"{type(value).__name__}"
        )
    if horizon_steps is not None:
        scenario.check_motion(horizon_steps)
    return scenario
