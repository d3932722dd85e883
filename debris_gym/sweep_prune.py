"""Candidate pairs of bodies by sweep and prune: the pairs whose extents overlap on one axis,
in chunks of bounded size (the scenario checks' overlap and motion tests take them from
here)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

__all__ = ["overlapping_intervals"]


def overlapping_intervals(
    starts: np.ndarray, ends: np.ndarray, chunk: int, *, touching: bool
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield ``(a, b)`` index arrays of the pairs whose intervals ``[starts, ends]`` (B,)
    overlap, each pair once (a before b in the order of ``starts``), at most about ``chunk``
    pairs a time (a single interval's pairs are never split).

    Args:
        starts: (B,) interval starts.
        ends: (B,) interval ends (≥ starts).
        chunk: pairs per yield, roughly (one interval's pairs may exceed it).
        touching: whether intervals that only touch (one's end equals the other's start)
            count as overlapping.
    """
    count = len(starts)
    order = np.argsort(starts, kind="stable")
    ordered_starts, ordered_ends = starts[order], ends[order]
    # sorted intervals k+1 .. last-1 start before interval k ends
    last = np.searchsorted(ordered_starts, ordered_ends, side="right" if touching else "left")
    pending = np.maximum(last - np.arange(count) - 1, 0)
    k = 0
    while k < count:
        stop = k + max(1, int(np.searchsorted(np.cumsum(pending[k:]), chunk, side="right")))
        rows = np.arange(k, min(stop, count))
        n_pairs = pending[rows]
        first = np.repeat(rows, n_pairs)
        offset = np.arange(n_pairs.sum()) - np.repeat(np.cumsum(n_pairs) - n_pairs, n_pairs)
        yield order[first], order[first + 1 + offset]
        k = rows[-1] + 1
