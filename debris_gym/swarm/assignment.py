"""Which chaser of a swarm captures which target, when the swarm is given an assignment.

With ``assignment="given"`` every target is one chaser's: its goal, its captures and its
success count its own targets alone. :func:`balanced_assignment` is the default rule;
:func:`checked_assignment` validates one a user (or a baseline) gives. No gymnasium import.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["balanced_assignment", "checked_assignment"]


def balanced_assignment(docks: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(K, T) bool: each target to one chaser, each chaser at most ⌈T / K⌉ targets, with the
    smallest total distance (m) from a chaser's dock slot to its targets' surfaces (an optimal
    assignment, scipy's ``linear_sum_assignment``, over K · ⌈T / K⌉ chaser places).

    Args:
        docks: (K, dim) the chasers' dock slots (m).
        centers: (T, dim) the targets' centres (m).
        radii: (T,) the targets' bounding radii (m).
    """
    k, t = docks.shape[0], centers.shape[0]
    places = math.ceil(t / k)
    gaps = np.linalg.norm(docks[:, None, :] - centers[None, :, :], axis=-1) - radii[None, :]
    cost = np.repeat(gaps, places, axis=0)  # row p is chaser p // places
    rows, cols = linear_sum_assignment(cost)
    out = np.zeros((k, t), dtype=bool)
    out[rows // places, cols] = True
    return out


def checked_assignment(value: Any, n_chasers: int, n_targets: int) -> np.ndarray:
    """An assignment given as one list of target indices per chaser, or a (K, T) bool array,
    as (K, T) bool; every target must be exactly one chaser's.

    Raises:
        ValueError: naming ``assignment`` and what is wrong.
    """
    k, t = n_chasers, n_targets
    if isinstance(value, np.ndarray) and value.dtype == bool:
        if value.shape != (k, t):
            raise ValueError(
                f"assignment must have shape ({k}, {t}) (chasers, targets), got {value.shape}"
            )
        out = value.copy()
    else:
        if not isinstance(value, (list, tuple)) or len(value) != k:
            raise ValueError(
                f"assignment must be {k} lists of target indices (one per chaser) or a ({k}, "
                f"{t}) bool array, got {value!r}"
            )
        out = np.zeros((k, t), dtype=bool)
        for chaser, targets in enumerate(value):
            for j in np.atleast_1d(np.asarray(targets)).tolist():
                if isinstance(j, bool) or not isinstance(j, int) or not 0 <= j < t:
                    raise ValueError(
                        f"assignment[{chaser}] holds {j!r}; target indices are integers in "
                        f"[0, {t - 1}]"
                    )
                out[chaser, j] = True
    owners = out.sum(axis=0)
    if np.any(owners != 1):
        j = int(np.flatnonzero(owners != 1)[0])
        raise ValueError(
            f"assignment gives target {j} to {int(owners[j])} chasers; every target must be "
            "exactly one chaser's"
        )
    return out
