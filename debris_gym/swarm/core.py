"""E swarm missions (fields) of K chasers each, the core every swarm env is a view of.

:class:`SwarmCore` holds a :class:`~debris_gym.envs.shell.MissionShell` with K chasers per
field (row e·K + k is chaser k of field e) and what a swarm adds to it: the dock slots, the
chasers still flying, the team term of the reward and the team's outcome. The PettingZoo env
(:class:`~debris_gym.swarm.parallel.SwarmParallelEnv`) is its one-field view, the SB3 training
env (:class:`~debris_gym.integrations.sb3_swarm.SwarmVecEnv`) its many-field view.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    DEFAULT_HORIZON_STEPS,
    checked_continuous_actions,
    checked_discrete_action,
    discrete_action_table,
    field_spec,
    observation_names,
    single_spaces,
)
from debris_gym.envs.shell import Autoreset, MissionShell
from debris_gym.field_spec import FieldArrays
from debris_gym.rewards import REWARD_TERMS
from debris_gym.swarm.assignment import balanced_assignment, checked_assignment
from debris_gym.swarm.config import SwarmConfig, dock_slots, mission_config, split_options
from debris_gym.swarm.formation import checked_slot_assignment, formation_slots, nearest_slots

__all__ = ["TEAM_INFO_KEYS", "SwarmCore", "SwarmStep"]

TEAM_INFO_KEYS = (
    "assigned",
    "team_success",
    "team_captures",
    "min_separation",
    "teammate_collision",
    "separation",
    "reward_team",
)
"""The keys a swarm adds to every chaser's single-agent info (docs/swarm.md); its
``captured`` is the team's."""

_CAPTURE, _SUCCESS = REWARD_TERMS.index("capture"), REWARD_TERMS.index("success")


class SwarmStep(NamedTuple):
    """One step of every field (row i = chaser i; new arrays)."""

    reward: np.ndarray
    """(N,) each chaser's reward with its team term (0 for chasers that did not fly)."""
    terminated: np.ndarray
    """(N,) bool: the chaser ended in this step (success, collision, exit, budget)."""
    truncated: np.ndarray
    """(N,) bool: the time limit ended the chaser in this step."""
    terms: np.ndarray
    """(N, 8) the named reward terms."""
    team: np.ndarray
    """(N,) each chaser's team term."""
    flew: np.ndarray
    """(N,) bool: the chasers that flew this step."""
    field_over: np.ndarray
    """(E,) bool: every chaser of the field has ended."""


