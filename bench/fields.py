"""Cost per field of the random-field generator, frozen (v0) and moving (v1), and of a reset.

    python -m bench.fields [--passes 5] [--count 2048] [--resets 2000]

Draws ``count`` default fields (3 targets, 20 obstacles, 1 km, n = 1.1314e-3 rad/s, the env's
clearances; moving fields checked over one orbit) in batches of 1 and of 64, one generator per
field as the envs do, and prints the best pass's µs per field (best of ``passes``: the least
disturbed by other processes). Then the cost of ``env.reset()`` (no seed: a new random field)
of ``gym.make(id)`` for CartPole-v1 and the DebrisGym IDs, ``resets`` resets per pass, the
passes of the IDs interleaved so that machine noise hits them alike, best pass each, and its
ratio to CartPole's. Times are the thread's CPU time (``time.thread_time``: time lost to other
processes is not counted). One thread; run it pinned (``taskset -c 1``) on a shared machine.
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the IDs)
from agents.experiments.cli import integer
from debris_gym.generators import FieldSpec, random_fields

N = 1.1314e-3  # rad/s
CAPTURE = 5.0  # m, the env's default capture radius


def field_cost(spec: FieldSpec, batch: int, count: int, passes: int) -> float:
    """Best-of-``passes`` seconds per field of drawing ``count`` fields ``batch`` at a time."""
    random_fields([np.random.default_rng(s) for s in range(batch)], spec, capture_radius=CAPTURE)
    best = float("inf")
    for _ in range(passes):
        rngs = [np.random.default_rng(s) for s in range(count)]
        start = time.thread_time()
        for i in range(0, count, batch):
            random_fields(rngs[i : i + batch], spec, capture_radius=CAPTURE)
        best = min(best, (time.thread_time() - start) / count)
    return best


RESET_IDS = (
    "CartPole-v1",
    "DebrisGym/Rendezvous2D-v2",
    "DebrisGym/Rendezvous3D-v2",
    "DebrisGym/Rendezvous2D-v1",
    "DebrisGym/Rendezvous3D-v1",
    "DebrisGym/Rendezvous2D-v0",
    "DebrisGym/Rendezvous3D-v0",
)


def reset_costs(ids: tuple[str, ...], resets: int, passes: int) -> dict[str, float]:
    """Best-of-``passes`` seconds per ``env.reset()`` (no seed) of ``gym.make(id)`` for each
    ID, after ``reset(seed=0)`` and 100 warm-up resets; the passes of the IDs interleaved."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the v0 and v1 IDs' "out of date" notice
        envs = {i: gym.make(i) for i in ids}
    for env in envs.values():
        env.reset(seed=0)
        for _ in range(100):
            env.reset()
    best = dict.fromkeys(ids, float("inf"))
    for _ in range(passes):
        for i, env in envs.items():
            start = time.thread_time()
            for _ in range(resets):
                env.reset()
            best[i] = min(best[i], (time.thread_time() - start) / resets)
    for env in envs.values():
        env.close()
    return best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--passes", type=integer(1, 1_000), default=5)
    parser.add_argument("--count", type=integer(1, 1_000_000), default=2048)
    parser.add_argument("--resets", type=integer(1, 1_000_000), default=2000)
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
    costs = reset_costs(RESET_IDS, args.resets, args.passes)
    print()
    print("| env | µs per `env.reset()` | × CartPole-v1 |")
    print("|---|---|---|")
    for i, cost in costs.items():
        print(f"| {i} | {cost * 1e6:.1f} | {cost / costs['CartPole-v1']:.1f} |")


if __name__ == "__main__":
    main()
