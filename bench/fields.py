"""Cost per field of the random-field generator, frozen (v0) and moving (v1).

    python -m bench.fields [--passes 5] [--count 2048]

Draws ``count`` default fields (3 targets, 20 obstacles, 1 km, n = 1.1314e-3 rad/s, the env's
clearances; moving fields checked over one orbit) in batches of 1 and of 64, one generator per
field as the envs do, and prints the best pass's µs per field (best of ``passes``: the least
disturbed by other processes). One thread; run it pinned (``taskset -c 1``) on a shared machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from debris_gym.generators import FieldSpec, random_fields

N = 1.1314e-3  # rad/s
CAPTURE = 5.0  # m, the env's default capture radius


def field_cost(spec: FieldSpec, batch: int, count: int, passes: int) -> float:
    """Best-of-``passes`` seconds per field of drawing ``count`` fields ``batch`` at a time."""
    random_fields([np.random.default_rng(s) for s in range(batch)], spec, capture_radius=CAPTURE)
    best = float("inf")
    for _ in range(passes):
        rngs = [np.random.default_rng(s) for s in range(count)]
        start = time.perf_counter()
        for i in range(0, count, batch):
            random_fields(rngs[i : i + batch], spec, capture_radius=CAPTURE)
        best = min(best, (time.perf_counter() - start) / count)
    return best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--passes", type=int, default=5)
    parser.add_argument("--count", type=int, default=2048)
    args = parser.parse_args(argv)
    print("| field | batch of 1 (µs/field) | batch of 64 (µs/field) |")
    print("|---|---|---|")
    for dim in (2, 3):
        for motion in ("frozen", "bounded", "drifting"):
            spec = FieldSpec(
                dim=dim, motion=motion, mean_motion=N, target_clearance=17.0, dock_clearance=50.0,
                spin_max=0.01 if dim == 2 and motion != "frozen" else 0.0,
            )  # fmt: skip
            count = args.count if motion != "drifting" else max(64, args.count // 8)
            cells = [field_cost(spec, b, count, args.passes) * 1e6 for b in (1, 64)]
            print(f"| {dim}D {motion} | {cells[0]:.0f} | {cells[1]:.0f} |", flush=True)


if __name__ == "__main__":
    main()
