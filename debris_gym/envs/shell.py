"""The mission shell: N missions of one env, with everything around the compiled step written once.

Every env of the package is a view of a :class:`MissionShell`: the single env
(:class:`~debris_gym.envs.DebrisFieldEnv`) its one row, the native vector env
(:class:`~debris_gym.envs.vector.DebrisFieldVectorEnv`) all of its rows. The shell owns

* **field supply** — a random field per row from the row's generator, a pinned field, or the
  paper world (:class:`~debris_gym.envs.field_supply.FieldSupply`, which draws moving fields
  ahead on a worker thread);
* **the transactional reset** — seeds, options, the fields and the initial states are all
  checked before anything changes, then committed; a reset that raises leaves the shell as it
  was (fields, states, clocks, generators, pending autoresets);
* **the step boundary** — one call of the compiled kernel
  (:meth:`~debris_gym.mission_batch.MissionBatch.step`, named records in and out);
* **truncation** — the mission's step count against ``max_episode_steps``, in the kernel (the
  single env leaves the limit to gymnasium's ``TimeLimit``, as every gymnasium env does: made
  by ``gym.make`` it has no limit of its own);
* **autoreset** — the next-step and same-step modes of gymnasium's vector envs;
* **the info dict** — one table of keys (:mod:`debris_gym.envs.shell_info`), read per row or
  for all rows.

No view repeats any of it; docs/architecture.md shows where a view with several chasers per
field plugs in.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    DEFAULT_HORIZON_STEPS,
    check_motion_matches,
    checked_mission,
    checked_reset_options,
    observation_names,
    warn_if_physics_differ,
)
from debris_gym.envs.episode_errors import EpisodeErrors
from debris_gym.envs.field_supply import FieldSupply
from debris_gym.envs.loop_shield import LoopShield, check_shield_support
from debris_gym.envs.shell_fields import (
    FieldShape,
    batch_holds,
    checked_initial_states,
    drawn_scenario,
    drawn_shape,
    scenario_shape,
)
from debris_gym.envs.shell_info import all_rows_info, one_row_info
from debris_gym.envs.starts import (
    EpisodeEnds,
    StartPlan,
    StartSampler,
    plan_starts,
    starts_for_reset,
    with_words,
)
from debris_gym.field_spec import FieldArrays
from debris_gym.mission_batch import MissionBatch, check_threads
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.scenario_checks import check_dock_clear

__all__ = ["Autoreset", "MissionShell", "ShellView", "StepResult"]


class Autoreset(enum.Enum):
    """When a shell's ended missions restart."""

    NEVER = "never"
    """Never by themselves: the next :meth:`MissionShell.reset` starts them (a single env)."""
    NEXT_STEP = "next_step"
    """The step after a mission ends restarts it (its action ignored, reward 0)."""
    SAME_STEP = "same_step"
    """The step that ends a mission restarts it; the last observation and info are kept."""


class StepResult(NamedTuple):
    """A shell step's outputs (new arrays, row i = mission i)."""

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    terms: np.ndarray
    """(N, 8) reward terms, columns in :data:`~debris_gym.rewards.REWARD_TERMS` order."""
    final_observation: np.ndarray | None = None
    """Same-step autoreset: the ended missions' last observations (rows of ``ended``)."""
    final_info: dict[str, Any] | None = None
    """Same-step autoreset: the info of the step that ended them (all rows; read ``ended``)."""
    ended: np.ndarray | None = None
    """Same-step autoreset: the missions that ended and restarted in this step."""


