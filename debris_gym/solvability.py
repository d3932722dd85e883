"""Is a field solvable? Proofs and searches for a collision-free route to every target.

A random field handed to a user must be solvable: a route from the dock to a capture point of
every target that keeps the chaser clear of every body. :func:`route_proof` proves it for many
fields at once when the inflated bodies are pairwise disjoint balls inside the bounds (the free
space is then connected); :func:`grid_route_exists` searches an occupancy grid of the library's
geometry for any other field; :func:`is_solvable` tries the proof, then the search.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.ndimage

from debris_gym.batch_geometry import FieldBatch
from debris_gym.geometry import FieldGeometry, distance
from debris_gym.scenario import Scenario


@functools.cache
def _capture_directions(dim: int) -> np.ndarray:
    """Unit directions (16 in 2D, 26 in 3D) of the candidate capture points around a target."""
    if dim == 2:
        ang = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
        dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    else:
        grid = np.array(np.meshgrid(*[[-1, 0, 1]] * 3, indexing="ij")).reshape(3, -1).T
        grid = grid[np.any(grid != 0, axis=1)]
        dirs = grid / np.linalg.norm(grid, axis=1, keepdims=True)
    dirs.setflags(write=False)
    return dirs


PROOF_PAIRS = 1 << 21
"""Most body pairs :func:`route_proof` holds at once (about 50 MB of temporaries in 2D)."""


def route_proof(
    centers: np.ndarray,
    radii: np.ndarray,
    n_targets: int,
    low: np.ndarray,
    high: np.ndarray,
    dock: np.ndarray,
    chaser_radius: float,
    capture_radius: float,
) -> np.ndarray:
    """The disjoint-balls proof of :func:`is_solvable` for K fields at once, shape (K,).

    True where the bounding balls inflated by ``chaser_radius`` are pairwise disjoint and
    strictly inside the bounds, the dock is free, and each target has a free capture point.
    Fields are taken :data:`PROOF_PAIRS` body pairs at a time (the pairwise gaps of 64 fields
    of 2000 bodies would take gigabytes); each field's answer is its own.
    """
    num, n_bodies, dim = centers.shape
    rows = max(1, PROOF_PAIRS // max(n_bodies * n_bodies, 1))
    if num > rows:
        return np.concatenate([
            route_proof(
                centers[k : k + rows], radii[k : k + rows], n_targets, low, high, dock,
                chaser_radius, capture_radius,
            )
            for k in range(0, num, rows)
        ])  # fmt: skip
    reach = radii + chaser_radius

    def inside(points: np.ndarray, margin) -> np.ndarray:  # (K, P, dim) -> (K, P)
        ok = np.ones(points.shape[:-1], dtype=bool)
        for axis in range(dim):
            x = points[..., axis]
            ok &= (x - margin > low[axis]) & (x + margin < high[axis])
        return ok

    def free(points: np.ndarray) -> np.ndarray:  # (K, P, dim) -> (K, P)
        dist = distance(points[:, :, None, :], centers[:, None]) - reach[:, None]
        return inside(points, 0.0) & (dist > 0.0).all(axis=2)

    gaps = distance(centers[:, :, None], centers[:, None]) - reach[:, :, None] - reach[:, None]
    gaps[:, np.arange(n_bodies), np.arange(n_bodies)] = np.inf
    ok = inside(centers, reach).all(axis=1) & (gaps > 0.0).all(axis=(1, 2))
    ok &= free(np.broadcast_to(dock, (num, 1, dim)))[:, 0]
    dirs = _capture_directions(dim)
    t = n_targets
    depth = radii[:, :t] + chaser_radius + 0.5 * capture_radius
    points = centers[:, :t, None, :] + depth[..., None, None] * dirs  # (K, T, D, dim)
    ok &= np.any(free(points.reshape(num, -1, dim)).reshape(num, t, -1), axis=2).all(axis=1)
    return ok


TILE_CELLS = {2: 16, 3: 8}
"""Cells per edge of the square / cubic tiles :func:`occupancy_grid` sorts the bodies into."""

_CHUNK = 4096
"""Cells per call into the compiled gaps (bounds the (cells, bodies) temporary)."""


def occupancy_grid(
    scenario: Scenario, inflate: float, cell: float
) -> tuple[np.ndarray, np.ndarray]:
    """Rasterise the field: True where a cell centre is within ``inflate`` (m) of a body.

    The grid is cut into tiles of :data:`TILE_CELLS` cells per edge, and each cell is tested
    only against the bodies whose reach (bounding radius, or farthest polygon vertex) plus
    ``inflate`` comes near its tile; every other body is provably farther than ``inflate``
    from the cell. Each tested (cell, body) gap is the library's own
    (:meth:`~debris_gym.batch_geometry.FieldBatch.gaps`, the same operations), so the grid is
    the one a test of every cell against every body gives, at a cost of about cells × (bodies
    near a tile) instead of cells × bodies.

    Returns:
        ``(occupied, centres)``: a boolean array with one axis per dimension and the (…, dim)
        cell-centre coordinates (m).
    """
    geom = FieldGeometry(scenario)
    vertices, counts = geom.batch.vertex_arrays(0)
    return field_occupancy(
        geom.centers, geom.radii, vertices, counts, geom.batch.polygon_start, scenario.low,
        scenario.high, inflate, cell,
    )  # fmt: skip


def field_occupancy(
    centers: np.ndarray,
    radii: np.ndarray,
    vertices: np.ndarray,
    n_vertices: np.ndarray,
    polygon_start: int,
    low: np.ndarray,
    high: np.ndarray,
    inflate: float,
    cell: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`occupancy_grid` of a field given as arrays (no :class:`Scenario` built).

    Args:
        centers: (B, dim) body centres (m); ``radii`` (B,) their bounding radii (m).
        vertices: (P, V, 2) polygon vertices of bodies ``polygon_start …`` relative to their
            centres (m); ``n_vertices`` (P,) their counts, 0 for a circle (2D; empty in 3D).
        low, high: (dim,) world bounds (m).
        inflate, cell: as :func:`occupancy_grid`.
    """
    dim = len(low)
    axes = [np.arange(lo + cell / 2.0, hi, cell) for lo, hi in zip(low.tolist(), high.tolist())]
    mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    shape = mesh.shape[:-1]
    occupied = np.zeros(shape, dtype=bool)
    if len(radii) == 0 or occupied.size == 0:
        return occupied, mesh
    counts = n_vertices
    reach = np.array(radii, dtype=float)
    if dim == 2 and len(counts):
        far = np.hypot(vertices[..., 0], vertices[..., 1])
        far[np.arange(vertices.shape[1]) >= counts[:, None]] = 0.0
        body = polygon_start + np.arange(len(counts))
        reach[body] = np.maximum(reach[body], far.max(axis=1))
    # a tile's bodies: those within inflate of its box of cell centres, with a slack far
    # above rounding (a polygon's vertices lie on its circumcircle to the last bit)
    tile = TILE_CELLS[dim]
    n_tiles = [-(-n // tile) for n in shape]
    first = [ax[::tile] for ax in axes]
    last = [ax[np.minimum(np.arange(n) * tile + tile - 1, len(ax) - 1)] for ax, n in
            zip(axes, n_tiles)]  # fmt: skip
    lo = np.stack(np.meshgrid(*first, indexing="ij"), axis=-1).reshape(-1, dim)
    hi = np.stack(np.meshgrid(*last, indexing="ij"), axis=-1).reshape(-1, dim)
    outside = np.maximum(lo[:, None] - centers, 0.0) + np.maximum(centers - hi[:, None], 0.0)
    size = float(np.max(high - low))
    slack = 1e-6 * (size + reach)
    near = np.sqrt((outside**2).sum(axis=-1)) - reach <= inflate + slack  # (tiles, bodies)
    per_tile = near.sum(axis=1)
    width = int(per_tile.max())
    if width == 0:
        return occupied, mesh
    # one batch row per tile holding its bodies, padded with points far outside the world
    rows = len(per_tile)
    pad = high + size + inflate + 1.0
    tile_centers = np.broadcast_to(pad, (rows, width, dim)).copy()
    tile_radii = np.zeros((rows, width))
    polygonal = dim == 2 and len(counts)
    v = vertices.shape[1] if polygonal else 0
    tile_vertices = np.zeros((rows, width, v, 2))
    tile_counts = np.zeros((rows, width), dtype=np.int64)
    tile_of, body_of = np.nonzero(near)
    slot = np.arange(len(tile_of)) - np.repeat(np.cumsum(per_tile) - per_tile, per_tile)
    tile_centers[tile_of, slot] = centers[body_of]
    tile_radii[tile_of, slot] = radii[body_of]
    if polygonal:
        poly = body_of - polygon_start
        has = poly >= 0
        tile_vertices[tile_of[has], slot[has]] = vertices[poly[has]]
        tile_counts[tile_of[has], slot[has]] = counts[poly[has]]
    tiles = FieldBatch(rows, width, dim, max_vertices=max(v, 3))
    tiles.load_arrays(np.arange(rows), tile_centers, tile_radii, tile_vertices, tile_counts)
    index = np.indices(shape).reshape(dim, -1) // tile
    index_rows: tuple[np.ndarray, ...] = tuple(index)
    cell_tile = np.ravel_multi_index(index_rows, n_tiles)
    flat = mesh.reshape(-1, dim)
    out = occupied.reshape(-1)
    for start in range(0, flat.shape[0], _CHUNK):
        stop = start + _CHUNK
        gaps = tiles.gaps(flat[start:stop], cell_tile[start:stop])
        out[start:stop] = (gaps <= inflate).any(axis=1)
    return occupied, mesh


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


def _disjoint_balls_route(scenario: Scenario, chaser_radius: float, capture_radius: float) -> bool:
    radii = np.array([b.radius for b in scenario.bodies])
    return bool(
        route_proof(
            scenario.body_positions(0.0)[None], radii[None], len(scenario.targets),
            scenario.low, scenario.high, np.asarray(scenario.dock, dtype=float),
            chaser_radius, capture_radius,
        )[0]
    )  # fmt: skip


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
    geom = FieldGeometry(scenario)
    vertices, counts = geom.batch.vertex_arrays(0)
    return field_route_exists(
        geom.centers, geom.radii, vertices, counts, geom.batch.polygon_start,
        len(scenario.targets), scenario.low, scenario.high, np.asarray(scenario.dock, float),
        chaser_radius, capture_radius, cell,
    )  # fmt: skip


def field_route_exists(
    centers: np.ndarray,
    radii: np.ndarray,
    vertices: np.ndarray,
    n_vertices: np.ndarray,
    polygon_start: int,
    n_targets: int,
    low: np.ndarray,
    high: np.ndarray,
    dock: np.ndarray,
    chaser_radius: float,
    capture_radius: float,
    cell: float | None = None,
) -> bool:
    """:func:`grid_route_exists` of a field given as arrays (:func:`field_occupancy`'s; the
    first ``n_targets`` bodies are the targets, ``dock`` (dim,) is in m)."""
    dim = len(low)
    if cell is None:
        cell = float(np.max(high - low)) / (200.0 if dim == 2 else 60.0)
    half_diag = cell * math.sqrt(dim) / 2.0
    occupied, centres = field_occupancy(
        centers, radii, vertices, n_vertices, polygon_start, low, high,
        chaser_radius + half_diag, cell,
    )  # fmt: skip
    labels, _ = scipy.ndimage.label(~occupied)

    def cell_of(p):
        idx = np.floor((np.asarray(p) - low) / cell).astype(int)
        return tuple(np.clip(idx, 0, np.array(occupied.shape) - 1))

    dock_label = labels[cell_of(dock)]
    if dock_label == 0:
        return False
    for position, radius in zip(centers[:n_targets], radii[:n_targets].tolist()):
        gap = np.linalg.norm(centres - position, axis=-1) - radius
        # From a free cell centre the chaser may move half a diagonal in any direction (the free
        # disc), e.g. straight at the target, which shortens the surface gap by that much.
        zone = (gap - chaser_radius <= capture_radius + half_diag) & (labels == dock_label)
        if not zone.any():
            return False
    return True
