"""Section ``scaling``: the native vector env against the debris count, up to 1000 debris.

The 2D env with ``n_obstacles`` debris in a field whose edge grows as
``1000 m * sqrt(max(1, n / 20))`` (constant debris density), at the N given for each count in
``scaling_rows``, next to a 20-debris reference at every such N.

What is timed: the vector env right after ``reset(seed=0)`` (a few warm-up steps, then at most
``early_steps`` steps in all), i.e. the *step* cost with (almost) no autoresets, next to the
reset cost per sub-env timed on that ``reset``. Rows have section "vector_scaling".
"""

from __future__ import annotations

from typing import Any

from bench.config import DEFAULT_OBSTACLES, ID_2D, field_size_for
from bench.harness import drop_rates, interleave, paired_ratio
from bench.vector import VecMeasurement, vector_rows

EARLY_WARMUP = 3
"""Untimed steps after ``reset(seed=0)`` (fewer if ``early_steps`` is smaller)."""


def scaling_measurements(
    cfg: dict[str, Any], n_repeats: int = 1, steps: int | None = None
) -> list[VecMeasurement]:
    """Native vector env against the debris count; a 20-debris reference for every N.

    Args:
        cfg: sizes (:data:`bench.config.QUICK` or alike): ``scaling_rows`` ((debris, N)
            pairs), ``early_steps`` and ``scaling_seconds``.
        n_repeats: repeats that share the ``early_steps`` budget after the warm-up.
        steps: fixed vector steps per repeat (default: calibrated, within that budget).
    """
    pairs = [(int(n), int(num)) for n, num in cfg["scaling_rows"]]
    for num in dict.fromkeys(num for _, num in pairs):
        if (DEFAULT_OBSTACLES, num) not in pairs:
            pairs.append((DEFAULT_OBSTACLES, num))
    warm = max(1, min(EARLY_WARMUP, cfg["early_steps"]))
    # stay in the first steps after reset, before episodes start to end
    high = max(1, (cfg["early_steps"] - warm) // max(n_repeats, 1))
    out = []
    for n, num in sorted(pairs, key=lambda p: (-p[1], p[0])):
        kwargs = {"n_obstacles": n, "field_size": field_size_for(n)}
        m = VecMeasurement(
            "vector_scaling",
            "native",
            ID_2D,
            num,
            kwargs,
            n_obstacles=n,
            warmup=warm,
            fixed=steps,
            seconds=cfg["scaling_seconds"],
            max_count=high,
        )
        out.append(m)
    return out


def run_scaling(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`bench.vector.vector_rows`).

    ``ratio`` is the cost per env-step relative to the 20-debris row at the same N.
    """
    todo = scaling_measurements(cfg, n_repeats, steps)
    interleave(todo, n_repeats, "vector_scaling", progress)
    rows = vector_rows(todo)
    for row in rows:
        ref = next(
            (r for r in rows
             if r["n_obstacles"] == DEFAULT_OBSTACLES and r["num_envs"] == row["num_envs"]),
            None,
        )  # fmt: skip
        paired_ratio(row, ref, "ratio", cost=True)
    return drop_rates(rows)
