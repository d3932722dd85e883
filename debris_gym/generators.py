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

import numpy as np

from debris_gym.convex_polygons import ANGLE_JITTER, POLYGON_DRAWS, convex_polygon
from debris_gym.field_spec import (
    FIELD_MOTIONS,
    MAX_POLYGON_VERTICES,
    MAX_TRIES,
    FieldArrays,
    FieldSpec,
    route_by_construction,
    scenario_from_arrays,
)
from debris_gym.jit import kernel
from debris_gym.orbit_fields import (
    WIDE_TRIES,
    moving_unplaceable,
    orbit_drawer,
    random_orbit_fields,
)
from debris_gym.scenario import Body, Scenario
from debris_gym.solvability import field_route_exists, route_proof

__all__ = [
    "ANGLE_JITTER",
    "FIELD_MOTIONS",
    "MAX_CANDIDATES",
    "MAX_POLYGON_VERTICES",
    "MAX_TRIES",
    "MIN_CANDIDATES",
    "FieldArrays",
    "FieldSpec",
    "candidates",
    "draw_size",
    "paper_field",
    "placement_problem",
    "random_field",
    "random_fields",
    "route_by_construction",
    "scenario_from_arrays",
    "unplaceable",
]


MIN_CANDIDATES = 32
"""Fewest candidate positions per body in one draw (crowded fields get more: :func:`candidates`)."""

MAX_CANDIDATES = 256
"""Most candidate positions per body in one draw."""


def random_field(
    rng: np.random.Generator,
    spec: FieldSpec,
    *,
    mean_motion: float,
    dt: float,
    max_accel: float,
    capture_radius: float,
    max_tries: int = MAX_TRIES,
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


TRIAL_FIELDS = 32
"""Fields :func:`placement_problem` draws to decide whether a spec places reliably."""

TRIAL_SEED = 0x5EED_F1E1D
"""Seed of the trial fields' generators (fixed: a spec is always accepted or always refused)."""

TRIAL_SHARE = 8
"""A trial field must place within 1/TRIAL_SHARE of the draw's budget of tries."""


@functools.lru_cache(maxsize=256)  # asked when an env is made or its mission set
def placement_problem(spec: FieldSpec, capture_radius: float) -> str | None:
    """Why fields of ``spec`` cannot be drawn reliably, or None: every seed should place.

    :func:`unplaceable` and, for moving fields, the spec checks of
    :func:`~debris_gym.orbit_fields.orbit_drawer` first. Then :data:`TRIAL_FIELDS` fields are
    drawn from fixed seeds with an eighth of the budget (frozen: 1/:data:`TRIAL_SHARE` of
    :data:`MAX_TRIES` draws; moving: the narrow tries and 1/:data:`TRIAL_SHARE` of the wide
    ones), and every one must place. Were a seed's chance to need more than that q, the trials
    would all pass with chance (1 − q)^32, while a seed fails the whole budget with chance
    about q^8: a spec that passes has q small (below about 0.1), so that no seed of it fails
    in practice, and one whose fields only sometimes place is refused before any draw.

    Deterministic (fixed seeds), and remembered per spec.
    """
    why = unplaceable(spec)
    if why is not None:
        return why
    seeds = np.random.SeedSequence(TRIAL_SEED).generate_state(TRIAL_FIELDS, dtype=np.uint64)
    if spec.motion == "frozen":
        tries = max(1, MAX_TRIES // TRIAL_SHARE)
        try:
            for seed in seeds:  # one field at a time: bounded memory, and the first failure ends it
                rng = np.random.default_rng(int(seed))
                random_fields([rng], spec, capture_radius=capture_radius, max_tries=tries)
        except ValueError:
            return _unreliable(spec, f"{tries} of its {MAX_TRIES} draws")
        return None
    try:
        drawer = orbit_drawer(spec, capture_radius, MAX_TRIES, WIDE_TRIES // TRIAL_SHARE)
    except ValueError as exc:
        return str(exc)
    # one field at a time: a spec that fails is refused at its first failing field
    if not all(drawer.place(seeds[k : k + 1]).placed[0] for k in range(TRIAL_FIELDS)):
        budget = f"{MAX_TRIES} + {WIDE_TRIES // TRIAL_SHARE} of its {MAX_TRIES} + {WIDE_TRIES}"
        return _unreliable(spec, f"{budget} tries")
    return None


def _unreliable(spec: FieldSpec, budget: str) -> str:
    return (
        f"could not place n_targets={spec.n_targets} and n_obstacles={spec.n_obstacles} in "
        f"field_size={spec.field_size} m with min_gap={spec.min_gap} m reliably: of "
        f"{TRIAL_FIELDS} trial fields, some found no layout within {budget} (a spec must "
        "place well within its budget, so that every seed places); lower n_obstacles or the "
        "radii, or raise field_size"
    )


@functools.lru_cache(maxsize=64)  # called on every reset; the spec is frozen
def draw_size(spec: FieldSpec) -> int:
    """Uniform numbers one draw of one field consumes from its generator (a fixed block)."""
    bodies = spec.n_targets + spec.n_obstacles
    polygons = spec.n_obstacles * (1 + POLYGON_DRAWS) if spec.dim == 2 else 0
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
    max_tries: int = MAX_TRIES,
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
    start = b_all + (o * (1 + POLYGON_DRAWS) if dim == 2 else 0)
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
                    first = b_all + o + j * POLYGON_DRAWS
                    n_vertices[k, j] = convex_polygon(
                        u[k, first : first + POLYGON_DRAWS], radii[k, t + j], vertices[k, j]
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
