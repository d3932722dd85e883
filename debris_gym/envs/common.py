"""What the single env and the native vector env share: spaces, fields, the observation names
(:func:`observation_names`, from :mod:`debris_gym.observation`'s table of slots)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from debris_gym.config import EnvConfig
from debris_gym.generators import FieldSpec, placement_problem
from debris_gym.observation import OBS_LIMIT, observation_names
from debris_gym.scenario import Scenario
from debris_gym.scenario_values import known_keys

__all__ = [
    "DEFAULT_HORIZON_STEPS",
    "MISSION_KEYS",
    "RESET_OPTIONS",
    "checked_chaser_states",
    "checked_continuous_actions",
    "checked_discrete_action",
    "checked_mission",
    "checked_reset_options",
    "checked_seed",
    "discrete_action_table",
    "field_spec",
    "observation_names",
    "real_array",
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
    if cfg.action != "discrete":  # "continuous", "residual"
        act_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(cfg.dim,), dtype=np.float32)
    else:
        act_space = spaces.Discrete(len(discrete_action_table(cfg.dim, cfg.fine_thrust)))
    return obs_space, act_space


def discrete_action_table(dim: int, fine_thrust: float = 0.0) -> np.ndarray:
    """Row k = normalised thrust of discrete action k: coast, +x, −x, +y, −y (, +z, −z) at
    full thrust, then (when ``fine_thrust`` > 0) the same directions at ``fine_thrust`` of it:
    the levels that let a discrete agent match a target's velocity finely enough to capture."""
    levels = (1.0, fine_thrust) if fine_thrust > 0.0 else (1.0,)
    table = np.zeros((2 * dim * len(levels) + 1, dim))
    for level, thrust in enumerate(levels):
        for axis in range(dim):
            table[1 + 2 * dim * level + 2 * axis, axis] = thrust
            table[2 + 2 * dim * level + 2 * axis, axis] = -thrust
    return table


FIELD_KEYS = (
    "field_size",
    "n_targets",
    "n_obstacles",
    "target_radius_min",
    "obstacle_radius_min",
    "min_gap",
    "capture_radius",
    "chaser_radius",
)
"""The options that decide whether a random field can be placed at all."""


FIELD_HORIZON_STEPS = 1000
"""Steps over which a random moving field is checked (the v1 IDs' time limit); a drift-free
field repeats every orbit and is checked over at least one, so it stays valid for ever."""


def field_spec(cfg: EnvConfig) -> FieldSpec:
    """Generator settings of the random fields an env with ``cfg`` draws.

    Raises:
        ValueError: for a random-field env whose fields cannot be placed reliably
            (:func:`~debris_gym.generators.placement_problem`), naming the options that decide
            it, before any draw.
    """
    spec = _field_spec(cfg)
    why = placement_problem(spec, cfg.capture_radius) if cfg.scenario == "random" else None
    if why is not None:
        settings = ", ".join(f"{key}={getattr(cfg, key)!r}" for key in FIELD_KEYS)
        raise ValueError(
            f"these options ask for random fields the generator cannot place: {why} (a target's "
            "dock distance is max(0.15 · field_size, 5 · capture_radius), an obstacle's max(0.05 · "
            f"field_size, 5 · capture_radius)); options: {settings}. Raise field_size or "
            "lower capture_radius, min_gap or the smallest radii"
        )
    return spec


def _field_spec(cfg: EnvConfig) -> FieldSpec:
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
        motion=cfg.debris_motion,
        mean_motion=cfg.n,
        horizon=FIELD_HORIZON_STEPS * cfg.dt,
        drift_offset=(cfg.drift_offset_min, cfg.drift_offset_max),
        rho_max=cfg.field_size / 4.0,
        spin_max=cfg.spin_max,
    )


