"""Native vectorised DebrisField env: N envs as numpy arrays, one batched step.

Reached through ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
Every sub-env behaves exactly like ``gym.make(id)`` reset with seed ``seed + i`` (same fields,
same dynamics, same rewards, observations and infos; ``tests/test_vector_env.py`` checks it
against N single envs): the propagation uses the same cached CWH matrices from
:mod:`debris_gym.dynamics`, thrust and rewards the same functions; geometry runs on
:class:`debris_gym.batch_geometry.FieldBatch`, the batched twin of the single env's geometry.

Autoreset follows Gymnasium 1.x's default *next-step* mode: the step after a sub-env terminates or
truncates resets it (its action is ignored) and returns the first observation of the new episode
with reward 0. Each sub-env keeps its own seeded generator; the sub-envs that reset on a step
draw their fields together (:func:`debris_gym.generators.random_fields`, one fixed block of
random numbers per sub-env and draw, so a field never depends on which other sub-envs reset with
it) and the fields go into the batch as arrays; :attr:`DebrisFieldVectorEnv.scenarios` builds a
sub-env's :class:`Scenario` only when read. Everything in ``step`` is batched, with no Python loop
over envs or debris.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from debris_gym.batch_geometry import FieldBatch
from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize, substep_position_matrix
from debris_gym.envs.common import (
    OBS_LIMIT,
    discrete_action_table,
    field_spec,
    observation_names,
    registered_horizon,
    single_spaces,
)
from debris_gym.generators import (
    MAX_POLYGON_VERTICES,
    paper_field,
    random_fields,
    scenario_from_arrays,
)
from debris_gym.geometry import distance, lidar_directions
from debris_gym.rewards import REWARD_TERMS, reward_terms
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.thrust import commanded_accel, delta_v_rate


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
        **kwargs: any :class:`~debris_gym.config.EnvConfig` key, as for the single env.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        if not (isinstance(num_envs, (int, np.integer)) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be >= 1 or None, got {max_episode_steps!r}")
        if render_mode is not None:
            raise ValueError(
                "the vector env does not render; make a single env with render_mode='rgb_array'"
            )
        mode = AutoresetMode(autoreset_mode)
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {mode!r}")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.autoreset_mode = mode
        self.config = cfg = EnvConfig.from_kwargs(**kwargs)
        self.num_envs = n = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.dim = d = cfg.dim
        self.single_observation_space, self.single_action_space = single_spaces(cfg)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self._obs_names = observation_names(cfg)
        self._discrete_actions = discrete_action_table(d)
        lidar = cfg.observation == "lidar"
        self._lidar_dirs = lidar_directions(d, cfg.lidar_rays) if lidar else None
        self._field_spec = field_spec(cfg)
        self._rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(n)]
        self._pinned: list[Scenario | None] = [None] * n  # fields not drawn by the env
        self._paper: Scenario | None = None
        self._physics: tuple[float, float, float] | None = None
        self._field: FieldBatch | None = None
        self._autoreset = np.zeros(n, dtype=bool)

    # --- fields -------------------------------------------------------------------------------

    @property
    def scenarios(self) -> Sequence[Scenario | None]:
        """The current field of every sub-env (None before the first reset).

        A read-only sequence; a random field is stored as arrays and turned into its
        :class:`Scenario` when accessed (the same ``Scenario`` the single env builds).
        """
        return _ScenarioList(self)

    def _scenario(self, i: int) -> Scenario | None:
        if self._field is None:
            return None
        pinned = self._pinned[i]
        if pinned is not None:
            return pinned
        cfg, field = self.config, self._field
        vertices, counts = field.vertex_arrays(i)
        half = self._field_spec.field_size / 2.0
        return scenario_from_arrays(
            field.centers[i], field.radii[i], vertices, counts, self._n_targets,
            ((-half, half),) * self.dim, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel,
        )  # fmt: skip

    def _load_new(self, rows: np.ndarray) -> None:
        """Give the sub-envs ``rows`` the field a reset draws (each from its own generator)."""
        cfg = self.config
        if cfg.scenario == "paper":
            if self._paper is None:
                self._paper = paper_field(dt=cfg.dt, max_accel=cfg.max_accel)
            self._load_scenario(rows, self._paper)
            return
        fields = random_fields(
            [self._rngs[i] for i in rows], self._field_spec, capture_radius=cfg.capture_radius
        )
        self._fit((cfg.n, cfg.dt, cfg.max_accel), fields.n_targets, fields.centers.shape[1])
        self._field.load_arrays(
            rows, fields.centers, fields.radii, fields.vertices, fields.n_vertices
        )
        for i in rows.tolist():
            self._pinned[i] = None
        half = fields.half_size
        self._dock[rows] = 0.0
        self._low[rows] = -half
        self._high[rows] = half
        self._length_scale[rows] = (half - -half) / 2.0  # as Scenario.size / 2
        self._speed_scale[rows] = math.sqrt(cfg.max_accel * self._length_scale[rows[0]])

    def _load_scenario(self, rows: np.ndarray, scenario: Scenario) -> None:
        """Install ``scenario`` in the sub-envs ``rows``."""
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")
        physics = (scenario.mean_motion, scenario.dt, scenario.max_accel)
        self._fit(physics, len(scenario.targets), len(scenario.bodies))
        self._field.load_scenario(rows, scenario)
        for i in rows.tolist():
            self._pinned[i] = scenario
        self._dock[rows] = scenario.dock
        self._low[rows] = scenario.low
        self._high[rows] = scenario.high
        self._length_scale[rows] = scenario.size / 2.0
        self._speed_scale[rows] = math.sqrt(scenario.max_accel * (scenario.size / 2.0))

    def _fit(self, physics: tuple[float, float, float], n_targets: int, n_bodies: int) -> None:
        """Allocate the batch on first use; afterwards check a field fits it."""
        if self._field is None:
            self._allocate(physics, n_targets, n_bodies)
        elif (physics, n_targets, n_bodies) != (
            self._physics,
            self._n_targets,
            self._field.n_bodies,
        ):
            raise ValueError(
                "all sub-envs of a vector env must share mean_motion, dt, max_accel and the "
                f"numbers of targets and bodies; got {physics} with {n_targets} targets of "
                f"{n_bodies} bodies, expected {self._physics} with {self._n_targets} of "
                f"{self._field.n_bodies}"
            )

    def _allocate(self, physics: tuple[float, float, float], t: int, n_bodies: int) -> None:
        n, d, cfg = self.num_envs, self.dim, self.config
        mean_motion, dt, max_accel = physics
        self._physics = physics
        self._n_targets = t
        # exact polygon gaps are needed for the obstacle slots and the smallest clearance only
        self._cull = (
            (max(cfg.obs_obstacles, 1), t) if cfg.observation == "kinematics" else (None, 0)
        )
        self._field = FieldBatch(n, n_bodies, d, MAX_POLYGON_VERTICES, polygon_start=t)
        model = discretize(mean_motion, dt, d)
        sub = substep_position_matrix(mean_motion, dt, d, cfg.collision_substeps)
        end_velocity = np.hstack([model.ad[d:], model.bd[d:]])
        self._step_matrix_t = np.ascontiguousarray(np.vstack([sub, end_velocity]).T)
        self._dt = dt
        self._max_accel = max_accel
        self._dock = np.zeros((n, d))
        self._low = np.zeros((n, d))
        self._high = np.zeros((n, d))
        self._length_scale = np.ones(n)
        self._speed_scale = np.ones(n)
        self._state = np.zeros((n, 2 * d))
        self._time = np.zeros(n)
        self._steps = np.zeros(n, dtype=np.int64)
        self._delta_v = np.zeros(n)
        self._captured = np.zeros((n, t), dtype=bool)
        self._collision = np.zeros(n, dtype=bool)
        self._out_of_bounds = np.zeros(n, dtype=bool)
        self._success = np.zeros(n, dtype=bool)
        self._gaps = np.zeros((n, self._field.n_bodies))
        self._min_clearance = np.full(n, math.inf)
        self._potential = np.zeros(n)
        self._accel = np.zeros((n, d))
        self._obs = np.zeros((n, len(self._obs_names)), dtype=np.float32)
        self._row_base = np.arange(n)[:, None] * n_bodies  # row offsets into flattened (N, B)

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-env.

        Args:
            seed: an int seeds sub-env i with ``seed + i``; a list gives one seed per sub-env.
            options: ``{"scenario": ...}`` pins the same field in every sub-env;
                ``{"chaser_state": array (N, 2·dim) or (2·dim,)}`` sets the initial states.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed list must have num_envs={n} entries, got {len(seeds)}")
        options = dict(options or {})
        unknown = sorted(set(options) - {"scenario", "chaser_state"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: chaser_state, scenario")
        pinned = options.get("scenario")
        pinned = as_scenario(pinned) if pinned is not None else None
        states = options.get("chaser_state")
        if states is not None:
            states = np.array(states, dtype=float)
            if states.ndim == 1:
                states = np.broadcast_to(states, (n, states.shape[0]))
            if states.shape != (n, 2 * self.dim):
                raise ValueError(
                    f"chaser_state must have shape ({n}, {2 * self.dim}) or ({2 * self.dim},), "
                    f"got {np.shape(options['chaser_state'])}"
                )
        for i in range(n):
            if seeds[i] is not None:  # like the single env: no seed continues the generator
                self._rngs[i], _ = seeding.np_random(seeds[i])
        rows = np.arange(n)
        if pinned is not None:
            self._load_scenario(rows, pinned)
        else:
            self._load_new(rows)
        mask = np.ones(n, dtype=bool)
        self._start_episodes(mask, states)
        self._autoreset[:] = False
        terms = {k: np.zeros(n) for k in REWARD_TERMS}
        return self._observe(), self._info(terms)

    def _start_episodes(self, mask: np.ndarray, states: np.ndarray | None = None) -> None:
        """Initialise the episode state of the sub-envs in ``mask`` (fields already loaded)."""
        d = self.dim
        if states is None:
            self._state[mask, :d] = self._dock[mask]
            self._state[mask, d:] = 0.0
        else:
            self._state[mask] = self._validated_states(states[mask], np.flatnonzero(mask))
        self._time[mask] = 0.0
        self._steps[mask] = 0
        self._delta_v[mask] = 0.0
        self._captured[mask] = False
        self._collision[mask] = False
        self._out_of_bounds[mask] = False
        self._success[mask] = False
        self._accel[mask] = 0.0
        rows = np.flatnonzero(mask)
        if rows.size == self.num_envs:  # a full reset: no copies of the batch
            rows = slice(None)
            self._gaps = self._field.gaps(self._state[:, :d], None, *self._cull)
        else:
            self._gaps[rows] = self._field.gaps(self._state[rows, :d], rows, *self._cull)
        obstacle_gaps = self._gaps[rows, self._n_targets :]
        self._min_clearance[rows] = (
            obstacle_gaps.min(axis=1) if obstacle_gaps.shape[1] else math.inf
        )
        self._potential[rows] = self._potential_now(rows)

    def _validated_states(self, states: np.ndarray, rows: np.ndarray) -> np.ndarray:
        d = self.dim
        if not np.all(np.isfinite(states)):
            raise ValueError("chaser_state must be finite")
        pos = states[:, :d]
        outside = np.any(pos <= self._low[rows], axis=1) | np.any(pos >= self._high[rows], axis=1)
        if outside.any():
            raise ValueError(f"chaser_state of sub-env {rows[outside][0]} is outside the bounds")
        gaps = self._field.gaps(pos, rows).min(axis=1) - self.config.chaser_radius
        if np.any(gaps <= 0.0):
            raise ValueError(f"chaser_state of sub-env {rows[gaps <= 0][0]} touches debris")
        return states

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env (sub-envs that ended last step reset instead)."""
        if self._field is None:
            raise RuntimeError("call reset() before step()")
        cfg, d, n = self.config, self.dim, self.num_envs
        accel, dv = self._thrust(actions)
        restart = self._autoreset.copy()
        live = ~restart

        # simulate: one matmul gives every sub-step position and the end velocity
        start = self._state
        out = np.concatenate([start, accel], axis=1) @ self._step_matrix_t
        paths = np.empty((n, cfg.collision_substeps + 1, d))
        paths[:, 0] = start[:, :d]
        paths[:, 1:] = out[:, :-d].reshape(n, -1, d)
        new_state = np.concatenate([paths[:, -1], out[:, -d:]], axis=1)
        touched = self._field.touched(paths, self._gaps, cfg.chaser_radius)
        self._state = np.where(live[:, None], new_state, start)
        self._time += np.where(live, self._dt, 0.0)
        self._steps += live
        self._delta_v += np.where(live, dv, 0.0)
        self._accel = np.where(live[:, None], accel, self._accel)

        new_captures = self._update_mission(touched, live, start)
        terms = self._reward_terms(new_captures, np.where(live, dv, 0.0))
        budget = cfg.delta_v_budget
        spent = np.zeros(n, dtype=bool) if budget is None else self._delta_v >= budget
        terminated = (self._success | self._collision | self._out_of_bounds | spent) & live
        terms["progress"] = np.where(
            terminated & (cfg.shaping_terminal == "zero"),
            terms["progress"] - cfg.reward_progress * cfg.shaping_gamma * self._potential,
            terms["progress"],
        )
        limit = self.max_episode_steps
        truncated = (self._steps >= limit) & live if limit is not None else np.zeros(n, bool)

        reward = np.zeros(n)
        for term in REWARD_TERMS:
            reward = reward + terms[term]
        ended = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            if not ended.any():
                return self._observe(), reward, terminated, truncated, self._info(terms)
            final_obs, final_info = self._observe(), self._info(terms, mask=ended)
            self._restart(ended, terms)
            info = self._info(terms)
            info["final_obs"] = np.full(n, None, dtype=object)
            for i in np.flatnonzero(ended):
                info["final_obs"][i] = final_obs[i]
            info["_final_obs"] = ended.copy()
            info["final_info"] = final_info
            info["_final_info"] = ended.copy()
            return self._observe(), reward, terminated, truncated, info
        if restart.any():
            self._restart(restart, terms)
            reward[restart] = 0.0
        self._autoreset = ended
        return self._observe(), reward, terminated, truncated, self._info(terms)

    def _restart(self, mask: np.ndarray, terms: dict[str, np.ndarray]) -> None:
        """Draw new fields for the sub-envs in ``mask`` and start their episodes."""
        self._load_new(np.flatnonzero(mask))
        self._start_episodes(mask)
        for term in terms.values():
            term[mask] = 0.0

    # --- step hooks ---------------------------------------------------------------------------

    def _thrust(self, actions: Any) -> tuple[np.ndarray, np.ndarray]:
        cfg, n, d = self.config, self.num_envs, self.dim
        if cfg.action == "discrete":
            idx = np.asarray(actions)
            if idx.shape != (n,) or not np.issubdtype(idx.dtype, np.integer):
                raise ValueError(f"discrete actions must be {n} integers, got {idx!r}")
            if np.any((idx < 0) | (idx > 2 * d)):
                raise ValueError(f"discrete actions must lie in [0, {2 * d}], got {idx}")
            a = self._discrete_actions[idx]
        else:
            a = np.asarray(actions, dtype=float)
            if a.shape != (n, d):
                raise ValueError(f"actions must have shape ({n}, {d}), got {a.shape}")
            bad = ~np.isfinite(a).all(axis=1)
            if bad.any():
                raise ValueError(
                    f"actions must be finite (no NaN or inf); sub-env {np.flatnonzero(bad)[0]} "
                    f"got {a[bad][0]}"
                )
        accel = commanded_accel(a, self._max_accel, cfg.thrust_model)
        dv = delta_v_rate(accel, cfg.thrust_model) * self._dt
        budget = cfg.delta_v_budget
        if budget is not None:
            over = (dv > 0.0) & (self._delta_v + dv > budget)
            if over.any():
                with np.errstate(divide="ignore", invalid="ignore"):
                    scale = np.where(over, np.maximum(budget - self._delta_v, 0.0) / dv, 1.0)
                accel = accel * scale[:, None]
                dv = dv * scale
        return accel, dv

    def _update_mission(
        self, touched: np.ndarray, live: np.ndarray, start: np.ndarray
    ) -> np.ndarray:
        cfg, d, t = self.config, self.dim, self._n_targets
        pos, vel = self._state[:, :d], self._state[:, d:]
        self._gaps = gaps = self._field.gaps(pos, None, *self._cull)
        if gaps.shape[1] > t:
            clearance = np.minimum(self._min_clearance, gaps[:, t:].min(axis=1))
            self._min_clearance = np.where(live, clearance, self._min_clearance)
        speed = distance(vel, np.zeros(d))
        slow = speed <= cfg.capture_speed
        reach = cfg.capture_radius + cfg.chaser_radius
        capturable = self._eligible(self._captured) & (gaps[:, :t] <= reach)
        capturable &= (slow & live)[:, None]
        new = capturable.sum(axis=1)
        self._captured |= capturable
        hit = live & touched[:, t:].any(axis=1)
        fast_contact = touched[:, :t] & ~slow[:, None]
        if fast_contact.any():
            # a target touched too fast counts unless the chaser leaves it at both step ends
            r, c = np.nonzero(fast_contact)
            centres = self._field.centers[r, c]
            p0, v0 = start[r, :d], start[r, d:]
            closing = ((centres - p0) * v0).sum(axis=1) > 0.0
            closing |= ((centres - pos[r]) * vel[r]).sum(axis=1) > 0.0
            hit[r[closing & live[r]]] = True
        self._collision |= hit
        oob = np.zeros_like(live)
        for axis in range(d):
            oob |= (pos[:, axis] <= self._low[:, axis]) | (pos[:, axis] >= self._high[:, axis])
        self._out_of_bounds = np.where(live, oob, self._out_of_bounds)
        done = self._captured.all(axis=1) & ~self._collision & live
        if cfg.return_to_dock:
            done &= (distance(pos, self._dock) <= cfg.capture_radius) & slow
        self._success |= done
        return new

    def _eligible(self, captured: np.ndarray) -> np.ndarray:
        """(R, T) mask of targets that can be captured now, given the capture flags (R, T)."""
        remaining = ~captured
        if self.config.target_order == "queued":
            first = np.zeros_like(remaining)
            has = remaining.any(axis=1)
            first[np.flatnonzero(has), remaining[has].argmax(axis=1)] = True
            return first
        return remaining

    def _potential_now(self, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Shaping potential Φ of the sub-envs ``rows`` (all by default)."""
        cfg, d, t = self.config, self.dim, self._n_targets
        captured = self._captured[rows]
        eligible = self._eligible(captured)
        has_target = eligible.any(axis=1)
        gap = np.where(eligible, self._gaps[rows, :t], np.inf).min(axis=1) - cfg.chaser_radius
        dock_goal = 1 if cfg.return_to_dock else 0
        left = t - captured.sum(axis=1)
        if dock_goal:
            dock_dist = distance(self._state[rows, :d], self._dock[rows])
        else:
            dock_dist = np.zeros(len(has_target))
        goal_gap = np.where(has_target, np.maximum(gap, 0.0), dock_dist)
        after = np.where(has_target, left - 1 + dock_goal, 0)
        return -(goal_gap / self._length_scale[rows] + after)

    def _reward_terms(self, new_captures: np.ndarray, dv: np.ndarray) -> dict[str, np.ndarray]:
        cfg = self.config
        phi = self._potential_now()
        progress = cfg.shaping_gamma * phi - self._potential
        self._potential = phi
        return reward_terms(
            cfg,
            new_captures=new_captures,
            success=self._success,
            progress=progress,
            delta_v=dv,
            collision=self._collision,
            out_of_bounds=self._out_of_bounds,
        )

    def _observe(self) -> np.ndarray:
        cfg, d, n, t = self.config, self.dim, self.num_envs, self._n_targets
        field = self._field
        L = self._length_scale[:, None]
        V = self._speed_scale[:, None]
        pos, vel = self._state[:, :d], self._state[:, d:]
        # built in float32 directly: each value is rounded once from the same float64 value the
        # single env computes, and clipping commutes with that rounding (±OBS_LIMIT is exact)
        obs = self._obs
        obs[:, :d] = pos / L
        obs[:, d : 2 * d] = vel / V
        k = 2 * d
        slot = 2 * d + 2
        width = cfg.obs_targets * slot
        targets = obs[:, k : k + width].reshape(n, cfg.obs_targets, slot)
        # uncaptured first (nearest first, or queue order), then captured, in index order
        key = (
            self._gaps[:, :t]
            if cfg.target_order == "any"
            else np.broadcast_to(np.arange(t, dtype=float), (n, t))
        )
        key = np.where(self._captured, np.inf, key)
        order = np.lexsort((np.arange(t)[None].repeat(n, 0), key, self._captured))
        m = min(cfg.obs_targets, t)
        flat = order[:, :m] + self._row_base  # body index in the flattened (N, B) arrays
        centres = field.centers.reshape(-1, d).take(flat, axis=0)  # (n, m, d)
        centres -= pos[:, None, :]
        centres /= L[:, :, None]
        targets[:, :m, :d] = centres
        targets[:, :m, d : 2 * d] = (-vel / V)[:, None, :]
        targets[:, :m, 2 * d] = field.radii.take(flat) / L
        targets[:, :m, 2 * d + 1] = np.take_along_axis(self._captured, order[:, :m], 1)
        targets[:, m:] = 0.0
        targets[:, m:, -1] = 1.0  # empty slots read as "captured"
        k += width
        obs[:, k : k + d] = (self._dock - pos) / L
        k += d
        if cfg.observation == "kinematics":
            slot = d + 2
            width = cfg.obs_obstacles * slot
            slots = obs[:, k : k + width].reshape(n, cfg.obs_obstacles, slot)
            gaps = self._gaps[:, t:]
            m = min(cfg.obs_obstacles, gaps.shape[1])
            if m:
                if gaps.shape[1] > max(m, 64):
                    nearest = np.argpartition(gaps, m - 1, axis=1)[:, :m]
                    nearest = np.take_along_axis(
                        nearest, np.argsort(np.take_along_axis(gaps, nearest, 1), axis=1), 1
                    )
                else:
                    nearest = np.argsort(gaps, axis=1)[:, :m]
                flat = nearest + (self._row_base + t)
                centres = field.centers.reshape(-1, d).take(flat, axis=0)
                centres -= pos[:, None, :]
                centres /= L[:, :, None]
                slots[:, :m, :d] = centres
                slots[:, :m, d] = field.radii.take(flat) / L
                slots[:, :m, d + 1] = self._gaps.take(flat) / L
            slots[:, m:] = 0.0
            slots[:, m:, -1] = 1.0
        else:
            width = cfg.lidar_rays
            ranges = field.lidar(pos, self._lidar_dirs, cfg.lidar_range)
            obs[:, k : k + width] = ranges / cfg.lidar_range
        k += width
        budget = cfg.delta_v_budget
        obs[:, k] = 1.0 if budget is None else np.maximum(budget - self._delta_v, 0.0) / budget
        horizon = registered_horizon(self.spec)
        obs[:, k + 1] = np.maximum(horizon - self._steps, 0) / horizon
        np.clip(obs, -OBS_LIMIT, OBS_LIMIT, out=obs)
        return obs.copy()

    def _info(self, terms: dict[str, np.ndarray], mask: np.ndarray | None = None) -> dict[str, Any]:
        n = self.num_envs
        mask = np.ones(n, dtype=bool) if mask is None else mask
        values = {
            "chaser_state": self._state.copy(),
            "time": self._time.copy(),
            "delta_v": self._delta_v.copy(),
            "targets_captured": self._captured.sum(axis=1),
            "n_targets": np.full(n, self._n_targets),
            "captured": self._captured.copy(),
            "min_clearance": self._min_clearance - self.config.chaser_radius,
            "collision": self._collision.copy(),
            "out_of_bounds": self._out_of_bounds.copy(),
            "is_success": self._success.copy(),
        }
        info: dict[str, Any] = {}
        for key, value in values.items():
            info[key] = value
            info["_" + key] = mask
        info["reward_terms"] = {k: np.array(v, dtype=float) for k, v in terms.items()}
        info["_reward_terms"] = mask
        return info

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order (as the single env)."""
        return list(self._obs_names)


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
