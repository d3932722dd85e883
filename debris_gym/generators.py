"""Seeded debris-field generators and presets.

Every generator takes a :class:`numpy.random.Generator` and returns a :class:`Scenario` that is
guaranteed to be usable: bodies do not overlap (their bounding circles / spheres are at least
``min_gap`` apart), the dock and every target's capture zone are kept free, and a collision-free
route from the dock to every target is verified on an occupancy grid (:func:`is_solvable`), not
assumed. A draw that fails the check is thrown away and drawn again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.ndimage

from debris_gym.geometry import FieldGeometry
from debris_gym.scenario import Body, Scenario


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


def _random_convex_polygon(rng: np.random.Generator, radius: float) -> np.ndarray:
    """CCW convex polygon (3-7 vertices) with circumradius ``radius`` about the origin (m)."""
    while True:
        k = int(rng.integers(3, 8))
        angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, size=k))
        gaps = np.diff(np.concatenate([angles, angles[:1] + 2.0 * np.pi]))
        if gaps.max() < 0.8 * np.pi and gaps.min() > 0.15:
            break
    pts = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    pts[:, 0] *= rng.uniform(0.5, 1.0)  # an affine squash keeps it convex and counter-clockwise
    rot = rng.uniform(0.0, 2.0 * np.pi)
    c, s = math.cos(rot), math.sin(rot)
    pts = pts @ np.array([[c, s], [-s, c]])
    pts *= radius / np.linalg.norm(pts, axis=1).max()
    return pts


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

    The dock sits at the origin, the one point at rest under CWH. Raises ``ValueError`` naming the
    setting to change if no valid field is found in ``max_tries`` draws.
    """
    half = spec.field_size / 2.0
    bounds = tuple((-half, half) for _ in range(spec.dim))
    for _ in range(max_tries):
        scenario = _draw_field(rng, spec, bounds, mean_motion, dt, max_accel)
        if scenario is not None and is_solvable(scenario, spec.chaser_radius, capture_radius):
            return scenario
    raise ValueError(
        f"could not place n_targets={spec.n_targets} and n_obstacles={spec.n_obstacles} "
        f"in field_size={spec.field_size} m with min_gap={spec.min_gap} m after {max_tries} "
        "draws; lower n_obstacles or the obstacle radius range, or raise field_size"
    )


def _draw_field(rng, spec: FieldSpec, bounds, mean_motion, dt, max_accel) -> Scenario | None:
    dim = spec.dim
    half = spec.field_size / 2.0
    centers: list[np.ndarray] = []
    radii: list[float] = []
    keep_out: list[float] = []  # extra free margin each placed body demands around itself

    def place(radius: float, margin: float, min_dock: float) -> np.ndarray | None:
        lim = half - radius - spec.min_gap
        if lim <= 0:
            return None
        for _ in range(200):
            p = rng.uniform(-lim, lim, size=dim)
            if np.linalg.norm(p) < min_dock + radius:
                continue
            if centers:
                gaps = np.linalg.norm(np.asarray(centers) - p, axis=1) - np.asarray(radii) - radius
                need = spec.min_gap + np.maximum(np.asarray(keep_out), margin)
                if np.any(gaps < need):
                    continue
            centers.append(p)
            radii.append(radius)
            keep_out.append(margin)
            return p
        return None

    targets = []
    for _ in range(spec.n_targets):
        r = float(rng.uniform(*spec.target_radius))
        p = place(r, spec.target_clearance, max(spec.min_target_distance, spec.dock_clearance))
        if p is None:
            return None
        targets.append(Body(position=tuple(p), radius=r, velocity=(0.0,) * dim))
    obstacles = []
    for _ in range(spec.n_obstacles):
        r = float(rng.uniform(*spec.obstacle_radius))
        polygon = dim == 2 and rng.uniform() < spec.polygon_fraction
        verts = _random_convex_polygon(rng, r) if polygon else None
        p = place(r, 0.0, spec.dock_clearance)
        if p is None:
            return None
        vertices = None if verts is None else tuple((float(x), float(y)) for x, y in verts)
        obstacles.append(
            Body(position=tuple(p), radius=r, velocity=(0.0,) * dim, vertices=vertices)
        )
    return Scenario(
        dim=dim,
        bounds=bounds,
        dock=(0.0,) * dim,
        targets=tuple(targets),
        obstacles=tuple(obstacles),
        mean_motion=mean_motion,
        dt=dt,
        max_accel=max_accel,
        name=f"random{dim}d",
    )


