"""The options ``train.py`` and ``sweep.py`` share, written once: the recipe (``--env``,
``--algo``, ``--config``, ``--set``), its budget and size (``--timesteps``, ``--n-envs``), the
seed and the torch threads — with the ranges :class:`~agents.experiments.training.config.
TrainConfig` and :func:`~agents.experiments.training.run.train` enforce."""

from __future__ import annotations

import argparse

from agents.experiments import cli
from agents.experiments.training.config import ALGOS, EVAL_SEED, MAX_ENVS, MAX_TIMESTEPS
from agents.experiments.training.resolve import MAX_THREADS

__all__ = ["add_recipe_options"]


def add_recipe_options(
    parser: argparse.ArgumentParser, *, each: str = "", seed_default: int | None = None
) -> None:
    """Add the shared options to ``parser``; their destinations are the option names of
    :class:`~agents.experiments.training.resolve.TrainOptions`.

    Args:
        parser: a script's parser.
        each: words that say whom the budget, size, seed and threads apply to (``" of every
            trial"`` for a sweep); empty for a single run.
        seed_default: the ``--seed`` default (None: the script decides).
    """
    parser.add_argument(
        "--env",
        dest="env_id",
        metavar="ID",
        help="environment ID; picks the checked-in recipe with --algo (default: "
        "DebrisGym/Rendezvous2D-v2)",
    )
    parser.add_argument("--algo", choices=ALGOS, help="algorithm (default: ppo)")
    cli.add_config_options(
        parser,
        "agents/configs/<env>_<algo>.yaml",
        "--set algo_kwargs.batch_size=512 --set normalize.enabled=false",
    )
    parser.add_argument(
        "--timesteps",
        type=cli.integer(1, MAX_TIMESTEPS),
        metavar="N",
        help=f"training budget{each} in env steps, in [1, {MAX_TIMESTEPS:_}] (default: the "
        "recipe's); with train.py --resume: steps to add (default: finish the run's budget)",
    )
    parser.add_argument(
        "--n-envs",
        type=cli.integer(1, MAX_ENVS),
        metavar="N",
        help=f"training envs{each}, in [1, {MAX_ENVS:_}] (default: the recipe's)",
    )
    parser.add_argument(
        "--seed",
        type=cli.integer(0, EVAL_SEED - 1),
        default=seed_default,
        metavar="S",
        help=f"base seed{each}: training sub-env i is seeded with S + i, S + n_envs <= "
        f"{EVAL_SEED:_} (the held-out evaluation seeds start there) (default: 0)",
    )
    parser.add_argument(
        "--threads",
        type=cli.integer(1, MAX_THREADS),
        default=1,
        metavar="N",
        help=f"torch CPU threads{each}, in [1, {MAX_THREADS}] (default: 1; more threads compete "
        "with the envs for the cores, see docs/training.md)",
    )
