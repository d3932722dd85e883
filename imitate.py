"""Teach a policy network to fly like a classical baseline: behaviour cloning, then DAgger.

The expert (APF-MPC by default) flies training fields; an MLP policy is fit to its actions; then
for each DAgger round the policy flies while the expert labels every state it visits, and the
policy is refit on all the data. Settings come from agents/configs/<env>_imitation.yaml (or
--config FILE) with --set overrides. Outputs in --out DIR: model.zip + vecnormalize.pkl (an SB3
PPO model: evaluate it with evaluate.py --agents ppo=DIR/model.zip), config.yaml,
imitation_log.json (per round: the policy's success rate on its rollouts, data set size, losses,
wall times) and imitation_curve.png. The library is agents/experiments/imitation/;
docs/training.md has the measured runs.
"""

from __future__ import annotations

import argparse
import sys

from agents.experiments import cli
from agents.experiments.run_directory import OutputDirError, check_output_dir

EXAMPLES = """\
examples:
  python imitate.py --out /tmp/im1 --set bc_episodes=4 --set dagger_rounds=1 \\
      --set dagger_episodes=2 --set workers=1                          # a quick check
  python imitate.py --out runs/dagger                                  # the full recipe
  python evaluate.py --agents apf-mpc,ppo=runs/dagger/model.zip --episodes 30 --seed 10000000
"""


def build_parser() -> argparse.ArgumentParser:
    from agents.experiments.imitation.config import MAX_SEED

    parser = cli.script_parser("imitate.py", __doc__, EXAMPLES)
    # kept as text: Path("") would turn an empty argument into the current directory
    parser.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="run directory (created; one run at a time; refused if it holds a model)",
    )
    parser.add_argument(
        "--env",
        metavar="ID",
        default="DebrisGym/Rendezvous2D-v2",
        help="environment ID (default: DebrisGym/Rendezvous2D-v2)",
    )
    cli.add_config_options(parser, "agents/configs/<env>_imitation.yaml", "--set dagger_rounds=2")
    parser.add_argument(
        "--seed",
        type=cli.integer(0, MAX_SEED),
        metavar="S",
        help=f"base seed, in [0, {MAX_SEED:_}] (default: the config's)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    cli.add_suite_refusal(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.refuse_suite(parser, args)
    cli.interrupt_on_signals()
    from agents.experiments.imitation.config import load_imitation_config
    from agents.experiments.imitation.run import imitate

    try:
        out = check_output_dir(args.out)
        config = load_imitation_config(args.env, args.config, args.overrides, args.seed)
        command = " ".join(["python", *cli.command_words(argv)])
        result = imitate(config, out, progress=not args.no_progress, command=command)
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        usage = f"argument {exc.flag}: {exc}" if isinstance(exc, OutputDirError) else str(exc)
        parser.error(usage)
    except KeyboardInterrupt:
        print("\ninterrupted; nothing saved (a run writes its files at the end)", file=sys.stderr)
        return 130
    print(
        f"done in {result['wall_s']:.0f} s\n  {result['model']}\n  {out / 'config.yaml'}\n"
        f"  {out / 'imitation_log.json'}\n  {out / 'imitation_curve.png'}\n"
        "evaluate with: " + cli.evaluate_command(config.env_id, f"apf-mpc,ppo={result['model']}")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
