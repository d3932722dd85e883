"""One chaser of a swarm as the env a single-agent classical baseline flies.

A :class:`ChaserView` is a read-only :class:`~agents.policies.base.FieldView` of chaser ``k`` of
a swarm (:class:`debris_gym.swarm.SwarmCore`, the core of every swarm env): its state, its own
capture flags, the swarm's clock and options, and the field as a
:class:`~debris_gym.scenario.Scenario` whose dock is the chaser's own dock slot. A baseline built
on it (``agents.make_agent("apf-mpc", ChaserView(env.core, k))``) flies chaser ``k`` exactly as it
would fly a single env holding the same field and chaser state (``tests/test_swarm_team.py``).

With ``assignment="given"`` the chaser's flags mark the targets of the other chasers as
captured, so the baseline goes after its own targets alone, and still avoids the others: they
stay bodies of the field.

The other chasers are not bodies of the view's field (its ``scenario`` and ``geometry``, which
stay those of the single-agent world); the view answers for them apart:
:meth:`ChaserView.teammates` gives each other chaser still in the field — flying, or held at its
slot in a reconfiguration — as a sphere on its predicted track, the prediction of
:func:`agents.planners.teammates.predict_tracks` from the plans the team shares
(:class:`TeamPlans`; a teammate without one coasts). A baseline that reads them (the MPC
trackers: :class:`agents.policies.tracking.MPCPathAgent`) keeps clear of them; the others do
not see them (their contacts are still collisions in the swarm).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from gymnasium import spaces

from agents.planners.teammates import MovingSpheres, predict_tracks
from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize
from debris_gym.geometry import FieldGeometry, geometry_now
from debris_gym.scenario import Scenario
from debris_gym.swarm import SwarmCore

__all__ = ["ChaserView", "TeamPlans"]


class TeamPlans:
    """The plans a team's members share: per chaser of a field, the states it last planned to
    fly (a :meth:`~agents.policies.tracking.MPCPathAgent.planned_states` answer).

    Args:
        chasers: K, the chasers of the field.
    """

    def __init__(self, chasers: int) -> None:
        self._plans: list[tuple[float, np.ndarray] | None] = [None] * int(chasers)

    def post(self, chaser: int, plan: tuple[float, np.ndarray] | None) -> None:
        """Chaser ``chaser``'s plan: (its time, s; (P + 1, 2·dim) states at it and the P steps
        after, m and m/s), or None (it has none)."""
        self._plans[chaser] = plan

    def get(self, chaser: int) -> tuple[float, np.ndarray] | None:
        """Chaser ``chaser``'s last posted plan, or None."""
        return self._plans[chaser]

    def clear(self) -> None:
        """Forget every plan (a new episode)."""
        self._plans = [None] * len(self._plans)


