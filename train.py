"""Train an SB3 agent (PPO, SAC, TD3, DQN) on a DebrisGym env from a versioned config file.

Hyper-parameters come from agents/configs/<env>_<algo>.yaml (or --config FILE), with --set
overrides. Outputs in --out DIR: model.zip (+ vecnormalize.pkl), config.yaml (the resolved config
and this command line), learning_curve.png, train_log.json (wall time, env-steps/s),
evaluations.npz and best_model.zip (held-out seeds >= 1,000,000), checkpoints/, tb/ (TensorBoard).
Ctrl-C saves DIR/checkpoints/interrupted.zip; --resume DIR continues from the latest checkpoint.
The library is agents/experiments/training/; docs/training.md explains the configs.
"""

from __future__ import annotations

import argparse
import sys

from agents.experiments import cli
from agents.experiments.run_directory import OutputDirError

EXAMPLES = """\
examples:
  python train.py --algo ppo --timesteps 4096 --n-envs 2 --out /tmp/t1     # a quick check
  python train.py --env DebrisGym/Rendezvous2D-v2 --algo ppo --out runs/ppo  # the full recipe
  python train.py --algo sac --out runs/sac --set algo_kwargs.batch_size=512
  python train.py --config agents/configs/rendezvous2d_finetune.yaml --init runs/dagger \
      --out runs/ft                                      # RL fine-tuning of a DAgger policy
  python train.py --env DebrisGym/Swarm2D-Easy-v0 --algo ppo --out runs/ippo  # one policy
                                     # for every chaser of a swarm, n_envs counting chasers
  python train.py --resume runs/ppo                                          # after Ctrl-C
  python train.py --resume runs/ppo --timesteps 1000000                      # 1M steps more
  python evaluate.py --agents apf,ppo=runs/ppo/model.zip
"""


def build_parser() -> argparse.ArgumentParser:
    from agents.experiments.training.command_line import add_recipe_options
    from agents.experiments.training.config import available_configs

    epilog = EXAMPLES + "\nchecked-in configs: " + ", ".join(available_configs())
    parser = cli.script_parser("train.py", __doc__, epilog)
    add_recipe_options(parser)
    # kept as text: Path("") would turn an empty argument into the current directory
    parser.add_argument(
        "--out",
        metavar="DIR",
        help="run directory (created; one run at a time; refused if it holds a model)",
    )
    parser.add_argument(
        "--init",
        metavar="DIR",
        help="fine-tune the policy of run DIR (imitate.py or train.py output) with PPO: its "
        "weights, observation statistics and options; see the 'init' config keys",
    )
    parser.add_argument(
        "--resume",
        metavar="DIR",
        help="continue the run in DIR from its latest checkpoint, with its own config",
    )
    parser.add_argument(
        "--no-progress", dest="progress", action="store_false", help="no progress bar"
    )
    cli.add_suite_refusal(parser)
    parser.add_argument(
        "--device",
        default="cpu",
        help="torch device: cpu, auto, cuda, cuda:<N> or mps, if this machine has it "
        "(default: cpu)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.refuse_suite(parser, args)
    if args.out is None and args.resume is None:
        parser.error("give --out DIR (a new run) or --resume DIR")
    cli.interrupt_on_signals()

    from agents.experiments.training.run import TrainOptions, TrainWriteError, train

    # the parser's destinations are the option names
    options = TrainOptions(**vars(args), argv=cli.command_words(argv))
    try:
        result = train(options)
    except TrainWriteError as exc:  # mid-run: not a usage error
        print(f"train.py: {exc}", file=sys.stderr)
        return 1
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        parser.error(cli_error(exc))
    except KeyboardInterrupt:  # before learning started: nothing to save
        print("\ninterrupted before training started; nothing saved", file=sys.stderr)
        return 130
    out = result.out
    if result.status == "interrupted":
        print(
            f"\ninterrupted at {result.num_timesteps:,} steps; checkpoint {result.model_path}\n"
            f"resume with: python train.py --resume {out}",
            file=sys.stderr,
        )
        return 130
    from debris_gym.swarm import SWARM_SPECS

    evaluate = "evaluate with: " + (
        cli.evaluate_command(
            result.env_id, f"team-apf-mpc,team-{result.algo}:{result.model_path}"
        )  # every chaser flies the shared policy, behind the default assignment rule
        if result.env_id in SWARM_SPECS
        else cli.evaluate_command(result.env_id, f"apf,{result.algo}={result.model_path}")
    )
    print(
        f"done: {result.num_timesteps:,} steps in {result.wall_time_s:.1f} s "
        f"({result.env_steps_per_s:,.0f} env-steps/s)\n"
        f"  {result.model_path}\n  {out / 'config.yaml'}\n  {out / 'learning_curve.png'}\n"
        f"  {out / 'train_log.json'}\n" + evaluate
    )
    return 0


def cli_error(exc: Exception) -> str:
    """The usage-error text of a rejected option (output-directory errors name their flag)."""
    return f"argument {exc.flag}: {exc}" if isinstance(exc, OutputDirError) else str(exc)


if __name__ == "__main__":
    sys.exit(main())
