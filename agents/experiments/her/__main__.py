"""Train SAC with hindsight experience replay (goal-conditioned) on a one-target debris-gym rung.

Writes DIR/model.zip (atomically), DIR/curve.csv (held-out success vs env steps, missions with
reset seeds 1 000 000+) and DIR/train_log.json (wall time, env-steps/s). With --no-her: plain
SAC on the env's own reward and observation, the same network and hyper-parameters (the
control). One core: torch uses one thread.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from agents.experiments.cli import integer, script_parser
from agents.experiments.training.config import EVAL_SEED, MAX_EVAL_EPISODES, MAX_TIMESTEPS

EPILOG = """examples:
  python -m agents.experiments.her --timesteps 300000 --seed 0 --out runs/her
  python -m agents.experiments.her --timesteps 300000 --seed 0 --out runs/sac --no-her
  DEBRIS_HER_MODEL=runs/her/model.zip python evaluate.py --env DebrisGym/Rendezvous2D-Easy-v2 \\
      --agents her=agents.experiments.her.policy:policy --episodes 30
"""


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and train; returns the exit status."""
    parser = script_parser("python -m agents.experiments.her", __doc__, EPILOG)
    parser.add_argument(
        "--timesteps",
        type=integer(1, MAX_TIMESTEPS),
        required=True,
        metavar="N",
        help="env steps, >= 1",
    )
    parser.add_argument(
        "--seed", type=integer(0, EVAL_SEED - 1), default=0, help="seed, >= 0 (default: 0)"
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="run directory")
    parser.add_argument(
        "--env",
        default="DebrisGym/Rendezvous2D-Easy-v2",
        metavar="ID",
        help="a one-target, no-return env (default: DebrisGym/Rendezvous2D-Easy-v2)",
    )
    parser.add_argument("--no-her", action="store_true", help="plain SAC, the control")
    parser.add_argument(
        "--eval-freq",
        type=integer(1, MAX_TIMESTEPS),
        default=25_000,
        metavar="N",
        help="env steps between evaluations",
    )
    parser.add_argument(
        "--eval-episodes",
        type=integer(1, MAX_EVAL_EPISODES),
        default=20,
        metavar="N",
        help="held-out missions per evaluation",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    from agents.experiments.her.train import train_sac

    try:
        log = train_sac(
            args.out,
            args.timesteps,
            seed=args.seed,
            her=not args.no_her,
            env_id=args.env,
            eval_freq=args.eval_freq,
            eval_episodes=args.eval_episodes,
            progress=not args.no_progress,
        )
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(
        f"{log['timesteps']:,} steps in {log['wall_seconds']:.0f} s "
        f"({log['steps_per_second']:.0f} env-steps/s); model: {args.out}/model.zip"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
