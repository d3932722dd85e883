"""Missions that start part-way, as a mission shell's reset and autoreset start them.

``reset(options={"start": ...})`` names one :class:`~debris_gym.mission_starts.MissionStart`
for every row (a dict or a ``MissionStart``) or one per row (a sequence with None for the rows
that start as usual). A :class:`StartSampler` attached to a shell gives the starts of the
missions that restart by themselves (autoreset), told how each ended mission ended, which is
what a sampler that favours the legs a learner fails needs.

:func:`plan_starts` checks every start against the fields the reset installs, flown on to the
start's step, before anything changes (the reset is a transaction); the shell then installs the
fields and applies the :class:`StartPlan`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import checked_chaser_states
from debris_gym.envs.field_supply import FieldSupply
from debris_gym.field_spec import FieldArrays
from debris_gym.mission_batch import MissionBatch
from debris_gym.mission_starts import MissionStart, beside_state, checked_start
from debris_gym.scenario import Scenario

__all__ = [
    "EpisodeEnds",
    "StartPlan",
    "StartSampler",
    "checked_starts",
    "plan_starts",
    "starts_for_reset",
    "with_words",
]


class EpisodeEnds(NamedTuple):
    """How the missions that are about to restart ended (one entry per restarting row)."""

    captured: np.ndarray
    """(R,) int64 targets captured by the end."""
    success: np.ndarray
    """(R,) bool: the mission succeeded."""


class StartSampler(Protocol):
    """Gives the starts of restarting missions (see :attr:`MissionShell.start_sampler
    <debris_gym.envs.shell.MissionShell.start_sampler>`)."""

    def __call__(
        self, rows: np.ndarray, ended: EpisodeEnds | None
    ) -> Sequence[MissionStart | None]:
        """One start (None: the usual start) for each row of ``rows`` (R,); ``ended``: how the
        rows' last missions ended (None at a reset of every row, which ends nothing)."""
        ...


class ShellParts(Protocol):
    """What :func:`starts_for_reset` reads of a :class:`~debris_gym.envs.shell.MissionShell`."""

    num: int
    n_fields: int
    chasers: int
    config: EnvConfig
    start_sampler: StartSampler | None

    @property
    def horizon_steps(self) -> int: ...

    def batch_n_targets(self) -> int: ...


class StartPlan(NamedTuple):
    """Checked starts of some rows of a reset, ready to apply."""

    positions: np.ndarray
    """(R,) int64 positions, within the reset's rows, of the rows that start part-way."""
    states: np.ndarray
    """(R, 2·dim) their chasers' states (m, m/s)."""
    captured: np.ndarray
    """(R, T) bool the targets already captured."""
    counts: np.ndarray
    """(R,) int64 steps already flown."""
    spent: np.ndarray
    """(R,) Δv already spent (m/s)."""
    words: np.ndarray
    """(R,) uint64 the field word each row flies (0 where ``has_word`` is False)."""
    has_word: np.ndarray
    """(R,) bool: the row flies the field of its word instead of its generator's."""


def checked_starts(
    value: Any, num: int, config: EnvConfig, horizon: int, n_targets: int
) -> list[MissionStart | None]:
    """The ``start`` reset option as one entry per row: a dict or
    :class:`~debris_gym.mission_starts.MissionStart` for every row, or a sequence of ``num``
    of them (None: that row starts as usual).

    Raises:
        ValueError: naming the option, the row and the bad key.
    """
    dim = config.dim
    budget = math.inf if config.delta_v_budget is None else config.delta_v_budget

    def check(v: Any, name: str) -> MissionStart:
        return checked_start(
            v, n_targets=n_targets, dim=dim, horizon=horizon, delta_v_budget=budget, name=name
        )

    if isinstance(value, (Mapping, MissionStart)):
        return [check(value, "options['start']")] * num
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ValueError(
            "options['start'] must be a dict (or MissionStart) for every sub-env or a list of "
            f"{num} of them (None: a usual start), got {type(value).__name__}"
        )
    if len(value) != num:
        raise ValueError(
            f"options['start'] must list {num} starts (one per sub-env), got {len(value)}"
        )
    return [None if v is None else check(v, f"options['start'][{i}]") for i, v in enumerate(value)]


def starts_for_reset(
    shell: ShellParts, option: Any, with_states: bool
) -> list[MissionStart | None] | None:
    """The starts of a reset of every row of ``shell``: its ``start`` option, else its
    :attr:`~debris_gym.envs.shell.MissionShell.start_sampler`'s (None: every row at its dock
    at t = 0; also when the reset sets ``chaser_state``, which the sampler yields to).

    Raises:
        ValueError: a bad ``start`` option, or one the shell cannot fly (naming why).
    """
    if option is None:
        if shell.start_sampler is None or with_states:
            return None
        starts = list(shell.start_sampler(np.arange(shell.n_fields), None))
    else:
        if with_states:
            raise ValueError(
                "give options['chaser_state'] or options['start'] (which has its own "
                "'chaser_state'), not both"
            )
        starts = checked_starts(
            option, shell.num, shell.config, shell.horizon_steps, shell.batch_n_targets()
        )
    if all(s is None for s in starts):
        return None
    if shell.chasers > 1:
        raise ValueError("options['start'] is for one chaser per field; a swarm has no starts")
    if shell.config.truth_model != "cw" and any(s is not None and s.step for s in starts):
        raise ValueError(
            f"options['start'] with a 'step' flies the bodies on by CW; truth_model="
            f"{shell.config.truth_model!r} moves them otherwise: use step 0"
        )
    return starts


