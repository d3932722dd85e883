"""Seeded moving (v1) debris fields: every body on a natural CWH relative orbit.

A moving field (``FieldSpec.motion`` ``"bounded"`` or ``"drifting"``) puts each body on the
unforced CWH trajectory ([Clohessy60]; [Curtis14] §7.4) with elements (see
:mod:`debris_gym.relative_orbits`)::

    x(t) = x_c + ρ sin(nt + α)
    y(t) = y_c − (3/2) n x_c t + 2ρ cos(nt + α)
    z(t) = ρ_z sin(nt + β)                                     (3D)

``"bounded"`` (the default of v1) draws x_c = 0 (ẏ₀ = −2n x₀): closed 2:1 ellipses about the
V-bar that repeat every orbit 2π/n, so a field valid over one orbit is valid for ever.
``"drifting"`` draws |x_c| in ``drift_offset``: the ellipse's centre slides along-track at
−(3/2) n x_c, and the field is checked over ``horizon`` (at least one orbit).

Placement (:func:`_draw_orbits`), body after body (targets first), each at its first candidate
orbit that keeps, over the checked time (all time for ``"bounded"``):

* inside the bounds with ``min_gap`` to spare (the orbit's extent, exact: |x − x_c| ≤ ρ,
  |y − y_c(t)| ≤ 2ρ, |z| ≤ ρ_z);
* its surface ``dock_clearance`` from the dock at the origin (where the chaser starts and ends),
  and a target's centre ``min_target_distance`` from it at t = 0;
* a centre distance of at least r_i + r_j + max(s_i, s_j) to every body placed before it
  (s = ``min_gap``, plus ``target_clearance`` around targets).

The relative motion of two bodies (or of a body and the dock) is itself CWH motion, so whether
they keep a distance is decided from their element differences: exactly for drift-free pairs in
the plane, by a branch and bound that proves the gap or finds a violation otherwise
(:func:`debris_gym.orbit_separation.apart`).

Solvability in space-time (the argument; tested against an independent time-expanded search in
``tests/test_orbit_fields.py``). With ``min_gap > 2 · chaser_radius`` and the other conditions
of :func:`~debris_gym.generators.route_by_construction` (required of a moving spec), the checks
above give at *every* instant what the v0 disjoint-balls proof needs: the bodies' balls,
inflated by the chaser radius c, are pairwise disjoint and strictly inside the bounds and off the
dock, so the free space is connected at every t and each target has a free capture point. Each
body also carries a collar, the shell r_i + c < |p − p_i(t)| < r_i + s_i/2, that no other body
enters at any time. The chaser moves with authority to spare: a body moves at most
n·√(4ρ² + ρ_z²) (+ 1.5 n |x_c|), ≈ 0.63 m/s at ρ = ρ_z = 250 m in LEO, and accelerates at most
n²·√(4ρ² + ρ_z²) < 1e-3 m/s², against the chaser's 0.05 m/s² (1 m/s within 20 s); riding a
collar at a fixed offset d from a body costs a thrust (3n² d_x, 0, −n² d_z), at most 3n²|d|
≈ 2e-4 m/s² at 50 m (chaser and body obey the same law, Coriolis terms included);
the dock is an equilibrium kept clear at all times, where the chaser can wait. So the chaser can
wait (at the dock or in a collar) for a gap and cross the connected free space faster than it
deforms, reach a target's collar, match the target's velocity (≤ 0.6 m/s: ≤ 12 s of thrust)
there, and return. This is an argument, not a proof for every conceivable field; the search in
the tests confirms it on a seeded sample of fields.

Randomness: a field takes one 64-bit word from its own generator (so it depends on that
generator only, whichever other fields are drawn with it). The compiled draw expands the word with
the counter-based generator SplitMix64 ([Steele14]): uniform number i of a try is output i of
SplitMix64 seeded with the try's key, computed on demand, so candidates are decoded only as far
as they are tried. Try 0's key is the word itself; a field where some body found no candidate is
tried again, up to ``max_tries`` times, with the key of try j the j-th SplitMix64 output of the
word mixed once more (:func:`_try_key`); then up to :data:`WIDE_TRIES` times more with
:data:`WIDE_CANDIDATES` candidates per body (a field placed in its first tries is the same
whether or not the wide ones exist). The kernels read their settings and write their results
as named records (:class:`OrbitRules`, :class:`PlaceScratch`, :class:`DrawnOrbits`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from debris_gym.convex_polygons import POLYGON_DRAWS, convex_polygon
from debris_gym.field_spec import (
    MAX_POLYGON_VERTICES,
    MAX_TRIES,
    FieldArrays,
    FieldSpec,
    check_motion,
    checked_horizon,
    route_by_construction,
)
from debris_gym.jit import inlined, kernel, specialise
from debris_gym.orbit_separation import apart

__all__ = [
    "ORBIT_CANDIDATES",
    "WIDE_CANDIDATES",
    "WIDE_TRIES",
    "DrawnOrbits",
    "OrbitDrawer",
    "OrbitRules",
    "PlaceScratch",
    "check_motion",
    "checked_horizon",
    "moving_unplaceable",
    "orbit_drawer",
    "random_orbit_fields",
    "stream_uniform",
]

ORBIT_CANDIDATES = {2: 64, 3: 32}
"""Candidate orbits per body in one of the first ``max_tries`` tries, by dim: a default field
places every body in almost every try (docs/benchmarks.md); a field that fails is tried again
with a new key."""

WIDE_CANDIDATES = 4096
"""Candidate orbits per body in the tries after the first ``max_tries``: a crowded field (for
example 50 obstacles in the default 2D world, whose drift-free orbits all crowd the along-track
axis) rarely finds a place for its last bodies among 64 candidates, and almost always among
these. Only a field that failed every one of its first tries gets here, so the fields drawn in
those tries are the same as without the wide ones."""

WIDE_TRIES = 32
"""Tries with :data:`WIDE_CANDIDATES` candidates after the first ``max_tries``."""

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
"""SplitMix64's counter increment (2^64 / golden ratio, odd) [Steele14]."""
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TRY_GAMMA = np.uint64(0xD1B54A32D192ED03)
"""Odd constant spacing the keys of a draw's tries (any odd constant other than _GAMMA)."""
_S11, _S27, _S30, _S31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)
_ONE = np.uint64(1)
_UNIT = 2.0**-53


