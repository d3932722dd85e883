"""Seeded debris-field generators and presets.

Every generator takes a :class:`numpy.random.Generator` and returns a :class:`Scenario` that is
guaranteed to be usable: bodies do not overlap (their bounding circles / spheres are at least
``min_gap`` apart, and ``target_clearance`` more around targets), bodies keep ``min_gap`` to the
bounds, the dock and every target's capture zone are kept free (``dock_clearance``,
``min_target_distance``), and a collision-free route from the dock to every target is verified
(:func:`is_solvable`), not assumed. A draw that fails is thrown away and drawn again.

Random fields are drawn in batches (:func:`random_fields`, one generator per field, the work in
array operations across the batch); :func:`random_field` is the same code for one field. Each draw
takes a fixed block of uniform numbers from its field's generator, so a field depends only on its
own generator, whichever other fields are drawn beside it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from debris_gym.jit import inlined, kernel
from debris_gym.scenario import Body, Scenario
from debris_gym.solvability import field_route_exists, route_proof


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
        from debris_gym.orbit_fields import check_motion  # imports this module

        check_motion(self)


FIELD_MOTIONS = ("frozen", "bounded", "drifting")
"""Body motions a random field may have (:attr:`FieldSpec.motion`)."""


MAX_POLYGON_VERTICES = 7
"""Most vertices of a generated polygon (they have 3 to 7)."""

MIN_CANDIDATES = 32
"""Fewest candidate positions per body in one draw (crowded fields get more: :func:`candidates`)."""

MAX_CANDIDATES = 256
"""Most candidate positions per body in one draw."""

ANGLE_JITTER = 0.3
"""Polygon vertex angles deviate from even spacing by at most ± half this share of the spacing."""

_POLYGON_DRAWS = 3 + MAX_POLYGON_VERTICES
"""Uniform numbers per polygon: vertex count, one angle jitter per vertex, squash, rotation."""


@dataclass(frozen=True)
class FieldArrays:
    """K random fields as arrays, one row per field (what :func:`random_fields` returns).

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
        moving = self.velocities is not None
        return scenario_from_arrays(
            self.centers[k], self.radii[k], self.vertices[k], self.n_vertices[k],
            self.n_targets, self.bounds, mean_motion=mean_motion, dt=dt, max_accel=max_accel,
            velocities=self.velocities[k] if moving else None,
            spins=self.spins[k] if moving and self.spins is not None else None,
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


def random_field(
    rng: np.random.Generator,
    spec: FieldSpec,
    *,
    mean_motion: float,
    dt: float,
    max_accel: float,
    capture_radius: float,
    max_tries: int = 50,
) -> Scenario:
    """Draw a solvable random field (2D or 3D) centred on the dock at the LVLH origin.

    :func:`random_fields` for one generator: the same ``rng`` state gives the same field as row
    ``k`` of a batch whose ``k``-th generator is in that state. The dock sits at the origin, the
    one point at rest under CWH. Raises ``ValueError`` naming the setting to change if no valid
    field is found in ``max_tries`` draws.
    """
    fields = random_fields([rng], spec, capture_radius=capture_radius, max_tries=max_tries)
    return fields.scenario(0, mean_motion=mean_motion, dt=dt, max_accel=max_accel)


def unplaceable(spec: FieldSpec) -> str | None:
    """Why no field of ``spec`` can ever be placed, or None.

    The placement (:func:`_draw`) puts a body's centre in the box that keeps ``min_gap`` to
    the bounds, at least its dock distance plus its radius from the dock at the origin. When
    even the smallest target (or obstacle) cannot meet both anywhere in the box — its corner
    is the farthest point — every draw fails. A spec this refuses can never give a field; one
    it lets through may still fail when crowded (:func:`random_fields` then says so).
    """
    if spec.motion != "frozen":
        from debris_gym.orbit_fields import moving_unplaceable  # imports this module

        return moving_unplaceable(spec)
    dock_clearance = spec.dock_clearance
    kinds = [("target", spec.target_radius[0], max(spec.min_target_distance, dock_clearance))]
    if spec.n_obstacles:
        kinds.append(("obstacle", spec.obstacle_radius[0], dock_clearance))
    for kind, radius, dock_distance in kinds:
        lim = spec.field_size / 2.0 - radius - spec.min_gap
        reach = dock_distance + radius
        if not (lim > 0.0 and spec.dim * lim * lim >= reach * reach):
            return (
                f"no {kind} of radius {radius:g} m fits: its centre must lie {reach:g} m or more "
                f"from the dock and {radius + spec.min_gap:g} m or more inside the bounds, "
                f"which are {spec.field_size / 2.0:g} m from the dock"
            )
    return None


@functools.lru_cache(maxsize=64)  # called on every reset; the spec is frozen
def draw_size(spec: FieldSpec) -> int:
    """Uniform numbers one draw of one field consumes from its generator (a fixed block)."""
    bodies = spec.n_targets + spec.n_obstacles
    polygons = spec.n_obstacles * (1 + _POLYGON_DRAWS) if spec.dim == 2 else 0
    return bodies + polygons + bodies * candidates(spec) * spec.dim


def candidates(spec: FieldSpec) -> int:
    """Candidate positions per body in one draw: enough that the last, largest body of a field
    still finds a free spot in about 10 candidates' worth of the free share of the field.

    The free share is estimated as exp(-excluded / available) (randomly placed exclusion zones
    overlap): ``available`` is the box of possible centres, ``excluded`` the zones that every
    other body (its mean radius + the largest obstacle radius + ``min_gap`` + its margin) and the
    dock keep free of a new body's centre. Between :data:`MIN_CANDIDATES` and
    :data:`MAX_CANDIDATES`; a fixed number per spec, so a draw's block has a fixed size.
    """
    d = spec.dim
    r_new = max(spec.obstacle_radius[1], spec.target_radius[1])
    t_mean, o_mean = sum(spec.target_radius) / 2.0, sum(spec.obstacle_radius) / 2.0
    side = spec.field_size - 2.0 * (spec.min_gap + min(spec.obstacle_radius[0], t_mean))
    ball = math.pi if d == 2 else 4.0 * math.pi / 3.0
    zones = [
        (spec.n_targets, t_mean + r_new + spec.min_gap + spec.target_clearance),
        (spec.n_obstacles, o_mean + r_new + spec.min_gap),
        (1, max(spec.dock_clearance, spec.min_target_distance) + r_new),
    ]
    excluded = sum(count * ball * radius**d for count, radius in zones)
    free = math.exp(-excluded / max(side, 1e-9) ** d)
    wanted = 10.0 / max(free, 1e-9)
    return int(min(max(math.ceil(wanted / 32.0) * 32, MIN_CANDIDATES), MAX_CANDIDATES))


_CHUNK = 64
"""Most fields :func:`random_fields` draws in one set of array operations."""

_ARRAY_FIELDS = ("centers", "radii", "vertices", "n_vertices")


def random_fields(
    rngs: Sequence[np.random.Generator],
    spec: FieldSpec,
    *,
    capture_radius: float,
    max_tries: int = 50,
) -> FieldArrays:
    """Draw one solvable random field per generator, all at once.

    Each draw of a field takes a fixed block of :func:`draw_size` uniform numbers from that
    field's own generator (one ``rng.random`` call), so a field depends only on its generator's
    state, never on which other fields are drawn in the same batch. The block sets the radii,
    the polygon shapes and :func:`candidates` candidate positions per body; bodies are placed in
    order (targets first), each at its first candidate that keeps the gaps of the module
    docstring to every body placed before it, with every field of the batch handled in the same
    array operations. A field where some body has no valid candidate, or that fails
    :func:`is_solvable`, is drawn again from the next block of its generator.

    Args:
        rngs: one generator per field (K of them).
        spec: the field parameters.
        capture_radius: capture depth (m) the route check must reach around each target.
        max_tries: draws per field before giving up.

    A moving spec (``motion`` ``"bounded"`` / ``"drifting"``) is drawn by
    :func:`debris_gym.orbit_fields.random_orbit_fields` instead (bodies on relative orbits,
    checked over the horizon; ``velocities`` and ``spins`` filled).

    Raises:
        ValueError: some field found no valid draw in ``max_tries``; names the settings to change.
    """
    if spec.motion != "frozen":
        from debris_gym.orbit_fields import random_orbit_fields  # imports this module

        return random_orbit_fields(rngs, spec, capture_radius=capture_radius, max_tries=max_tries)
    rngs = list(rngs)
    if len(rngs) > _CHUNK:  # bounded temporaries: a big batch goes in chunks (same fields)
        parts = [
            random_fields(rngs[i : i + _CHUNK], spec, capture_radius=capture_radius,
                          max_tries=max_tries)
            for i in range(0, len(rngs), _CHUNK)
        ]  # fmt: skip
        return FieldArrays(
            parts[0].dim, parts[0].half_size, parts[0].n_targets,
            *(np.concatenate([getattr(p, k) for p in parts]) for k in _ARRAY_FIELDS),
        )  # fmt: skip
    num, dim, t = len(rngs), spec.dim, spec.n_targets
    half = spec.field_size / 2.0
    block = np.empty((num, draw_size(spec)))
    out: FieldArrays | None = None  # filled field by field when some need another draw
    pending = np.arange(num)
    for _ in range(max_tries):
        u = block[: pending.size]
        for row, i in zip(u, pending.tolist()):
            rngs[i].random(out=row)
        centers, radii, vertices, n_vertices, placed = _draw_fields(u, spec)
        ok = _accepted(centers, radii, vertices, n_vertices, placed, spec, capture_radius)
        if out is None:
            if ok.all():  # everything on the first draw (the usual case)
                return FieldArrays(dim, half, t, centers, radii, vertices, n_vertices)
            out = FieldArrays(
                dim, half, t,
                *(np.zeros((num, *a.shape[1:]), a.dtype) for a in (centers, radii, vertices,
                                                                    n_vertices)),
            )  # fmt: skip
        done = pending[ok]
        out.centers[done] = centers[ok]
        out.radii[done] = radii[ok]
        out.vertices[done] = vertices[ok]
        out.n_vertices[done] = n_vertices[ok]
        pending = pending[~ok]
        if pending.size == 0:
            return out
    raise ValueError(
        f"could not place n_targets={spec.n_targets} and n_obstacles={spec.n_obstacles} "
        f"in field_size={spec.field_size} m with min_gap={spec.min_gap} m after {max_tries} "
        "draws; lower n_obstacles or the obstacle radius range, or raise field_size"
    )


def _accepted(centers, radii, vertices, n_vertices, placed, spec: FieldSpec, capture_radius):
    """Which placed fields of a draw are solvable, (K,) bool: by construction, by
    :func:`route_proof`, or (where the proof does not apply) by the grid search of
    :func:`is_solvable` (:func:`~debris_gym.solvability.field_route_exists`)."""
    if route_by_construction(spec, capture_radius):
        return placed
    dim, t = spec.dim, spec.n_targets
    half = spec.field_size / 2.0
    low, high = np.full(dim, -half), np.full(dim, half)
    ok = placed.copy()
    if ok.any():
        ok[ok] = route_proof(
            centers[ok], radii[ok], t, low, high, np.zeros(dim), spec.chaser_radius, capture_radius
        )
    for j in np.flatnonzero(placed & ~ok):  # the proof failed: search a grid
        # is_solvable without its first step (route_proof just failed on this very field),
        # on the arrays: the same grid as on the field's Scenario, without building one
        ok[j] = field_route_exists(
            centers[j], radii[j], vertices[j], n_vertices[j], t, t, low, high, np.zeros(dim),
            spec.chaser_radius, capture_radius,
        )  # fmt: skip
    return ok


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

    each with a margin far above rounding. Otherwise the proof is checked field by field.
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


def _draw_fields(u: np.ndarray, spec: FieldSpec):
    """Place the bodies of K fields from their blocks ``u`` (K, :func:`draw_size`).

    Returns:
        ``(centers (K, B, dim), radii (K, B), vertices (K, O, V, 2), n_vertices (K, O),
        placed (K,))``; ``placed`` is False where some body found no valid candidate (the rest
        of that row is then meaningless).
    """
    min_dock = (spec.dock_clearance, max(spec.min_target_distance, spec.dock_clearance))
    return _draw(
        np.ascontiguousarray(u), spec.dim, spec.n_targets, spec.n_obstacles,
        *spec.target_radius, *spec.obstacle_radius, spec.polygon_fraction, spec.field_size,
        spec.min_gap, spec.target_clearance, *min_dock,
    )  # fmt: skip


@kernel
def _draw(
    u, dim, t, o, target_lo, target_hi, obstacle_lo, obstacle_hi, polygon_fraction, field_size,
    min_gap, target_clearance, obstacle_dock, target_dock,
):  # fmt: skip
    """The bodies of K fields from their blocks ``u`` (:func:`_draw_fields`).

    Block layout: B radii (targets first), then in 2D O polygon flags and O × 10 polygon shape
    numbers, then B × C × dim candidate coordinates. A candidate is uniform in the box that
    keeps ``min_gap`` to the bounds; it is valid when at least the body's dock distance
    (``target_dock`` / ``obstacle_dock``) plus its radius from the dock at the origin. Bodies are
    placed one after another: body b takes its first valid candidate that keeps, to every body
    j < b, a centre distance of at least r_b + r_j + max(s_b, s_j) (compared squared), where s
    is the free gap a body demands (``min_gap``, plus ``target_clearance`` for targets).
    Candidates are decoded only as far as they are tried.
    """
    num = u.shape[0]
    b_all = t + o
    radii = np.empty((num, b_all))
    v_max = MAX_POLYGON_VERTICES if dim == 2 else 0
    vertices = np.zeros((num, o, v_max, 2))
    n_vertices = np.zeros((num, o), dtype=np.int64)
    centers = np.zeros((num, b_all, dim))
    placed = np.ones(num, dtype=np.bool_)
    start = b_all + (o * (1 + _POLYGON_DRAWS) if dim == 2 else 0)
    n_cand = (u.shape[1] - start) // (b_all * dim)
    spacing = np.full(b_all, float(min_gap))
    for b in range(t):
        spacing[b] += target_clearance
    x = np.empty(dim)
    for k in range(num):
        for b in range(b_all):
            if b < t:
                radii[k, b] = target_lo + (target_hi - target_lo) * u[k, b]
            else:
                radii[k, b] = obstacle_lo + (obstacle_hi - obstacle_lo) * u[k, b]
        if dim == 2:
            for j in range(o):
                if u[k, b_all + j] < polygon_fraction:
                    first = b_all + o + j * _POLYGON_DRAWS
                    n_vertices[k, j] = _convex_polygon(
                        u[k, first : first + _POLYGON_DRAWS], radii[k, t + j], vertices[k, j]
                    )
        for b in range(b_all):
            lim = field_size / 2.0 - radii[k, b] - min_gap
            reach = (target_dock if b < t else obstacle_dock) + radii[k, b]
            found = False
            for c in range(n_cand):
                norm2 = 0.0
                for a in range(dim):
                    x[a] = (u[k, start + (b * n_cand + c) * dim + a] * 2.0 - 1.0) * lim
                    norm2 += x[a] * x[a]
                if not (norm2 >= reach * reach and lim > 0.0):
                    continue
                clear = True
                for j in range(b):
                    need = radii[k, b] + radii[k, j] + max(spacing[b], spacing[j])
                    dist2 = 0.0
                    for a in range(dim):
                        delta = x[a] - centers[k, j, a]
                        dist2 += delta * delta
                    if dist2 < need * need:
                        clear = False
                        break
                if clear:
                    for a in range(dim):
                        centers[k, b, a] = x[a]
                    found = True
                    break
            if not found:
                placed[k] = False
                break
    return centers, radii, vertices, n_vertices, placed


@inlined
def _convex_polygon(shape, radius, out):
    """A CCW convex polygon from 10 uniform numbers ``shape``, no rejection; returns its count.

    ``shape[0]`` picks 3 to 7 vertices; they sit on the unit circle at evenly spaced angles,
    each moved by at most ± ``ANGLE_JITTER`` / 2 of the spacing (``shape[1:8]``), so
    consecutive angles stay strictly increasing and every gap is below 1.3 · 2π/3 < π: the
    polygon is strictly convex, counter-clockwise, and holds the centre strictly inside. An
    affine squash of x into [0.5, 1) (``shape[8]``) and a rotation (``shape[9]``) keep all of
    that; the result is scaled so its largest vertex distance (circumradius) is ``radius`` (m).
    The vertices go into ``out`` (V, 2); unused slots repeat the first vertex.
    """
    v = MAX_POLYGON_VERTICES
    count = 3 + min(int(shape[0] * (v - 2)), v - 3)
    spacing = 2.0 * np.pi / count
    squash = 0.5 + 0.5 * shape[1 + v]
    rot = 2.0 * np.pi * shape[2 + v]
    c, s = np.cos(rot), np.sin(rot)
    far = 0.0
    for j in range(count):
        angle = (j + ANGLE_JITTER * (shape[1 + j] - 0.5)) * spacing
        x = np.cos(angle) * squash
        y = np.sin(angle)
        out[j, 0] = x * c - y * s
        out[j, 1] = x * s + y * c
        far = max(far, np.sqrt(out[j, 0] * out[j, 0] + out[j, 1] * out[j, 1]))
    scale = radius / far
    for j in range(v):
        if j < count:
            out[j, 0] *= scale
            out[j, 1] *= scale
        else:
            out[j, 0] = out[0, 0]
            out[j, 1] = out[0, 1]
    return count


@kernel
def _convex_polygons(shape, radius):
    """:func:`_convex_polygon` for K polygons: (K, V, 2) vertices and (K,) counts."""
    vertices = np.zeros((shape.shape[0], MAX_POLYGON_VERTICES, 2))
    counts = np.zeros(shape.shape[0], dtype=np.int64)
    for k in range(shape.shape[0]):
        counts[k] = _convex_polygon(shape[k], radius[k], vertices[k])
    return vertices, counts


def paper_field(dt: float = 0.1, max_accel: float = 1.0) -> Scenario:
    """The [APF-MPC] world: a 20 × 20 unit square, spherical debris between the targets, a dock.

    The paper's exact obstacle file (``sphereWorld1.mat``) is not published; this preset follows
    its description and figures: four targets visited from a dock in a corner, obstacles set
    between consecutive targets, a double integrator (n = 0), unit lengths.

    Args:
        dt: step length (s); the paper's MPC uses 0.1.
        max_accel: thrust limit (units/s²).
    """
    dock = (2.0, 2.0)
    targets = [(6.0, 14.0), (12.0, 17.0), (17.0, 11.0), (13.0, 4.0)]
    obstacles = [
        ((3.5, 7.0), 1.0),
        ((9.0, 16.5), 0.9),
        ((8.0, 11.0), 1.2),
        ((15.0, 14.5), 1.0),
        ((12.5, 11.0), 1.3),
        ((16.0, 7.0), 1.1),
        ((8.0, 4.0), 1.2),
        ((5.5, 2.0), 0.7),
        ((11.0, 7.5), 0.8),
    ]
    return Scenario(
        dim=2,
        bounds=((0.0, 20.0), (0.0, 20.0)),
        dock=dock,
        targets=tuple(Body(position=p, radius=0.3, velocity=(0.0, 0.0)) for p in targets),
        obstacles=tuple(Body(position=p, radius=r, velocity=(0.0, 0.0)) for p, r in obstacles),
        mean_motion=0.0,
        dt=dt,
        max_accel=max_accel,
        name="paper_field",
    )