def with_words(
    supply: FieldSupply, starts: Sequence[MissionStart | None], fields: FieldArrays | None
) -> FieldArrays | None:
    """``fields`` (one per row of a reset) with the fields of the starts that name a
    ``field_word`` drawn from it.

    Raises:
        ValueError: a word where the rows fly a pinned field or the paper world.
    """
    positions = [k for k, s in enumerate(starts) if s is not None and s.field_word is not None]
    if not positions:
        return fields
    if fields is None:
        raise ValueError(
            "options['start']['field_word'] names a moving random field; this reset flies "
            "a pinned field or the paper world"
        )
    words = np.array([starts[k].field_word for k in positions], dtype=np.uint64)  # type: ignore[union-attr]
    return supply.with_words(fields, np.array(positions), words)


def plan_starts(
    starts: Sequence[MissionStart | None],
    batch: MissionBatch,
    config: EnvConfig,
    fields: FieldArrays | None,
    scenario: Scenario | None,
) -> StartPlan | None:
    """The starts checked against the fields they fly: ``fields`` (drawn, one per row, with
    the starts' words already drawn in) or the one ``scenario`` every row flies, flown on to
    each start's step (:meth:`MissionBatch.flown_copy`). None when every start is the usual one.

    Raises:
        ValueError: a chaser that would start outside the world, too fast, or not clear of a
            body there (naming the row and the start's keys).
    """
    positions = np.array([k for k, s in enumerate(starts) if s is not None], dtype=np.int64)
    if len(positions) == 0:
        return None
    chosen = [starts[k] for k in positions.tolist()]
    assert all(s is not None for s in chosen)
    counts = np.array([s.step for s in chosen if s is not None], dtype=np.int64)
    captured = np.zeros((len(chosen), batch.n_targets), dtype=bool)
    for r, s in enumerate(chosen):
        if s is not None:
            captured[r, list(s.captured)] = True
    if fields is not None:
        flown = batch.flown_copy(_rows_of(fields, positions), counts)
        low, high = np.array(fields.bounds).T
        dock = np.zeros(config.dim)
        size = 2.0 * fields.half_size
    else:
        assert scenario is not None
        flown = batch.flown_copy(scenario, counts)
        low, high, dock, size = (
            scenario.low,
            scenario.high,
            np.asarray(scenario.dock),
            scenario.size,
        )
    states = np.empty((len(chosen), 2 * config.dim))
    for r, s in enumerate(chosen):
        assert s is not None
        if s.chaser_state is not None:
            states[r] = s.chaser_state
        elif s.beside is not None:
            j = s.beside
            states[r] = beside_state(
                flown.centers[r, j], flown.velocities[r, j], float(flown.radii[r, j]), dock,
                config.chaser_radius, config.capture_radius,
            )  # fmt: skip
        else:
            states[r, : config.dim], states[r, config.dim :] = dock, 0.0
    try:
        states = checked_chaser_states(
            states, len(chosen), low, high, size / config.dt,
            lambda points: flown.gaps(points), config.chaser_radius,
        )  # fmt: skip
    except ValueError as err:
        raise ValueError(
            f"options['start']: the chaser cannot start there at the start's step ({err})"
        ) from err
    words = np.array([s.field_word or 0 for s in chosen if s is not None], dtype=np.uint64)
    has_word = np.array([s.field_word is not None for s in chosen if s is not None], dtype=bool)
    return StartPlan(positions, states, captured, counts, spent_of(chosen), words, has_word)


def spent_of(starts: Sequence[MissionStart | None]) -> np.ndarray:
    """(R,) the Δv already spent of each start (m/s)."""
    return np.array([s.delta_v for s in starts if s is not None], dtype=float)


def _rows_of(fields: FieldArrays, positions: np.ndarray) -> FieldArrays:
    """The fields at ``positions`` as fields of their own."""

    def pick(array: np.ndarray | None) -> np.ndarray | None:
        return None if array is None else array[positions]

    return FieldArrays(
        fields.dim, fields.half_size, fields.n_targets, fields.centers[positions],
        fields.radii[positions], fields.vertices[positions], fields.n_vertices[positions],
        velocities=pick(fields.velocities), spins=pick(fields.spins),
    )  # fmt: skip
