"""Missions that start part-way: some targets already captured, the field's bodies flown on, Δv
already spent, the chaser anywhere clear (by default holding beside the target it just took).

A :class:`MissionStart` is what ``reset(options={"start": ...})`` and a start sampler give; the
compiled :func:`advance_bodies` flies a field's bodies on with the very moves the step makes,
so a start taken from a recorded episode puts every body where that episode had it, bit for
bit, and :func:`resume_rows` sets the missions' clocks, captures and Δv after the episode has
begun (:func:`~debris_gym.mission_step.begin_rows`). No gymnasium import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from debris_gym.jit import kernel
from debris_gym.mission_step import move_bodies, settle_row, tour_scratch
from debris_gym.scenario_values import known_keys

__all__ = [
    "START_KEYS",
    "MissionStart",
    "advance_bodies",
    "beside_state",
    "checked_start",
    "resume_rows",
]

START_KEYS = ("captured", "step", "delta_v", "chaser_state", "beside", "field_word")
"""Keys of a ``reset(options={"start": {...}})`` dict (all optional)."""


@dataclass(frozen=True)
class MissionStart:
    """Where a mission starts, if not at the dock at t = 0 with nothing done.

    Attributes:
        captured: the targets already captured, in the order they were taken (indices).
        step: the steps already flown (>= 0, below the time limit): the mission clock starts at
            ``step · dt`` and every body has flown ``step`` steps of its natural motion from the
            field as drawn (``env.scenario`` stays the field at t = 0).
        delta_v: Δv already spent (m/s, below the budget).
        chaser_state: (2·dim,) LVLH position (m) and velocity (m/s); None: holding beside
            ``beside`` (or at rest at the dock when nothing is captured).
        beside: the target the chaser holds beside when ``chaser_state`` is None (default: the
            last of ``captured``): on the side facing the dock, half the capture radius off the
            target's surface, at the target's velocity.
        field_word: the 64-bit word of a moving random field (:meth:`MissionShell.field_word
            <debris_gym.envs.shell.MissionShell.field_word>`): the mission flies that field
            instead of the one its generator gives next; None: the usual field.
    """

    captured: tuple[int, ...] = ()
    step: int = 0
    delta_v: float = 0.0
    chaser_state: np.ndarray | None = field(default=None, compare=False)
    beside: int | None = None
    field_word: int | None = None

    @property
    def leg(self) -> int:
        """The leg the mission starts on: the number of targets already captured."""
        return len(self.captured)


def _whole(value: Any, name: str, low: int, high: int) -> int:
    """An integer in [low, high] (Python or numpy integer, not a bool)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    if not low <= value <= high:
        raise ValueError(f"{name}={value} is out of range; allowed: [{low}, {high}]")
    return int(value)