def check_motion_matches(cfg: EnvConfig, scenario: Scenario) -> None:
    """A pinned field's motion must be the env's: a moving (``"cwh"``) field in an env whose
    ``debris_motion`` is "frozen" (a v0 ID), or a frozen field in a moving-world env (a v1
    ID), would be flown by the other world's rules.

    Raises:
        ValueError: naming the scenario's ``motion`` and the env's ``debris_motion``.
    """
    env_moving = cfg.debris_motion != "frozen"
    if scenario.moving != env_moving:
        raise ValueError(
            f"the pinned scenario has motion={scenario.motion!r} but the env has "
            f"debris_motion={cfg.debris_motion!r}; fly a 'cwh' scenario in a moving-world env "
            "(the v1 IDs) and a 'frozen' one in a frozen-world env (the v0 IDs)"
        )


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


# --- user input at reset and step: one check each, shared by the single and the vector env ---

RESET_OPTIONS = ("chaser_state", "mission", "scenario", "start")
"""Keys ``reset(options=...)`` accepts."""

MISSION_KEYS = ("n_targets", "n_obstacles", "return_to_dock")
"""Config keys ``reset(options={"mission": {...}})`` may change: what a mission asks and how
cluttered its field is, never the physics, the rules of capture, the reward weights or the
spaces — so a curriculum can move a running learner between difficulty rungs."""


def checked_mission(made: EnvConfig, mission: Any) -> EnvConfig:
    """The config of a ``{"mission": {...}}`` reset option: ``made`` (the env's config as made)
    with the :data:`MISSION_KEYS` the option names replaced.

    An empty dict gives ``made`` back (the env's own mission again).

    The observation's size never depends on these keys (the target slots are
    ``obs_targets``, the obstacle slots ``obs_obstacles``), so the spaces stay.

    Raises:
        ValueError: naming the key: a key outside :data:`MISSION_KEYS`, a value out of its
            range, or a field that cannot be placed.
    """
    known_keys(
        mission, "options['mission']", MISSION_KEYS,
        unknown="{key} may change only {allowed}; got {names} (the other options are the "
        "env's own: make another env to change them)",
    )  # fmt: skip
    if not mission:
        return made
    config = EnvConfig.from_kwargs(**{**made.to_dict(), **mission})
    if made.scenario == "random":
        field_spec(config)  # raises naming the options when such a field cannot be placed
    return config


def checked_seed(seed: Any, name: str = "seed") -> int | None:
    """A reset seed: None or a whole number >= 0 (Python or numpy integer, not a bool)."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= 0 or None, got {seed!r}")
    if seed < 0:
        raise ValueError(f"{name}={seed} is out of range; allowed: an integer >= 0 or None")
    return int(seed)


def checked_reset_options(options: Any) -> dict[str, Any]:
    """``reset``'s ``options`` as a dict, checked for unknown keys (None gives ``{}``)."""
    if options is None:
        return {}
    unknown = "unknown reset option(s) {names}; allowed: {allowed}"
    known_keys(options, "options", RESET_OPTIONS, unknown=unknown)
    return dict(options)


def real_array(value: Any, name: str) -> np.ndarray:
    """``value`` as an array of real numbers (integer or floating dtype).

    Raises:
        ValueError: naming ``name`` for a masked array (its mask would be dropped), complex
            numbers (the imaginary part would be dropped), strings, booleans, objects or
            ragged nesting (each would be silently coerced or fail later).
    """
    if isinstance(value, np.ma.MaskedArray):
        raise ValueError(f"{name} must be a plain array of real numbers, got a masked array")
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as err:  # ragged nesting
        raise ValueError(f"{name} must be an array of real numbers, got {value!r}") from err
    if array.dtype.kind not in "iuf":
        raise ValueError(
            f"{name} must be real numbers (integer or float dtype), got {value!r} "
            f"(dtype {array.dtype})"
        )
    return array


_FLOAT_TYPES = (np.dtype(np.float32), np.dtype(np.float64))
_SMALL = 16
"""Actions of at most this many elements are checked element by element (faster than numpy's
reductions for one env's action)."""