class SwarmCore:
    """E fields of K chasers: the shell, the dock slots, the flying mask and the team.

    Args:
        num_fields: fields E.
        max_episode_steps: the time limit that truncates every chaser (None: none).
        **options: single-agent options and the swarm's (:class:`SwarmConfig`).

    Raises:
        ValueError: naming a bad option.
    """

    render_mode: str | None = None
    """Swarm envs do not render yet (vector-env wrappers ask for this)."""

    def __init__(
        self, num_fields: int = 1, max_episode_steps: int | None = DEFAULT_HORIZON_STEPS,
        **options: Any,
    ) -> None:  # fmt: skip
        env_options, swarm = split_options(options)
        made = EnvConfig.from_kwargs(**env_options)
        self.swarm: SwarmConfig = swarm.checked(made)
        self.config = config = mission_config(made, self.swarm)
        k = self.chasers = self.swarm.n_chasers
        if self.swarm.reconfigure and config.scenario != "random":
            raise ValueError(
                f"scenario={config.scenario!r} is not allowed with mission='reconfigure'; "
                "allowed: 'random' (a field of the reset option 'scenario' may be pinned)"
            )
        self.num_fields = num_fields
        self.num = num_fields * k
        slots = dock_slots(k, self.swarm.dock_spacing, config.dim)
        reach = float(np.max(np.linalg.norm(slots, axis=1))) + config.chaser_radius
        clear = field_spec(config).dock_clearance
        if config.scenario == "random" and reach >= clear:
            raise ValueError(
                f"{k} dock slots at dock_spacing={self.swarm.dock_spacing:g} m reach "
                f"{reach:g} m from the dock, beyond its clear zone ({clear:g} m): lower "
                "dock_spacing or n_chasers"
            )
        self._slots = slots
        self.max_episode_steps = max_episode_steps
        self.shell = MissionShell(
            config, self.num, autoreset=Autoreset.NEVER, max_episode_steps=max_episode_steps,
            chasers=k, chaser_separation=self.swarm.r_col, dock_offsets=slots,
            field_loop=True, arrived_stay=self.swarm.reconfigure,
        )  # fmt: skip
        if max_episode_steps is not None:
            self.shell.horizon = max_episode_steps
        self.observation_space, self.action_space = single_spaces(config)
        self.obs_names = observation_names(config)
        self._discrete = discrete_action_table(config.dim, config.fine_thrust)
        self._obs = np.zeros((self.num, len(self.obs_names)), dtype=np.float32)
        self.flying = np.zeros(self.num, dtype=bool)
        """(N,) the chasers that have not ended."""
        self._given: np.ndarray | None = None  # the reset option "assignment": (K, T) bool,
        # or (K,) slot indices in a reconfiguration
        self.formation = (
            formation_slots(k, self.swarm.formation_core, self.swarm.spacing(config), config.dim)
            if self.swarm.reconfigure else None
        )  # fmt: skip
        """(K, dim) the formation's slot offsets (m) from its centre (a reconfiguration), or
        None."""
        self.shell.on_install = self._place_formation if self.swarm.reconfigure else self._assign
        if self.swarm.reconfigure:
            self.shell.on_draw = self._shrink_core

    # --- episodes -----------------------------------------------------------------------------

    def reset(self, generators: list | None = None, options: Any = None) -> np.ndarray:
        """Every field anew (``generators``: one per field or None); the observations (N, size),
        a buffer the next call overwrites. ``options``: the single-agent reset options and, with
        ``assignment="given"``, ``assignment`` (one list of target indices per chaser, or a
        (K, T) bool array) for every field from this reset on (None: the balanced rule).

        Raises:
            ValueError: naming a bad option; nothing changed.
        """
        saved = self._given
        if isinstance(options, dict) and "assignment" in options:
            options = dict(options)
            given = options.pop("assignment")
            if given is not None and self.swarm.assignment != "given":
                raise ValueError("options['assignment'] needs an env made with assignment='given'")
            if given is None:
                self._given = None
            elif self.swarm.reconfigure:
                self._given = checked_slot_assignment(given, self.chasers)
            else:
                self._given = checked_assignment(given, self.chasers, self.config.n_targets)
        try:
            self.shell.reset(generators, options)
        except BaseException:
            self._given = saved
            raise
        self.flying[:] = True
        return self.observe()

    def _assign(self, fields: np.ndarray) -> None:
        """Each chaser's targets in the fields just installed (before their missions begin)."""
        batch = self.shell.batch_in_use
        k, assigned = self.chasers, batch.missions.assigned
        if self.swarm.assignment == "free":
            for e in fields.tolist():
                assigned[e * k : e * k + k] = True
            return
        t = batch.n_targets
        if self._given is not None and self._given.shape[1] != t:
            raise ValueError(
                f"options['assignment'] names {self._given.shape[1]} targets but the field has {t}"
            )
        for e in fields.tolist():
            rows = slice(e * k, e * k + k)
            assigned[rows] = (
                self._given if self._given is not None
                else balanced_assignment(
                    batch.dock[rows], batch.field.centers[e, :t], batch.field.radii[e, :t]
                )
            )  # fmt: skip

    def _shrink_core(self, fields: FieldArrays) -> None:
        """Drawn fields of a reconfiguration: the first body, the place the generator kept free
        for the formation (:func:`~debris_gym.swarm.config.mission_config`), shrunk to the
        body at its centre."""
        fields.radii[:, 0] = self.swarm.formation_core

    def _place_formation(self, fields: np.ndarray) -> np.ndarray:
        """A reconfiguration's fields just installed: the formation around the first body
        (a pinned field's slots stand off from its own radius), each chaser's dock moved to
        its slot (the reset option
        ``assignment``, else :func:`~debris_gym.swarm.formation.nearest_slots`), the body
        assigned to no chaser; returns the chasers' start states: at rest at the dock slots
        the shell set."""
        batch = self.shell.batch_in_use
        k, dim = self.chasers, self.config.dim
        spacing = self.swarm.spacing(self.config)
        starts = np.zeros((len(fields) * k, 2 * dim))
        for n, e in enumerate(fields.tolist()):
            rows = slice(e * k, e * k + k)
            pinned = self.shell.pinned[e]
            # the field's dock plus each chaser's dock slot (not batch.dock, which holds the
            # last formation's slots when the shell leaves a random world as it was)
            start = (np.zeros(dim) if pinned is None else np.asarray(pinned.dock)) + self._slots
            centre, core = batch.field.centers[e, 0], float(batch.field.radii[e, 0])
            offsets = (
                self.formation if core == self.swarm.formation_core
                else formation_slots(k, core, spacing, dim)
            )  # fmt: skip
            slots = centre + offsets
            order = self._given if self._given is not None else nearest_slots(start, slots)
            batch.dock[rows] = slots[order]
            batch.missions.assigned[rows] = False
            starts[n * k : n * k + k, :dim] = start
        return starts

    def restart(self, fields: np.ndarray) -> None:
        """New episodes in the fields in the mask ``fields`` (E,), every chaser at its slot."""
        self.shell.restart(fields)
        self.flying.reshape(self.num_fields, self.chasers)[fields] = True

    def step(self, commands: np.ndarray) -> SwarmStep:
        """One step of the chasers still flying (``commands``: (N, dim) validated normalised
        thrust, rows of ended chasers ignored)."""
        flew = self.flying.copy()
        out = self.shell.step(commands, flew)
        terms = out.terms.copy()
        team = self._team_term(terms) * flew
        reward = (out.reward + team) * flew
        terminated, truncated = out.terminated & flew, out.truncated & flew
        self.flying &= ~(terminated | truncated)
        field_over = np.logical_not(self.flying.reshape(self.num_fields, self.chasers).any(axis=1))
        return SwarmStep(reward, terminated, truncated, terms, team, flew, field_over)

    def command(self, action: Any) -> np.ndarray:
        """One chaser's action as a normalised thrust (dim,) (raises ``ValueError`` naming
        ``action``)."""
        if self.config.action == "discrete":
            return self._discrete[checked_discrete_action(action, len(self._discrete))]
        return checked_continuous_actions(action, (self.config.dim,))

    def _team_term(self, terms: np.ndarray) -> np.ndarray:
        """Each chaser's team term: ``reward_team`` times its field's mean capture and success
        terms."""
        w = self.swarm.reward_team
        if w == 0.0:
            return np.zeros(self.num)
        shared = (terms[:, _CAPTURE] + terms[:, _SUCCESS]).reshape(self.num_fields, -1)
        return np.repeat(w * shared.mean(axis=1), self.chasers)

    # --- reading ------------------------------------------------------------------------------

    def observe(self) -> np.ndarray:
        """Every chaser's observation (N, size), into a buffer the next call overwrites."""
        return self.shell.observe(self._obs)

    def team_success(self) -> np.ndarray:
        """(E,) a capture mission: every target captured, every chaser that did not fail back
        at its dock slot, and at least one did; a reconfiguration: every chaser at its slot."""
        return self._team_success(self.team_captured())

    def _team_success(self, captured: np.ndarray) -> np.ndarray:
        """:meth:`team_success` given :meth:`team_captured`."""
        m = self.shell.batch_in_use.missions
        shape = (self.num_fields, self.chasers)
        success = m.success.reshape(shape)
        if self.swarm.reconfigure:
            return np.all(success, axis=1)
        failed = (m.collision | m.out_of_bounds | m.budget_spent).reshape(shape)
        return captured.all(axis=1) & np.all(success | failed, axis=1) & np.any(success, axis=1)

    def team_captured(self) -> np.ndarray:
        """(E, T) bool: the targets the team has captured (a chaser's own captures; the flags
        it starts with for targets assigned to others do not count)."""
        m = self.shell.batch_in_use.missions
        own = (m.captured & m.assigned).reshape(self.num_fields, self.chasers, -1)
        return own.any(axis=1)

    def team_captures(self) -> np.ndarray:
        """(E,) targets the team has captured."""
        return np.count_nonzero(self.team_captured(), axis=1)

    def min_separation(self) -> np.ndarray:
        """(E,) the closest two chasers of each field came this episode (m)."""
        m = self.shell.batch_in_use.missions
        return m.separation.reshape(self.num_fields, self.chasers).min(axis=1)

    def row_infos(self, rows: list[int], terms: np.ndarray, team: np.ndarray) -> list[dict]:
        """The infos of the chasers ``rows``: the single-agent keys of each (``terms`` (N, 8)
        the step's reward terms) and :data:`TEAM_INFO_KEYS` (``team`` (N,) the team terms);
        the team's values are computed once for all of them."""
        m = self.shell.batch_in_use.missions
        captured = self.team_captured()
        success, separation = self._team_success(captured), self.min_separation()
        infos = []
        for i in rows:
            e = i // self.chasers
            info = self.shell.row_info(i, terms[i].tolist())
            info["captured"] = captured[e].copy()
            info["targets_captured"] = int(np.count_nonzero(captured[e]))
            info["assigned"] = m.assigned[i].copy()
            info["team_success"] = bool(success[e])
            info["team_captures"] = info["targets_captured"]
            info["min_separation"] = float(separation[e])
            info["teammate_collision"] = bool(m.teammate_collision[i])
            info["separation"] = float(m.separation[i])
            info["reward_team"] = float(team[i])
            infos.append(info)
        return infos

    def close(self) -> None:
        """Stop the field supply's worker thread."""
        self.shell.close()
