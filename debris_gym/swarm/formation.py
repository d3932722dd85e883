"""The formation of a reconfiguration: slots on shells around a central body, and who flies where.

A reconfiguration ([Bandyopadhyay17]) flies N chasers from their start slots to
N formation slots, one each. The slots here lie on shells around the field's first body (its
"asteroid", Fig. 6 of the paper): shell j at ``core + j · spacing`` (j = 1, 2, …), a circle in
2D and a sphere in 3D, each holding as many slots as keep every two of them ``spacing`` apart;
the last shell holds the rest. No gymnasium or PettingZoo import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import pdist

__all__ = ["checked_slot_assignment", "formation_slots", "nearest_slots", "outer_radius"]

_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def _circle(m: int, radius: float, phase: float) -> np.ndarray:
    angles = phase + 2.0 * math.pi * np.arange(m) / m
    return radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _sphere(m: int, radius: float) -> np.ndarray:
    """``m`` points spread evenly over a sphere (a Fibonacci lattice)."""
    k = np.arange(m) + 0.5
    z = 1.0 - 2.0 * k / m
    rho = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = _GOLDEN_ANGLE * k
    return radius * np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


def _min_distance(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


def _shell(m: int, radius: float, dim: int, phase: float) -> np.ndarray:
    return _circle(m, radius, phase) if dim == 2 else _sphere(m, radius)


def _shell_capacity(radius: float, spacing: float, dim: int, most: int) -> int:
    """Most slots, up to ``most``, a shell of ``radius`` holds ``spacing`` apart (at least 1)."""
    if dim == 2:
        if spacing >= 2.0 * radius:
            return 1
        m = math.floor(math.pi / math.asin(spacing / (2.0 * radius)) + 1e-9)
        return max(1, min(m, most))
    # a sphere's area over a slot's square bounds the count; the lattice then decides
    m = max(1, min(most, int(4.0 * math.pi * radius * radius / (spacing * spacing))))
    while m > 1 and _min_distance(_sphere(m, radius)) < spacing:
        m -= 1
    return m


def formation_slots(n: int, core: float, spacing: float, dim: int) -> np.ndarray:
    """(n, dim) slot offsets (m) from the formation's centre: shells at ``core + j · spacing``
    (j = 1, 2, …), filled inside out, every two slots at least ``spacing`` apart (and every
    slot ``spacing`` or more outside the core's surface).

    Raises:
        ValueError: ``n`` < 1, ``dim`` not 2 or 3, or a length not positive and finite.
    """
    if not 1 <= n:
        raise ValueError(f"n={n} is out of range; allowed: at least 1")
    if dim not in (2, 3):
        raise ValueError(f"dim={dim} is not allowed; allowed: 2 or 3")
    for name, value in (("core", core), ("spacing", spacing)):
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name}={value!r} m is out of range; allowed: > 0 and finite")
    slots: list[np.ndarray] = []
    left, j = n, 1
    while left > 0:
        radius = core + j * spacing
        m = _shell_capacity(radius, spacing, dim, left)
        take = min(m, left)
        # every other ring turned by half a slot: neighbouring rings do not line up radially
        shell = _shell(take, radius, dim, phase=0.5 * (j % 2) * 2.0 * math.pi / m)
        slots.append(shell)
        left -= take
        j += 1
    return np.concatenate(slots)


def outer_radius(slots: np.ndarray, capture_radius: float, chaser_radius: float) -> float:
    """Radius (m) of the ball around the formation's centre that holds every slot's capture
    zone with the chaser in it."""
    return float(np.max(np.linalg.norm(slots, axis=1))) + capture_radius + chaser_radius


def nearest_slots(starts: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """(K,) the slot of each chaser that minimises the sum of straight-line distances from the
    starts (K, dim) to the slots (K, dim) (Hungarian, ``linear_sum_assignment``)."""
    cost = np.linalg.norm(starts[:, None, :] - slots[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(len(starts), dtype=np.int64)
    out[rows] = cols
    return out


def checked_slot_assignment(value: Sequence[Any] | np.ndarray, k: int) -> np.ndarray:
    """``value`` — one slot index per chaser, or one one-slot list per chaser (the form of
    a target assignment's lists), or a (K, K) bool table (row: chaser, column: slot) — every
    slot once, as a (K,) int array.

    Raises:
        ValueError: not a permutation of 0 … K − 1 in one of those forms.
    """
    try:
        array = np.asarray(value)
        if array.shape == (k, k) and array.dtype == bool and (array.sum(axis=1) == 1).all():
            array = np.argmax(array, axis=1)
        elif array.shape == (k, 1):
            array = array[:, 0]
    except (TypeError, ValueError) as err:
        raise ValueError(f"assignment={value!r} is not a list of {k} slot indices") from err
    if (
        array.shape != (k,)
        or array.dtype.kind not in "iu"
        or sorted(array.tolist()) != list(range(k))
    ):
        raise ValueError(
            f"assignment={value!r} must give each of the {k} chasers its own slot: a "
            f"permutation of 0 … {k - 1}"
        )
    return array.astype(np.int64)
