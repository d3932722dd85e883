"""What the single env and the native vector env share: spaces, fields, the observation names
(:func:`observation_names`, from :mod:`debris_gym.observation`'s table of slots)."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from debris_gym.config import EnvConfig
from debris_gym.generators import FieldSpec, paper_field, random_field
from debris_gym.observation import OBS_LIMIT, observation_names
from debris_gym.scenario import Scenario

__all__ = [
    "DEFAULT_HORIZON_STEPS",
    "discrete_action_table",
    "field_spec",
    "new_scenario",
    "observation_names",
    "registered_horizon",
    "single_spaces",
    "warn_if_physics_differ",
]

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
    """The field an env draws on reset: the [APF-MPC] world, or a random field from ``rng``."""
    if cfg.scenario == "paper":
        return paper_field(dt=cfg.dt, max_accel=cfg.max_accel)
    return random_field(
        rng, spec, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel,
        capture_radius=cfg.capture_radius,
    )  # fmt: skip


PHYSICS_DIFFER = "the pinned scenario's physics differ from the env's options"
"""Start of the warning :func:`warn_if_physics_differ` gives (for filters)."""


def warn_if_physics_differ(cfg: EnvConfig, scenario: Scenario) -> None:
    """Warn (``UserWarning``) when a pinned scenario's ``mean_motion``, ``dt`` or ``max_accel``
    differ from the env's options.

    A pinned scenario is flown with its own physics (docs/environments.md, Options): a saved
    field keeps the physics it was made with. A hand-built :class:`Scenario` whose physics were
    left at their defaults (free space, ``mean_motion=0``) would then silently fly in free space
    in a LEO env; the warning names every differing parameter with both values.
    """
    ours = {"mean_motion": cfg.n, "dt": cfg.dt, "max_accel": cfg.max_accel}
    differ = [
        f"{name} {getattr(scenario, name)!r} (env {value!r})"
        for name, value in ours.items()
        if not math.isclose(getattr(scenario, name), value, rel_tol=1e-9, abs_tol=0.0)
    ]
    if differ:
        warnings.warn(
            f"{PHYSICS_DIFFER}: {', '.join(differ)}; the scenario's are used (build the "
            "Scenario with the env's values, or the env with the scenario's, to silence this)",
            UserWarning,
            stacklevel=3,
        )