class MissionShell:
    """N missions with one config, their fields, resets, steps and infos.

    Args:
        config: the env configuration (validated).
        num: number of missions N.
        autoreset: when ended missions restart (:class:`Autoreset`).
        max_episode_steps: the step limit that truncates a mission, or None.
        threads: threads that step and observe the missions (results do not depend on it).
        draw_ahead: draw each row's next moving field on a worker thread
            (:class:`~debris_gym.envs.field_supply.FieldSupply`).
        chasers: chasers per field K (a swarm): ``num`` missions fly in ``num / K`` fields,
            missions f·K … f·K + K − 1 in field f, each from its own dock slot
            (``dock_offsets``); fields, generators and pinned scenarios are per field. A
            swarm shell does not restart missions by itself (``autoreset`` NEVER).
        chaser_separation: centre-to-centre distance (m) at which two chasers of a field
            collide (default: twice the chaser radius).
        dock_offsets: (K, dim) each chaser's dock slot relative to the field's dock (m;
            default: all at the dock).
        field_loop: step field by field, as swarms do, even with one chaser per field (the
            results are those of the row loop: what the swarm's one-chaser test checks).
        arrived_stay: a chaser that succeeded stays in its field as a body held where it
            ended (a reconfiguration's formation slots).

    Raises:
        ValueError: a random-field config whose fields can never be placed; a bad ``threads``
            or ``chasers``.
    """

    def __init__(
        self,
        config: EnvConfig,
        num: int,
        *,
        autoreset: Autoreset = Autoreset.NEVER,
        max_episode_steps: int | None = None,
        threads: int = 1,
        draw_ahead: bool = False,
        chasers: int = 1,
        chaser_separation: float | None = None,
        dock_offsets: np.ndarray | None = None,
        field_loop: bool = False,
        arrived_stay: bool = False,
    ) -> None:
        self.threads = check_threads(threads)
        self.made_config = self.config = config
        self.num, self.dim = num, config.dim
        if chasers < 1 or num % chasers:
            raise ValueError(f"chasers={chasers} must be at least 1 and divide num={num}")
        if chasers > 1 and autoreset is not Autoreset.NEVER:
            raise ValueError("a swarm shell (chasers > 1) does not autoreset: use Autoreset.NEVER")
        if chasers == 1 and config.obs_teammates:
            raise ValueError(
                f"obs_teammates={config.obs_teammates} is a swarm option (teammate slots); "
                "single-agent envs have none: use 0, or debris_gym.swarm.make"
            )
        check_shield_support(config, chasers)
        self.chasers, self.n_fields = chasers, num // chasers
        self.chaser_separation = chaser_separation
        self.field_loop = field_loop  # make_rules adds "or chasers > 1"
        self.arrived_stay = arrived_stay
        self.dock_offsets = None if dock_offsets is None else np.asarray(dock_offsets, float)
        self.autoreset = autoreset
        self.max_episode_steps = max_episode_steps
        self.horizon = DEFAULT_HORIZON_STEPS
        """Steps the ``time_remaining`` observation counts down from (the views set it)."""
        fields = self.n_fields
        self.supply = FieldSupply(config, fields, ahead=draw_ahead)
        self.batch: MissionBatch | None = None
        """The missions and fields as arrays (None before the first reset)."""
        self.pinned: list[Scenario | None] = [None] * fields
        """Each field's scenario when it was not drawn (pinned or the paper world), else None."""
        self._pin: Scenario | None = None  # pinned by the last reset: autoresets fly it again
        self._built: list[Scenario | None] = [None] * fields  # random fields' Scenarios, built
        self._random_world = np.zeros(fields, dtype=bool)  # the field has the random world
        self._restart = np.zeros(num, dtype=bool)  # next-step autoreset: rows to restart
        self._obs_size = len(observation_names(config))
        self._all_rows = np.arange(num, dtype=np.int64)
        self._all_fields = np.arange(fields, dtype=np.int64)
        self.on_install: Callable[[np.ndarray], np.ndarray | None] | None = None
        """Called with the fields (indices) that a reset or restart has just installed, before
        their missions begin (a swarm assigns its targets there). It may return the initial
        chaser states of those fields' rows, (R, 2·dim), in row order (a reconfiguration
        starts its chasers away from their slots); None: every chaser at rest at its dock. A
        reset's ``chaser_state`` option overrides them."""
        self.on_draw: Callable[[FieldArrays], None] | None = None
        """Called with every batch of drawn fields before they are checked and installed; it
        may edit their arrays in place (a reconfiguration shrinks the place the generator kept
        for its formation to the body at the formation's centre)."""
        self._live = np.ones(num, dtype=bool)
        self._shield = LoopShield(config, num) if config.shield else None
        """The compiled safety shield (the ``shield`` option), or None."""
        self._errors = EpisodeErrors(fields, chasers)
        self.start_sampler: StartSampler | None = None
        """Gives the starts of the missions a reset or an autoreset begins (part-way; see
        :mod:`debris_gym.envs.starts`), unless the reset names its own; None: every mission
        starts at the dock."""
        self.started_late = np.zeros(num, dtype=bool)
        """(N,) bool: the mission's clock did not start at 0 (its time limit is the mission
        clock's, which a step counter outside the shell cannot know)."""

    # --- reading ------------------------------------------------------------------------------

    @property
    def batch_in_use(self) -> MissionBatch:
        """The batch, after the first reset.

        Raises:
            RuntimeError: before the first reset.
        """
        batch = self.batch
        if batch is None:
            raise RuntimeError("call reset() first")
        return batch

    def scenario(self, i: int) -> Scenario | None:
        """Field ``i`` (row ``i``'s with one chaser per field) as a :class:`Scenario` (a pinned
        one as given; a random one built from its arrays, as drawn at t = 0, when first asked
        for), or None before the first reset."""
        batch = self.batch
        if batch is None:
            return None
        known = self.pinned[i] or self._built[i]
        if known is not None:
            return known
        self._built[i] = built = drawn_scenario(batch, i, self.config, self.supply.spec.field_size)
        return built

    def estimated_scenario(self, i: int) -> Scenario | None:
        """Field ``i`` as the chaser's navigation saw it at its episode's start: every body's
        initial state plus the navigation errors of the episode's first observation (the truth,
        :meth:`scenario`, without navigation errors); None before the first reset."""
        truth = self.scenario(i)
        if truth is None or not self.config.navigation_errors:
            return truth
        key = int(self.batch_in_use.missions.noise_key[i * self.chasers])
        return self._errors.estimated(i, truth, key, self.config)

    def observe(self, out: np.ndarray | None = None) -> np.ndarray:
        """Every mission's observation, into ``out`` (N, size) float32 or a new array."""
        if out is None:
            out = np.empty((self.num, self._obs_size), dtype=np.float32)
        return self.batch_in_use.observe(out, self.horizon)

    def info(self, terms: np.ndarray) -> dict[str, Any]:
        """The :data:`~debris_gym.envs.shell_info.INFO_KEYS` of every mission as new arrays
        (row i = mission i); ``terms`` (N, 8) the step's reward terms."""
        return all_rows_info(self.batch_in_use, self.config.chaser_radius, self._shield, terms)

    def row_info(self, i: int, terms: Sequence[float]) -> dict[str, Any]:
        """The :data:`~debris_gym.envs.shell_info.INFO_KEYS` of mission ``i`` as Python scalars
        and arrays of its own; ``terms`` its 8 reward terms."""
        return one_row_info(self.batch_in_use, i, self.config.chaser_radius, self._shield, terms)

    # --- reset --------------------------------------------------------------------------------

    def reset(
        self,
        generators: Sequence[np.random.Generator | None] | None = None,
        options: Any = None,
    ) -> None:
        """Start a new episode in every row, as a transaction.

        Args:
            generators: per field (per row with one chaser per field), a new generator (a
                seeded reset) or None (the field's own goes on); None for all going on.
            options: ``reset``'s options (:data:`~debris_gym.envs.common.RESET_OPTIONS`):
                ``scenario`` pins one field in every row, ``chaser_state`` sets the initial
                states ((2·dim,) or (N, 2·dim)), ``mission`` changes what the missions ask
                from now on (``{}``: the env's own again).

        Raises:
            ValueError: naming the bad option; nothing changed.
        """
        options = checked_reset_options(options)
        rows, fields_rows = self._all_rows, self._all_fields
        saved_supply = self.supply.save()
        saved = self.config, self.batch
        try:
            if options.get("mission") is not None:
                config = self.checked_mission(options["mission"])
                if options["mission"] and options.get("scenario") is not None:
                    raise ValueError(
                        "options['mission'] changes the random fields and options['scenario'] "
                        "pins the field: give one or the other"
                    )
                if config != self.config:  # a new batch, sized and ruled by the new mission
                    self.supply.configure(config)
                    self.config, self.batch = config, None
            if generators is not None:
                self.supply.set_generators(
                    fields_rows, [g if g is not None else self.supply.generators[i]
                                  for i, g in enumerate(generators)],
                )  # fmt: skip
            pinned = options.get("scenario")
            fields = None
            if pinned is not None:
                steps = self.max_episode_steps or self.horizon  # its motion is checked so long
                pinned = self._checked_pinned(as_scenario(pinned, horizon_steps=steps))
            else:
                fields = self._take(fields_rows)
                if fields is None:
                    self._fit(scenario_shape(self.supply.paper_field()))
                else:
                    self._fit(drawn_shape(self.config, fields))
            states = options.get("chaser_state")
            starts = starts_for_reset(self, options.get("start"), states is not None)
            if starts is not None:
                fields = with_words(self.supply, starts, fields)
            if states is not None:
                states = self._checked_states(states, pinned, fields)
            elif pinned is not None and starts is None:
                check_dock_clear(pinned, self.config.chaser_radius)  # every row at the dock
            plan = None
            if starts is not None:
                flown = pinned if pinned is not None or fields is not None else self._paper()
                plan = plan_starts(starts, self.batch_in_use, self.config, fields, flown)
        except BaseException:
            self.supply.restore(saved_supply)
            self.config, self.batch = saved
            raise
        # commit: everything is valid, nothing below raises on it
        if generators is not None:
            for f, g in enumerate(generators):
                if g is not None:
                    self._errors.forget(f)
        self._pin = pinned
        if pinned is not None:
            self._install_scenario(fields_rows, pinned)
        else:
            self._install(fields_rows, fields)
        if self.on_install is not None:
            placed = self.on_install(fields_rows)
            if states is None:
                states = placed
        self._begin(rows, fields_rows, states, plan)
        self._restart[:] = False
        if pinned is None:
            self.supply.draw_ahead(fields_rows)

    @property
    def horizon_steps(self) -> int:
        """The mission's time limit in steps (``max_episode_steps``, else the horizon the
        observation counts down from)."""
        return self.max_episode_steps or self.horizon

    def batch_n_targets(self) -> int:
        """Targets per mission of the fields the config draws (the batch's once it holds
        them)."""
        if self.batch is not None:
            return self.batch.n_targets
        return self.config.n_targets

    def _paper(self) -> Scenario:
        return self.supply.paper_field()

    def _begin(
        self,
        rows: np.ndarray,
        fields: np.ndarray,
        states: np.ndarray | None,
        plan: StartPlan | None,
    ) -> None:
        """Begin the missions of ``rows`` (in ``fields``, installed): at ``states`` or their
        docks, then those of ``plan`` resumed part-way."""
        batch = self.batch_in_use
        if plan is not None:
            batch.advance(fields[plan.positions], plan.counts)
        batch.begin(rows, states, self._errors.keys(fields, self.supply.generators, self.config))
        if self._shield is not None:
            self._shield.begin(rows)
        self.started_late[rows] = False
        if plan is None:
            return
        late = rows[plan.positions]
        batch.resume(late, plan.states, plan.captured, plan.counts, plan.spent)
        self.started_late[late] = plan.counts > 0
        if plan.has_word.any():
            self.supply.taken_words[fields[plan.positions[plan.has_word]]] = plan.words[
                plan.has_word
            ]

    def field_word(self, i: int) -> int | None:
        """The 64-bit word field ``i``'s moving random field was drawn from (what
        ``options={"start": {"field_word": ...}}`` takes to fly it again), or None: a pinned
        field, the paper world or a frozen (v0) field."""
        if self.batch is None or self.pinned[i] is not None or not self.supply.moving:
            return None
        if self.supply.paper:
            return None
        return int(self.supply.taken_words[i])

    def checked_mission(self, mission: Any) -> EnvConfig:
        """The config a ``{"mission": ...}`` reset option gives
        (:func:`~debris_gym.envs.common.checked_mission`).

        Raises:
            ValueError: naming the bad key or value; for an env that flies the paper world,
                whose mission is fixed.
        """
        config = checked_mission(self.made_config, mission)
        if mission and self.made_config.scenario == "paper":
            raise ValueError(
                "options['mission'] changes the random fields; this env flies the paper world "
                "(scenario='paper'), whose mission is fixed"
            )
        return config

    def _checked_pinned(self, scenario: Scenario) -> Scenario:
        """A pinned field, checked against the env (dim, motion; physics warned) and the
        batch."""
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")
        warn_if_physics_differ(self.config, scenario)
        check_motion_matches(self.config, scenario)
        self._fit(scenario_shape(scenario))
        return scenario

    def _checked_states(
        self, value: Any, pinned: Scenario | None, fields: FieldArrays | None
    ) -> np.ndarray:
        """Initial chaser states checked against the fields this reset installs."""
        if pinned is None and fields is None:  # the paper world
            pinned = self._paper()
        return checked_initial_states(
            value, self.num, self.chasers, self.config, self.supply.spec.field_size, pinned,
            fields,
        )  # fmt: skip

    # --- the batch and its fields -------------------------------------------------------------

    def _fit(self, shape: FieldShape) -> MissionBatch:
        """The batch, made (again) for fields of ``shape`` when it cannot hold them (only a
        reset of every row calls this: the rows that restart by themselves later get fields of
        the same shape, drawn by the same config or pinned)."""
        batch = self.batch
        if batch is not None and batch_holds(batch, shape):
            return batch
        self.batch = MissionBatch(
            self.config, self.num, shape.n_targets, shape.n_bodies, physics=shape.physics,
            polygon_start=0 if shape.polygon_targets else None,
            max_episode_steps=self.max_episode_steps, threads=self.threads,
            chasers=self.chasers, chaser_separation=self.chaser_separation,
            field_loop=self.field_loop, arrived_stay=self.arrived_stay,
        )  # fmt: skip
        self._random_world[:] = False
        return self.batch

    def _take(self, rows: np.ndarray) -> FieldArrays | None:
        """The next drawn fields of the fields ``rows`` from the supply, passed through
        :attr:`on_draw` (None: the paper world)."""
        fields = self.supply.take(rows)
        if fields is not None and self.on_draw is not None:
            self.on_draw(fields)
        return fields

    def _install(
        self, rows: np.ndarray, fields: FieldArrays | None, sources: np.ndarray | None = None
    ) -> None:
        """Load the drawn ``fields`` (None: the paper world; ``sources``: the ones to load, if
        not all in order) into the fields ``rows``."""
        if fields is None:
            self._install_scenario(rows, self.supply.paper_field())
            return
        batch = self.batch_in_use
        batch.load_fields(rows, fields, sources)
        for i in rows.tolist():
            self.pinned[i] = self._built[i] = None
        stale = rows[~self._random_world[rows]]
        if len(stale):  # every random field has the same world: set it where it changed
            half = fields.half_size
            self._set_world(stale, 0.0, -half, half, half)
            self._random_world[stale] = True

    def _install_scenario(self, rows: np.ndarray, scenario: Scenario) -> None:
        """Load ``scenario`` into the fields ``rows``."""
        batch = self.batch_in_use
        batch.load_scenario(rows, scenario)
        for i in rows.tolist():
            self.pinned[i], self._built[i] = scenario, None
        self._set_world(rows, scenario.dock, scenario.low, scenario.high, scenario.size / 2.0)
        self._random_world[rows] = False

    def _set_world(self, rows: np.ndarray, dock, low, high, length_scale: float) -> None:
        """The world of the fields ``rows``; each chaser's dock is the field's plus its slot's
        offset (:attr:`dock_offsets`)."""
        batch = self.batch_in_use
        batch.set_world(rows, dock, low, high, length_scale)
        if self.dock_offsets is not None:
            k = self.chasers
            missions = (np.asarray(rows, dtype=np.int64)[:, None] * k + np.arange(k)).ravel()
            batch.dock[missions] += np.tile(self.dock_offsets, (len(rows), 1))

    # --- step ---------------------------------------------------------------------------------

    def step(
        self,
        actions: np.ndarray,
        live: np.ndarray | None = None,
        observe_into: np.ndarray | None = None,
    ) -> StepResult:
        """One step of every mission (validated normalised thrust commands (N, dim)); ended
        missions restart as :attr:`autoreset` says. ``live`` (N,) bool: with autoreset NEVER,
        the missions that step (default all; a swarm leaves out its ended chasers).
        ``observe_into``: with autoreset NEVER, a buffer for :meth:`observe` after the step,
        written in the same compiled call (:meth:`MissionBatch.step_observe`).

        Raises:
            RuntimeError: before the first reset.
            ValueError: ``observe_into`` with an autoreset.
        """
        if self.batch is None:
            raise RuntimeError("call reset() before step()")
        batch = self.batch
        if self.autoreset is Autoreset.NEVER:
            live = self._live if live is None else live
            commands, whole = self._shielded(batch, actions, live)
            if observe_into is None:
                out = batch.step(commands, live, whole)
            else:
                out = batch.step_observe(commands, live, observe_into, self.horizon, whole)
            return StepResult(self._penalised(out.reward), out.terminated, out.truncated, out.terms)
        if observe_into is not None:
            raise ValueError("observe_into is for a shell without autoreset (it restarts rows)")
        restart = self._restart
        commands, whole = self._shielded(batch, actions, ~restart)
        out = batch.step(commands, ~restart, whole)
        reward, terminated = self._penalised(out.reward).copy(), out.terminated.copy()
        truncated, terms = out.truncated.copy(), out.terms
        ended = terminated | truncated
        if self.autoreset is Autoreset.SAME_STEP:
            if not ended.any():
                return StepResult(reward, terminated, truncated, terms)
            final_obs, final_info = self.observe(), self.info(terms)
            self.restart(ended)
            terms[ended] = 0.0
            return StepResult(reward, terminated, truncated, terms, final_obs, final_info, ended)
        if restart.any():
            self.restart(restart)
        self._restart = ended
        return StepResult(reward, terminated, truncated, terms)

    def _shielded(
        self, batch: MissionBatch, actions: np.ndarray, live: np.ndarray
    ) -> tuple[np.ndarray, bool]:
        """``actions`` through the shield in the rows ``live`` (as they are without it), and
        whether they are whole commands: in the residual mode the shield judges the command
        flown, the base law's plus the correction, and the step flies what it lets through."""
        if self._shield is None:
            return actions, False
        if batch.residual:
            actions = batch.residual_commands(actions, live)
            return self._shield.filter(batch, actions, live), True
        return self._shield.filter(batch, actions, live), False

    def _penalised(self, reward: np.ndarray) -> np.ndarray:
        """The step's rewards less the shield's penalties (as they are without any)."""
        shield = self._shield
        return reward if shield is None or shield.penalty == 0.0 else reward - shield.penalties()

    def restart(self, mask: np.ndarray) -> None:
        """New episodes in the fields in ``mask`` (F,) (an autoreset; with one chaser per field
        the rows): in a field pinned by the last reset again, else in the next field of each
        field's supply; every chaser of the field at rest at its dock (or where
        :attr:`on_install` starts it)."""
        fields = np.flatnonzero(mask)
        k = self.chasers
        rows = fields if k == 1 else (fields[:, None] * k + np.arange(k)).ravel()
        drawn, plan, in_place = None, None, False
        if self._pin is None and self.on_draw is None and self.start_sampler is None:
            drawn = self.supply.take_drawn(fields)  # the fields drawn ahead, in place
            in_place = drawn is not None
        if self._pin is None and drawn is None:
            drawn = self._take(fields)
        if self.start_sampler is not None:
            batch = self.batch_in_use
            ended = EpisodeEnds(batch.captured_counts()[rows], batch.missions.success[rows].copy())
            starts = list(self.start_sampler(fields, ended))
            if any(s is not None for s in starts):
                drawn = with_words(self.supply, starts, drawn)
                flown = self._pin if self._pin is not None or drawn is not None else self._paper()
                plan = plan_starts(starts, batch, self.config, drawn, flown)
        if self._pin is not None:
            self._install_scenario(fields, self._pin)
        elif in_place:
            self._install(fields, drawn, sources=fields)
        else:
            self._install(fields, drawn)
        placed = None if self.on_install is None else self.on_install(fields)
        self._begin(rows, fields, placed, plan)
        if self._pin is None:
            self.supply.draw_ahead(fields)

    def close(self) -> None:
        """Stop the field supply's worker thread."""
        self.supply.close()


class ShellView:
    """What every env that is a view of a :class:`MissionShell` reads the same way (the single
    env's one row, the vector env's all rows). A view sets ``_shell`` and ``_obs_names``."""

    _shell: MissionShell
    _obs_names: list[str]

    @property
    def config(self) -> EnvConfig:
        """The config in force (a ``{"mission": ...}`` reset option changes its mission keys)."""
        return self._shell.config

    @property
    def made_config(self) -> EnvConfig:
        """The config the env was made with: what ``reset(options={"mission": {...}})`` changes
        keys of (``self.config`` is the one in force)."""
        return self._shell.made_config

    @property
    def shell(self) -> MissionShell:
        """The :class:`MissionShell` this env is a view of."""
        return self._shell

    @property
    def batch(self) -> MissionBatch | None:
        """The env's missions and fields as a :class:`~debris_gym.mission_batch.MissionBatch`
        (one row per sub-env; None before the first reset). Read it; writing to it bypasses
        the env's checks."""
        return self._shell.batch

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order."""
        return list(self._obs_names)
