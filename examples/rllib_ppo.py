"""PPO from RLlib (new API stack) on a DebrisGym ID: a short run that prints the mean return of
the episodes ending in each training iteration.

    pip install 'debris-gym[distributed]'
    python examples/rllib_ppo.py --iterations 5                 # DebrisGym/Rendezvous2D-Easy-v2
    python examples/rllib_ppo.py --env DebrisGym/Rendezvous2D-v2 --env-runners 2 --iterations 50

The env is made on every env runner by its "debris_gym:DebrisGym/..." name, each runner's
sub-envs through the package's native vector env (agents/experiments/distributed/rllib.py;
docs/distributed.md).
"""

from __future__ import annotations

import argparse
import math
import sys
import time


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="DebrisGym/Rendezvous2D-Easy-v2", help="DebrisGym ID")
    parser.add_argument("--iterations", type=int, default=5, help="training iterations")
    parser.add_argument("--env-runners", type=int, default=1, help="sampling processes")
    parser.add_argument("--envs-per-runner", type=int, default=8, help="sub-envs per runner")
    parser.add_argument("--batch", type=int, default=4000, help="env steps per iteration")
    parser.add_argument("--vectorize", default="vector_entry_point",
                        choices=("vector_entry_point", "sync", "async"))  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    from agents.experiments.distributed.rllib import ppo_config, train_ppo

    try:
        config = ppo_config(
            args.env, num_env_runners=args.env_runners,
            num_envs_per_env_runner=args.envs_per_runner, vectorize=args.vectorize,
            train_batch_size=args.batch, seed=args.seed,
        )  # fmt: skip
    except (ValueError, ImportError) as exc:
        parser.error(str(exc))
    start = time.perf_counter()
    summaries = train_ppo(config, args.iterations)
    print("iteration  env steps  episodes  mean return  wall [s]")
    for s in summaries:
        ret = "-" if math.isnan(s.episode_return_mean) else f"{s.episode_return_mean:.2f}"
        print(
            f"{s.iteration:9d}  {s.env_steps:9d}  {s.episodes:8d}  {ret:>11}  {s.wall_time_s:8.1f}"
        )
    print(f"total {time.perf_counter() - start:.1f} s (including Ray start-up and the build)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
