"""The compiled calls alone, timed inside the native vector env's loop (for A/B comparisons).

``MissionBatch.step`` and ``.observe`` are wrapped with a ``perf_counter_ns`` timer while the
native vector env steps (N sub-envs, seeded, actions uniform in ±0.05); after a warm-up, each
call's time divided by N gives ns per sub-env, reported as p10 / p50 over the timed calls.
Run it pinned to one core, alternating the trees compared (docs/benchmarks.md)::

    taskset -c 0 env PYTHONPATH=$PWD python -m bench.compiled_calls Rendezvous3D-v0,Rendezvous2D-v0
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the IDs)
from agents.experiments.cli import integer
from debris_gym.mission_batch import MissionBatch


def time_calls(env_id: str, num: int, steps: int, warmup: int) -> dict[str, np.ndarray]:
    """ns per sub-env of every timed ``step`` and ``observe`` call of ``env_id``'s native vector
    env with ``num`` sub-envs (``steps`` timed vector steps after ``warmup`` untimed ones)."""
    times: dict[str, list[float]] = {"step": [], "observe": []}
    step, observe = MissionBatch.step, MissionBatch.observe

    def timed(name, call):
        def wrapper(self, *args):
            start = time.perf_counter_ns()
            result = call(self, *args)
            times[name].append((time.perf_counter_ns() - start) / self.num)
            return result

        return wrapper

    MissionBatch.step, MissionBatch.observe = timed("step", step), timed("observe", observe)
    try:
        env = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point")
        env.reset(seed=0)
        dim = env.unwrapped.dim
        rng = np.random.default_rng(0)
        actions = (rng.uniform(-1, 1, (warmup + steps, num, dim)) * 0.05).astype(np.float32)
        for a in actions[:warmup]:
            env.step(a)
        times["step"].clear()
        times["observe"].clear()
        for a in actions[warmup:]:
            env.step(a)
        env.close()
    finally:
        MissionBatch.step, MissionBatch.observe = step, observe
    return {k: np.array(v) for k, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("ids", help="comma-separated env IDs (DebrisGym/ may be left out)")
    parser.add_argument("--num", type=integer(1, 1_000_000), default=1024)
    parser.add_argument("--steps", type=integer(1, 1_000_000), default=400)
    parser.add_argument("--warmup", type=integer(0, 1_000_000), default=150)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")  # the v0 and v1 IDs' deprecation notice
    for env_id in args.ids.split(","):
        env_id = env_id if "/" in env_id else f"DebrisGym/{env_id}"
        t = time_calls(env_id, args.num, args.steps, args.warmup)
        p = {k: np.percentile(v, [10, 50]) for k, v in t.items()}
        print(
            f"{env_id:28s} step p10 {p['step'][0]:7.0f} p50 {p['step'][1]:7.0f}  "
            f"observe p10 {p['observe'][0]:5.0f} p50 {p['observe'][1]:5.0f} ns/sub-env",
            flush=True,
        )


if __name__ == "__main__":
    main()