class ChaserView:
    """Chaser ``chaser`` of field ``field`` of a swarm, read-only.

    Args:
        core: the swarm's core (``env.core`` of a
            :class:`~debris_gym.swarm.parallel.SwarmParallelEnv`).
        chaser: the chaser's index k in its field, 0 … K − 1.
        field: the field's index (0 for a PettingZoo env, which has one).
        plans: the plans the team shares (None: every teammate coasts in :meth:`teammates`).

    Raises:
        ValueError: ``chaser`` or ``field`` out of range.
    """

    def __init__(
        self, core: SwarmCore, chaser: int, field: int = 0, plans: TeamPlans | None = None
    ) -> None:
        k, fields = int(core.chasers), int(core.num_fields)
        if isinstance(chaser, bool) or not isinstance(chaser, (int, np.integer)):
            raise ValueError(f"chaser must be an integer in [0, {k - 1}], got {chaser!r}")
        if not 0 <= chaser < k:
            raise ValueError(f"chaser={chaser} is out of range; allowed: [0, {k - 1}]")
        if isinstance(field, bool) or not isinstance(field, (int, np.integer)):
            raise ValueError(f"field must be an integer in [0, {fields - 1}], got {field!r}")
        if not 0 <= field < fields:
            raise ValueError(f"field={field} is out of range; allowed: [0, {fields - 1}]")
        self.core = core
        self.chaser, self.field = int(chaser), int(field)
        self.row = self.field * k + self.chaser
        """The chaser's row in the swarm's missions."""
        self._source: Scenario | None = None  # the swarm's field the cached view was made from
        self._scenario: Scenario | None = None
        self._geometry: FieldGeometry | None = None
        self.plans = plans

    # --- the FieldView members ------------------------------------------------------------------

    @property
    def config(self) -> EnvConfig:
        """The swarm's single-agent options."""
        return self.core.config

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.core.config.dim)

    @property
    def observation_space(self) -> spaces.Space:
        """One chaser's observation space in the swarm (its single-agent observation and the
        teammate slots)."""
        return self.core.observation_space

    @property
    def scenario(self) -> Scenario | None:
        """The field as drawn at t = 0, its ``dock`` the chaser's dock slot (m); the same
        object until the swarm installs another field. None before the first reset."""
        source = self.core.shell.scenario(self.field)
        if source is None:
            return None
        if source is not self._source:
            slot = self.core.shell.batch_in_use.dock[self.row]
            self._scenario = dataclasses.replace(source, dock=tuple(float(x) for x in slot))
            self._source = source
        return self._scenario

    @property
    def chaser_state(self) -> np.ndarray:
        """The chaser's LVLH state [position (m), velocity (m/s)] (a copy)."""
        return self._missions.state[self.row].copy()

    @property
    def captured(self) -> np.ndarray:
        """(T,) bool, the chaser's own flags (a copy): the targets captured by the team, and,
        with ``assignment="given"``, every target that is another chaser's."""
        return self._missions.captured[self.row].copy()

    @property
    def elapsed(self) -> float:
        """Time since the episode began (s)."""
        return float(self._missions.time[self.row])

    @property
    def geometry(self) -> FieldGeometry:
        """The field's geometry with the bodies where they are now (the view's clock),
        inflated by the chaser radius; rebuilt when the field or the time changes."""
        scenario = self.scenario
        if scenario is None:
            raise RuntimeError("reset the swarm before reading its geometry")
        self._geometry = geometry_now(
            self._geometry, scenario, self.elapsed, self.config.chaser_radius
        )
        return self._geometry

    # --- what a team reads besides ---------------------------------------------------------------

    @property
    def assigned(self) -> np.ndarray:
        """(T,) bool: the targets that are this chaser's (every one with ``assignment="free"``)."""
        return self._missions.assigned[self.row].copy()

    @property
    def flying(self) -> bool:
        """Whether the chaser has not ended its mission."""
        return bool(self.core.flying[self.row])

    def teammates(self, steps: int, ahead: bool = False) -> MovingSpheres:
        """The other chasers of the field still in it (flying, or held at their slots in a
        reconfiguration), each a sphere of radius ``r_col`` − ``chaser_radius`` (grown by the
        chaser's radius, the collision distance) on its predicted track over ``steps`` steps
        (:func:`~agents.planners.teammates.predict_tracks`): its shared plan flown on from its
        state now, coasting without one (a plan from the future or older than its horizon is
        none), standing still when held.

        Args:
            steps: the horizon (steps).
            ahead: only the chasers ahead of this one in the team's order of priority (a lower
                index: they decide first in a step, so their plans of this step are known),
                and those held at their slots (which stand still for everyone): what a
                prioritised planner avoids.

        Raises:
            RuntimeError: the swarm has not been reset.
        """
        scenario = self.scenario
        if scenario is None:
            raise RuntimeError("reset the swarm before reading the teammates")
        core, k = self.core, self.core.chasers
        batch = core.shell.batch_in_use
        missions = batch.missions
        others = [self.field * k + q for q in range(k) if q != self.chaser]
        flying = core.flying[others]
        held = missions.success[others] & bool(core.swarm.reconfigure)
        rows = [
            r
            for r, f, h in zip(others, flying, held, strict=True)
            if h or (f and (not ahead or r < self.row))
        ]
        dim, dt, now = self.dim, float(scenario.dt), self.elapsed
        plans: list[np.ndarray | None] = []
        offsets = np.zeros(len(rows), dtype=np.int64)
        for i, row in enumerate(rows):
            posted = None if self.plans is None else self.plans.get(row - self.field * k)
            plan = None
            if posted is not None:
                lag = round((now - posted[0]) / dt)
                if 0 <= lag < len(posted[1]) and abs(now - posted[0] - lag * dt) <= 1e-6 * dt:
                    plan, offsets[i] = posted[1], lag
            plans.append(plan)
        radius = float(batch.rules.chaser_separation) - float(self.config.chaser_radius)
        tracks = predict_tracks(
            missions.state[rows], plans, offsets, ~core.flying[rows],
            discretize(scenario.mean_motion, dt, dim).ad, steps,
        )  # fmt: skip
        return MovingSpheres(tracks, np.full(len(rows), radius))

    @property
    def _missions(self) -> Any:
        return self.core.shell.batch_in_use.missions

    def __repr__(self) -> str:
        return f"ChaserView(chaser={self.chaser}, field={self.field})"
