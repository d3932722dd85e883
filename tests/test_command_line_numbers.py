"""Integer options read the same way on every command line (train.py, evaluate.py, sweep.py,
imitate.py, python -m bench): whole numbers written as digits, with ``_`` between digits or in
exponent form are accepted, anything else — a fraction, an overflow, a value out of the
option's range — is a usage error naming the option and its range."""

from __future__ import annotations

import argparse
import ast
import contextlib
import io
import json
from decimal import Decimal
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.experiments.cli import IntegerOption
from tests.helpers import ROOT, load_script

SCRIPTS = ("train.py", "evaluate.py", "sweep.py", "imitate.py")
REQUIRED = {"sweep.py": ["--out", "x"], "imitate.py": ["--out", "x"]}
"""Options a script's parser requires, given so that only the option under test can fail."""


def _integer_options(parser: argparse.ArgumentParser) -> dict[str, tuple[str, IntegerOption]]:
    """flag → (destination, integer type) of every integer option of ``parser``."""
    return {
        action.option_strings[-1]: (action.dest, action.type)
        for action in parser._actions  # argparse has no public list of a parser's options
        if isinstance(action.type, IntegerOption)
    }


PARSERS = {name: load_script(name).build_parser() for name in SCRIPTS}
OPTIONS = [
    (name, flag, dest, kind)
    for name, parser in PARSERS.items()
    for flag, (dest, kind) in sorted(_integer_options(parser).items())
]


def test_every_script_has_its_integer_options_read_by_the_shared_parser():
    flags = {name: {flag for n, flag, _, _ in OPTIONS if n == name} for name in SCRIPTS}
    assert {"--timesteps", "--n-envs", "--seed", "--threads"} <= flags["train.py"]
    assert {"--timesteps", "--n-envs", "--seed", "--threads", "--samples"} <= flags["sweep.py"]
    assert {"--episodes", "--seed", "--plots", "--max-steps", "--video"} <= flags["evaluate.py"]
    assert {"--seed"} <= flags["imitate.py"]


