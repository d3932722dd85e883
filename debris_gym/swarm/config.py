"""Typed, validated configuration of a swarm: several chasers in one field.

:class:`SwarmConfig` holds what a swarm adds to the single-agent options (which stay an
:class:`~debris_gym.config.EnvConfig`): how many chasers share a field, when two of them
collide, where their dock slots are and how much of the team's reward each one gets.
:func:`dock_slots` lays the slots out. No gymnasium or PettingZoo import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from debris_gym.config import MAX_WEIGHT, EnvConfig

MAX_CHASERS = 256
"""Most chasers in one field."""

MAX_TEAMMATE_SLOTS = 4
"""Teammate slots of the observation when ``obs_teammates`` is not given: the nearest four
other chasers (or all of them in a smaller swarm)."""

SWARM_KEYS = ("n_chasers", "r_col", "dock_spacing", "reward_team", "assignment")

ASSIGNMENTS = ("free", "given")
"""``free``: every chaser may capture every target; ``given``: every target is one chaser's
(:mod:`debris_gym.swarm.assignment`)."""
"""The options a swarm adds to the single-agent ones."""


@dataclass(frozen=True)
class SwarmConfig:
    """What a swarm adds to an :class:`~debris_gym.config.EnvConfig` (SI units).

    Attributes:
        n_chasers: chasers in the field, 1 … :data:`MAX_CHASERS`.
        r_col: centre-to-centre distance (m) at or below which two chasers collide (both
            fail); None = touching, twice ``chaser_radius``.
        dock_spacing: distance (m) between neighbouring dock slots (each chaser starts at, and
            returns to, its own slot: a hexagonal lattice around the field's dock, slot 0 at
            the dock itself).
        reward_team: weight of the shared team term: each chaser also gets this times the
            mean, over the chasers, of the step's capture and success terms (0 = off).
        assignment: ``"free"`` (any chaser captures any target) or ``"given"`` (each target is
            one chaser's: by the reset option ``assignment``, else the balanced nearest rule of
            :func:`~debris_gym.swarm.assignment.balanced_assignment`).
    """

    n_chasers: int = 3
    r_col: float | None = None
    dock_spacing: float = 5.0
    reward_team: float = 0.0
    assignment: str = "free"

    def checked(self, env: EnvConfig) -> SwarmConfig:
        """This config validated against ``env``'s (raises ``ValueError`` naming the key and
        the allowed range)."""
        k = self.n_chasers
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_CHASERS:
            raise ValueError(f"n_chasers={k!r} is out of range; allowed: [1, {MAX_CHASERS}]")
        touching = 2.0 * env.chaser_radius
        if self.r_col is not None and not (
            _real(self.r_col) and touching <= self.r_col <= env.field_size
        ):
            raise ValueError(
                f"r_col={self.r_col!r} m is out of range; allowed: [{touching:g}, "
                f"{env.field_size:g}] m (at least two chaser radii: chasers touch there) or None"
            )
        separation = touching if self.r_col is None else float(self.r_col)
        if not (_real(self.dock_spacing) and separation < self.dock_spacing <= env.field_size):
            raise ValueError(
                f"dock_spacing={self.dock_spacing!r} m is out of range; allowed: "
                f"({separation:g}, {env.field_size:g}] m (more than r_col: chasers start apart)"
            )
        if not (_real(self.reward_team) and 0.0 <= self.reward_team <= MAX_WEIGHT):
            raise ValueError(
                f"reward_team={self.reward_team!r} is out of range; allowed: [0, {MAX_WEIGHT:g}]"
            )
        if self.assignment not in ASSIGNMENTS:
            raise ValueError(
                f"assignment={self.assignment!r} is not allowed; allowed: one of "
                f"{', '.join(map(repr, ASSIGNMENTS))}"
            )
        if env.obs_teammates > k - 1:
            raise ValueError(
                f"obs_teammates={env.obs_teammates} is out of range for {k} chasers; "
                f"allowed: [0, {k - 1}]"
            )
        return SwarmConfig(int(k), None if self.r_col is None else float(self.r_col),
                           float(self.dock_spacing), float(self.reward_team),
                           str(self.assignment))  # fmt: skip


def _real(value: Any) -> bool:
    return (
        not isinstance(value, bool)
        and isinstance(value, (int, float, np.integer, np.floating))
        and math.isfinite(value)
    )


def split_options(options: dict[str, Any]) -> tuple[dict[str, Any], SwarmConfig]:
    """Single-agent options and the :class:`SwarmConfig` of a swarm's keyword arguments (not
    yet checked); ``obs_teammates`` defaults to min(n_chasers − 1, :data:`MAX_TEAMMATE_SLOTS`)."""
    env = {k: v for k, v in options.items() if k not in SWARM_KEYS}
    swarm = SwarmConfig(**{k: v for k, v in options.items() if k in SWARM_KEYS})
    if "obs_teammates" not in env and isinstance(swarm.n_chasers, (int, np.integer)):
        env["obs_teammates"] = max(0, min(int(swarm.n_chasers) - 1, MAX_TEAMMATE_SLOTS))
    return env, swarm


def dock_slots(n: int, spacing: float, dim: int) -> np.ndarray:
    """(n, dim) dock slot offsets (m) from the field's dock: the points of a hexagonal lattice
    of pitch ``spacing`` in the x–y plane nearest the dock (slot 0 the dock itself; ties by
    angle from +x), so every two slots are at least ``spacing`` apart."""
    rings = math.ceil(math.sqrt(n)) + 1
    points = []
    for a in range(-rings, rings + 1):
        for b in range(-rings, rings + 1):
            x, y = a + 0.5 * b, b * math.sqrt(3.0) / 2.0
            angle = math.atan2(y, x) % (2.0 * math.pi)
            points.append((round(x * x + y * y, 9), angle, x, y))
    points.sort()
    slots = np.zeros((n, dim))
    slots[:, 0] = [p[2] for p in points[:n]]
    slots[:, 1] = [p[3] for p in points[:n]]
    return slots * spacing
