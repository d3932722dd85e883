"""Command-line pieces that ``train.py``, ``evaluate.py`` and ``imitate.py`` share: the parser
frame, the config-file options, Ctrl-C handling and the command line a run records."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    "add_config_options",
    "command_words",
    "int_at_least",
    "interrupt_on_signals",
    "script_parser",
]


def int_at_least(text: str, low: int) -> int:
    """An integer option's value (``1_000_000`` and ``1e6`` read too), at least ``low``.

    Raises:
        argparse.ArgumentTypeError: not an integer, or below ``low``.
    """
    try:
        value = int(float(text)) if "e" in text.lower() else int(text.replace("_", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if value < low:
        raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
    return value


def script_parser(prog: str, doc: str | None, epilog: str) -> argparse.ArgumentParser:
    """A script's parser: its module docstring as the description, the examples as the epilog,
    both printed as written."""
    return argparse.ArgumentParser(
        prog=prog,
        description=doc,
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def add_config_options(parser: argparse.ArgumentParser, default: str, example: str) -> None:
    """``--config FILE`` (``default`` names the file used without it) and the repeatable
    ``--set KEY=VALUE`` overrides (into ``args.overrides``; ``example`` shows one in the help)."""
    parser.add_argument(
        "--config", type=Path, metavar="FILE", help=f"config YAML (default: {default})"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"override a config key (dotted, value parsed as YAML), e.g. {example}; repeatable",
    )


def interrupt_on_signals() -> None:
    """Make Ctrl-C (and SIGTERM) raise ``KeyboardInterrupt``, so a run can save and stop cleanly.

    Ctrl-C must reach Python even when the parent process ignores SIGINT.
    """
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)


def command_words(argv: Sequence[str] | None) -> list[str]:
    """The script's name and its arguments (``argv``, or the process's own when None)."""
    return [Path(sys.argv[0]).name, *(sys.argv[1:] if argv is None else argv)]


def add_suite_refusal(parser: argparse.ArgumentParser) -> None:
    """``--suite NAME``, accepted only to be refused by :func:`refuse_suite` with a clear
    message (frozen suites are evaluation-only), rather than argparse's "unrecognized"."""
    parser.add_argument(
        "--suite",
        metavar="NAME",
        help="refused: frozen evaluation suites (evaluate.py --suite) are evaluation-only and "
        "never used for training or model selection",
    )


def refuse_suite(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Exit with a usage error if ``--suite`` was given; drop it from ``args`` otherwise."""
    suite = vars(args).pop("suite", None)
    if suite is not None:
        from debris_gym.suites import EVALUATION_ONLY

        parser.error(
            f"argument --suite: {EVALUATION_ONLY}; evaluate on it with python evaluate.py "
            f"--suite {suite} --agents ..."
        )
