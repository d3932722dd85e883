"""Command-line pieces that ``train.py``, ``evaluate.py`` and ``imitate.py`` share: the parser
frame, the config-file options, Ctrl-C handling and the command line a run records."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["add_config_options", "command_words", "interrupt_on_signals", "script_parser"]


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
