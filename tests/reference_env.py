"""Reference implementation of the DebrisField rules (the pre-compiled single env), for tests.

Independent of the code under test where a shared mistake would hide: the observation layout
(names and order) and the clip limit are written out here by hand from docs/environments.md,
and the reference draws no fields (a test pins the field the env drew, so the library's field
generator is not part of the reference).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize, substep_position_matrix
from debris_gym.geometry import lidar_directions
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.thrust import commanded_accel, delta_v_rate
from tests.geometry_oracle import OracleField

OBS_LIMIT = 10.0
"""Observations are clipped to ±10 (docs/environments.md)."""


def reference_observation_names(cfg: EnvConfig) -> list[str]:
    """The observation's element names, in order, as docs/environments.md lists them."""
    axes = "xyz"[: cfg.dim]
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
    if cfg.obs_goal:
        names += [f"goal_rel_pos_{a}" for a in axes] + [f"goal_rel_vel_{a}" for a in axes]
        names += ["goal_gap"]
    return names


def reference_discrete_actions(dim: int) -> np.ndarray:
    """Row k = normalised thrust of discrete action k: coast, +x, −x, +y, −y (, +z, −z)."""
    table = np.zeros((2 * dim + 1, dim))
    for axis in range(dim):
        table[1 + 2 * axis, axis], table[2 + 2 * axis, axis] = 1.0, -1.0
    return table


