"""The timing harness every section shares: set up, interleaved repeats, tear down.

A section builds a list of measurements (objects following :class:`Timed`) and hands it to
:func:`interleave`, which sets every measurement up once, then times them in rounds
(A, B, C, A, B, C, …) so that machine noise hits them alike, and finally tears every one down,
also when a round raises. A measurement that fails keeps the message in ``error`` and drops out
of the later rounds; the others go on.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from bench.config import CARTPOLE, DISCRETE_COAST, THRUST


class Timed(Protocol):
    """One thing to time. ``error`` is None until a step of it fails."""

    error: str | None

    def describe(self) -> str:
        """A short name for the progress bar."""
        ...

    def set_up(self) -> None:
        """Build, warm up and calibrate; called once before the first round."""
        ...

    def measure(self, round_index: int) -> None:
        """Time one repeat (round ``round_index``, from 0) and keep the result."""
        ...

    def tear_down(self) -> None:
        """Close what :meth:`set_up` built; called once, also after a failure."""
        ...


def guard(item: Any, fn: Callable[[], Any]) -> None:
    """Call ``fn``; an exception becomes ``item.error`` instead of ending the run.

    Reported, not hidden: e.g. the field generator giving up on a crowded field is a row of the
    report with the message, and the other measurements still run.
    """
    try:
        fn()
    except Exception as exc:
        item.error = f"{type(exc).__name__}: {exc}"


def progress_bar(total: int, desc: str, progress: bool) -> tqdm:
    """A tqdm bar on stderr (stdout carries the report), counting measurement calls."""
    return tqdm(
        total=total, desc=desc, unit="meas", file=sys.stderr, disable=not progress, leave=False
    )


def interleave(
    todo: Sequence[Timed], rounds: int, desc: str, progress: bool, round_word: str = "rep"
) -> None:
    """Set up every measurement, time them in ``rounds`` interleaved rounds, tear them down.

    Args:
        todo: the measurements, in the order they run within a round.
        rounds: repeats per measurement.
        desc: the progress bar's label (the section name).
        progress: show the progress bar.
        round_word: what a round is called on the bar ("rep", "mission").
    """
    try:
        with progress_bar(len(todo) * (rounds + 1), desc, progress) as bar:
            for item in todo:
                bar.set_postfix_str(f"setup {item.describe()}", refresh=False)
                if item.error is None:
                    guard(item, item.set_up)
                bar.update()
            for k in range(rounds):
                for item in todo:
                    where = f"{round_word} {k + 1}/{rounds} {item.describe()}"
                    bar.set_postfix_str(where, refresh=False)
                    if item.error is None:
                        guard(item, lambda item=item, k=k: item.measure(k))
                    bar.update()
    finally:
        for item in todo:
            guard(item, item.tear_down)


def calibrated(per_item: float, seconds: float, low: int, high: int) -> int:
    """How many items (steps, resets) of ``per_item`` seconds fill ``seconds``, in [low, high]."""
    return int(min(high, max(low, round(seconds / max(per_item, 1e-9)))))


ACTION_KINDS = ("gentle", "random")
"""How a bench draws actions: ``"gentle"`` small thrusts that rarely end an episode, ``"random"``
uniformly random actions over the whole action space, as an exploring policy gives them (about
3 % of episodes end every step, so resets weigh in)."""


RANDOM = "actions=random"
"""The variant label of the rows timed with uniformly random actions."""


def draw_actions(
    space: gym.Space,
    env_id: str,
    lead: tuple[int, ...],
    rng: np.random.Generator,
    kind: str = "gentle",
) -> np.ndarray:
    """Valid actions of shape ``(*lead, *space.shape)``, drawn up front so sampling is not timed.

    ``kind="gentle"``: continuous DebrisGym actions are small thrusts, uniform in
    [-THRUST, THRUST] (a fraction of ``max_accel``); discrete ones coast with probability
    DISCRETE_COAST and fire a random thruster otherwise. ``kind="random"``: uniform over the
    whole space. CartPole's are uniform {0, 1} either way.
    """
    if kind not in ACTION_KINDS:
        raise ValueError(f"kind must be one of {ACTION_KINDS}, got {kind!r}")
    if isinstance(space, gym.spaces.Discrete):
        if env_id == CARTPOLE or kind == "random":
            return rng.integers(0, int(space.n), size=lead)
        thrust = rng.integers(1, int(space.n), size=lead)
        return np.where(rng.random(lead) < DISCRETE_COAST, 0, thrust)
    if not isinstance(space, gym.spaces.Box):
        raise ValueError(f"action space must be Discrete or Box, got {space}")
    high = 1.0 if kind == "random" else THRUST
    return rng.uniform(-high, high, size=(*lead, *space.shape)).astype(space.dtype)


def paired_ratio(
    row: dict[str, Any],
    ref: dict[str, Any] | None,
    key: str,
    cost: bool = False,
    rate: str = "env_steps_per_s",
) -> None:
    """Set ``row[key]`` to the ratio of median rates and ``row[key + "_range"]`` to its range.

    Rates are ``row[rate]`` (the median; env-steps/s unless ``rate`` names another key), per
    repeat in ``_rates``. The ratio is row / ref, or ref / row when ``cost`` (a cost per step
    instead of a rate). The range pairs
    the two measurements taken in the same round, which share that round's machine load. Left
    untouched (NaN) when either side has no repeats.
    """
    if ref is None or not row["_rates"] or not ref["_rates"]:
        return
    a, b = (ref, row) if cost else (row, ref)
    row[key] = a[rate] / b[rate]
    paired = [x / y for x, y in zip(a["_rates"], b["_rates"], strict=False)]
    row[key + "_range"] = (min(paired), max(paired))


def drop_rates(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Remove the per-repeat ``_rates`` that :func:`paired_ratio` needed; returns ``rows``."""
    for row in rows:
        del row["_rates"]
    return rows


def pin_torch() -> Any:
    """Import torch with one thread: every measurement but the ``num_threads=2`` rows compares
    single-threaded work."""
    import torch

    torch.set_num_threads(1)
    return torch


NAN_RANGE = (math.nan, math.nan)
"""The ``*_range`` of a ratio that could not be measured."""
