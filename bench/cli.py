"""The command line: ``python bench/run.py [--quick] [--only SECTIONS] [--out FILE]``.

``python -m bench`` takes the same options. The Markdown report goes to stdout (the progress
bar to stderr) and, with ``--out``, atomically to a file; the exit status is 1 if any
measurement failed.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from agents.experiments.cli import integer
from bench.machine import machine_description
from bench.memory import memory_child
from bench.report import format_report
from bench.suite import SECTIONS, choose_sections, run
from debris_gym.files import write_atomic

MAX_ENVS = 1_000_000
"""Most sub-envs of one memory measurement."""

DESCRIPTION = "Step and reset throughput of the DebrisGym environments, relative to CartPole-v1."


def check_report_path(path: str) -> Path:
    """The report file ``--out`` names, checked before anything runs: a file name (existing or
    not) in a directory that exists, or can be created, and is writable
    (:func:`agents.experiments.run_directory.check_output_dir` on the parent).

    Raises:
        ValueError: an empty name, a directory, or a parent that is a file, lies under one, or
            cannot be written.
    """
    from agents.experiments.run_directory import check_output_dir

    if not path.strip():
        raise ValueError("must name a report file, got an empty string")
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"{out} is a directory; name a file in it, e.g. {out / 'bench.md'}")
    check_output_dir(out.parent if str(out.parent) else ".")
    return out


def main(
    argv: list[str] | None = None, command: str = "python bench/run.py", prog: str | None = None
) -> int:
    """Parse ``argv``, run the benchmark, print (and write) the report.

    Args:
        argv: the options (default: ``sys.argv[1:]``).
        command: how the benchmark was started, for the report's "Command" line.
        prog: the program's name in the usage (default: the script's file name).

    Returns:
        The exit status: 0, or 1 if a measurement failed (its row says why).
    """
    parser = argparse.ArgumentParser(prog=prog, description=DESCRIPTION)
    parser.add_argument("--quick", action="store_true", help="fewer, shorter repeats, smaller N")
    parser.add_argument(
        "--only",
        metavar="SECTIONS",
        help=f"comma-separated sections to run, from: {','.join(SECTIONS)} (default: all). "
        "single = single-env step, scaling and reset tables; scaling = the vector env "
        "against the debris count; shield = the compiled safety shield's cost per decision in "
        "the vector env; swarm = chaser-steps/s of the swarm core at K = 1, 8, 48, "
        "256 chasers per field next to VMAS navigation (needs the bench extra)",
    )
    parser.add_argument("--out", metavar="FILE", help="also write the Markdown report to FILE")
    parser.add_argument(
        "--memory-child", type=integer(1, MAX_ENVS), metavar="N", help=argparse.SUPPRESS
    )
    args = parser.parse_args(argv)
    if args.memory_child is not None:  # internal: one fresh-process memory measurement
        print(json.dumps(memory_child(args.memory_child)))
        return 0
    try:  # an empty --only is a mistake, not "everything"
        sections = choose_sections(args.only.split(",")) if args.only is not None else SECTIONS
    except ValueError as exc:
        parser.error(f"argument --only: {exc}")
    if args.out is not None:
        try:  # before any section runs: a report that cannot be written is a wasted run
            check_report_path(args.out)
        except ValueError as exc:
            parser.error(f"argument --out: {exc}")
    command += " --quick" if args.quick else ""
    if args.only:
        command += f" --only {','.join(sections)}"
    if args.out:
        command += f" --out {args.out}"
    machine = machine_description()  # taken before the run (load average at start)
    start = time.perf_counter()
    rows = run(quick=args.quick, sections=sections)
    elapsed = time.perf_counter() - start
    report = format_report(rows, command=command, elapsed=elapsed, machine=machine)
    print(report, end="")
    if args.out:
        write_atomic(args.out, report)
    return 1 if any(r["error"] for r in rows) else 0
