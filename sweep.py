"""Sweep a train.py recipe's hyper-parameters with Ray Tune; export the best trial's model.

The search space is the recipe's `sweep:` section (agents/configs/<env>_<algo>.yaml or --config
FILE; docs/distributed.md explains it). Each trial is a normal train.py run in
OUT/trials/<trial id>/ (model.zip, vecnormalize.pkl, config.yaml, checkpoints/, tb/), trained
with the same seed, and reports the success rate and mean return of its final evaluation
(held-out seeds) to Tune. Outputs in --out OUT:

  best/model.zip (+ vecnormalize.pkl, config.yaml)   the best trial's model
  sweep.json                                          every trial: values, metrics, run dir
  trials/<trial id>/                                  each trial's train.py run directory
  tune/                                               Ray Tune's own records

Needs Ray: pip install 'debris-gym[distributed]'. A local Ray is started for the sweep unless
--address names a cluster (then OUT must be on a file system every node sees).
"""

from __future__ import annotations

import argparse
import sys

from agents.experiments import cli

EXAMPLES = """\
examples:
  python sweep.py --env DebrisGym/Rendezvous2D-Easy-v2 --samples 4 --timesteps 20000 \\
      --n-envs 4 --out runs/sweep                    # 4 trials on a local Ray
  python sweep.py --config my_recipe.yaml --address auto --out /shared/sweep   # a cluster
  python evaluate.py --env DebrisGym/Rendezvous2D-Easy-v2 --agents apf,ppo=runs/sweep/best/model.zip
"""


def build_parser() -> argparse.ArgumentParser:
    from agents.experiments.training.command_line import add_recipe_options
    from agents.experiments.training.sweep_config import MAX_SAMPLES

    parser = cli.script_parser("sweep.py", __doc__, EXAMPLES)
    add_recipe_options(parser, each=" of every trial", seed_default=0)
    parser.add_argument("--out", required=True, metavar="DIR", help="the sweep's directory")
    parser.add_argument(
        "--samples",
        type=cli.integer(1, MAX_SAMPLES),
        metavar="N",
        help=f"trials, in [1, {MAX_SAMPLES:_}] (default: the recipe's sweep.num_samples)",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="the Ray cluster to join (auto, HOST:6379); default: a local Ray for the sweep",
    )
    parser.add_argument(
        "--workers",
        type=cli.integer(1, cli.MAX_WORKERS),
        metavar="N",
        help=f"trials at once, in [1, {cli.MAX_WORKERS:_}] (default: one per CPU of the cluster)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from agents.experiments.distributed.sweep import SweepOptions, run_sweep
    from agents.experiments.run_directory import OutputDirError

    try:
        result = run_sweep(SweepOptions(**vars(args)))
    except OutputDirError as exc:
        parser.error(f"argument {exc.flag}: {exc}")
    except (FileNotFoundError, ValueError, ImportError) as exc:
        parser.error(str(exc))
    from agents.experiments.config_files import load_config_file

    best, _ = load_config_file(result.best_dir / "config.yaml")
    env_id, algo = str(best["env_id"]), str(best["algo"])
    print(
        f"{len(result.trials)} trials in {result.wall_time_s:.1f} s; by {result.metric} "
        f"({result.mode}):"
    )
    for trial in sorted(result.trials, key=lambda t: t.trial_id):
        shown = trial.error or ", ".join(f"{k} {v:.4g}" for k, v in trial.metrics.items())
        mark = "*" if trial is result.best else " "
        print(f" {mark} {trial.trial_id}  {trial.params}  {shown}")
    print(
        f"best: {result.best.run_dir}\nexported: {result.best_dir}/model.zip\n"
        "evaluate with: " + cli.evaluate_command(env_id, f"{algo}={result.best_dir / 'model.zip'}")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