class OrbitRules(NamedTuple):
    """What the draw of one spec's moving fields obeys (built once by :class:`OrbitDrawer`,
    read by name in the kernels). Lengths in m, n in rad/s, times in s.

    Attributes:
        dim: 2 or 3.
        n_targets, n_obstacles: bodies per field T and O.
        target_radius_lo, target_radius_hi: target radius range.
        obstacle_radius_lo, obstacle_radius_hi: obstacle (bounding) radius range.
        polygon_fraction: share of 2D obstacles that are polygons.
        half_size: half the world edge.
        min_gap: gap every body keeps to the bounds and to every other body.
        target_clearance: extra gap around targets.
        dock_clearance: gap every body's surface keeps to the dock, at all times.
        target_start: smallest dock-to-target centre distance at t = 0 (less the radius).
        mean_motion: n.
        horizon: time span the field is checked over (all time when not drifting).
        drifting: the orbits' centres drift (|x_c| drawn in the drift range).
        drift_lo, drift_hi: range of |x_c|.
        rho_max: largest in-plane (and cross-track) amplitude.
        spin_max: polygons' tumble rates are drawn in ±spin_max (rad/s).
        tries: tries with ``candidates`` candidates per body.
        candidates: candidates per body in those tries.
        wide_tries: tries after them with ``wide_candidates`` candidates per body.
        wide_candidates: candidates per body in those.
    """

    dim: int
    n_targets: int
    n_obstacles: int
    target_radius_lo: float
    target_radius_hi: float
    obstacle_radius_lo: float
    obstacle_radius_hi: float
    polygon_fraction: float
    half_size: float
    min_gap: float
    target_clearance: float
    dock_clearance: float
    target_start: float
    mean_motion: float
    horizon: float
    drifting: bool
    drift_lo: float
    drift_hi: float
    rho_max: float
    spin_max: float
    tries: int
    candidates: int
    wide_tries: int
    wide_candidates: int


class DrawnOrbits(NamedTuple):
    """K moving fields as the kernels write them, one row per field (shapes as
    :class:`~debris_gym.field_spec.FieldArrays`; ``placed`` (K,): every body found an orbit)."""

    centers: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    vertices: np.ndarray
    n_vertices: np.ndarray
    spins: np.ndarray
    placed: np.ndarray


class PlaceScratch(NamedTuple):
    """Working arrays of one try (reused across tries and fields).

    Attributes:
        spacing: (B,) gap each body demands (m): ``min_gap``, plus ``target_clearance`` for
            targets.
        elem: (B, 6) elements x_c, y_c, a, b, a_z, b_z (m) of the bodies placed so far.
        shape: (:data:`~debris_gym.convex_polygons.POLYGON_DRAWS`,) one polygon's numbers.
    """

    spacing: np.ndarray
    elem: np.ndarray
    shape: np.ndarray