def occupancy_grid(
    scenario: Scenario, inflate: float, cell: float
) -> tuple[np.ndarray, np.ndarray]:
    """Rasterise the field: True where a cell centre is within ``inflate`` (m) of a body.

    Returns:
        ``(occupied, centres)``: a boolean array with one axis per dimension and the (…, dim)
        cell-centre coordinates (m).
    """
    axes = [np.arange(lo + cell / 2.0, hi, cell) for lo, hi in scenario.bounds]
    mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    geom = FieldGeometry(scenario)
    flat = mesh.reshape(-1, scenario.dim)
    occupied = np.zeros(flat.shape[0], dtype=bool)
    for start in range(0, flat.shape[0], 4096):
        chunk = flat[start : start + 4096]
        occupied[start : start + 4096] = (geom.signed_distance(chunk) <= inflate).any(axis=1)
    return occupied.reshape(mesh.shape[:-1]), mesh


def is_solvable(
    scenario: Scenario, chaser_radius: float, capture_radius: float, cell: float | None = None
) -> bool:
    """True if a collision-free route links the dock to a capture point of every target.

    Two checks, the first a proof and the second a search:

    1. If the bodies' bounding circles / spheres, inflated by ``chaser_radius``, are pairwise
       disjoint and lie strictly inside the bounds, the space left for the chaser's centre is
       connected (the complement of finitely many disjoint closed balls in an open box of dimension
       >= 2 is path-connected). It then suffices that the dock and one capture point per target
       are free. Generated fields always take this route; it costs O(bodies²).
    2. Otherwise (a hand-made field with touching bodies): :func:`grid_route_exists`.
    """
    if _disjoint_balls_route(scenario, chaser_radius, capture_radius):
        return True
    return grid_route_exists(scenario, chaser_radius, capture_radius, cell)


def _capture_points(scenario: Scenario, chaser_radius: float, capture_radius: float):
    """Candidate chaser positions inside each target's capture zone (16 / 26 directions)."""
    dim = scenario.dim
    if dim == 2:
        ang = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
        dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    else:
        grid = np.array(np.meshgrid(*[[-1, 0, 1]] * 3, indexing="ij")).reshape(3, -1).T
        grid = grid[np.any(grid != 0, axis=1)]
        dirs = grid / np.linalg.norm(grid, axis=1, keepdims=True)
    for t in scenario.targets:
        reach = t.radius + chaser_radius + 0.5 * capture_radius
        yield np.asarray(t.position) + reach * dirs


def _disjoint_balls_route(scenario: Scenario, chaser_radius: float, capture_radius: float) -> bool:
    centres = scenario.body_positions(0.0)
    reach = np.array([b.radius for b in scenario.bodies]) + chaser_radius
    low, high = scenario.low, scenario.high
    if np.any(centres - reach[:, None] <= low) or np.any(centres + reach[:, None] >= high):
        return False
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1) - reach[:, None] - reach[None]
    np.fill_diagonal(gaps, np.inf)
    if np.any(gaps <= 0.0):
        return False

    def free(points: np.ndarray) -> np.ndarray:
        inside = np.all((points > low) & (points < high), axis=-1)
        dist = np.linalg.norm(points[:, None] - centres[None], axis=-1) - reach[None]
        return inside & np.all(dist > 0.0, axis=1)

    if not free(np.asarray(scenario.dock, dtype=float)[None])[0]:
        return False
    return all(
        free(points).any() for points in _capture_points(scenario, chaser_radius, capture_radius)
    )


def grid_route_exists(
    scenario: Scenario, chaser_radius: float, capture_radius: float, cell: float | None = None
) -> bool:
    """Occupancy-grid search for a route from the dock to every target's capture zone.

    Conservative: a cell counts as free only if a disc (ball) of half its diagonal around its
    centre clears every body by ``chaser_radius``, so neighbouring free cells are joined by a
    collision-free straight segment. Free cells are grouped into face-connected components
    (``scipy.ndimage.label``); the dock's cell and, for each target, a free cell from whose free
    disc the chaser's surface gets within ``capture_radius`` of the target surface must share a
    component. Works for any field, overlapping bodies included.
    """
    if cell is None:
        cell = scenario.size / (200.0 if scenario.dim == 2 else 60.0)
    half_diag = cell * math.sqrt(scenario.dim) / 2.0
    occupied, centres = occupancy_grid(scenario, chaser_radius + half_diag, cell)
    labels, _ = scipy.ndimage.label(~occupied)
    low = scenario.low

    def cell_of(p):
        idx = np.floor((np.asarray(p) - low) / cell).astype(int)
        return tuple(np.clip(idx, 0, np.array(occupied.shape) - 1))

    dock_label = labels[cell_of(scenario.dock)]
    if dock_label == 0:
        return False
    for target in scenario.targets:
        gap = np.linalg.norm(centres - np.asarray(target.position), axis=-1) - target.radius
        # From a free cell centre the chaser may move half a diagonal in any direction (the free
        # disc), e.g. straight at the target, which shortens the surface gap by that much.
        zone = (gap - chaser_radius <= capture_radius + half_diag) & (labels == dock_label)
        if not zone.any():
            return False
    return True


def paper_field(dt: float = 0.1, max_accel: float = 1.0) -> Scenario:
    """Seed 000's world: a 20 × 20 unit square, spherical debris between the targets, a dock.

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