class ReferenceDebrisFieldEnv(gym.Env):
    """The rules of docs/environments.md, one env at a time, in plain numpy and pymunk.

    The independent reference the compiled step is tested against
    (``tests/test_mission_batch.py``): one env at a time, in plain Python, with the tests' own
    geometry (:class:`tests.geometry_oracle.OracleField`: pymunk in 2D, closed forms for
    spheres) instead of the library's compiled one.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 15}

    def __init__(self, render_mode: str | None = None, horizon: int = 1000, **kwargs: Any) -> None:
        self.config = EnvConfig.from_kwargs(**kwargs)
        if self.config.obs_goal or self.config.obs_other_targets:
            raise ValueError("the reference has no obs_goal / obs_other_targets observations")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.dim = d = cfg.dim
        self._obs_names = reference_observation_names(cfg)
        size = len(self._obs_names)
        self.observation_space = spaces.Box(-OBS_LIMIT, OBS_LIMIT, (size,), dtype=np.float32)
        if cfg.action == "continuous":
            self.action_space = spaces.Box(-1.0, 1.0, shape=(d,), dtype=np.float32)
        else:
            self.action_space = spaces.Discrete(2 * d + 1)
        self._discrete_actions = reference_discrete_actions(d)
        lidar = cfg.observation == "lidar"
        self._lidar_dirs = lidar_directions(d, cfg.lidar_rays) if lidar else None
        self.scenario: Scenario | None = None
        self._horizon = horizon
        """Steps the time-remaining element counts down from."""
        self._renderer = None

    # --- observation layout -------------------------------------------------------------------

    @property
    def chaser_state(self) -> np.ndarray:
        """Current chaser LVLH state [position (m), velocity (m/s)] (a copy)."""
        return self._state.copy()

    @property
    def captured(self) -> np.ndarray:
        """Per-target capture flags (a copy), in scenario target order."""
        return self._captured.copy()

    @property
    def elapsed(self) -> float:
        """Simulated time since reset (s)."""
        return self._time

    @property
    def trail(self) -> np.ndarray:
        """Chaser positions at every step end so far, shape (steps + 1, dim) (m)."""
        return np.asarray(self._trail)

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order."""
        return list(self._obs_names)

    # --- scenario -----------------------------------------------------------------------------

    def _set_scenario(self, scenario: Scenario) -> None:
        cfg = self.config
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")
        self.scenario = scenario
        self._geometry = OracleField(scenario, inflate=cfg.chaser_radius)
        model = discretize(scenario.mean_motion, scenario.dt, self.dim)
        sub_positions = substep_position_matrix(
            scenario.mean_motion, scenario.dt, self.dim, cfg.collision_substeps
        )
        # One matrix maps [x₀, u] to the K sub-step positions (the last is the end position)
        # followed by the end velocity: a single matmul per step gives the path and the new state.
        end_velocity = np.hstack([model.ad[self.dim :], model.bd[self.dim :]])
        self._step_matrix = np.vstack([sub_positions, end_velocity])
        self._n_targets = len(scenario.targets)
        self._length_scale = scenario.size / 2.0
        self._speed_scale = math.sqrt(scenario.max_accel * self._length_scale)
        self._dock = np.asarray(scenario.dock, dtype=float)
        self._low, self._high = scenario.low, scenario.high
        self._obstacle_radii = self._geometry.radii[self._n_targets :]
        self._obstacle_centers = self._geometry.centers[self._n_targets :]
        self._obs_buffer = np.zeros(self.observation_space.shape[0])
        self._target_radii = self._geometry.radii[: self._n_targets]

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode.

        Args:
            seed: seeds the env's generator.
            options: ``{"scenario": Scenario | dict | path}`` the field (required);
                ``{"chaser_state": array (2·dim,)}`` sets the initial LVLH state (m, m/s).
        """
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"scenario", "chaser_state"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: chaser_state, scenario")
        if options.get("scenario") is None:
            raise ValueError(
                "the reference draws no fields: pin one with options={'scenario': ...}"
            )
        self._set_scenario(as_scenario(options["scenario"]))
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
        self._path = np.empty((self.config.collision_substeps + 1, d))
        self._gaps = self._geometry.point_gaps(state[:d])
        obstacle_gaps = self._gaps[self._n_targets :]
        self._min_clearance = float(obstacle_gaps.min()) if obstacle_gaps.size else math.inf
        self._trail = [state[:d].copy()]
        self._potential = self._potential_now()
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
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
            raise ValueError(
                f"chaser_state position {state[:d]} is outside the bounds {scen.bounds}"
            )
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
        touched = self._simulate(accel, dv)
        new_captures = self._update_mission(touched)
        terms = self._reward_terms(new_captures, dv)
        terminated = self._success or self._collision or self._out_of_bounds or self._budget_spent()
        if terminated and self.config.shaping_terminal == "zero":
            terms["progress"] -= (
                self.config.reward_progress * self.config.shaping_gamma * (self._potential)
            )  # Φ(terminal) = 0
        reward = float(sum(terms.values()))
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
            if not math.isfinite(a.sum()):  # NaN or ±inf anywhere makes the sum non-finite
                raise ValueError(f"action must be finite (no NaN or inf), got {a}")
        accel = commanded_accel(a, scen.max_accel, cfg.thrust_model)
        dv = float(delta_v_rate(accel, cfg.thrust_model)) * scen.dt
        budget = cfg.delta_v_budget
        if budget is not None and dv > 0.0 and self._delta_v + dv > budget:
            # The last burn is cut so the total spent is exactly the budget.
            scale = max(budget - self._delta_v, 0.0) / dv
            accel, dv = accel * scale, dv * scale
        return accel, dv

    def _simulate(self, accel: np.ndarray, dv: float) -> list[int]:
        """Propagate one step exactly and sweep the path; returns the bodies it touched."""
        d = self.dim
        self._start_state = start = self._state
        out = self._step_matrix @ np.concatenate([start, accel])
        path = self._path
        path[0] = start[:d]
        path[1:] = out[:-d].reshape(-1, d)
        self._state = np.concatenate([path[-1], out[-d:]])
        self._time += self.scenario.dt
        self._steps += 1
        self._delta_v += dv
        self._accel = accel
        self._trail.append(path[-1].copy())
        return self._geometry.touched(path, self._gaps)

    def _update_mission(self, touched: list[int]) -> int:
        """Update captures, collision, bounds and success; return the number of new captures."""
        cfg, d = self.config, self.dim
        pos, vel = self._state[:d], self._state[d:]
        self._gaps = gaps = self._geometry.point_gaps(pos)
        if gaps.size > self._n_targets:  # clearance to debris other than targets
            self._min_clearance = min(self._min_clearance, float(gaps[self._n_targets :].min()))
        speed = math.sqrt(float(vel @ vel))  # targets are at rest in LVLH (frozen field)
        new = 0
        if speed <= cfg.capture_speed:
            reach = cfg.capture_radius + cfg.chaser_radius
            for i in self._eligible_targets():
                if gaps[i] <= reach:
                    self._captured[i] = True
                    new += 1
        if touched:
            if touched[-1] >= self._n_targets:
                self._collision = True  # any contact with debris that is not a target
            elif speed > cfg.capture_speed:
                # touching a target too fast, unless the chaser is leaving it: moving away from
                # its centre at both ends of the step and over the step as a whole
                centres = self._geometry.centers[touched]
                start = self._start_state
                toward = centres - start[:d]
                closing = (toward @ start[d:] > 0.0) | ((centres - pos) @ vel > 0.0)
                closing |= toward @ (pos - start[:d]) > 0.0
                self._collision = bool(closing.any())
        self._out_of_bounds = bool((pos <= self._low).any() or (pos >= self._high).any())
        if not self._collision and self._captured.all():
            if not cfg.return_to_dock:
                self._success = True
            else:
                off = pos - self._dock
                if math.sqrt(float(off @ off)) <= cfg.capture_radius and speed <= cfg.capture_speed:
                    self._success = True
        return new

    def _eligible_targets(self) -> list[int]:
        """Targets that can be captured now: all uncaptured, or the queue head if queued."""
        remaining = [i for i, c in enumerate(self._captured.tolist()) if not c]
        return remaining[:1] if self.config.target_order == "queued" else remaining

    def _budget_spent(self) -> bool:
        budget = self.config.delta_v_budget
        return budget is not None and self._delta_v >= budget

    def _current_goal(self) -> tuple[float, int]:
        """(gap (m) to the current goal, number of goals after it)."""
        cfg, d = self.config, self.dim
        remaining = self._eligible_targets()
        dock_goal = 1 if cfg.return_to_dock else 0
        if remaining:
            gaps = self._gaps
            gap = min(float(gaps[i]) for i in remaining) - cfg.chaser_radius
            left = self._n_targets - int(self._captured.sum())
            return max(gap, 0.0), left - 1 + dock_goal
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
        return reward_terms(
            cfg,
            new_captures=new_captures,
            success=self._success,
            progress=progress,
            delta_v=dv,
            collision=self._collision,
            out_of_bounds=self._out_of_bounds,
            budget_spent=self._budget_failure(),
        )

    def _budget_failure(self) -> bool:
        """The Δv budget ran out in a step that neither succeeded, collided nor left the
        bounds: the mission failed for want of Δv."""
        failed_otherwise = self._success or self._collision or self._out_of_bounds
        return self._budget_spent() and not failed_otherwise

    def _observe(self) -> np.ndarray:
        cfg, d = self.config, self.dim
        L, V = self._length_scale, self._speed_scale
        pos, vel = self._state[:d], self._state[d:]
        obs = self._obs_buffer
        obs[:d] = pos / L
        obs[d : 2 * d] = vel / V
        k = 2 * d
        width = cfg.obs_targets * (2 * d + 2)
        self._fill_target_slots(obs[k : k + width].reshape(cfg.obs_targets, 2 * d + 2), pos, vel)
        k += width
        obs[k : k + d] = (self._dock - pos) / L
        k += d
        if cfg.observation == "kinematics":
            width = cfg.obs_obstacles * (d + 2)
            self._fill_obstacle_slots(obs[k : k + width].reshape(cfg.obs_obstacles, d + 2), pos)
        else:
            width = cfg.lidar_rays
            ranges = self._geometry.lidar(pos, self._lidar_dirs, cfg.lidar_range)
            obs[k : k + width] = ranges / cfg.lidar_range
        k += width
        budget = cfg.delta_v_budget
        obs[k] = 1.0 if budget is None else max(budget - self._delta_v, 0.0) / budget
        horizon = self._horizon
        obs[k + 1] = max(horizon - self._steps, 0) / horizon
        np.minimum(obs, OBS_LIMIT, out=obs)
        np.maximum(obs, -OBS_LIMIT, out=obs)
        return obs.astype(np.float32)

    def _fill_target_slots(self, slots: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """K × (rel pos, rel vel, radius, captured): goals first (queue order or nearest)."""
        d = self.dim
        L, V = self._length_scale, self._speed_scale
        captured = self._captured.tolist()
        remaining = [i for i, c in enumerate(captured) if not c]
        if self.config.target_order == "any" and len(remaining) > 1:
            remaining.sort(key=self._gaps[: self._n_targets].tolist().__getitem__)
        order = (remaining + [i for i, c in enumerate(captured) if c])[: len(slots)]
        m = len(order)
        slots[m:] = 0.0
        slots[m:, -1] = 1.0  # empty slots read as "captured"
        if m:
            slots[:m, :d] = (self._geometry.centers[order] - pos) / L
            slots[:m, d : 2 * d] = -vel / V  # target velocity (0, frozen) minus chaser's
            slots[:m, 2 * d] = self._target_radii[order] / L
            slots[:m, 2 * d + 1] = [captured[i] for i in order]

    def _fill_obstacle_slots(self, slots: np.ndarray, pos: np.ndarray) -> None:
        """M nearest obstacles × (rel pos, radius, gap); empty slots: zero offset, gap 1."""
        d = self.dim
        L = self._length_scale
        gaps = self._gaps[self._n_targets :]
        k = min(len(slots), gaps.size)
        slots[k:] = 0.0
        slots[k:, -1] = 1.0
        if k:
            if gaps.size > k:
                nearest = np.argpartition(gaps, k - 1)[:k]
                nearest = nearest[np.argsort(gaps[nearest])]
            else:
                nearest = np.argsort(gaps)
            slots[:k, :d] = (self._obstacle_centers[nearest] - pos) / L
            slots[:k, d] = self._obstacle_radii[nearest] / L
            slots[:k, d + 1] = gaps[nearest] / L

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
            "budget_spent": self._budget_failure(),
            # one step end captures in this rule set, so a target's count is 1 once captured
            "hold": self._captured.astype(np.int64),
            "is_success": self._success,
            "reward_terms": terms,
        }


def potential(goal_gap: float, goals_after: int, length_scale: float) -> float:
    """Shaping potential Φ(s) = −(gap to the current goal / length_scale + goals after it).

    Args:
        goal_gap: distance (m) from the chaser to the current goal (a target's surface, or the
            dock); 0 when no goal is left.
        goals_after: number of goals still to visit after the current one (targets, plus the dock
            if a return is required), so that completing a goal raises Φ by about 1.
        length_scale: normalising length (m), e.g. half the field size.
    """
    return -(goal_gap / length_scale + goals_after)


def reward_terms(
    cfg: EnvConfig,
    *,
    new_captures: Any,
    success: Any,
    progress: Any,
    delta_v: Any,
    collision: Any,
    out_of_bounds: Any,
    budget_spent: Any = False,
) -> dict[str, Any]:
    """The weighted reward terms of one step, for one env (scalars) or a batch (arrays).

    Args:
        cfg: weights ``reward_<term>``.
        new_captures: targets captured this step.
        success, collision, out_of_bounds, budget_spent: this step's flags.
        progress: γΦ(s′) − Φ(s) (before the terminal correction).
        delta_v: Δv spent this step (m/s).
    """
    time = np.full(np.shape(delta_v), -cfg.reward_time) if np.ndim(delta_v) else -cfg.reward_time
    return {
        "capture": cfg.reward_capture * new_captures,
        "success": cfg.reward_success * success,
        "progress": cfg.reward_progress * progress,
        "delta_v": -cfg.reward_delta_v * delta_v,
        "collision": -cfg.reward_collision * collision,
        "out_of_bounds": -cfg.reward_out_of_bounds * out_of_bounds,
        "time": time,
        "budget": -cfg.reward_budget * budget_spent,
    }
