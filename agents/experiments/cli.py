"""Command-line pieces every script shares (``train.py``, ``evaluate.py``, ``sweep.py``,
``imitate.py``, ``starts.py``, ``python -m bench``): the parser frame, integer and JSON-object
options, the config-file options, Ctrl-C handling and the command line a run records."""

from __future__ import annotations

import argparse
import contextlib
import decimal
import json
import shlex
import signal
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = [
    "IntegerOption",
    "add_config_options",
    "add_suite_refusal",
    "command_words",
    "evaluate_command",
    "integer",
    "interrupt_on_signals",
    "json_object",
    "refuse_suite",
    "script_parser",
]


MAX_SEED = 2**128 - 1
"""Largest reset seed a script's ``--seed`` takes (gymnasium takes any integer >= 0 as a numpy
``SeedSequence`` entropy; 128 bits is that entropy's size)."""

MAX_EPISODES = 1_000_000
"""Most episodes (per agent, plotted or recorded) a script's option asks for."""

MAX_EPISODE_STEPS = 10_000_000
"""Longest episode time limit (steps) an option sets."""

MAX_WORKERS = 4096
"""Most worker processes (or Ray tasks at once) a script's ``--workers`` asks for."""

MAX_NUMBER_TEXT = 100
"""Longest integer option text read (a longer one is a typo)."""


@dataclass(frozen=True)
class IntegerOption:
    """The ``type=`` of an integer option: a whole number in ``[low, high]``.

    Every script reads integer options with it, so they all accept the same forms: plain
    digits, ``_`` between digits, and exponent or decimal forms whose value is whole (``1e6``,
    ``1.5e3``, ``2.0``). The value is read exactly (as a :class:`~decimal.Decimal`), so
    ``2.5e0`` is refused rather than cut to 2 and ``1e400`` is out of range rather than an
    overflow.

    Attributes:
        low, high: the allowed range, both included.
    """

    low: int
    high: int

    def __call__(self, text: str) -> int:
        """The value of ``text``.

        Raises:
            argparse.ArgumentTypeError: not a whole number in ``[low, high]`` (the message
                gives the range; argparse names the option in front of it).
        """
        stripped = text.strip()
        value = None
        if len(stripped) <= MAX_NUMBER_TEXT and stripped.isascii():
            with contextlib.suppress(ValueError):
                float(stripped)  # the forms of a Python number literal ("_" between digits)
                value = decimal.Decimal(stripped.replace("_", ""))  # its exact value
        if (
            value is None
            or not value.is_finite()
            or value != value.to_integral_value()
            or not self.low <= value <= self.high
        ):
            raise argparse.ArgumentTypeError(
                f"must be an integer >= {self.low:_} and <= {self.high:_} (e.g. 1000, 1_000 or "
                f"1e3), got {text!r}"
            )
        return int(value)


def integer(low: int, high: int) -> IntegerOption:
    """The ``type=`` of an integer option in ``[low, high]`` (:class:`IntegerOption`)."""
    return IntegerOption(low, high)


def json_object(text: str) -> dict[str, Any]:
    """The ``type=`` of an option that takes a JSON object (``--env-kwargs``): its value.

    Raises:
        argparse.ArgumentTypeError: ``text`` is not JSON, or not a JSON object (argparse names
            the option in front of the message).
    """
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"invalid JSON ({exc}): {text!r}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"must be a JSON object such as '{{\"n_obstacles\": 40}}', got {text!r}"
        )
    return value


def evaluate_command(env_id: str, agents: str) -> str:
    """The ``evaluate.py`` command line that flies ``agents`` on ``env_id`` (what a script that
    made a model prints: the model's own env, not evaluate.py's default)."""
    return shlex.join(["python", "evaluate.py", "--env", env_id, "--agents", agents])


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
