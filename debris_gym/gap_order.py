"""The order of a mission's bodies by gap: the obstacle ranking the step keeps and the
observation reads (the nearest bodies first), re-sorted after every step and for the navigated
copy of a world (:mod:`debris_gym.uncertainty`)."""

from __future__ import annotations

from debris_gym.jit import inlined

__all__ = ["sort_by_gap"]


@inlined
def sort_by_gap(gaps, order):
    """Sort the body indices ``order`` by ``gaps`` (B,), nearest first, equal gaps by index.

    An insertion sort, started from the order of the step before: the chaser moves little in a
    step, so the order is nearly sorted already and the sort costs about one comparison per
    body, with branches that predict well (selecting the nearest few afresh every step, by
    insertion into a short sorted list, costs more: its branches mispredict). The result is the
    same (gap, index) order whatever the starting permutation.
    """
    for j in range(1, order.shape[0]):
        x = order[j]
        g = gaps[x]
        k = j - 1
        while k >= 0:
            y = order[k]
            h = gaps[y]
            if h < g or (h == g and y < x):
                break
            order[k + 1] = y
            k -= 1
        order[k + 1] = x
