"""Post-processing of planned paths: polylines made easier to track without changing their course.

Gradient-descent paths chatter: near a body lying straight in the way to the goal the descent
zig-zags with its step length while it slides round. :func:`dejitter` jumps, from each kept point,
to the last later point within a few steps *in space* whose straight chord the caller's collision
test accepts. Over such short hops the path keeps its shape (its distance to the bodies) but loses
the back-and-forth that would make an arc-length reference stall.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["dejitter"]


def dejitter(
    points: np.ndarray, reach: float, clear: Callable[[np.ndarray, np.ndarray], bool]
) -> np.ndarray:
    """Drop back-and-forth detours from a dense path without changing its course.

    From each kept point, jump to the highest-index later point within ``reach`` (m, straight
    distance) whose chord ``clear(a, b)`` accepts (at most 8 candidates tried, farthest index
    first); the next point is always allowed.

    Args:
        points: (K, dim) path (m).
        reach: largest hop (m).
        clear: collision test of a straight segment.

    Returns:
        (K', dim) sub-sequence of ``points`` with the same first and last point.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) <= 2:
        return pts
    out = [pts[0]]
    i, last = 0, len(pts) - 1
    while i < last:
        dist = np.linalg.norm(pts[i + 1 :] - pts[i], axis=1)
        within = np.flatnonzero(dist <= reach) + i + 1
        j = i + 1
        for c in within[::-1][:8]:
            if c == i + 1 or clear(pts[i], pts[c]):
                j = int(c)
                break
        out.append(pts[j])
        i = j
    return np.asarray(out)
