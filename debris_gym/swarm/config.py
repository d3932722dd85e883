"""Typed, validated configuration of a swarm: several chasers in one field.

:class:`SwarmConfig` holds what a swarm adds to the single-agent options (which stay an
:class:`~debris_gym.config.EnvConfig`): how many chasers share a field, when two of them
collide, where their dock slots are and how much of the team's reward each one gets.
:func:`dock_slots` lays the slots out. No gymnasium or PettingZoo import.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from debris_gym.config import MAX_WEIGHT, UNCERTAINTY_KEYS, EnvConfig
from debris_gym.swarm.formation import formation_slots, outer_radius

MAX_CHASERS = 256
"""Most chasers in one field."""

MAX_TEAMMATE_SLOTS = 4
"""Teammate slots of the observation when ``obs_teammates`` is not given: the nearest four
other chasers (or all of them in a smaller swarm)."""

SWARM_KEYS = (
    "n_chasers",
    "r_col",
    "dock_spacing",
    "reward_team",
    "assignment",
    "mission",
    "slot_spacing",
    "formation_core",
)
"""The options a swarm adds to the single-agent ones."""

ASSIGNMENTS = ("free", "given")
"""``free``: every chaser may capture every target; ``given``: every target is one chaser's
(:mod:`debris_gym.swarm.assignment`)."""

MISSIONS = ("capture", "reconfigure")
"""``capture``: the targets shared by the team, then every chaser back at its dock slot;
``reconfigure``: every chaser to its own formation slot (:mod:`debris_gym.swarm.formation`)."""


_DEFAULTS = {f.name: f.default for f in dataclasses.fields(EnvConfig)}


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
            :func:`~debris_gym.swarm.assignment.balanced_assignment`; in a reconfiguration each
            slot is one chaser's: by the reset option, else the least total straight-line
            distance, :func:`~debris_gym.swarm.formation.nearest_slots`).
        mission: ``"capture"`` or ``"reconfigure"`` (:data:`MISSIONS`).
        slot_spacing: distance (m) between neighbouring formation slots and between the
            formation's shells (a reconfiguration); None = 2 · (capture_radius +
            chaser_radius), the least at which two chasers inside their slots' zones never
            touch.
        formation_core: radius (m) of the body at the formation's centre (a reconfiguration).
    """

    n_chasers: int = 3
    r_col: float | None = None
    dock_spacing: float = 5.0
    reward_team: float = 0.0
    assignment: str = "free"
    mission: str = "capture"
    slot_spacing: float | None = None
    formation_core: float = 5.0

    @property
    def reconfigure(self) -> bool:
        """The mission flies chasers to formation slots."""
        return self.mission == "reconfigure"

    def spacing(self, env: EnvConfig) -> float:
        """The formation's slot spacing (m) under ``env``."""
        if self.slot_spacing is not None:
            return float(self.slot_spacing)
        return 2.0 * (env.capture_radius + env.chaser_radius)

    def checked(self, env: EnvConfig) -> SwarmConfig:
        """This config validated against ``env``'s (raises ``ValueError`` naming the key and
        the allowed range)."""
        k = self.n_chasers
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_CHASERS:
            raise ValueError(f"n_chasers={k!r} is out of range; allowed: [1, {MAX_CHASERS}]")
        if env.uncertain:
            on = [key for key in UNCERTAINTY_KEYS if getattr(env, key) != _DEFAULTS[key]]
            raise ValueError(
                f"the uncertain world's options ({', '.join(on)}) are for the single-agent "
                "IDs; a swarm flies the exact world: leave them at their defaults"
            )
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
        if self.mission not in MISSIONS:
            raise ValueError(
                f"mission={self.mission!r} is not allowed; allowed: one of "
                f"{', '.join(map(repr, MISSIONS))}"
            )
        least = 2.0 * (env.capture_radius + env.chaser_radius)
        if self.slot_spacing is not None and not (
            _real(self.slot_spacing) and least <= self.slot_spacing <= env.field_size
        ):
            raise ValueError(
                f"slot_spacing={self.slot_spacing!r} m is out of range; allowed: [{least:g}, "
                f"{env.field_size:g}] m (two chasers inside their slots' capture zones must "
                "not touch) or None"
            )
        if not (_real(self.formation_core) and 0.1 <= self.formation_core <= env.field_size / 4):
            raise ValueError(
                f"formation_core={self.formation_core!r} m is out of range; allowed: "
                f"[0.1, {env.field_size / 4:g}] m"
            )
        if self.reconfigure and self.assignment != "given":
            raise ValueError(
                f"assignment={self.assignment!r} is not allowed with mission='reconfigure'; "
                "allowed: 'given' (each formation slot is one chaser's)"
            )
        if env.obs_teammates > k - 1:
            raise ValueError(
                f"obs_teammates={env.obs_teammates} is out of range for {k} chasers; "
                f"allowed: [0, {k - 1}]"
            )
        return SwarmConfig(
            int(k), None if self.r_col is None else float(self.r_col), float(self.dock_spacing),
            float(self.reward_team), str(self.assignment), str(self.mission),
            None if self.slot_spacing is None else float(self.slot_spacing),
            float(self.formation_core),
        )  # fmt: skip


def mission_config(env: EnvConfig, swarm: SwarmConfig) -> EnvConfig:
    """The single-agent config a swarm's fields are drawn and flown with: ``env`` itself for a
    capture mission; for a reconfiguration, one target (the formation's place: the generator
    keeps its ball free and reachable, :func:`~debris_gym.swarm.formation.outer_radius` wide;
    the body left at its centre is ``formation_core`` wide) — ``target_radius_min`` and
    ``target_radius_max`` are set from the formation.

    Raises:
        ValueError: ``n_targets`` other than 1 in a reconfiguration, or a formation the field
            cannot hold (the message names ``n_chasers`` and ``slot_spacing``).
    """
    if not swarm.reconfigure:
        return env
    if env.n_targets != 1:
        raise ValueError(
            f"n_targets={env.n_targets} is not allowed with mission='reconfigure'; allowed: 1 "
            "(the body at the formation's centre)"
        )
    slots = formation_slots(swarm.n_chasers, swarm.formation_core, swarm.spacing(env), env.dim)
    reach = outer_radius(slots, env.capture_radius, env.chaser_radius)
    try:
        return EnvConfig.from_kwargs(
            **{**dataclasses.asdict(env), "target_radius_min": reach, "target_radius_max": reach}
        )
    except ValueError as err:
        raise ValueError(
            f"a formation of n_chasers={swarm.n_chasers} at slot_spacing="
            f"{swarm.spacing(env):g} m reaches {reach:g} m from its centre, more than "
            f"field_size={env.field_size:g} m holds ({err}); lower n_chasers or slot_spacing"
        ) from err


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