def moving_unplaceable(spec: FieldSpec) -> str | None:
    """Why no moving field of ``spec`` can ever be placed, or None.

    Every drift-free orbit is centred on the V-bar (x = 0), so the smallest body must fit at
    its dock distance along it; a drifting body's centre slides 1.5 n |x_c| · horizon along-track,
    which must fit in the box."""
    half = spec.field_size / 2.0
    kinds = [("target", spec.target_radius[0], max(spec.min_target_distance, spec.dock_clearance))]
    if spec.n_obstacles:
        kinds.append(("obstacle", spec.obstacle_radius[0], spec.dock_clearance))
    for kind, radius, dock_distance in kinds:
        lim = half - radius - spec.min_gap
        if lim < dock_distance + radius:
            return (
                f"no moving {kind} of radius {radius:g} m fits: every drift-free orbit is "
                f"centred on the along-track axis, where its centre must lie "
                f"{dock_distance + radius:g} m or more from the dock and {radius + spec.min_gap:g}"
                f" m or more inside the bounds, which are {half:g} m from the dock"
            )
        if spec.motion == "drifting":
            slide = 1.5 * spec.mean_motion * spec.drift_offset[0] * checked_horizon(spec)
            if slide > 2.0 * lim or spec.drift_offset[0] > lim:
                return (
                    f"FieldSpec.drift_offset={spec.drift_offset!r} m: a {kind} with the smallest "
                    f"offset slides {slide:g} m along-track over the horizon "
                    f"{checked_horizon(spec):g} s, more than the {2.0 * lim:g} m it has; lower "
                    "drift_offset or horizon"
                )
    return None


def random_orbit_fields(
    rngs: Sequence[np.random.Generator],
    spec: FieldSpec,
    *,
    capture_radius: float,
    max_tries: int = MAX_TRIES,
) -> FieldArrays:
    """Draw one moving field per generator (the moving branch of
    :func:`~debris_gym.generators.random_fields`); ``velocities`` and ``spins`` are filled.

    Each field takes one 64-bit word from its generator (module docstring). The envs keep an
    :func:`orbit_drawer` instead, which checks the spec once.

    Raises:
        ValueError: the spec breaks the solvability conditions (naming them), can never be
            placed, or some field found no valid try in ``max_tries``.
    """
    return orbit_drawer(spec, capture_radius, max_tries).draw(list(rngs))


