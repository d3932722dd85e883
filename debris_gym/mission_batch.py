"""N rendezvous missions as arrays, stepped by compiled loops: the core of both environments.

:class:`MissionBatch` holds everything that changes during an episode — chaser states, clocks,
captures, collision / bounds / success flags, the gaps to every body, the shaping potential —
for N missions (:class:`~debris_gym.mission_data.Missions`), plus their fields (a
:class:`~debris_gym.batch_geometry.FieldBatch` and the world of each). Its
:meth:`~MissionBatch.step` runs one decision step of every live mission in one numba-compiled
loop (:mod:`debris_gym.mission_step`: burn, propagate, contacts, measure, captures, judge,
reward); :meth:`~MissionBatch.observe` writes the observations (:mod:`debris_gym.observation`).

The single env (:class:`~debris_gym.envs.DebrisFieldEnv`) is a batch of one and the native
vector env a batch of N, so both run this one implementation of the rules. The rules are those
of ``docs/environments.md``; ``tests/test_mission_batch.py`` holds them to an independent
reference (numpy and pymunk, one env at a time). No gymnasium import.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np

from debris_gym.base_law import BaseLaw, base_commands, make_base_law, residual_rows
from debris_gym.batch_geometry import FieldBatch, polygon_turns
from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize, substep_position_matrix
from debris_gym.field_spec import MAX_POLYGON_VERTICES, FieldArrays
from debris_gym.jit import specialise
from debris_gym.mission_data import (
    Field,
    Missions,
    StepOutputs,
    make_rules,
    make_shaping,
    new_missions,
    new_step_outputs,
)
from debris_gym.mission_starts import advance_bodies, resume_rows
from debris_gym.mission_step import begin_rows, count_rows, step_all, step_all_threaded
from debris_gym.observation import (
    OBS_LIMIT,
    observation_layout,
    observe_all,
    observe_all_threaded,
)
from debris_gym.orbit_truth import ATMOSPHERE, reference_start, substeps_for
from debris_gym.step_observe import step_observe
from debris_gym.uncertainty import navigate_rows

__all__ = ["OBS_LIMIT", "MissionBatch", "Physics", "check_threads"]


class Physics(NamedTuple):
    """The physics of a batch's fields, held here once (the kernels read them from
    :class:`~debris_gym.mission_data.Rules`, which is built from this)."""

    mean_motion: float
    """n (rad/s) of the reference orbit; 0 is free space."""
    dt: float
    """Decision step (s)."""
    max_accel: float
    """Thrust limit (m/s²)."""


def check_transition(phi: np.ndarray) -> np.ndarray:
    """``phi``, the state-transition matrix Φ(dt) of a free body, after checking the structure
    :func:`~debris_gym.mission_step.move_bodies` relies on: no state depends on the along-track
    position y but y itself (Φ_yy = 1 exactly), and in 3D the cross-track pair (z, ż) neither
    feeds nor is fed by the plane (those entries exactly zero, as the matrix exponential of the
    CWH matrix gives them)."""
    dim = phi.shape[0] // 2
    expected_zero = np.zeros_like(phi, dtype=bool)
    expected_zero[:, 1] = True
    expected_zero[1, 1] = False
    if dim == 3:
        cross = np.array([2, 5])
        plane = np.array([0, 1, 3, 4])
        expected_zero[np.ix_(cross, plane)] = True
        expected_zero[np.ix_(plane, cross)] = True
    if np.any(phi[expected_zero] != 0.0) or phi[1, 1] != 1.0:
        raise RuntimeError("the CWH state-transition matrix lost its structure: " + repr(phi))
    return phi


def body_reach(sub: np.ndarray, dim: int) -> tuple[float, float]:
    """Bounds of how far a free body moves within a step: the largest 2-norms, over the
    sub-steps, of the position blocks Φ_pp(t) − I and Φ_pv(t) of the state-transition matrix
    (``sub``: :func:`~debris_gym.dynamics.substep_position_matrix`), widened by 1e-9 of
    themselves so that rounding never shrinks them below the truth."""
    eye = np.eye(dim)
    blocks = sub.reshape(-1, dim, sub.shape[1])
    position = max(np.linalg.norm(b[:, :dim] - eye, 2) for b in blocks)
    velocity = max(np.linalg.norm(b[:, dim : 2 * dim], 2) for b in blocks)
    return float(position) * (1 + 1e-9), float(velocity) * (1 + 1e-9)


def check_threads(threads: int) -> int:
    """``threads`` validated: a whole number from 1 to numba's thread count (the cores, or
    ``NUMBA_NUM_THREADS``)."""
    # numba sets its config from the environment at run time: the name is invisible to a checker
    limit = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)):
        raise ValueError(f"num_threads must be a whole number in [1, {limit}], got {threads!r}")
    if not 1 <= threads <= limit:
        raise ValueError(
            f"num_threads={threads} is out of range; allowed: [1, {limit}] (numba's thread "
            "count: the CPU cores, or NUMBA_NUM_THREADS)"
        )
    return int(threads)


class MissionBatch:
    """N missions with the same rules, physics and number of bodies.

    Args:
        cfg: the env configuration (rules, weights, observation layout).
        num: number of missions N.
        n_targets: targets per field T (the first T bodies).
        n_bodies: bodies per field B (targets and obstacles).
        physics: the fields' mean motion, step and thrust limit (:class:`Physics`).
        polygon_start: first body index that may be a convex polygon (default: T).
        max_episode_steps: truncation limit per episode, or None (the single env leaves it to
            gymnasium's ``TimeLimit``).
        threads: threads that step and observe the missions (row ranges in parallel; 1 = the
            calling thread only). The results do not depend on it.
        chasers: chasers per field K: missions f·K … f·K + K − 1 fly in field f (a swarm;
            ``num`` must be a multiple of K).
        chaser_separation: centre-to-centre distance (m) at which two chasers of a field
            collide (default: twice the chaser radius).
        field_loop: step field by field (:func:`~debris_gym.mission_step.step_fields`) even
            with one chaser per field (always with several).
        arrived_stay: a chaser that succeeded stays in its field as a body held where it
            ended (:attr:`~debris_gym.mission_data.Rules.arrived_stay`).

    Per-mission arrays (row i = mission i; SI units): ``state`` (N, 2·dim) LVLH position and
    velocity, ``time`` (N,) s, ``steps`` (N,), ``delta_v`` (N,) m/s spent, ``captured`` (N, T),
    ``collision`` / ``out_of_bounds`` / ``success`` (N,), ``gaps`` (N, B) signed distance from
    the chaser's centre to every body (m), ``nearest`` (N, O) the obstacles by gap, nearest
    first (kinematics observations only), ``min_clearance`` (N,) smallest obstacle gap so far
    (m, chaser radius not subtracted), ``potential`` (N,) Φ, ``accel`` (N, dim) last commanded
    acceleration (m/s²); ``dock`` (N, dim) m, each mission's; per field (F = N / K rows):
    ``low``, ``high`` (F, dim) m, ``length_scale`` (F,) m and ``speed_scale`` (F,) m/s (the
    observation's L and V).
    """

    def __init__(
        self,
        cfg: EnvConfig,
        num: int,
        n_targets: int,
        n_bodies: int,
        *,
        physics: Physics,
        polygon_start: int | None = None,
        max_episode_steps: int | None = None,
        threads: int = 1,
        chasers: int = 1,
        chaser_separation: float | None = None,
        field_loop: bool = False,
        arrived_stay: bool = False,
    ) -> None:
        n, d, t = num, cfg.dim, n_targets
        truth = cfg.truth_model == "j2_drag"
        if truth and (chasers != 1 or field_loop):
            raise ValueError("truth_model='j2_drag' is for one chaser per field")
        if chasers < 1 or num % chasers:
            raise ValueError(f"chasers={chasers} must be at least 1 and divide num={num}")
        self.chasers = int(chasers)
        self.n_fields = fields = num // chasers
        self.threads = check_threads(threads)
        self.config = cfg
        self.num, self.dim, self.n_targets = n, d, t
        self.physics = physics = Physics(*map(float, physics))
        mean_motion, dt, max_accel = physics
        start = t if polygon_start is None else polygon_start
        self.field = FieldBatch(fields, n_bodies, d, MAX_POLYGON_VERTICES, polygon_start=start)
        model = discretize(mean_motion, dt, d)
        sub = substep_position_matrix(mean_motion, dt, d, cfg.collision_substeps)
        # one matrix maps [x₀, u] to the sub-step positions (the last is the end position)
        # followed by the end velocity
        end_velocity = np.hstack([model.ad[d:], model.bd[d:]])
        step_matrix_t = np.ascontiguousarray(np.vstack([sub, end_velocity]).T)
        self.rules = make_rules(
            cfg, t, step_matrix_t, dt=dt, max_accel=max_accel, max_episode_steps=max_episode_steps,
            body_matrix_t=np.ascontiguousarray(check_transition(model.ad).T),
            reach=body_reach(sub, d), n_chasers=chasers, chaser_separation=chaser_separation,
            field_loop=field_loop, arrived_stay=arrived_stay,
            truth_substeps=substeps_for(dt), atmosphere=ATMOSPHERE,
        )  # fmt: skip
        self._turn_angles = (dt, dt / cfg.collision_substeps)
        self.shaping = make_shaping(cfg)
        """The optional potential terms, or None when all are off (the kernels are compiled
        without them then)."""
        self.layout = observation_layout(cfg)
        # every obstacle ranked by gap when the observation shows obstacles
        ranked = cfg.observation == "kinematics" and cfg.obs_obstacles > 0
        self.missions: Missions = new_missions(n, d, t, n_bodies, n_bodies - t if ranked else 0)
        # per field, beside the bodies of self.field (the dock: per mission, each chaser's own)
        self.dock = np.zeros((n, d))
        self.low = np.zeros((fields, d))
        self.high = np.zeros((fields, d))
        self.length_scale = np.ones(fields)
        self.speed_scale = np.ones(fields)
        self.turns = np.zeros((fields, self.field.spins.shape[1], 6))
        """(N, P, 6) cos, sin of each polygon's turn over one step, then one sub-step, then the
        two angles (rad)."""
        self.turns[:, :, 0] = self.turns[:, :, 2] = 1.0
        # the truth model's reference orbit (set as each episode begins) and each body's
        # C_D·A/m: the targets', then the other debris'
        self.reference = np.zeros((fields, 6))
        self.inv_ballistic = np.full((fields, n_bodies), 1.0 / cfg.ballistic_coefficient)
        self.inv_ballistic[:, :t] = 1.0 / cfg.target_ballistic_coefficient
        self._reference_start = (
            reference_start(cfg.orbit_radius, math.radians(cfg.orbit_inclination))
            if truth
            else None
        )
        self._outputs: StepOutputs = new_step_outputs(n)
        self._field_view: Field | None = None
        self._heads: dict[str, tuple] | None = None
        # the step's machine code, resolved on the first step
        self._step_code: Callable[..., Any] | None = None
        self._observe_code: Callable[..., Any] | None = None
        self._begin_code: dict[bool, Callable[..., Any]] = {}
        self._observed: tuple[np.ndarray, ...] | None = None
        self.base_law: BaseLaw = make_base_law(cfg, mean_motion, dt, max_accel, chasers)
        """The base law of these missions' rules and physics (:mod:`debris_gym.base_law`):
        with ``action="residual"`` each step adds its command to the actions."""
        self.residual = cfg.action == "residual"
        self._commands = np.zeros((n, d))  # the residual mode's summed commands
        self._residual_code: Callable[..., Any] | None = None
        self._step_observe_code: Callable[..., Any] | None = None
        if cfg.navigation_errors:
            if chasers != 1:
                raise ValueError("navigation errors are for one chaser per field")
            m = self.missions
            self._observed = (
                np.zeros_like(m.state), np.zeros_like(self.field.centers),
                np.zeros_like(self.field.velocities), np.zeros_like(m.gaps),
                np.zeros_like(m.nearest),
            )  # fmt: skip

    def __getstate__(self) -> dict:
        # the resolved machine code does not pickle: it is resolved again on first use
        state = self.__dict__.copy()
        state.update(_step_code=None, _observe_code=None, _begin_code={}, _field_view=None)
        state.update(_heads=None, _residual_code=None, _step_observe_code=None)
        return state

    @property
    def field_arrays(self) -> Field:
        """The per-field arrays as one :class:`~debris_gym.mission_data.Field` (rebuilt when the
        field batch reallocated its vertices for a polygon with more of them)."""
        view = self._field_view
        f = self.field
        if view is None or view.vertices is not f.vertices:
            view = self._field_view = Field(
                centers=f.centers, radii=f.radii, polygon_start=f.polygon_start,
                polygons=f.polygons, n_vertices=f.n_vertices, vertices=f.vertices,
                velocities=f.velocities, attitude=f.attitude, turns=self.turns, dock=self.dock,
                low=self.low, high=self.high, length_scale=self.length_scale,
                speed_scale=self.speed_scale, reference=self.reference,
                inv_ballistic=self.inv_ballistic,
            )  # fmt: skip
            self._heads = None
        return view

    def _head(self) -> dict[str, tuple]:
        """The kernels' arguments that stay the same from call to call, built once (and again
        when the field's arrays change): ``step`` before the actions, ``tail`` after them,
        ``observe`` before the horizon."""
        field = self.field_arrays
        heads = self._heads
        if heads is None:
            threads = (self.threads,) if self.threads > 1 else ()
            heads = self._heads = {
                "step": threads,
                "tail": (self.rules, self.shaping, self.missions, field, self._outputs),
                "observe": (*threads, self.rules, self.layout, self.missions, field),
            }
        return heads

    def load_scenario(self, rows: np.ndarray, scenario) -> None:
        """Put ``scenario``'s bodies (as at t = 0) into the fields ``rows``."""
        self.field.load_scenario(rows, scenario)
        self._set_turns(rows)

    def load_fields(
        self, rows: np.ndarray, fields: FieldArrays, sources: np.ndarray | None = None
    ) -> None:
        """Put drawn fields (K of them, :class:`~debris_gym.field_spec.FieldArrays`) into the
        fields ``rows``: their vertices are the obstacles' (bodies from T on), their spins every
        body's (see :meth:`FieldBatch.load_arrays
        <debris_gym.batch_geometry.FieldBatch.load_arrays>`); ``sources`` (K,): the fields of
        ``fields`` to load, if not all of them in order."""
        rows = np.asarray(rows, dtype=np.int64)
        spins = None if fields.spins is None else fields.spins[:, self.field.polygon_start :]
        self.field.load_arrays(
            rows, fields.centers, fields.radii, fields.vertices, fields.n_vertices,
            fields.velocities, spins, vertex_start=fields.n_targets, sources=sources,
        )  # fmt: skip
        self._set_turns(rows)

    def _set_turns(self, rows: np.ndarray) -> None:
        """The polygons' turn per step and per sub-step in ``rows``: at spin − n in LVLH in a
        moving field (an inertially fixed attitude turns at −n in the rotating frame), none in
        a frozen one."""
        if not self.rules.moving or self.turns.shape[1] == 0:
            return
        step, sub = self._turn_angles
        polygon_turns(
            np.asarray(rows, dtype=np.int64), self.field.spins, self.physics.mean_motion, step, sub,
            self.turns,
        )  # fmt: skip

    def set_world(self, rows: np.ndarray, dock, low, high, length_scale: float) -> None:
        """Dock position, bounds (m) and length scale L of the fields in ``rows`` (the dock of
        every chaser of those fields; :attr:`dock` rows may be set one by one after)."""
        k = self.chasers
        if k == 1:
            self.dock[rows] = dock
        else:
            rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
            docks = np.asarray(dock, dtype=float)
            if docks.ndim == 2:  # one dock per field: every chaser of the field starts at it
                docks = np.repeat(docks, k, axis=0)
            self.dock[(rows[:, None] * k + np.arange(k)).ravel()] = docks
        self.low[rows] = low
        self.high[rows] = high
        self.length_scale[rows] = length_scale
        self.speed_scale[rows] = math.sqrt(self.physics.max_accel * length_scale)

    def begin(
        self, rows: np.ndarray, states: np.ndarray | None = None, keys: np.ndarray | None = None
    ) -> None:
        """Start new episodes in ``rows`` (fields loaded): chaser at ``states`` (R, 2·dim) or at
        rest at the dock, clocks and flags cleared, gaps and potential computed; ``keys`` (R,)
        uint64 the episodes' error keys (:attr:`Missions.noise_key
        <debris_gym.mission_data.Missions.noise_key>`; the uncertain world's)."""
        rows = np.ascontiguousarray(rows, dtype=np.int64)
        if keys is not None:
            self.missions.noise_key[rows] = keys
        if self._reference_start is not None:  # the reference orbit starts again
            self.reference[np.unique(rows // self.chasers)] = self._reference_start
        states = None if states is None else np.ascontiguousarray(states, dtype=float)
        args = (rows, states, self.rules, self.shaping, self.missions, self.field_arrays)
        code = self._begin_code.get(states is None)
        if code is None:  # one machine code with initial states, one without
            code = self._begin_code[states is None] = specialise(begin_rows, *args)
        code(*args)

    def advance(self, fields: np.ndarray, counts: np.ndarray) -> None:
        """Fly the bodies of each field ``fields[k]`` on by ``counts[k]`` steps of their
        natural motion, exactly as that many steps would (a start part-way; a frozen field
        stays)."""
        fields = np.ascontiguousarray(fields, dtype=np.int64)
        counts = np.ascontiguousarray(counts, dtype=np.int64)
        f = self.field
        advance_bodies(
            fields, counts, self.rules.moving, self.rules.body_matrix_t, f.centers, f.velocities,
            f.polygons, f.attitude, self.turns,
        )  # fmt: skip

    def flown_copy(self, fields: FieldArrays | Any, counts: np.ndarray) -> FieldBatch:
        """A :class:`~debris_gym.batch_geometry.FieldBatch` of its own holding the drawn
        ``fields`` (K of them; or a pinned scenario, K = len(counts) copies of it), each flown
        on by ``counts[k]`` steps as :meth:`advance` flies them: where a start's chaser can be
        checked before anything of the batch changes."""
        k = len(counts)
        copy = FieldBatch(
            k, self.field.n_bodies, self.dim, MAX_POLYGON_VERTICES, self.field.polygon_start
        )
        if isinstance(fields, FieldArrays):
            spins = None if fields.spins is None else fields.spins[:, copy.polygon_start :]
            copy.load_arrays(
                np.arange(k), fields.centers, fields.radii, fields.vertices, fields.n_vertices,
                fields.velocities, spins, vertex_start=fields.n_targets,
            )  # fmt: skip
        else:
            copy.load_scenario(np.arange(k), fields)
        turns = np.zeros((k, copy.spins.shape[1], 6))
        turns[:, :, 0] = turns[:, :, 2] = 1.0
        if self.rules.moving and turns.shape[1]:
            step, sub = self._turn_angles
            polygon_turns(np.arange(k), copy.spins, self.physics.mean_motion, step, sub, turns)
        advance_bodies(
            np.arange(k), np.ascontiguousarray(counts, dtype=np.int64), self.rules.moving,
            self.rules.body_matrix_t, copy.centers, copy.velocities, copy.polygons, copy.attitude,
            turns,
        )  # fmt: skip
        return copy

    def resume(
        self,
        rows: np.ndarray,
        states: np.ndarray,
        captured: np.ndarray,
        counts: np.ndarray,
        spent: np.ndarray,
    ) -> None:
        """Rows ``rows``, just begun (:meth:`begin`), resume part-way: the chasers at
        ``states`` (R, 2·dim), ``captured`` (R, T) bool targets already taken, ``counts`` (R,)
        steps on their clocks, ``spent`` (R,) Δv spent (m/s); gaps, clearance and potential
        measured again (see :mod:`debris_gym.mission_starts`)."""
        resume_rows(
            np.ascontiguousarray(rows, dtype=np.int64),
            np.ascontiguousarray(states, dtype=float),
            np.ascontiguousarray(captured, dtype=np.bool_),
            np.ascontiguousarray(counts, dtype=np.int64),
            np.ascontiguousarray(spent, dtype=float),
            self.rules, self.shaping, self.missions, self.field_arrays,
        )  # fmt: skip

    def step(self, actions: np.ndarray, live: np.ndarray, whole: bool = False) -> StepOutputs:
        """One decision step of the missions in ``live`` (the others are left as they are).

        Args:
            actions: (N, dim) normalised thrust commands (validated: finite), held over the step;
                the thrust model turns them into accelerations, and a burn that would overspend
                the Δv budget is cut to spend it exactly. With ``action="residual"`` they are
                corrections: each live row flies its base law's command plus its action,
                clipped to [−1, 1] per axis (:func:`~debris_gym.base_law.residual_rows`).
            live: (N,) bool, the missions that step.
            whole: with ``action="residual"``, ``actions`` are already the whole commands
                (:meth:`residual_commands`, then filtered by a shield): the base law is not
                added again.

        Returns:
            :class:`~debris_gym.mission_data.StepOutputs`: ``reward`` (N,), ``terminated``
            (N,), ``truncated`` (N,), ``terms`` (N, 8), buffers that the next call overwrites;
            rows not in ``live`` are zero / False. ``terms`` columns follow
            :data:`debris_gym.rewards.REWARD_TERMS`.
        """
        live, actions = self._step_arguments(actions, live, whole)
        head = self._head()
        code = self._step_code
        if code is None:
            kernel = step_all_threaded if self.threads > 1 else step_all
            code = self._step_code = specialise(kernel, *head["step"], live, actions, *head["tail"])
        code(*head["step"], live, actions, *head["tail"])
        return self._outputs

    def step_observe(
        self,
        actions: np.ndarray,
        live: np.ndarray,
        out: np.ndarray,
        horizon: int,
        whole: bool = False,
    ) -> StepOutputs:
        """:meth:`step`, then :meth:`observe` into ``out``: the same results, in one compiled
        call where the two share their records (one thread, no navigation errors; see
        :mod:`debris_gym.step_observe`)."""
        if self.threads > 1 or self._observed is not None:
            outputs = self.step(actions, live, whole)
            self.observe(out, horizon)
            return outputs
        live, actions = self._step_arguments(actions, live, whole)
        head = self._head()
        args = (live, actions, *head["tail"], head["observe"][1], float(horizon), out)
        code = self._step_observe_code
        if code is None:
            code = self._step_observe_code = specialise(step_observe, *args)
        code(*args)
        return self._outputs

    def residual_commands(self, actions: np.ndarray, live: np.ndarray) -> np.ndarray:
        """With ``action="residual"``: the whole commands the step would fly for the
        corrections ``actions`` in the rows ``live`` (the base law's command plus the
        correction, clipped per axis), in a buffer the next call overwrites; pass them (or
        commands that replace them) to :meth:`step` with ``whole=True``.

        Raises:
            ValueError: another action mode.
        """
        if not self.residual:
            raise ValueError("residual_commands is for action='residual'")
        live, actions = self._step_arguments(actions, live)
        return actions

    def _step_arguments(
        self, actions: np.ndarray, live: np.ndarray, whole: bool = False
    ) -> tuple[np.ndarray, ...]:
        """``live`` and the commands the step kernel flies, in the types its machine code was
        resolved for (see :func:`~debris_gym.jit.specialise`): with ``action="residual"`` the
        base law's commands plus ``actions`` (unless they are ``whole`` already)."""
        if live.dtype != np.bool_ or not live.flags.c_contiguous:
            live = np.ascontiguousarray(live, dtype=np.bool_)
        if actions.dtype != np.float64 or not actions.flags.c_contiguous:
            actions = np.ascontiguousarray(actions, dtype=np.float64)
        if self.residual and not whole:
            actions = self._with_base(actions, live)
        return live, actions

    def _with_base(self, actions: np.ndarray, live: np.ndarray) -> np.ndarray:
        """The residual mode's commands: ``actions`` plus the base law's, clipped per axis, in
        the live rows of a buffer the next call overwrites."""
        args = (live, actions, self.base_law, self.missions, self.field_arrays, self._commands)
        code = self._residual_code
        if code is None:
            code = self._residual_code = specialise(residual_rows, *args)
        code(*args)
        return self._commands

    def base_commands(self, rows: np.ndarray | None = None) -> np.ndarray:
        """(R, dim) the base law's normalised commands for missions ``rows`` (default: all) in
        their current state (:func:`~debris_gym.base_law.base_commands`: the code the residual
        mode adds inside the step; with several chasers per field, each toward its own goal).

        Raises:
            ValueError: a row out of range.
        """
        return base_commands(self.base_law, self.missions, self.field_arrays, rows)

    def captured_counts(self) -> np.ndarray:
        """(N,) int64: targets captured so far in each mission (a new array)."""
        out = np.empty(self.num, dtype=np.int64)
        count_rows(self.missions.captured, out)
        return out

    def observe(self, out: np.ndarray, horizon: int) -> np.ndarray:
        """Write every mission's observation into ``out`` (N, obs size) float32 and return it.

        Args:
            out: the buffer, a C-contiguous float32 array (not checked: the envs own it).
            horizon: steps the ``time_remaining`` element counts down from.
        """
        head = self._head()["observe"]
        if self._observed is not None:
            head = (*head[:-2], *self._navigate(head[-2], head[-1]))
        code = self._observe_code
        if code is None:
            kernel = observe_all_threaded if self.threads > 1 else observe_all
            code = self._observe_code = specialise(kernel, *head, float(horizon), out)
        code(*head, float(horizon), out)
        return out

    def _navigate(self, missions: Missions, field: Field) -> tuple[Missions, Field]:
        """The observed copy of the missions and fields (navigation errors; see
        :func:`~debris_gym.uncertainty.navigate_rows`), in the records' own types."""
        assert self._observed is not None
        state, centers, velocities, gaps, nearest = self._observed
        cfg = self.config
        navigate_rows(
            float(cfg.nav_sigma_position), float(cfg.nav_sigma_velocity), bool(cfg.nav_bias),
            missions, field, state, centers, velocities, gaps, nearest,
        )  # fmt: skip
        return (
            missions._replace(state=state, gaps=gaps, nearest=nearest),
            field._replace(centers=centers, velocities=velocities),
        )

    def observed_state(self) -> np.ndarray:
        """(N, 2·dim) each chaser's state as the last observation saw it (the truth without
        navigation errors; a copy)."""
        if self._observed is None:
            return self.missions.state.copy()
        return self._observed[0].copy()

    def observed_bodies(self) -> tuple[np.ndarray, np.ndarray]:
        """(F, B, dim) the bodies' centres and velocities as the last observation saw them
        (copies)."""
        if self._observed is None:
            return self.field.centers.copy(), self.field.velocities.copy()
        return self._observed[1].copy(), self._observed[2].copy()
