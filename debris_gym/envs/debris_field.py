"""The multi-target rendezvous environment on CWH dynamics."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize, substep_position_matrix
from debris_gym.generators import FieldSpec, paper_field, random_field
from debris_gym.geometry import FieldGeometry, lidar_directions
from debris_gym.rewards import REWARD_TERMS, potential
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.thrust import commanded_accel, delta_v_rate

OBS_LIMIT = 10.0
"""Observation values are normalised to about [−1, 1] and clipped to ±OBS_LIMIT."""

DEFAULT_HORIZON_STEPS = 1000
"""Steps used for the 'time remaining' observation when the env has no registered time limit."""


class DebrisFieldEnv(gym.Env):
    """Rendezvous with several pieces of debris in one trip through a debris field, and return.

    ## Description

    A chaser spacecraft starts at rest at the dock, at the origin of the LVLH (Hill) frame of a
    circular reference orbit, and must rendezvous with every target — come within
    ``capture_radius`` of its surface at a relative speed of at most ``capture_speed`` — without
    touching any other debris, then (if ``return_to_dock``) come back to the dock the same way.
    Motion follows the Clohessy-Wiltshire-Hill equations, propagated exactly (zero-order hold) over
    each step; collisions are checked continuously along the path, not only at step ends. Debris is
    frozen in LVLH (exact only for ``mean_motion = 0``; see ``docs/environments.md``).

    ## Action Space

    ``action="continuous"``: ``Box(-1, 1, (dim,), float32)``, the commanded acceleration as a
    fraction of ``max_accel`` (m/s²); ``thrust_model="box"`` clips each axis, ``"ball"`` scales
    vectors longer than 1 onto the unit ball. ``action="discrete"``: ``Discrete(2·dim + 1)``:
    0 coast, then +x, −x, +y, −y (, +z, −z) at full thrust. NaN or infinite actions raise
    ``ValueError``.

    ## Observation Space

    ``observation="kinematics"``: a float32 vector, normalised to about [−1, 1] (length scale
    L = half the world size, speed scale V = sqrt(max_accel · L)) and clipped to ±10:
    chaser position / L, velocity / V; K target slots (relative position / L, relative velocity / V,
    radius / L, captured flag); dock relative position / L; M nearest-obstacle slots (relative
    position / L, bounding radius / L, surface gap / L); Δv remaining fraction; time remaining
    fraction. ``observation="lidar"`` replaces the obstacle slots with ``lidar_rays`` ranges /
    ``lidar_range``. :meth:`observation_names` names every element; docs/environments.md has the
    table with units.

    ## Rewards

    A sum of named terms, each reported in ``info["reward_terms"]`` and weighted by the config key
    ``reward_<term>``: capture, success, progress (potential-based shaping), delta_v, collision,
    out_of_bounds, time. See :mod:`debris_gym.rewards`.

    ## Starting State

    The chaser at rest at the dock, unless ``reset(options={"chaser_state": ...})`` says
    otherwise. A new random field each reset (from the reset seed), unless
    ``options={"scenario": ...}`` pins one or ``scenario="paper"`` selects seed 000's world.

    ## Episode End

    Terminated on success, collision, leaving the bounds, or spending the whole Δv budget.
    Truncated by the registration's ``max_episode_steps`` (``TimeLimit``).

    ## Arguments

    Every key of :class:`debris_gym.config.EnvConfig` (see ``docs/environments.md``), plus
    ``render_mode`` ("rgb_array" or "human").

    ## Version History

    * v0: initial release.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 15}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        self.config = EnvConfig.from_kwargs(**kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.dim = d = cfg.dim
        if cfg.action == "continuous":
            self.action_space = spaces.Box(-1.0, 1.0, shape=(d,), dtype=np.float32)
        else:
            self.action_space = spaces.Discrete(2 * d + 1)
        table = np.zeros((2 * d + 1, d))
        for axis in range(d):
            table[1 + 2 * axis, axis] = 1.0
            table[2 + 2 * axis, axis] = -1.0
        self._discrete_actions = table
        self._obs_names = self._build_observation_names()
        self.observation_space = spaces.Box(
            -OBS_LIMIT, OBS_LIMIT, shape=(len(self._obs_names),), dtype=np.float32
        )
        self._lidar_dirs = lidar_directions(d, cfg.lidar_rays) if cfg.observation == "lidar" else None
        self._field_spec = FieldSpec(
            dim=d,
            n_targets=cfg.n_targets,
            n_obstacles=cfg.n_obstacles,
            field_size=cfg.field_size,
            target_radius=(cfg.target_radius_min, cfg.target_radius_max),
            obstacle_radius=(cfg.obstacle_radius_min, cfg.obstacle_radius_max),
            polygon_fraction=cfg.polygon_fraction,
            min_gap=cfg.min_gap,
            dock_clearance=max(5.0 * cfg.capture_radius, 0.05 * cfg.field_size),
            target_clearance=cfg.capture_radius + 2.0 * cfg.chaser_radius + cfg.min_gap,
            min_target_distance=0.15 * cfg.field_size,
            chaser_radius=cfg.chaser_radius,
        )
        self.scenario: Scenario | None = None
        self._renderer = None

    # --- observation layout -------------------------------------------------------------------

    def _build_observation_names(self) -> list[str]:
        cfg, axes = self.config, "xyz"[: self.config.dim]
        names = [f"chaser_pos_{a}" for a in axes] + [f"chaser_vel_{a}" for a in axes]
        for k in range(cfg.obs_targets):
            names += [f"target{k}_rel_pos_{a}" for a in axes]
            names += [f"target{k}_rel_vel_{a}" for a in axes]
            names += [f"target{k}_radius", f"target{k}_captured"]
        names += [f"dock_rel_pos_{a}" for a in axes]
        if cfg.observation == "kinematics":
            for k in range(cfg.obs_obstacles):
                names += [f"obstacle{k}_rel_pos_{a}" for a in axes]
                names += [f"obstacle{k}_radius", f"obstacle{k}_gap"]
        else:
            names += [f"lidar{k}" for k in range(cfg.lidar_rays)]
        names += ["delta_v_remaining", "time_remaining"]
        return names

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order."""
        return list(self._obs_names)

    # --- scenario -----------------------------------------------------------------------------

    def _new_scenario(self) -> Scenario:
        cfg = self.config
        if cfg.scenario == "paper":
            return paper_field(dt=cfg.dt, max_accel=cfg.max_accel)
        return random_field(
            self.np_random,
            self._field_spec,
            mean_motion=cfg.n,
            dt=cfg.dt,
            max_accel=cfg.max_accel,
            capture_radius=cfg.capture_radius,
        )

    def _set_scenario(self, scenario: Scenario) -> None:
        cfg = self.config
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")
        self.scenario = scenario
        self._geometry = FieldGeometry(scenario, inflate=cfg.chaser_radius)
        self._model = discretize(scenario.mean_motion, scenario.dt, self.dim)
        self._sub_positions = substep_position_matrix(
            scenario.mean_motion, scenario.dt, self.dim, cfg.collision_substeps
        )
        self._n_targets = len(scenario.targets)
        self._length_scale = scenario.size / 2.0
        self._speed_scale = math.sqrt(scenario.max_accel * self._length_scale)
        self._dock = np.asarray(scenario.dock, dtype=float)
        self._obstacle_radii = self._geometry.radii[self._n_targets :]
        self._target_radii = self._geometry.radii[: self._n_targets]

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode.

        Args:
            seed: seeds the env's generator (and so the random field).
            options: ``{"scenario": Scenario | dict | path}`` pins the field;
                ``{"chaser_state": array (2·dim,)}`` sets the initial LVLH state (m, m/s).
        """
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"scenario", "chaser_state"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: chaser_state, scenario")
        if options.get("scenario") is not None:
            self._set_scenario(as_scenario(options["scenario"]))
        else:
            self._set_scenario(self._new_scenario())
        d = self.dim
        if options.get("chaser_state") is not None:
            state = self._validated_chaser_state(options["chaser_state"])
        else:
            state = np.concatenate([self._dock, np.zeros(d)])
        self._state = state
        self._time = 0.0
        self._steps = 0
        self._delta_v = 0.0
        self._captured = np.zeros(self._n_targets, dtype=bool)
        self._accel = np.zeros(d)
        self._collision = False
        self._out_of_bounds = False
        self._success = False
        self._gaps = self._geometry.signed_distance(state[:d])
        self._min_clearance = float(self._gaps.min()) if self._gaps.size else math.inf
        self._trail = [state[:d].copy()]
        self._potential = self._potential_now()
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
        if self.render_mode == "human":
            self.render()
        return self._observe(), self._info(terms)

    def _validated_chaser_state(self, value: Any) -> np.ndarray:
        d = self.dim
        state = np.array(value, dtype=float).reshape(-1)
        if state.shape != (2 * d,):
            raise ValueError(f"chaser_state must have shape ({2 * d},), got {np.shape(value)}")
        if not np.all(np.isfinite(state)):
            raise ValueError("chaser_state must be finite")
        scen = self.scenario
        if np.any(state[:d] <= scen.low) or np.any(state[:d] >= scen.high):
            raise ValueError(f"chaser_state position {state[:d]} is outside the bounds {scen.bounds}")
        gap = self._geometry.signed_distance(state[:d]).min() - self.config.chaser_radius
        if gap <= 0:
            raise ValueError(f"chaser_state position {state[:d]} touches debris (gap {gap:.3g} m)")
        return state

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply one thrust command for ``dt`` seconds.

        Returns:
            observation, reward, terminated, truncated (always False: the time limit belongs to
            the ``TimeLimit`` wrapper), info.
        """
        if self.scenario is None:
            raise RuntimeError("call reset() before step()")
        accel, dv = self._thrust(action)
        hit = self._simulate(accel, dv)
        new_captures = self._update_mission(hit)
        terms = self._reward_terms(new_captures, dv)
        terminated = self._success or self._collision or self._out_of_bounds or self._budget_spent()
        if terminated:
            terms["progress"] -= self.config.reward_progress * self.config.shaping_gamma * (
                self._potential
            )  # Φ(terminal) = 0
        reward = float(sum(terms.values()))
        if self.render_mode == "human":
            self.render()
        return self._observe(), reward, terminated, False, self._info(terms)

    # --- step hooks ---------------------------------------------------------------------------

    def _thrust(self, action: Any) -> tuple[np.ndarray, float]:
        """Validated action → commanded acceleration (m/s²) and the Δv (m/s) it spends."""
        cfg, scen = self.config, self.scenario
        if cfg.action == "discrete":
            if isinstance(action, np.ndarray):
                if action.size != 1:
                    raise ValueError(f"a discrete action is one integer, got shape {action.shape}")
                action = action.reshape(()).item()
            if isinstance(action, (bool, np.bool_)) or not float(action).is_integer():
                raise ValueError(f"discrete action must be an integer in [0, {2 * self.dim}]")
            index = int(action)
            if not 0 <= index <= 2 * self.dim:
                raise ValueError(f"discrete action {index} is outside [0, {2 * self.dim}]")
            a = self._discrete_actions[index]
        else:
            a = np.asarray(action, dtype=float)
            if a.shape != (self.dim,):
                raise ValueError(f"action must have shape ({self.dim},), got {a.shape}")
            if not np.isfinite(a).all():
                raise ValueError(f"action must be finite (no NaN or inf), got {a}")
        accel = commanded_accel(a, scen.max_accel, cfg.thrust_model)
        dv = float(delta_v_rate(accel, cfg.thrust_model)) * scen.dt
        budget = cfg.delta_v_budget
        if budget is not None and dv > 0.0 and self._delta_v + dv > budget:
            # The last burn is cut so the total spent is exactly the budget.
            scale = max(budget - self._delta_v, 0.0) / dv
            accel, dv = accel * scale, dv * scale
        return accel, dv

    def _simulate(self, accel: np.ndarray, dv: float) -> int:
        """Propagate one step exactly and sweep the path; returns the first body hit or -1."""
        d = self.dim
        start = self._state
        stacked = np.concatenate([start, accel])
        path = np.empty((self.config.collision_substeps + 1, d))
        path[0] = start[:d]
        path[1:] = (self._sub_positions @ stacked).reshape(-1, d)
        self._state = self._model.step(start, accel)
        self._time += self.scenario.dt
        self._steps += 1
        self._delta_v += dv
        self._accel = accel
        self._trail.append(self._state[:d].copy())
        return self._geometry.first_hit(path)

    def _update_mission(self, hit: int) -> int:
        """Update captures, collision, bounds and success; return the number of new captures."""
        cfg, d = self.config, self.dim
        pos, vel = self._state[:d], self._state[d:]
        self._gaps = gaps = self._geometry.signed_distance(pos)
        if gaps.size:
            self._min_clearance = min(self._min_clearance, float(gaps.min()))
        speed = math.sqrt(float(vel @ vel))  # targets are at rest in LVLH (frozen field)
        new = 0
        if speed <= cfg.capture_speed:
            surface_gap = gaps[: self._n_targets] - cfg.chaser_radius
            for i in self._eligible_targets():
                if surface_gap[i] <= cfg.capture_radius:
                    self._captured[i] = True
                    new += 1
        if hit >= 0 and (hit >= self._n_targets or speed > cfg.capture_speed):
            self._collision = True  # any debris contact, or touching a target too fast
        self._out_of_bounds = bool(
            np.any(pos <= self.scenario.low) or np.any(pos >= self.scenario.high)
        )
        if self._captured.all() and not self._collision:
            if not cfg.return_to_dock:
                self._success = True
            else:
                off = pos - self._dock
                if math.sqrt(float(off @ off)) <= cfg.capture_radius and speed <= cfg.capture_speed:
                    self._success = True
        return new

    def _eligible_targets(self) -> list[int]:
        """Targets that can be captured now: all uncaptured, or the queue head if queued."""
        remaining = np.flatnonzero(~self._captured)
        if self.config.target_order == "queued":
            return [int(remaining[0])] if remaining.size else []
        return [int(i) for i in remaining]

    def _budget_spent(self) -> bool:
        budget = self.config.delta_v_budget
        return budget is not None and self._delta_v >= budget

    def _current_goal(self) -> tuple[float, int]:
        """(gap (m) to the current goal, number of goals after it)."""
        cfg, d = self.config, self.dim
        remaining = np.flatnonzero(~self._captured)
        dock_goal = 1 if cfg.return_to_dock else 0
        if remaining.size:
            surface = self._gaps[remaining] - cfg.chaser_radius
            k = 0 if cfg.target_order == "queued" else int(np.argmin(surface))
            return max(float(surface[k]), 0.0), remaining.size - 1 + dock_goal
        if dock_goal:
            off = self._state[:d] - self._dock
            return math.sqrt(float(off @ off)), 0
        return 0.0, 0

    def _potential_now(self) -> float:
        gap, after = self._current_goal()
        return potential(gap, after, self._length_scale)

    def _reward_terms(self, new_captures: int, dv: float) -> dict[str, float]:
        cfg = self.config
        phi = self._potential_now()
        progress = cfg.shaping_gamma * phi - self._potential
        self._potential = phi
        return {
            "capture": cfg.reward_capture * new_captures,
            "success": cfg.reward_success * self._success,
            "progress": cfg.reward_progress * progress,
            "delta_v": -cfg.reward_delta_v * dv,
            "collision": -cfg.reward_collision * self._collision,
            "out_of_bounds": -cfg.reward_out_of_bounds * self._out_of_bounds,
            "time": -cfg.reward_time,
        }

    def _observe(self) -> np.ndarray:
        cfg, d = self.config, self.dim
        L, V = self._length_scale, self._speed_scale
        pos, vel = self._state[:d], self._state[d:]
        parts = [pos / L, vel / V]
        parts.append(self._target_slots(pos, vel).ravel())
        parts.append((self._dock - pos) / L)
        if cfg.observation == "kinematics":
            parts.append(self._obstacle_slots(pos).ravel())
        else:
            ranges = self._geometry.lidar(pos, self._lidar_dirs, cfg.lidar_range)
            parts.append(ranges / cfg.lidar_range)
        budget = cfg.delta_v_budget
        dv_left = 1.0 if budget is None else max(budget - self._delta_v, 0.0) / budget
        horizon = self._horizon_steps()
        parts.append(np.array([dv_left, max(horizon - self._steps, 0) / horizon]))
        obs = np.concatenate(parts)
        np.clip(obs, -OBS_LIMIT, OBS_LIMIT, out=obs)
        return obs.astype(np.float32)

    def _horizon_steps(self) -> int:
        spec = self.spec
        if spec is not None and spec.max_episode_steps:
            return int(spec.max_episode_steps)
        return DEFAULT_HORIZON_STEPS

    def _target_slots(self, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """K × (rel pos, rel vel, radius, captured): goals first (queue order or nearest)."""
        cfg, d = self.config, self.dim
        L, V = self._length_scale, self._speed_scale
        slots = np.zeros((cfg.obs_targets, 2 * d + 2))
        slots[:, -1] = 1.0  # empty slots read as "captured"
        remaining = np.flatnonzero(~self._captured)
        if cfg.target_order == "any" and remaining.size > 1:
            remaining = remaining[np.argsort(self._gaps[remaining], kind="stable")]
        order = np.concatenate([remaining, np.flatnonzero(self._captured)])[: cfg.obs_targets]
        centres = self._geometry.centers[order]
        slots[: order.size, :d] = (centres - pos) / L
        slots[: order.size, d : 2 * d] = -vel / V  # target velocity (0, frozen) minus chaser's
        slots[: order.size, 2 * d] = self._target_radii[order] / L
        slots[: order.size, 2 * d + 1] = self._captured[order]
        return slots

    def _obstacle_slots(self, pos: np.ndarray) -> np.ndarray:
        """M nearest obstacles × (rel pos, radius, gap); empty slots: zero offset, gap 1."""
        cfg, d = self.config, self.dim
        L = self._length_scale
        m = cfg.obs_obstacles
        slots = np.zeros((m, d + 2))
        slots[:, -1] = 1.0
        gaps = self._gaps[self._n_targets :]
        if gaps.size and m:
            k = min(m, gaps.size)
            nearest = np.argpartition(gaps, k - 1)[:k] if gaps.size > k else np.arange(gaps.size)
            nearest = nearest[np.argsort(gaps[nearest], kind="stable")]
            centres = self._geometry.centers[self._n_targets + nearest]
            slots[:k, :d] = (centres - pos) / L
            slots[:k, d] = self._obstacle_radii[nearest] / L
            slots[:k, d + 1] = gaps[nearest] / L
        return slots

    def _info(self, terms: dict[str, float]) -> dict[str, Any]:
        return {
            "chaser_state": self._state.copy(),
            "time": self._time,
            "delta_v": self._delta_v,
            "targets_captured": int(self._captured.sum()),
            "n_targets": self._n_targets,
            "captured": self._captured.copy(),
            "min_clearance": self._min_clearance - self.config.chaser_radius,
            "collision": self._collision,
            "out_of_bounds": self._out_of_bounds,
            "is_success": self._success,
            "reward_terms": terms,
        }

    # --- rendering ----------------------------------------------------------------------------

    def render(self) -> np.ndarray | None:
        """Draw the field: ``rgb_array`` returns an (H, W, 3) uint8 image, ``human`` shows it."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        if self.scenario is None:
            raise RuntimeError("call reset() before render()")
        from debris_gym.envs.rendering import Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        frame = self._renderer.draw(
            scenario=self.scenario,
            chaser_state=self._state,
            captured=self._captured,
            trail=np.asarray(self._trail),
            accel=self._accel,
            time=self._time,
            delta_v=self._delta_v,
        )
        return frame if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
