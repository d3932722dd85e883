"""What the single env and the native vector env share: spaces, observation layout, fields."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from debris_gym.config import EnvConfig
from debris_gym.generators import FieldSpec, paper_field, random_field
from debris_gym.mission_batch import OBS_LIMIT
from debris_gym.scenario import Scenario

DEFAULT_HORIZON_STEPS = 1000
"""Steps used for the 'time remaining' observation when the env has no registered time limit."""


def registered_horizon(spec: EnvSpec | None) -> int:
    """Episode limit (steps) the 'time remaining' observation counts down from.

    The registered ``max_episode_steps`` of the env's ID (``gym.make`` hands the unwrapped env a
    spec without it: the TimeLimit wrapper owns the limit), or :data:`DEFAULT_HORIZON_STEPS` for
    an env built directly. A limit overridden at ``make`` time truncates episodes but does not
    rescale this feature.
    """
    if spec is not None and spec.id in gym.registry:
        registered = gym.registry[spec.id].max_episode_steps
        if registered:
            return int(registered)
    return DEFAULT_HORIZON_STEPS


def observation_names(cfg: EnvConfig) -> list[str]:
    """Name of every observation element, in order (see docs/environments.md)."""
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


def single_spaces(cfg: EnvConfig) -> tuple[spaces.Box, spaces.Space]:
    """Observation and action space of one env."""
    obs_space = spaces.Box(
        -OBS_LIMIT, OBS_LIMIT, shape=(len(observation_names(cfg)),), dtype=np.float32
    )
    if cfg.action == "continuous":
        act_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(cfg.dim,), dtype=np.float32)
    else:
        act_space = spaces.Discrete(2 * cfg.dim + 1)
    return obs_space, act_space


def discrete_action_table(dim: int) -> np.ndarray:
    """Row k = normalised thrust of discrete action k: coast, +x, −x, +y, −y (, +z, −z)."""
    table = np.zeros((2 * dim + 1, dim))
    for axis in range(dim):
        table[1 + 2 * axis, axis] = 1.0
        table[2 + 2 * axis, axis] = -1.0
    return table


def field_spec(cfg: EnvConfig) -> FieldSpec:
    """Generator settings of the random fields an env with ``cfg`` draws."""
    return FieldSpec(
        dim=cfg.dim,
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


def new_scenario(cfg: EnvConfig, spec: FieldSpec, rng: np.random.Generator) -> Scenario:
    """The field an env draws on reset: seed 000's world, or a random field from ``rng``."""
    if cfg.scenario == "paper":
        return paper_field(dt=cfg.dt, max_accel=cfg.max_accel)
    return random_field(
        rng, spec, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel,
        capture_radius=cfg.capture_radius,
    )  # fmt: skip
