"""Random convex polygons drawn without rejection, the 2D obstacles' shapes (compiled).

Both generators (:mod:`debris_gym.generators`, :mod:`debris_gym.orbit_fields`) shape their
polygons here from :data:`POLYGON_DRAWS` uniform numbers each. Lengths in m.
"""

from __future__ import annotations

import numpy as np

from debris_gym.field_spec import MAX_POLYGON_VERTICES
from debris_gym.jit import inlined, kernel

__all__ = ["ANGLE_JITTER", "POLYGON_DRAWS", "convex_polygon", "convex_polygons"]

ANGLE_JITTER = 0.3
"""Polygon vertex angles deviate from even spacing by at most ± half this share of the spacing."""

POLYGON_DRAWS = 3 + MAX_POLYGON_VERTICES
"""Uniform numbers per polygon: vertex count, one angle jitter per vertex, squash, rotation."""


@inlined
def convex_polygon(shape, radius, out):
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
def convex_polygons(shape, radius):
    """:func:`convex_polygon` for K polygons: (K, V, 2) vertices and (K,) counts from the
    (K, :data:`POLYGON_DRAWS`) uniform numbers ``shape`` and (K,) circumradii ``radius`` (m)."""
    vertices = np.zeros((shape.shape[0], MAX_POLYGON_VERTICES, 2))
    counts = np.zeros(shape.shape[0], dtype=np.int64)
    for k in range(shape.shape[0]):
        counts[k] = convex_polygon(shape[k], radius[k], vertices[k])
    return vertices, counts
