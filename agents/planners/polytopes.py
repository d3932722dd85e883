"""Polytopes inscribed in the unit ball: the linear stand-ins for ball constraints in the QPs.

OSQP and HiGHS take no second-order cones, so a ball constraint ‖x − c‖ ≤ r (a clearance ball of
the tube smoother, a sphere of the SCP's chain, the thrust ball of the MPC and of the SCP) is
written as ``N (x − c) ≤ r·h`` with the polytope ``N x ≤ h`` of this module. Every vertex of the
polytope lies on the unit sphere, so inside the polytope ⇒ inside the ball (conservative), and
the ball of radius ``h`` (the inner-radius factor κ) is inside the polytope.

Two layouts of the facets (``kind``):

* ``"lattice"`` — 2D: the regular ``facets``-gon with a facet normal on +x. 3D: the 26 facets
  normal to the directions of the lattice {−1, 0, 1}³ (the cube's faces, edges and corners);
  ``facets`` sets the 2D polygon only. Used by the tube smoother
  (:mod:`agents.planners.tube`) and the MPC's thrust ball (:mod:`agents.control.mpc_params`).
* ``"fibonacci"`` — 2D: the regular ``facets``-gon turned by half a facet (a vertex on +x).
  3D: ``facets`` normals spread evenly on a Fibonacci sphere. Used by the SCP
  (:mod:`agents.planners.scp`) for its spheres, its thrust ball and its ‖u‖ epigraph, and for
  the inner-radius factor the spherical expansion joins spheres with.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np
from scipy.spatial import HalfspaceIntersection

__all__ = ["POLYTOPE_KINDS", "InscribedPolytope", "PolytopeKind", "inscribed_polytope"]

PolytopeKind = Literal["lattice", "fibonacci"]
POLYTOPE_KINDS: tuple[PolytopeKind, ...] = ("lattice", "fibonacci")


@dataclass(frozen=True)
class InscribedPolytope:
    """The polytope ``normals · x ≤ offset`` inscribed in the unit ball (dimensionless).

    Attributes:
        kind: the facet layout, one of :data:`POLYTOPE_KINDS`.
        normals: (F, dim) unit facet normals, read-only.
        offset: h, the distance of every facet from the centre; also the inner-radius factor
            κ = h (the ball of radius h touches every facet).
    """

    kind: PolytopeKind
    normals: np.ndarray
    offset: float

    @property
    def offsets(self) -> np.ndarray:
        """(F,) the offset of each facet (all equal to :attr:`offset`)."""
        return np.full(len(self.normals), self.offset)


def _outer_offset(normals: np.ndarray) -> float:
    """The offset h that puts the farthest vertex of ``normals · x ≤ h`` on the unit sphere."""
    halfspaces = np.hstack([normals, -np.ones((len(normals), 1))])
    vertices = HalfspaceIntersection(halfspaces, np.zeros(normals.shape[1])).intersections
    return 1.0 / float(np.linalg.norm(vertices, axis=1).max())


def _polygon_normals(facets: int, turn: float) -> np.ndarray:
    """Normals of the regular ``facets``-gon, the first at angle ``turn`` · 2π/facets."""
    angles = 2.0 * np.pi * (np.arange(facets) + turn) / facets
    return np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _lattice_normals() -> np.ndarray:
    """The 26 unit directions of {−1, 0, 1}³ without the origin."""
    dirs = [np.array(s, float) for s in itertools.product((-1, 0, 1), repeat=3) if any(s)]
    return np.array([v / np.linalg.norm(v) for v in dirs])


def _fibonacci_normals(facets: int) -> np.ndarray:
    """``facets`` unit directions spread evenly on a Fibonacci sphere."""
    k = np.arange(facets) + 0.5
    z = 1.0 - 2.0 * k / facets
    phi = np.pi * (1.0 + 5**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def inscribed_polytope(dim: int, facets: int, kind: PolytopeKind) -> InscribedPolytope:
    """The polytope of layout ``kind`` inscribed in the unit ball (see the module).

    Args:
        dim: 2 or 3.
        facets: 2D: the polygon's facet count (>= 3). 3D ``"fibonacci"``: the facet count
            (>= 6); 3D ``"lattice"``: not used (always 26 facets).
        kind: ``"lattice"`` or ``"fibonacci"``.

    Returns:
        An :class:`InscribedPolytope` (cached: its arrays are read-only).
    """
    if kind not in POLYTOPE_KINDS:
        raise ValueError(f"kind must be one of {POLYTOPE_KINDS}, got {kind!r}")
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    least = 6 if (dim, kind) == (3, "fibonacci") else 3
    if not (isinstance(facets, int) and not isinstance(facets, bool) and facets >= least):
        raise ValueError(
            f"facets must be an integer >= {least} for a {dim}D {kind} polytope, got {facets!r}"
        )
    return _build(int(dim), int(facets), kind)


@lru_cache(maxsize=32)
def _build(dim: int, facets: int, kind: PolytopeKind) -> InscribedPolytope:
    if dim == 2:
        normals = _polygon_normals(facets, 0.0 if kind == "lattice" else 0.5)
        offset = math.cos(math.pi / facets)
    else:
        normals = _lattice_normals() if kind == "lattice" else _fibonacci_normals(facets)
        offset = _outer_offset(normals)
    normals.setflags(write=False)
    return InscribedPolytope(kind, normals, offset)