def checked_continuous_actions(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Continuous actions as float64 of ``shape``: real, finite, any magnitude (the thrust
    model saturates them, :func:`debris_gym.thrust.thrust_row`).

    Raises:
        ValueError: naming ``action`` (wrong type, shape, NaN or inf).
    """
    if type(value) is np.ndarray and value.dtype in _FLOAT_TYPES and value.shape == shape:
        # the common case, a float array of the right shape: only finiteness to check
        a = value.astype(np.float64)
        if a.size <= _SMALL and all(map(math.isfinite, a.ravel().tolist())):
            return a
    a = real_array(value, "action").astype(float, copy=False)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(
            f"action must be finite (no NaN or inf); got {a[tuple(bad)]} at index "
            f"{tuple(bad.tolist())}"
        )
    return a


def checked_discrete_action(value: Any, n_actions: int) -> int:
    """One discrete action index in [0, n_actions − 1]: an integer, a whole float or a
    one-element array of either (as gymnasium's ``Discrete.sample()`` gives).

    Raises:
        ValueError: naming ``action``.
    """
    last = n_actions - 1
    allowed = f"an integer in [0, {last}]"
    a = real_array(value, "action")
    if a.size != 1:
        raise ValueError(f"a discrete action is one integer ({allowed}), got shape {a.shape}")
    number = a.reshape(()).item()
    if not (math.isfinite(number) and float(number).is_integer()):
        raise ValueError(f"discrete action must be {allowed}, got {value!r}")
    index = int(number)
    if not 0 <= index <= last:
        raise ValueError(f"discrete action {index} is outside [0, {last}]; allowed: {allowed}")
    return index


def checked_chaser_states(
    value: Any,
    num: int,
    low: np.ndarray,
    high: np.ndarray,
    max_speed: float,
    gaps: Callable[[np.ndarray], np.ndarray],
    chaser_radius: float,
) -> np.ndarray:
    """Initial chaser states from ``reset(options={"chaser_state": ...})``, shape (num, 2·dim).

    Args:
        value: (2·dim,) one state for every env, or (num, 2·dim) one per env: LVLH position
            (m) and velocity (m/s).
        num: number of envs.
        low, high: (dim,) world bounds of the field(s) the states start in (m).
        max_speed: largest speed allowed (m/s): the world's size over ``dt`` (a faster
            chaser crosses the whole world in one step).
        gaps: positions (num, dim) -> signed distances (num, bodies) to each env's bodies (m).
        chaser_radius: the chaser's radius (m).

    Raises:
        ValueError: naming ``chaser_state``, the value and what is allowed: real numbers,
            finite, strictly inside the bounds, speed at most ``max_speed``, clear of debris.
    """
    d = len(low)
    states = real_array(value, "chaser_state").astype(float)
    if states.shape == (2 * d,):
        states = np.broadcast_to(states, (num, 2 * d)).copy()
    if states.shape != (num, 2 * d):
        expected = f"({2 * d},)" if num == 1 else f"({num}, {2 * d}) or ({2 * d},)"
        raise ValueError(f"chaser_state must have shape {expected}, got {np.shape(value)}")
    which = (lambda i: "") if num == 1 else (lambda i: f" of sub-env {i}")
    finite = np.isfinite(states).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"chaser_state{which(i)} must be finite, got {states[i]}")
    pos, vel = states[:, :d], states[:, d:]
    outside = np.any(pos <= low, axis=1) | np.any(pos >= high, axis=1)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        bounds = tuple(zip(np.asarray(low).tolist(), np.asarray(high).tolist()))
        raise ValueError(
            f"chaser_state{which(i)} position {pos[i]} is outside the bounds {bounds}; "
            "allowed: strictly inside them (m)"
        )
    with np.errstate(over="ignore"):  # a speed beyond float range is inf: too fast
        speed = np.sqrt((vel**2).sum(axis=1))
    fast = ~(speed <= max_speed)
    if fast.any():
        i = int(np.flatnonzero(fast)[0])
        raise ValueError(
            f"chaser_state{which(i)} velocity {vel[i]} (speed {speed[i]:.6g} m/s) is too "
            f"fast; allowed: speed <= {max_speed:.6g} m/s (the world's size over dt)"
        )
    clear = gaps(pos).min(axis=1, initial=math.inf) - chaser_radius
    touching = ~(clear > 0.0)
    if touching.any():
        i = int(np.flatnonzero(touching)[0])
        raise ValueError(
            f"chaser_state{which(i)} position {pos[i]} touches debris (gap {clear[i]:.3g} m); "
            "allowed: a gap > 0 to every body"
        )
    return states