def _int_typed_arguments(path: Path) -> list[int]:
    """Lines of ``add_argument(..., type=int)`` calls in ``path``."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
            for keyword in node.keywords:
                if keyword.arg == "type" and getattr(keyword.value, "id", "") == "int":
                    lines.append(node.lineno)
    return lines


def test_no_command_line_reads_an_integer_with_plain_int():
    files = [ROOT / name for name in SCRIPTS]
    files += sorted((ROOT / "bench").glob("*.py")) + sorted((ROOT / "agents").rglob("*.py"))
    found = {str(p.relative_to(ROOT)): _int_typed_arguments(p) for p in files}
    assert {p: lines for p, lines in found.items() if lines} == {}


def _parse(name: str, flag: str, text: str) -> tuple[int | None, str]:
    """(value, usage error) of ``name flag text``: exactly one is set."""
    parser = PARSERS[name]
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = parser.parse_args([*REQUIRED.get(name, []), f"{flag}={text}"])
    except SystemExit as exc:
        assert exc.code == 2
        return None, err.getvalue()
    dest = next(d for n, f, d, _ in OPTIONS if n == name and f == flag)
    return getattr(args, dest), ""


def _forms(value: int) -> list[str]:
    """Ways to write the whole number ``value``."""
    sign = "-" if value < 0 else ""
    digits = str(abs(value))
    forms = [str(value), f"{value:_}", f"{value}.0", f"{sign}{digits}e0"]
    stripped = digits.rstrip("0")
    if stripped and stripped != digits:  # 1_500_000 = 15e5 = 1.5e6
        zeros = len(digits) - len(stripped)
        forms += [
            f"{sign}{stripped}e{zeros}",
            f"{sign}{stripped[0]}.{stripped[1:]}e{len(digits) - 1}",
        ]
    return forms


def _check_refused(error: str, flag: str, kind: IntegerOption) -> None:
    assert f"argument {flag}: must be an integer >= {kind.low:_} and <= {kind.high:_}" in error
    assert "Traceback" not in error


@settings(max_examples=300, deadline=None)
@given(
    option=st.sampled_from(OPTIONS),
    value=st.one_of(
        st.integers(-5, 5_000),
        st.integers(-(10**15), 10**15),
        st.builds(lambda m, k: m * 10**k, st.integers(1, 99), st.integers(0, 20)),
    ),
    form=st.integers(0, 10),
)
def test_a_whole_number_is_read_in_any_form_or_refused_by_its_range(option, value, form):
    name, flag, _, kind = option
    forms = _forms(value)
    text = forms[form % len(forms)]
    got, error = _parse(name, flag, text)
    if kind.low <= value <= kind.high:
        assert (got, error) == (value, ""), text
    else:
        assert got is None, text
        _check_refused(error, flag, kind)


@settings(max_examples=200, deadline=None)
@given(
    option=st.sampled_from(OPTIONS),
    text=st.one_of(
        # a fraction, in exponent or decimal form: the exponent leaves the last digit, not 0,
        # behind the point
        st.builds(
            lambda whole, frac, k: f"{whole}.{frac}e{max(0, len(str(frac)) - 1 - k)}",
            st.integers(0, 10**6),
            st.integers(1, 999).filter(lambda f: f % 10),
            st.integers(0, 2),
        ),
        # past a float's range, or an exponent far past any option's
        st.builds(lambda exp: f"1e{exp}", st.integers(309, 10**6)),
        st.sampled_from(["nan", "inf", "-inf", "1e-3", "0x10", "1__0", "_1", "1_", "one", ""]),
        st.sampled_from(["1,000", "1 000", "\u0661\u0662", "10**3", "1e", "e3", "--1"]),
    ),
)
def test_anything_but_a_whole_number_in_range_is_a_usage_error(option, text):
    name, flag, _, kind = option
    got, error = _parse(name, flag, text)
    assert got is None, text
    _check_refused(error, flag, kind)


@settings(max_examples=200, deadline=None)
@given(option=st.sampled_from(OPTIONS), text=st.text(max_size=12))
def test_any_text_is_a_value_in_range_or_a_usage_error(option, text):
    name, flag, _, kind = option
    got, error = _parse(name, flag, text)
    if error:
        _check_refused(error, flag, kind)
    else:
        assert isinstance(got, int) and kind.low <= got <= kind.high
        assert Decimal(text.strip().replace("_", "")) == got


@pytest.mark.parametrize(
    ("name", "argv", "flag"),
    [
        ("train.py", ["--timesteps", "1e400"], "--timesteps"),  # was an OverflowError traceback
        ("train.py", ["--seed", "1e400"], "--seed"),
        ("train.py", ["--timesteps", "2.5e0"], "--timesteps"),  # was silently 2
        ("train.py", ["--n-envs", "1.9e0"], "--n-envs"),  # was silently 1
        ("train.py", ["--threads", "4096"], "--threads"),  # hung torch's thread pool
        ("sweep.py", ["--out", "x", "--threads", "20000"], "--threads"),
        ("evaluate.py", ["--episodes", "2.5"], "--episodes"),
        ("imitate.py", ["--out", "x", "--seed", "1e400"], "--seed"),
    ],
)
def test_the_reported_numbers_are_usage_errors(name, argv, flag, capsys):
    with pytest.raises(SystemExit) as exc:
        PARSERS[name].parse_args(argv)
    assert exc.value.code == 2
    assert f"argument {flag}: must be an integer" in capsys.readouterr().err


def test_the_same_forms_are_read_everywhere():
    """``1e3`` and ``1_000`` were read by train.py but refused by evaluate.py."""
    for text in ("1000", "1_000", "1e3", "1.0e3", "1000.0"):
        assert _parse("evaluate.py", "--episodes", text) == (1000, "")
        assert _parse("train.py", "--timesteps", text) == (1000, "")
        assert _parse("sweep.py", "--timesteps", text) == (1000, "")
        assert _parse("imitate.py", "--seed", text) == (1000, "")


def test_bench_reads_its_integer_option_with_the_shared_parser(monkeypatch, capsys):
    from bench import cli

    monkeypatch.setattr(cli, "memory_child", lambda n: {"envs": n})
    assert cli.main(["--memory-child", "1_024"]) == 0
    assert json.loads(capsys.readouterr().out) == {"envs": 1024}
    for bad in ("2.5", "1e400", "0"):
        with pytest.raises(SystemExit) as exc:
            cli.main(["--memory-child", bad])
        assert exc.value.code == 2
        assert "argument --memory-child: must be an integer >= 1" in capsys.readouterr().err
