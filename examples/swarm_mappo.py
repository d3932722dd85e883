"""MAPPO from RLlib (new API stack) on a swarm ID: one actor shared by every chaser on its own
observation, one critic on the team's state; one line per training iteration with the team's
success and the episode return.

    pip install 'debris-gym[distributed,multiagent]'
    python examples/swarm_mappo.py --iterations 5                 # DebrisGym/Swarm2D-Easy-v0
    python examples/swarm_mappo.py --algo ippo --iterations 5     # critic on the own observation
    python examples/swarm_mappo.py --env-kwargs '{"reward_team": 1.0}' --iterations 200

The config is agents.experiments.distributed.rllib.swarm_mappo_config (docs/swarm.md).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time


def _cell(value: float, fmt: str) -> str:
    return "-" if math.isnan(value) else format(value, fmt)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="DebrisGym/Swarm2D-Easy-v0", help="swarm ID")
    parser.add_argument("--env-kwargs", default="{}", help="swarm options as a JSON object")
    parser.add_argument(
        "--algo", default="mappo", choices=("mappo", "ippo"),
        help="mappo: critic on the team's state; ippo: on the own observation",
    )  # fmt: skip
    parser.add_argument("--iterations", type=int, default=5, help="training iterations")
    parser.add_argument("--env-runners", type=int, default=0, help="sampling processes")
    parser.add_argument("--batch", type=int, default=4000, help="env steps per iteration")
    parser.add_argument("--minibatch", type=int, default=500, help="SGD minibatch (env steps)")
    parser.add_argument("--epochs", type=int, default=5, help="passes over each batch")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import torch

    from agents.experiments.distributed.rllib import (
        IterationSummary,
        swarm_mappo_config,
        swarm_ppo_config,
        train_ppo,
    )

    torch.set_num_threads(1)
    try:
        env_kwargs = json.loads(args.env_kwargs)
        if not isinstance(env_kwargs, dict):
            raise ValueError(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
        make = swarm_mappo_config if args.algo == "mappo" else swarm_ppo_config
        config = make(
            args.env, env_kwargs, num_env_runners=args.env_runners, train_batch_size=args.batch,
            minibatch_size=args.minibatch, num_epochs=args.epochs, seed=args.seed,
        )  # fmt: skip
    except (ValueError, ImportError) as exc:
        parser.error(str(exc))
    start = time.perf_counter()
    print("iteration  env steps  episodes  team success  return  policy loss  value loss  wall [s]")

    def show(s: IterationSummary) -> None:
        cells = (
            f"{s.iteration:9d}", f"{s.env_steps:9d}", f"{s.episodes:8d}",
            f"{_cell(s.team_success, '.0%'):>12}", f"{_cell(s.episode_return_mean, '.1f'):>6}",
            f"{_cell(s.policy_loss, '.4f'):>11}", f"{_cell(s.vf_loss, '.1f'):>10}",
            f"{s.wall_time_s:8.1f}",
        )  # fmt: skip
        print("  ".join(cells), flush=True)

    train_ppo(config, args.iterations, on_iteration=show)
    print(f"total {time.perf_counter() - start:.1f} s (including Ray start-up and the build)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
