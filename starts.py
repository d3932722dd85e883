"""Build a start bank: fly a baseline on seeded missions and keep where each mission stood right
after every capture, to start training missions part-way (train.py's ``starts.bank``).

Each entry puts a mission back in the state the rollout reached: the same moving field, every
body flown on to that step, the same targets captured, Δv spent and chaser state. The bank is
one .npz file (debris_gym.start_bank.StartBank); docs/training.md, "Starting part-way", has
the recipe that uses it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.experiments import cli

EXAMPLES = """\
examples:
  python starts.py --out runs/starts/apf_mpc_2d.npz                      # 200 missions, apf-mpc
  python starts.py --env DebrisGym/Rendezvous3D-v2 --missions 50 --out /tmp/bank3d.npz
  python train.py --config agents/configs/rendezvous2d-v2_starts.yaml      # trains with one
"""


def build_parser() -> argparse.ArgumentParser:
    parser = cli.script_parser("starts.py", __doc__, EXAMPLES)
    parser.add_argument("--out", type=Path, required=True, metavar="FILE", help="the bank (.npz)")
    parser.add_argument(
        "--env",
        default="DebrisGym/Rendezvous2D-v2",
        metavar="ID",
        help="env ID (default: %(default)s)",
    )
    parser.add_argument(
        "--env-kwargs", type=cli.json_object, default=None, metavar="JSON",
        help="gym.make keyword arguments as a JSON object",
    )  # fmt: skip
    parser.add_argument(
        "--source", default="apf-mpc", metavar="AGENT",
        help="the baseline that flies the missions (default: %(default)s)",
    )  # fmt: skip
    parser.add_argument(
        "--missions", type=cli.integer(1, cli.MAX_EPISODES), default=200, metavar="N",
        help="missions flown (default: %(default)s)",
    )  # fmt: skip
    parser.add_argument(
        "--seed", type=cli.integer(0, cli.MAX_SEED), default=0, metavar="S",
        help="reset seed of the first mission; the others follow (default: %(default)s)",
    )  # fmt: skip
    parser.add_argument(
        "--workers", type=cli.integer(1, cli.MAX_WORKERS), default=1, metavar="N",
        help="worker processes (default: %(default)s)",
    )  # fmt: skip
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.out.suffix != ".npz":
        print(f"starts.py: error: --out must end in .npz, got {args.out}", file=sys.stderr)
        return 2
    from agents.experiments.starts import build_start_bank

    try:
        bank = build_start_bank(
            args.env, args.env_kwargs, source=args.source, missions=args.missions,
            seed=args.seed, workers=args.workers, progress=not args.no_progress,
        )  # fmt: skip
    except ValueError as err:
        print(f"starts.py: error: {err}", file=sys.stderr)
        return 2
    bank.save(args.out)
    legs = bank.legs
    counts = ", ".join(
        f"leg {k}: {int((legs == k).sum())}" for k in range(1, int(legs.max(initial=0)) + 1)
    )
    print(f"{len(bank)} starts from {args.missions} missions ({counts}) -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
