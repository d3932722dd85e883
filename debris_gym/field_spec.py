"""What a random debris field is drawn from and handed out as: plain data under both generators.

:class:`FieldSpec` holds the parameters of a random field (frozen and moving alike) and checks
them when built; :class:`FieldArrays` is K drawn fields as arrays, one row per field, and turns a
row into a :class:`~debris_gym.scenario.Scenario`. :func:`route_by_construction` says when the
placement's spacing alone proves a field solvable, :func:`checked_horizon` over which time span a
moving field is checked. The frozen draw (:mod:`debris_gym.generators`) and the moving draw
(:mod:`debris_gym.orbit_fields`) both read these; neither reads the other's names.

Lengths in m, times in s, mean motion in rad/s, velocities in m/s.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from debris_gym.scenario import Body, Scenario
from debris_gym.scenario_values import MAX_SPIN, number

__all__ = [
    "FIELD_MOTIONS",
    "MAX_POLYGON_VERTICES",
    "MAX_TRIES",
    "FieldArrays",
    "FieldSpec",
    "check_motion",
    "checked_horizon",
    "route_by_construction",
    "scenario_from_arrays",
]

FIELD_MOTIONS = ("frozen", "bounded", "drifting")
"""Body motions a random field may have (:attr:`FieldSpec.motion`)."""

MAX_POLYGON_VERTICES = 7
"""Most vertices of a generated polygon (they have 3 to 7)."""

MAX_TRIES = 50
"""Draws (frozen fields) or narrow tries (moving fields) per field before it is given up."""


@dataclass(frozen=True)
class FieldSpec:
    """Parameters of a random field (all lengths in m).

    Attributes:
        dim: 2 or 3.
        n_targets: number of targets (>= 1).
        n_obstacles: number of other debris (>= 0).
        field_size: edge length of the square / cubic world centred on the dock.
        target_radius: (min, max) target radius.
        obstacle_radius: (min, max) obstacle bounding radius.
        polygon_fraction: share of 2D obstacles that are convex polygons (rest are circles).
        min_gap: smallest free gap between any two bodies and between a body and the bounds.
        dock_clearance: radius of the free zone around the dock.
        target_clearance: free zone around each target's surface (holds the capture zone).
        min_target_distance: smallest dock-to-target centre distance.
        chaser_radius: chaser radius, used to inflate bodies in the route check.
        motion: ``"frozen"`` (bodies at rest in LVLH, the v0 fields), ``"bounded"`` (drift-free
            relative orbits, the v1 default) or ``"drifting"`` (orbits whose centre slides
            along-track); the moving draws are :mod:`debris_gym.orbit_fields`.
        mean_motion: n (rad/s) of the reference orbit the bodies move about (> 0 when moving).
        horizon: how long (s) a moving field must stay valid; at least one orbit 2π/n is
            checked (a drift-free field then stays valid for ever).
        drift_offset: (min, max) radial offset |x_c| (m) of a drifting body's orbit centre.
        rho_max: largest in-plane amplitude ρ (and cross-track ρ_z) of a body's orbit (m); each
            body's is also capped so that its orbit stays in the bounds.
        spin_max: tumble rates (rad/s) of 2D polygons are drawn uniformly in ±spin_max.
    """

    dim: int = 2
    n_targets: int = 3
    n_obstacles: int = 20
    field_size: float = 1000.0
    target_radius: tuple[float, float] = (3.0, 10.0)
    obstacle_radius: tuple[float, float] = (2.0, 25.0)
    polygon_fraction: float = 0.5
    min_gap: float = 10.0
    dock_clearance: float = 50.0
    target_clearance: float = 15.0
    min_target_distance: float = 150.0
    chaser_radius: float = 1.0
    motion: str = "frozen"
    mean_motion: float = 1.1314e-3
    horizon: float = 0.0
    drift_offset: tuple[float, float] = (2.0, 10.0)
    rho_max: float = 250.0
    spin_max: float = 0.0

    def __post_init__(self) -> None:
        # the counts size arrays and key the cached helpers (draw_size, route_by_construction):
        # a float count such as 3.0 hashes like 3 and would poison their caches for every
        # equal spec (EnvConfig stores whole numbers as int; this guards direct callers)
        for key in ("dim", "n_targets", "n_obstacles"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"FieldSpec.{key} must be an int, got {value!r}")
        check_motion(self)


def check_motion(spec: FieldSpec) -> None:
    """Check the motion keys of ``spec`` (``FieldSpec.__post_init__`` calls this).

    Raises:
        ValueError: naming the key (``FieldSpec.<key>``) and its allowed range.
    """
    if spec.motion not in FIELD_MOTIONS:
        raise ValueError(f"FieldSpec.motion={spec.motion!r}; allowed: {FIELD_MOTIONS}")
    low_n = 0.0 if spec.motion == "frozen" else 1e-9  # moving bodies need n > 0
    number(spec.mean_motion, "FieldSpec.mean_motion", low=low_n, high=1.0, unit="rad/s")
    number(spec.horizon, "FieldSpec.horizon", low=0.0, high=1e7, unit="s")
    number(spec.rho_max, "FieldSpec.rho_max", low=0.0, high=1e6, unit="m")
    number(spec.spin_max, "FieldSpec.spin_max", low=0.0, high=MAX_SPIN, unit="rad/s")
    offset = spec.drift_offset
    if not (isinstance(offset, tuple) and len(offset) == 2):
        raise ValueError(f"FieldSpec.drift_offset must be a (min, max) pair in m, got {offset!r}")
    low = number(offset[0], "FieldSpec.drift_offset[0]", low=0.0, high=1e6, unit="m")
    number(offset[1], "FieldSpec.drift_offset[1]", low=low, high=1e6, unit="m")


def checked_horizon(spec: FieldSpec) -> float:
    """The time span (s) a moving field of ``spec`` is checked over: ``horizon``, at least one
    orbit 2π/n (a drift-free field is then valid for ever, since its motion repeats)."""
    return max(float(spec.horizon), 2.0 * math.pi / spec.mean_motion)


@functools.lru_cache(maxsize=64)  # asked on every draw; the spec is frozen
def route_by_construction(spec: FieldSpec, capture_radius: float) -> bool:
    """True if every field the placement accepts passes :func:`is_solvable`'s proof by itself.

    The placement keeps bounding balls ``min_gap`` apart (``target_clearance`` more around
    targets), ``min_gap`` from the bounds and ``dock_clearance`` (or more) from the dock. With
    the chaser (radius ``chaser_radius``) and a capture point at ``0.5 · capture_radius`` from
    a target's surface, the disjoint-balls proof then holds for every such field when

    * ``min_gap > 2 · chaser_radius`` (inflated balls disjoint, and inside the bounds),
    * ``dock_clearance > chaser_radius`` (the dock is free),
    * ``min_gap + target_clearance > 2 · chaser_radius + 0.5 · capture_radius`` (every capture
      point is clear of the other bodies),
    * ``chaser_radius + 0.5 · capture_radius < min_gap`` (every capture point is inside the
      bounds), and ``capture_radius > 0`` (capture points are off the target),

    each with a margin far above rounding. Otherwise the proof is checked field by field
    (:func:`~debris_gym.solvability.is_solvable`).
    """
    slack = 1e-9 * spec.field_size
    half_capture = 0.5 * capture_radius
    cr = spec.chaser_radius
    return (
        half_capture > slack
        and spec.min_gap - 2.0 * cr > slack
        and spec.dock_clearance - cr > slack
        and spec.min_gap + spec.target_clearance - 2.0 * cr - half_capture > slack
        and spec.min_gap - cr - half_capture > slack
    )


@dataclass(frozen=True)
class FieldArrays:
    """K random fields as arrays, one row per field (what the generators return).

    Bodies are ordered targets first, then obstacles, as :attr:`Scenario.bodies`. The world of
    every field is the square / cube ``(-half_size, half_size)`` per axis with the dock at the
    origin.

    Attributes:
        dim: 2 or 3.
        half_size: half the world edge (m).
        n_targets: targets per field T.
        centers: (K, B, dim) body centres (m).
        radii: (K, B) radii (m); a polygon's circumradius.
        vertices: (K, O, V, 2) polygon vertices of the O obstacles relative to their centres (m),
            counter-clockwise, padded with the first vertex; V is
            :data:`MAX_POLYGON_VERTICES` in 2D and 0 in 3D.
        n_vertices: (K, O) vertex count of each obstacle, 0 for a circle / sphere.
        velocities: (K, B, dim) LVLH body velocities at t = 0 (m/s), or None (frozen field).
        spins: (K, B) tumble rates (rad/s), or None (frozen field).
    """

    dim: int
    half_size: float
    n_targets: int
    centers: np.ndarray
    radii: np.ndarray
    vertices: np.ndarray
    n_vertices: np.ndarray
    velocities: np.ndarray | None = None
    spins: np.ndarray | None = None

    def __len__(self) -> int:
        return self.centers.shape[0]

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]:
        """Per-axis ``(low, high)`` world limits (m), the same for every field."""
        return ((-self.half_size, self.half_size),) * self.dim

    def scenario(self, k: int, *, mean_motion: float, dt: float, max_accel: float) -> Scenario:
        """Field ``k`` as a :class:`Scenario` with the given physical parameters (a
        ``motion="cwh"`` one when the field moves)."""
        velocities, spins = self.velocities, self.spins
        moving = velocities is not None
        return scenario_from_arrays(
            self.centers[k], self.radii[k], self.vertices[k], self.n_vertices[k],
            self.n_targets, self.bounds, mean_motion=mean_motion, dt=dt, max_accel=max_accel,
            velocities=velocities[k] if velocities is not None else None,
            spins=spins[k] if moving and spins is not None else None,
        )  # fmt: skip


def scenario_from_arrays(
    centers: np.ndarray,
    radii: np.ndarray,
    vertices: np.ndarray,
    n_vertices: np.ndarray,
    n_targets: int,
    bounds: tuple[tuple[float, float], ...],
    *,
    mean_motion: float,
    dt: float,
    max_accel: float,
    velocities: np.ndarray | None = None,
    spins: np.ndarray | None = None,
) -> Scenario:
    """One random field's arrays (one row of :class:`FieldArrays`) as a :class:`Scenario`.

    Args:
        centers: (B, dim) body centres (m), targets first.
        radii: (B,) radii (m).
        vertices: (O, V, 2) obstacle polygon vertices relative to their centres (m).
        n_vertices: (O,) vertex counts, 0 for a circle / sphere.
        n_targets: number of targets T (the first T bodies).
        bounds: per-axis ``(low, high)`` world limits (m); the dock is at the origin.
        mean_motion, dt, max_accel: the scenario's physical parameters.
        velocities: (B, dim) LVLH velocities at t = 0 (m/s); given, the scenario moves
            (``motion="cwh"``); None keeps it frozen.
        spins: (B,) tumble rates (rad/s) of a moving field's bodies, or None (no tumble).
    """
    dim = centers.shape[1]
    zero = (0.0,) * dim
    counts = n_vertices.tolist()
    n_bodies = len(radii)
    speeds = [zero] * n_bodies if velocities is None else list(map(tuple, velocities.tolist()))
    turns = [0.0] * n_bodies if spins is None else spins.tolist()
    bodies = []
    for b, (position, radius) in enumerate(zip(centers.tolist(), radii.tolist())):
        m = counts[b - n_targets] if b >= n_targets else 0
        verts = tuple(map(tuple, vertices[b - n_targets, :m].tolist())) if m else None
        bodies.append(
            Body(position=tuple(position), radius=radius, velocity=speeds[b], vertices=verts,
                 spin=turns[b] if m else 0.0)
        )  # fmt: skip
    return Scenario(
        dim=dim,
        bounds=bounds,
        dock=zero,
        targets=tuple(bodies[:n_targets]),
        obstacles=tuple(bodies[n_targets:]),
        mean_motion=mean_motion,
        dt=dt,
        max_accel=max_accel,
        motion="frozen" if velocities is None else "cwh",
        name=f"random{dim}d",
    )