def checked_start(
    value: Any,
    *,
    n_targets: int,
    dim: int,
    horizon: int,
    delta_v_budget: float,
    name: str = "options['start']",
) -> MissionStart:
    """A :class:`MissionStart` from a reset option (a dict with keys among :data:`START_KEYS`,
    or a :class:`MissionStart`), checked against the mission; the chaser's clearance is checked
    where the field is known (:class:`~debris_gym.envs.shell.MissionShell`).

    Raises:
        ValueError: naming the key, the value and what is allowed.
    """
    if isinstance(value, MissionStart):
        value = {
            "captured": value.captured, "step": value.step, "delta_v": value.delta_v,
            "chaser_state": value.chaser_state, "beside": value.beside,
            "field_word": value.field_word,
        }  # fmt: skip
    value = known_keys(value, name, START_KEYS, also=" or a MissionStart")
    raw = value.get("captured", ())
    if isinstance(raw, (str, bytes)) or not isinstance(raw, (Sequence, np.ndarray)):
        raise ValueError(f"{name}['captured'] must be a list of target indices, got {raw!r}")
    captured = tuple(
        _whole(j, f"{name}['captured'][{k}]", 0, n_targets - 1) for k, j in enumerate(raw)
    )
    if len(set(captured)) != len(captured):
        raise ValueError(f"{name}['captured'] names a target twice: {list(captured)}")
    step = _whole(value.get("step", 0), f"{name}['step']", 0, horizon - 1)
    delta_v = value.get("delta_v", 0.0)
    if isinstance(delta_v, (bool, np.bool_)) or not isinstance(
        delta_v, (int, float, np.integer, np.floating)
    ):
        raise ValueError(f"{name}['delta_v'] must be a number in m/s, got {delta_v!r}")
    delta_v = float(delta_v)
    if not 0.0 <= delta_v < delta_v_budget:  # NaN fails too
        raise ValueError(
            f"{name}['delta_v']={delta_v} is out of range; allowed: [0, {delta_v_budget}) m/s "
            "(the Δv budget)"
        )
    state = value.get("chaser_state")
    if state is not None:
        state = np.asarray(state, dtype=float)
        if state.shape != (2 * dim,) or not np.isfinite(state).all():
            raise ValueError(
                f"{name}['chaser_state'] must be {2 * dim} finite numbers (LVLH m, m/s), got "
                f"{value.get('chaser_state')!r}"
            )
    beside = value.get("beside")
    if beside is not None:
        beside = _whole(beside, f"{name}['beside']", 0, n_targets - 1)
        if beside not in captured:
            raise ValueError(
                f"{name}['beside']={beside} must be one of the captured targets {list(captured)}"
            )
        if state is not None:
            raise ValueError(f"{name}: give 'chaser_state' or 'beside', not both")
    elif state is None and captured:
        beside = captured[-1]
    word = value.get("field_word")
    if word is not None:
        word = _whole(word, f"{name}['field_word']", 0, 2**64 - 1)
    return MissionStart(captured, step, delta_v, state, beside, word)


def beside_state(
    center: np.ndarray,
    velocity: np.ndarray,
    radius: float,
    dock: np.ndarray,
    chaser_radius: float,
    capture_radius: float,
) -> np.ndarray:
    """(2·dim,) the chaser holding beside a target (centre, velocity, radius in m, m/s): on the
    side facing ``dock``, its surface half the capture radius off the target's surface, at the
    target's velocity."""
    offset = dock - center
    norm = math.sqrt(float(offset @ offset))
    direction = offset / norm if norm > 0.0 else np.eye(len(center))[0]
    distance = radius + chaser_radius + 0.5 * capture_radius
    return np.concatenate([center + distance * direction, velocity])


@kernel
def advance_bodies(
    fields, counts, moving, matrix_t, centers, velocities, polygons, attitude, turns
):
    """Fly the bodies of each field ``fields[k]`` on by ``counts[k]`` steps of their natural
    motion, with the step's own moves (:func:`~debris_gym.mission_step.move_bodies`; nothing
    moves unless ``moving``)."""
    if not moving:
        return
    for k in range(fields.shape[0]):
        f = fields[k]
        for _ in range(counts[k]):
            move_bodies(f, matrix_t, centers, velocities, polygons, attitude, turns)


@kernel
def resume_rows(rows, states, captured, counts, spent, rules, shaping, missions, field):
    """Rows ``rows`` (just begun) resume part-way: row ``rows[r]`` at ``states[r]`` (R, 2·dim),
    with the targets ``captured[r]`` (R, T) bool taken, ``counts[r]`` steps on its clock and
    ``spent[r]`` m/s of Δv spent; its gaps, clearance and potential measured again."""
    n_targets = rules.n_targets
    order, tour_counters, legs, homes = tour_scratch(n_targets)
    for r in range(rows.shape[0]):
        i = rows[r]
        f = i // rules.n_chasers
        for a in range(states.shape[1]):
            missions.state[i, a] = states[r, a]
        for j in range(n_targets):
            if captured[r, j] and not missions.captured[i, j]:
                missions.captured[i, j] = True
                # where a capture leaves its hold count: the step that reached the rule's count
                missions.hold[i, j] = max(rules.hold_steps, 1)
        time = 0.0
        for _ in range(counts[r]):  # summed as the step sums it
            time += rules.dt
        missions.time[i] = time
        missions.steps[i] = counts[r]
        missions.delta_v[i] = spent[r]
        settle_row(i, f, rules, shaping, missions, field, order, tour_counters, legs, homes)
