"""Native vectorised DebrisField env: N envs as numpy arrays, one compiled step.

Reached through ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
Every sub-env behaves exactly like ``gym.make(id)`` reset with seed ``seed + i`` (same fields,
same dynamics, same rewards, observations and infos; ``tests/test_vector_env.py`` checks it
against N single envs): both envs run the rules of :class:`debris_gym.mission_batch.MissionBatch`,
the single env as a batch of one.

Autoreset follows Gymnasium 1.x's default *next-step* mode: the step after a sub-env terminates or
truncates resets it (its action is ignored) and returns the first observation of the new episode
with reward 0. Each sub-env keeps its own seeded generator; the sub-envs that reset on a step
draw their fields together (:func:`debris_gym.generators.random_fields`: one fixed block of
random numbers per sub-env and draw, or for a moving field one 64-bit word per sub-env, so a
field never depends on which other sub-envs reset with it) and the fields go into the batch as
arrays; :attr:`DebrisFieldVectorEnv.scenarios` builds a sub-env's :class:`Scenario` only when
read. ``step`` has no Python loop over envs or debris.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from debris_gym.batch_geometry import FieldBatch
from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    check_motion_matches,
    checked_chaser_states,
    checked_continuous_actions,
    checked_mission,
    checked_reset_options,
    checked_seed,
    discrete_action_table,
    field_spec,
    observation_names,
    real_array,
    registered_horizon,
    single_spaces,
    warn_if_physics_differ,
)
from debris_gym.generators import (
    MAX_POLYGON_VERTICES,
    FieldArrays,
    paper_field,
    random_fields,
    scenario_from_arrays,
)
from debris_gym.geometry import FieldGeometry
from debris_gym.mission_batch import MissionBatch, check_threads
from debris_gym.orbit_fields import OrbitDrawer, orbit_drawer
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.scenario_checks import check_dock_clear


class DebrisFieldVectorEnv(VectorEnv):
    """N DebrisField envs stepped together.

    Args:
        num_envs: number of sub-envs N (>= 1).
        max_episode_steps: truncation limit per episode (the registration's value when made
            through ``gym.make_vec``); None means no limit.
        render_mode: only None (render a single env to look at episodes).
        autoreset_mode: ``NEXT_STEP`` (Gymnasium's default) or ``SAME_STEP`` (the ending step
            already returns the new episode's first observation; the last one is in
            ``info["final_obs"]``, its info in ``info["final_info"]``), as for SyncVectorEnv.
        num_threads: threads that step the sub-envs (1, the default: the calling thread only;
            up to the number of cores). The sub-envs are split into row ranges stepped in
            parallel by numba; results are identical for any count. On a shared machine, or
            with other processes training beside it, keep 1.
        **kwargs: any :class:`~debris_gym.config.EnvConfig` key, as for the single env.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        num_threads: int = 1,
        **kwargs: Any,
    ) -> None:
        if not (_is_int(num_envs) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if max_episode_steps is not None and not (
            _is_int(max_episode_steps) and max_episode_steps >= 1
        ):
            raise ValueError(
                f"max_episode_steps must be an integer >= 1 or None, got {max_episode_steps!r}"
            )
        if render_mode is not None:
            raise ValueError(
                "the vector env does not render; make a single env with render_mode='rgb_array'"
            )
        self.num_threads = check_threads(num_threads)
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            mode = None
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(
                f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {autoreset_mode!r}"
            )
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.config = cfg = EnvConfig.from_kwargs(**kwargs)
        self._made_config = cfg  # what a {"mission": {}} reset option returns to
        self.num_envs = n = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.dim = d = cfg.dim
        self.single_observation_space, self.single_action_space = single_spaces(cfg)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self._obs_names = observation_names(cfg)
        self._discrete_actions = discrete_action_table(d, cfg.fine_thrust)
        self._field_spec = field_spec(cfg)
        self._drawer: OrbitDrawer | None = None  # draws the moving fields (spec checked once)
        self._rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self._pinned: list[Scenario | None] = [None] * n  # fields not drawn by the env
        self._paper: Scenario | None = None
        self._missions: MissionBatch | None = None
        self._autoreset = np.zeros(n, dtype=bool)
        self._obs = np.zeros((n, len(self._obs_names)), dtype=np.float32)

    # --- fields -------------------------------------------------------------------------------

    @property
    def made_config(self) -> EnvConfig:
        """The config the env was made with: what ``reset(options={"mission": {...}})`` changes
        keys of (``self.config`` is the one in force)."""
        return self._made_config

    @property
    def scenarios(self) -> Sequence[Scenario | None]:
        """The current field of every sub-env (None before the first reset).

        A read-only sequence; a random field is stored as arrays and turned into its
        :class:`Scenario` when accessed (the same ``Scenario`` the single env builds).
        """
        return _ScenarioList(self)

    @property
    def batch(self) -> MissionBatch | None:
        """The :class:`~debris_gym.mission_batch.MissionBatch` holding every sub-env's mission
        and field as arrays (None before the first reset). Read it; writing to it bypasses the
        env's checks."""
        return self._missions

    @property
    def _field(self) -> FieldBatch | None:
        return None if self._missions is None else self._missions.field

    def _scenario(self, i: int) -> Scenario | None:
        if self._missions is None:
            return None
        pinned = self._pinned[i]
        if pinned is not None:
            return pinned
        cfg, field, d = self.config, self._missions.field, self.dim
        vertices, counts = field.vertex_arrays(i)
        n_obstacles = field.n_bodies - self._missions.n_targets
        if counts.shape[0] != n_obstacles:  # 3D: spheres only, the batch keeps no polygon slots
            vertices, counts = np.zeros((n_obstacles, 0, 2)), np.zeros(n_obstacles, dtype=int)
        half = self._field_spec.field_size / 2.0
        moving = cfg.debris_motion != "frozen"
        start = field.start_states[i]  # the field as drawn: the bodies have moved since
        spins = np.zeros(field.n_bodies)
        spins[field.polygon_start :] = field.spins[i]
        return scenario_from_arrays(
            start[:, :d], field.radii[i], vertices, counts, self._missions.n_targets,
            ((-half, half),) * d, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel,
            velocities=start[:, d:] if moving else None, spins=spins if moving else None,
        )  # fmt: skip

    def _load_new(self, rows: np.ndarray) -> None:
        """Give the sub-envs ``rows`` the field a reset draws (each from its own generator)."""
        self._install(rows, self._draw(rows, self._rngs))

    def _draw(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> FieldArrays | None:
        """The random fields of the sub-envs ``rows`` from ``rngs`` (one per sub-env), or None
        for the paper world; changes nothing but the generators."""
        cfg = self.config
        if cfg.scenario == "paper":
            return None
        chosen = [rngs[i] for i in rows.tolist()]
        if self._field_spec.motion == "frozen":
            return random_fields(chosen, self._field_spec, capture_radius=cfg.capture_radius)
        if self._drawer is None:  # checks the spec (raises ValueError naming what is wrong)
            self._drawer = orbit_drawer(self._field_spec, cfg.capture_radius)
        return self._drawer.draw(chosen)

    def _install(self, rows: np.ndarray, fields: FieldArrays | None) -> None:
        """Load the fields :meth:`_draw` gave into the sub-envs ``rows``."""
        cfg = self.config
        if fields is None:
            self._load_scenario(rows, self._paper_field())
            return
        listed = rows.tolist()
        # every random field has the same world (dock, bounds, L): set it only in new batches
        # and in rows that held a pinned field
        stale = (
            rows if self._missions is None else [i for i in listed if self._pinned[i] is not None]
        )
        missions = self._fit((cfg.n, cfg.dt, cfg.max_accel), fields.n_targets, len(fields.radii[0]))
        spins = None if fields.spins is None else fields.spins[:, missions.field.polygon_start :]
        missions.load_arrays(
            rows, fields.centers, fields.radii, fields.vertices, fields.n_vertices,
            fields.velocities, spins,
        )  # fmt: skip
        for i in listed:
            self._pinned[i] = None
        if len(stale):
            half = fields.half_size
            missions.set_world(stale, 0.0, -half, half, (half - -half) / 2.0)  # L = size / 2

    def _paper_field(self) -> Scenario:
        if self._paper is None:
            cfg = self.config
            self._paper = paper_field(dt=cfg.dt, max_accel=cfg.max_accel)
        return self._paper

    def _load_scenario(self, rows: np.ndarray, scenario: Scenario) -> None:
        """Install ``scenario`` in the sub-envs ``rows``."""
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")
        physics = (scenario.mean_motion, scenario.dt, scenario.max_accel)
        missions = self._fit(physics, len(scenario.targets), len(scenario.bodies))
        missions.load_scenario(rows, scenario)
        for i in rows.tolist():
            self._pinned[i] = scenario
        missions.set_world(rows, scenario.dock, scenario.low, scenario.high, scenario.size / 2.0)

    def _fit(self, physics: tuple[float, float, float], n_targets: int, n_bodies: int):
        """The mission batch (allocated on first use); checks that a field fits it."""
        self._check_fits(physics, n_targets, n_bodies)
        missions = self._missions
        if missions is None:
            mean_motion, dt, max_accel = physics
            self._missions = missions = MissionBatch(
                self.config, self.num_envs, n_targets, n_bodies, mean_motion=mean_motion, dt=dt,
                max_accel=max_accel, max_episode_steps=self.max_episode_steps,
                threads=self.num_threads,
            )  # fmt: skip
        return missions

    def _check_fits(self, physics: tuple[float, float, float], n_targets: int, n_bodies: int):
        """Raise ``ValueError`` unless a field of this physics and size fits the batch."""
        missions = self._missions
        if missions is not None and (physics, n_targets, n_bodies) != (
            missions.physics,
            missions.n_targets,
            missions.field.n_bodies,
        ):
            raise ValueError(
                "all sub-envs of a vector env must share mean_motion, dt, max_accel and the "
                f"numbers of targets and bodies; got {physics} with {n_targets} targets of "
                f"{n_bodies} bodies, expected {missions.physics} with {missions.n_targets} of "
                f"{missions.field.n_bodies}"
            )

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-env.

        Transactional, as the single env: seeds, options, the fields (drawn or pinned) and the
        initial states are all checked before anything of the env changes, so a reset that
        raises leaves every sub-env as it was (fields, states, clocks, generators, pending
        autoresets).

        Args:
            seed: an int seeds sub-env i with ``seed + i``; a list gives one seed per sub-env.
            options: ``{"scenario": ...}`` pins the same field in every sub-env;
                ``{"chaser_state": array (N, 2·dim) or (2·dim,)}`` sets the initial states
                (:func:`~debris_gym.envs.common.checked_chaser_states`);
                ``{"mission": {...}}`` changes what every sub-env's missions ask
                (:data:`~debris_gym.envs.common.MISSION_KEYS`) from this reset on, autoresets
                included, until a reset names another mission (``{}``: the env's own again).

        Raises:
            ValueError: naming the bad seed or option; the env is unchanged.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            first = checked_seed(seed)
            seeds = [first + i for i in range(n)]
        else:
            if isinstance(seed, (str, bytes, bool)) or not isinstance(seed, (Sequence, np.ndarray)):
                raise ValueError(f"seed must be an int, a list of num_envs={n} ints or None")
            seeds = [checked_seed(s, f"seed[{i}]") for i, s in enumerate(seed)]
            if len(seeds) != n:
                raise ValueError(f"seed list must have num_envs={n} entries, got {len(seeds)}")
        options = checked_reset_options(options)
        rows = np.arange(n)
        # the generators of this reset: new ones for seeded sub-envs, the others continue
        # theirs (their states are put back if the reset fails)
        rngs = [None if s is None else seeding.np_random(s)[0] for s in seeds]
        rngs = [r if r is not None else self._rngs[i] for i, r in enumerate(rngs)]
        saved = [r.bit_generator.state for r in self._rngs]
        saved_mission = self.config, self._field_spec, self._drawer, self._missions
        try:
            if options.get("mission") is not None:
                config = checked_mission(self._made_config, options["mission"])
                if config != self.config:  # a new batch, sized and ruled by the new mission
                    self.config, self._drawer, self._missions = config, None, None
                    self._field_spec = field_spec(config)
            cfg = self.config
            pinned = options.get("scenario")
            fields = None
            if pinned is not None:
                steps = self.max_episode_steps or registered_horizon(self.spec)
                pinned = as_scenario(pinned, horizon_steps=steps)
                if pinned.dim != self.dim:
                    raise ValueError(
                        f"scenario has dim={pinned.dim} but the env has dim={self.dim}"
                    )
                physics = (pinned.mean_motion, pinned.dt, pinned.max_accel)
                self._check_fits(physics, len(pinned.targets), len(pinned.bodies))
                warn_if_physics_differ(cfg, pinned)
                check_motion_matches(cfg, pinned)
            else:
                fields = self._draw(rows, rngs)
                if fields is not None:
                    physics = (cfg.n, cfg.dt, cfg.max_accel)
                    self._check_fits(physics, fields.n_targets, fields.radii.shape[1])
            states = options.get("chaser_state")
            if states is not None:
                states = self._checked_states(states, pinned, fields)
            elif pinned is not None:
                check_dock_clear(pinned, cfg.chaser_radius)  # every sub-env starts at the dock
        except BaseException:
            self.config, self._field_spec, self._drawer, self._missions = saved_mission
            for rng, state in zip(self._rngs, saved):
                rng.bit_generator.state = state
            raise
        # commit: everything is valid, nothing below raises on it
        self._rngs = rngs
        if pinned is not None:
            self._load_scenario(rows, pinned)
        else:
            self._install(rows, fields)
        self._missions.begin(rows, states)
        self._autoreset[:] = False
        return self._observe(), self._info(np.zeros((n, len(REWARD_TERMS))))

    def _checked_states(
        self, value: Any, pinned: Scenario | None, fields: FieldArrays | None
    ) -> np.ndarray:
        """Initial chaser states checked against the fields this reset installs."""
        n, cfg = self.num_envs, self.config
        if fields is None:
            scenario = pinned if pinned is not None else self._paper_field()
            geometry = FieldGeometry(scenario)
            return checked_chaser_states(
                value, n, scenario.low, scenario.high, scenario.size / scenario.dt,
                geometry.signed_distance, cfg.chaser_radius,
            )  # fmt: skip
        # the drawn fields in a batch of their own: the gaps the env's batch would give
        bodies = fields.radii.shape[1]
        check = FieldBatch(n, bodies, self.dim, MAX_POLYGON_VERTICES, fields.n_targets)
        check.load_arrays(
            np.arange(n), fields.centers, fields.radii, fields.vertices, fields.n_vertices
        )
        low, high = np.array(fields.bounds).T
        return checked_chaser_states(
            value, n, low, high, self._field_spec.field_size / cfg.dt, check.gaps,
            cfg.chaser_radius,
        )  # fmt: skip

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env (sub-envs that ended last step reset instead)."""
        if self._missions is None:
            raise RuntimeError("call reset() before step()")
        restart = self._autoreset
        reward, terminated, truncated, terms = self._missions.step(self._actions(actions), ~restart)
        reward, terminated, truncated = reward.copy(), terminated.copy(), truncated.copy()
        ended = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            if not ended.any():
                return self._observe(), reward, terminated, truncated, self._info(terms)
            final_obs, final_info = self._observe(), self._info(terms, mask=ended)
            self._restart(ended)
            terms[ended] = 0.0
            info = self._info(terms)
            info["final_obs"] = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended):
                info["final_obs"][i] = final_obs[i]
            info["_final_obs"] = ended.copy()
            info["final_info"] = final_info
            info["_final_info"] = ended.copy()
            return self._observe(), reward, terminated, truncated, info
        if restart.any():
            self._restart(restart)
        self._autoreset = ended
        return self._observe(), reward, terminated, truncated, self._info(terms)

    def _restart(self, mask: np.ndarray) -> None:
        """Draw new fields for the sub-envs in ``mask`` and start their episodes."""
        rows = np.flatnonzero(mask)
        self._load_new(rows)
        self._missions.begin(rows)

    # --- step hooks ---------------------------------------------------------------------------

    def _actions(self, actions: Any) -> np.ndarray:
        """Validated actions as normalised thrust commands (N, dim)."""
        cfg, n, d = self.config, self.num_envs, self.dim
        if cfg.action == "discrete":
            idx = real_array(actions, "action")
            if idx.shape != (n,) or idx.dtype.kind not in "iu":
                raise ValueError(f"discrete actions must be {n} integers, got {actions!r}")
            last = len(self._discrete_actions) - 1
            if np.any((idx < 0) | (idx > last)):
                raise ValueError(f"discrete actions must lie in [0, {last}], got {idx}")
            return self._discrete_actions[idx]
        return checked_continuous_actions(actions, (n, d))

    def _observe(self) -> np.ndarray:
        """A new (N, obs size) array of every sub-env's observation."""
        out = np.empty_like(self._obs)  # every element is written: no zeroing, no copy
        return self._missions.observe(out, registered_horizon(self.spec))

    def _info(self, terms: np.ndarray, mask: np.ndarray | None = None) -> dict[str, Any]:
        n, m = self.num_envs, self._missions
        mask = np.ones(n, dtype=bool) if mask is None else mask
        values = {
            "chaser_state": m.state.copy(),
            "time": m.time.copy(),
            "delta_v": m.delta_v.copy(),
            "targets_captured": m.captured_counts(),
            "n_targets": np.full(n, m.n_targets),
            "captured": m.captured.copy(),
            "min_clearance": m.min_clearance - self.config.chaser_radius,
            "collision": m.collision.copy(),
            "out_of_bounds": m.out_of_bounds.copy(),
            "is_success": m.success.copy(),
            "applied_accel": m.accel.copy(),
            "task_score": m.score.copy(),
        }
        info: dict[str, Any] = {}
        for key, value in values.items():
            info[key] = value
            info["_" + key] = mask
        by_term = terms.T.copy()  # one copy; each term is a contiguous row of it
        info["reward_terms"] = dict(zip(REWARD_TERMS, by_term))
        info["_reward_terms"] = mask
        return info

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order (as the single env)."""
        return list(self._obs_names)


def _is_int(value: Any) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


class _ScenarioList(Sequence):
    """Read-only view of a vector env's fields: item i is sub-env i's :class:`Scenario`."""

    def __init__(self, env: DebrisFieldVectorEnv) -> None:
        self._env = env

    def __len__(self) -> int:
        return self._env.num_envs

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._env._scenario(i) for i in range(len(self))[index]]
        i = operator.index(index)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"sub-env index {index} out of range for {len(self)} sub-envs")
        return self._env._scenario(i)
