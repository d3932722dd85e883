"""Section ``shield``: what the compiled safety shield (``shield=True``) costs per decision in
the native vector env.

The default 2D and 3D envs at N = ``shield_envs`` sub-envs, one thread, uniformly random
actions (as an exploring policy gives them), each with the shield off and on, timed in
interleaved rounds. The cost per decision is (time with the shield − time without) / env-steps,
per round (both sides share the round's machine load), and its median over the rounds. The
rows also give the share of decisions the shield changed (counted outside the timed loop from
``info["shield_intervened"]``, which the env computes either way).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from bench.config import ID_2D, ID_3D
from bench.harness import RANDOM, drop_rates, interleave
from bench.vector import VecMeasurement, vector_rows


class ShieldMeasurement(VecMeasurement):
    """A native vector env timed like the vector section's, also counting interventions."""

    interventions: int = 0
    decisions: int = 0

    def _loop(self, actions: np.ndarray) -> tuple[float, int]:
        step, clock = self.env.step, time.perf_counter
        flags: list[Any] = []
        add = flags.append
        start = clock()
        for action in actions:
            _, _, terminated, truncated, info = step(action)
            add((terminated, truncated, info["shield_intervened"]))
        elapsed = clock() - start
        self.interventions += int(sum(np.count_nonzero(f[2]) for f in flags))
        self.decisions += len(flags) * self.num_envs
        return elapsed, int(sum(np.count_nonzero(np.logical_or(a, b)) for a, b, _ in flags))


def shield_measurements(cfg: dict[str, Any], steps: int | None = None) -> list[ShieldMeasurement]:
    """Shield off and on for the default 2D and 3D envs, in the order they are interleaved."""
    out = []
    for env_id in (ID_2D, ID_3D):
        for on in (False, True):
            out.append(
                ShieldMeasurement(
                    "shield",
                    "native",
                    env_id,
                    cfg["shield_envs"],
                    {"shield": on},
                    f"shield={on}, {RANDOM}",
                    action_kind="random",
                    warmup=max(1, cfg["warmup_steps"]),
                    fixed=steps,
                    seconds=cfg["vector_seconds"],
                )
            )
    return out


def run_shield(
    cfg: dict[str, Any], n_repeats: int, steps: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Run the section; one row per measurement (see :func:`bench.vector.vector_rows`), with
    ``shield`` (on or off), ``intervened_per_1000`` (decisions changed per 1000, timed windows
    and warm-up) and, in the shield-on rows, ``us_per_decision`` (median over rounds of the
    paired difference of µs per env-step) and its range ``us_per_decision_range``."""
    todo = shield_measurements(cfg, steps)
    interleave(todo, n_repeats, "shield", progress)
    rows = vector_rows(todo)
    for m, row in zip(todo, rows, strict=True):
        row["shield"] = bool(m.kwargs["shield"])
        row["intervened_per_1000"] = 1000.0 * m.interventions / max(m.decisions, 1)
        row["us_per_decision"] = float("nan")
        row["us_per_decision_range"] = (float("nan"), float("nan"))
    for off, on in zip(rows[::2], rows[1::2], strict=True):
        pairs = [1e6 / b - 1e6 / a for a, b in zip(off["_rates"], on["_rates"], strict=False)]
        if pairs:
            on["us_per_decision"] = statistics.median(pairs)
            on["us_per_decision_range"] = (min(pairs), max(pairs))
    return drop_rates(rows)