def orbit_drawer(
    spec: FieldSpec, capture_radius: float, max_tries: int = MAX_TRIES, wide_tries: int = WIDE_TRIES
) -> OrbitDrawer:
    """An :class:`OrbitDrawer` for ``spec``, the spec checked here once.

    Args:
        spec: the field parameters (a moving ``motion``).
        capture_radius: capture depth (m) the solvability conditions must leave room for.
        max_tries: tries with :data:`ORBIT_CANDIDATES` candidates per body.
        wide_tries: tries after them with :data:`WIDE_CANDIDATES` candidates per body.

    Raises:
        ValueError: the spec breaks the solvability conditions (naming them) or can never be
            placed; ``max_tries`` is not a whole number >= 1 or ``wide_tries`` one >= 0.
    """
    for key, value, least in (("max_tries", max_tries, 1), ("wide_tries", wide_tries, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise ValueError(f"{key} must be a whole number >= {least}, got {value!r}")
        if value < least:
            raise ValueError(f"{key}={value} is out of range; allowed: >= {least}")
    if spec.motion == "frozen":
        raise ValueError("FieldSpec.motion='frozen': an orbit drawer needs 'bounded' or 'drifting'")
    if not route_by_construction(spec, capture_radius):
        raise ValueError(
            "a moving field needs the disjoint-balls conditions at every instant (the "
            "solvability argument, module docstring): FieldSpec.min_gap > 2·chaser_radius and "
            "> chaser_radius + capture_radius/2, min_gap + target_clearance > 2·chaser_radius + "
            "capture_radius/2, dock_clearance > chaser_radius and capture_radius > 0; got "
            f"min_gap={spec.min_gap}, target_clearance={spec.target_clearance}, "
            f"dock_clearance={spec.dock_clearance}, chaser_radius={spec.chaser_radius}, "
            f"capture_radius={capture_radius}: raise min_gap or lower chaser_radius"
        )
    why = moving_unplaceable(spec)
    if why is not None:
        raise ValueError(why)
    return OrbitDrawer(spec, int(max_tries), int(wide_tries))


class OrbitDrawer:
    """Draws moving fields of one checked spec (made by :func:`orbit_drawer`): the kernel's
    rules are built once, so a draw is one word per generator and one compiled call."""

    __slots__ = ("_rows_code", "_rows_scratch", "max_tries", "rules", "spec")

    def __init__(self, spec: FieldSpec, max_tries: int, wide_tries: int = WIDE_TRIES) -> None:
        self.spec, self.max_tries = spec, max_tries
        self.rules = OrbitRules(
            dim=spec.dim,
            n_targets=spec.n_targets,
            n_obstacles=spec.n_obstacles,
            target_radius_lo=float(spec.target_radius[0]),
            target_radius_hi=float(spec.target_radius[1]),
            obstacle_radius_lo=float(spec.obstacle_radius[0]),
            obstacle_radius_hi=float(spec.obstacle_radius[1]),
            polygon_fraction=float(spec.polygon_fraction),
            half_size=float(spec.field_size) / 2.0,
            min_gap=float(spec.min_gap),
            target_clearance=float(spec.target_clearance),
            dock_clearance=float(spec.dock_clearance),
            target_start=float(max(spec.min_target_distance, spec.dock_clearance)),
            mean_motion=float(spec.mean_motion),
            horizon=checked_horizon(spec),
            drifting=spec.motion == "drifting",
            drift_lo=float(spec.drift_offset[0]),
            drift_hi=float(spec.drift_offset[1]),
            rho_max=float(spec.rho_max),
            spin_max=float(spec.spin_max),
            tries=int(max_tries),
            candidates=ORBIT_CANDIDATES[spec.dim],
            wide_tries=int(wide_tries),
            wide_candidates=WIDE_CANDIDATES,
        )
        self._rows_code: Callable[..., Any] | None = None
        self._rows_scratch: PlaceScratch | None = None

    def draw(self, rngs: Sequence[np.random.Generator]) -> FieldArrays:
        """One field per generator, each from one 64-bit word of its own generator.

        Raises:
            ValueError: some field found no valid try (naming what to change).
        """
        if len(rngs) == 1:
            words = rngs[0].bit_generator.random_raw(1)
        else:
            words = np.array([r.bit_generator.random_raw() for r in rngs], dtype=np.uint64)
        return self.from_words(words)

    def from_words(self, words: np.ndarray) -> FieldArrays:
        """The fields of the 64-bit words ``words`` (K,) uint64 (what :meth:`draw` takes from
        the generators)."""
        drawn = self.place(words)
        if not drawn.placed.all():
            spec, rules = self.spec, self.rules
            raise ValueError(
                f"could not place n_targets={spec.n_targets} and n_obstacles={spec.n_obstacles} "
                f"on relative orbits (motion={spec.motion!r}) in field_size={spec.field_size} m "
                f"with min_gap={spec.min_gap} m after {rules.tries} tries and "
                f"{rules.wide_tries} wider ones; lower n_obstacles or the radii, raise "
                "field_size, or give the orbits room (rho_max: every drift-free orbit is "
                "centred on the along-track axis, so small amplitudes crowd it)"
            )
        rules = self.rules
        return FieldArrays(
            rules.dim, rules.half_size, rules.n_targets, drawn.centers, drawn.radii,
            drawn.vertices, drawn.n_vertices, velocities=drawn.velocities, spins=drawn.spins,
        )  # fmt: skip

    def place(self, words: np.ndarray) -> DrawnOrbits:
        """Run the compiled draw on ``words`` (K,) uint64; rows whose ``placed`` is False found
        no valid try (their other arrays are meaningless)."""
        out = self.empty(len(words))
        rows = np.arange(len(words), dtype=np.int64)
        words = np.ascontiguousarray(words, dtype=np.uint64)
        _draw_orbits(words, rows, self.rules, self._scratch(), out)
        return out

    def empty(self, num: int) -> DrawnOrbits:
        """Room for ``num`` fields of this spec (zeros; none placed)."""
        rules = self.rules
        dim = rules.dim
        b_all = rules.n_targets + rules.n_obstacles
        v_max = MAX_POLYGON_VERTICES if dim == 2 else 0
        return DrawnOrbits(
            centers=np.zeros((num, b_all, dim)),
            velocities=np.zeros((num, b_all, dim)),
            radii=np.zeros((num, b_all)),
            vertices=np.zeros((num, rules.n_obstacles, v_max, 2)),
            n_vertices=np.zeros((num, rules.n_obstacles), dtype=np.int64),
            spins=np.zeros((num, b_all)),
            placed=np.zeros(num, dtype=np.bool_),
        )

    def draw_rows(self, words: np.ndarray, rows: np.ndarray, out: DrawnOrbits) -> None:
        """Draw the fields of ``words`` (K,) uint64 into the rows ``rows`` (K,) int64 of ``out``
        (made by :meth:`empty`; ``out.placed`` says which found a valid try): the fields
        :meth:`place` gives, each row overwritten whole.

        One call of machine code resolved once (:func:`~debris_gym.jit.specialise`), with
        working arrays kept from call to call: what a thread that draws fields ahead calls
        while the missions fly, holding Python's lock only to enter and leave. Calls must not
        overlap (one thread draws).
        """
        code, scratch = self._rows_code, self._rows_scratch
        if code is None or scratch is None:
            scratch = self._rows_scratch = self._scratch()
            code = self._rows_code = specialise(_draw_orbits, words, rows, self.rules, scratch, out)
        code(words, rows, self.rules, scratch, out)

    def _scratch(self) -> PlaceScratch:
        rules = self.rules
        b_all = rules.n_targets + rules.n_obstacles
        spacing = np.full(b_all, rules.min_gap)
        spacing[: rules.n_targets] += rules.target_clearance
        return PlaceScratch(spacing, np.zeros((b_all, 6)), np.empty(POLYGON_DRAWS))


def stream_uniform(key: int, index: int) -> float:
    """Uniform number ``index`` (0, 1, ...) of the stream of ``key``: output ``index`` of
    SplitMix64 seeded with ``key`` as a double in [0, 1) (the top 53 bits)."""
    return float(_uniform(np.uint64(key), index))


@inlined
def _mix(z):
    """SplitMix64's output function [Steele14] of a uint64."""
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@inlined
def _uniform(key, index):
    """Number ``index`` of key ``key``'s stream: SplitMix64 output ``index`` (its state after
    index + 1 increments), in [0, 1)."""
    z = _mix(key + (np.uint64(index) + _ONE) * _GAMMA)
    return np.float64(z >> _S11) * _UNIT


@inlined
def _try_key(word, j):
    """Key of try ``j`` of the draw of ``word``: the word itself for try 0, else the mixed
    j-th SplitMix64 output of the word, so the tries' streams are unrelated."""
    if j == 0:
        return word
    return _mix(_mix(word + np.uint64(j) * _TRY_GAMMA))


@kernel
def _draw_orbits(words, rows, rules, scratch, out):
    """The bodies of K moving fields from their words ``words`` (K,) uint64 (module docstring),
    written into the rows ``rows`` (K,) of ``out`` (:class:`DrawnOrbits`): each field tried
    with the keys :func:`_try_key` until every body is placed, ``rules.tries`` times with
    ``rules.candidates`` candidates per body, then ``rules.wide_tries`` times with
    ``rules.wide_candidates``.

    Stream layout of a try (indices of :func:`_uniform`): B radii (targets first); in 2D O
    polygon flags, O × 10 polygon shape numbers and O spins; then B × C candidates of P numbers:
    ρ, α, y_c (+ ρ_z, β in 3D; + x_c when drifting), computed only as far as they are tried. A
    body's elements (x_c, y_c, a = ρ cos α, b = ρ sin α, a_z = ρ_z cos β, b_z = ρ_z sin β)
    give x = x_c + a sin nt + b cos nt, y = y_c − 1.5 n x_c t + 2(a cos nt − b sin nt),
    z = a_z sin nt + b_z cos nt; its state at t = 0 is what the field hands out.
    """
    for r in range(words.shape[0]):
        k = rows[r]
        for attempt in range(rules.tries + rules.wide_tries):
            key = _try_key(words[r], attempt)
            n_cand = rules.candidates if attempt < rules.tries else rules.wide_candidates
            out.placed[k] = _place(key, k, n_cand, rules, scratch, out)
            if out.placed[k]:
                break


@kernel
def _place(key, k, n_cand, rules, scratch, out):
    """One try of field ``k`` from the stream of ``key`` with ``n_cand`` candidates per body
    (layout: :func:`_draw_orbits`), written into row ``k`` of ``out``; True if every body found
    a candidate."""
    dim, t, o = rules.dim, rules.n_targets, rules.n_obstacles
    n, horizon = rules.mean_motion, rules.horizon
    b_all = t + o
    p = 3 + (2 if dim == 3 else 0) + (1 if rules.drifting else 0)
    start = b_all + (o * (2 + POLYGON_DRAWS) if dim == 2 else 0)
    radii, vertices, n_vertices, spins = out.radii, out.vertices, out.n_vertices, out.spins
    spacing, elem, shape = scratch.spacing, scratch.elem, scratch.shape
    for b in range(b_all):
        if b < t:
            lo, hi = rules.target_radius_lo, rules.target_radius_hi
        else:
            lo, hi = rules.obstacle_radius_lo, rules.obstacle_radius_hi
        radii[k, b] = lo + (hi - lo) * _uniform(key, b)
    if dim == 2:
        for j in range(o):
            # a failed try may have left a polygon here
            n_vertices[k, j] = 0
            vertices[k, j] = 0.0
            spins[k, t + j] = 0.0
            if _uniform(key, b_all + j) < rules.polygon_fraction:
                first = b_all + o + j * POLYGON_DRAWS
                for i in range(POLYGON_DRAWS):
                    shape[i] = _uniform(key, first + i)
                n_vertices[k, j] = convex_polygon(shape, radii[k, t + j], vertices[k, j])
                spin_u = _uniform(key, b_all + o + o * POLYGON_DRAWS + j)
                spins[k, t + j] = rules.spin_max * (2.0 * spin_u - 1.0)
    for b in range(b_all):
        r = radii[k, b]
        lim = rules.half_size - r - rules.min_gap
        dock_need = rules.dock_clearance + r
        found = False
        for c in range(n_cand):
            q = start + (b * n_cand + c) * p
            xc = 0.0
            if rules.drifting:
                w = _uniform(key, q + p - 1)
                span = rules.drift_hi - rules.drift_lo
                mag = rules.drift_lo + span * (2.0 * w if w < 0.5 else 2.0 * w - 1.0)
                xc = -mag if w < 0.5 else mag
            slide = -1.5 * n * xc * horizon  # along-track displacement of the centre
            cap = min(rules.rho_max, lim - abs(xc), (2.0 * lim - abs(slide)) / 4.0)
            if cap < 0.0:
                continue
            rho = cap * np.sqrt(_uniform(key, q))  # area-uniform in the (x, y/2) disc
            alpha = 2.0 * np.pi * _uniform(key, q + 1)
            ea = rho * np.cos(alpha)
            eb = rho * np.sin(alpha)
            y_lo = -lim + 2.0 * rho - min(slide, 0.0)
            y_hi = lim - 2.0 * rho - max(slide, 0.0)
            yc = y_lo + (y_hi - y_lo) * _uniform(key, q + 2)
            ez = 0.0
            fz = 0.0
            if dim == 3:
                rho_z = min(rules.rho_max, lim) * _uniform(key, q + 3)
                beta = 2.0 * np.pi * _uniform(key, q + 4)
                ez = rho_z * np.cos(beta)
                fz = rho_z * np.sin(beta)
            if b < t:  # a target starts min_target_distance from the dock
                x0 = xc + eb
                y0 = yc + 2.0 * ea
                reach = rules.target_start + r
                if x0 * x0 + y0 * y0 + fz * fz < reach * reach:
                    continue
            if not apart(xc, yc, ea, eb, ez, fz, dock_need, dim, n, horizon):
                continue
            clear = True
            for j in range(b):
                need = r + radii[k, j] + max(spacing[b], spacing[j])
                if not apart(
                    xc - elem[j, 0], yc - elem[j, 1], ea - elem[j, 2], eb - elem[j, 3],
                    ez - elem[j, 4], fz - elem[j, 5], need, dim, n, horizon,
                ):  # fmt: skip
                    clear = False
                    break
            if clear:
                elem[b, 0] = xc
                elem[b, 1] = yc
                elem[b, 2] = ea
                elem[b, 3] = eb
                elem[b, 4] = ez
                elem[b, 5] = fz
                out.centers[k, b, 0] = xc + eb
                out.centers[k, b, 1] = yc + 2.0 * ea
                out.velocities[k, b, 0] = n * ea
                out.velocities[k, b, 1] = -1.5 * n * xc - 2.0 * n * eb
                if dim == 3:
                    out.centers[k, b, 2] = fz
                    out.velocities[k, b, 2] = n * ez
                found = True
                break
        if not found:
            return False
    return True
