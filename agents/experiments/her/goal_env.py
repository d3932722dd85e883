"""A goal-conditioned view of a one-target rendezvous env, for hindsight experience replay (HER).

:class:`GoalConditionedEnv` wraps a debris-gym env with one target and no return to the dock
(``DebrisGym/Rendezvous2D-Easy-v2``, ``…3D-Easy-v2``, their v1 forms, or any env made with
``n_targets=1, return_to_dock=False``) and gives it the interface SB3's ``HerReplayBuffer``
needs: a ``Dict`` observation with ``observation`` / ``achieved_goal`` / ``desired_goal`` and a
vectorised :meth:`GoalConditionedEnv.compute_reward`. Physics, rules, termination and
truncation are the env's own; only the observation and the reward change.

Design
------
A goal is a state, ``dim`` positions, ``dim`` velocities and one radius (length ``2·dim + 1``),
in the LVLH frame and scaled as the env's observation is (positions / L, velocities / V, radius
/ L; L = half the world size, V = sqrt(max_accel · L)), so it sits beside the observation at the
same scale:

* ``achieved_goal``: the chaser's position and velocity, radius 0 (the chaser is the thing that
  achieves; its own radius is counted in the tolerance below).
* ``desired_goal``: the target's position and velocity, and the target's radius.
* ``observation``: the env's flat observation, unchanged (it still holds the real target's
  relative state in target slot 0; see *relabelled goals* below).

**Reward** (``compute_reward``), per step end: ``0`` when the chaser is within the capture zone
of the goal, that is ``|p_a − p_d| ≤ r_d + chaser_radius + capture_radius`` (m) and
``|v_a − v_d| ≤ capture_speed`` (m/s) — exactly the env's per-step capture condition (surface gap
≤ ``capture_radius``, velocity relative to the target ≤ ``capture_speed``) when the goal is the
real target; ``−1`` otherwise. A capture needs the condition held over ``capture_hold`` (4 step
ends; in v2 also within ``capture_drift`` of where the hold began, untouched); the env still
judges and terminates on it, so a successful episode ends with a run of 0 rewards. A step that
ends in a **collision, out of bounds or with the Δv budget spent** (a failure) is worth
``−crash_penalty`` whatever the goal: the penalty is read from ``info["collision"]``,
``info["out_of_bounds"]`` and ``info["budget_spent"]``, which HER passes back to
``compute_reward`` with ``copy_info_dict=True``, so it survives relabelling (otherwise a
relabelled crash, a terminal transition, would look better than flying on at −1 a step). The
default penalty, 100, is twice the value of never reaching a goal (−1 / (1 − γ) = −50 at
γ = 0.98).

**Relabelled goals.** The target moves (natural CWH motion), so the real goal changes at every
step: ``desired_goal`` is the target's state *now*. HER's ``future`` strategy replaces it by
the chaser's state at a later step of the same episode, and that goal stays fixed for the
relabelled transition: "be at this LVLH point with this velocity" — a still point of the
rotating frame, with velocity and a 6 m (``chaser_radius + capture_radius``) tolerance. A
relabelled goal is thus a reachable rendezvous state, not a body; the policy has to generalise
from still goals to the moving target (whose velocity is part of the goal, so "match this
velocity here" is what both teach). Relabelling changes only the goals: the ``observation``
keeps the real target's slot, so the critic sees the real target beside a relabelled goal and
must learn to condition on ``desired_goal``; and HER keeps the original ``done`` flags, so a
relabelled transition at the step the real target was captured stays terminal.

Only one target and no return: with more targets the goal would switch mid-episode, which this
wrapper does not model (``ValueError`` at construction).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

__all__ = ["DEFAULT_CRASH_PENALTY", "FAILURE_KEYS", "GoalConditionedEnv", "GoalLayout", "failed"]

DEFAULT_CRASH_PENALTY = 100.0
"""Reward of a step that ends in a failure (:data:`FAILURE_KEYS`) is ``-DEFAULT_CRASH_PENALTY``."""

FAILURE_KEYS = ("collision", "out_of_bounds", "budget_spent")
"""The info flags of a step that ends the episode failed: a collision, leaving the bounds, the
Δv budget spent."""


class GoalLayout:
    """Where the goals sit in an env's flat observation, and the capture tolerances.

    Built from the unwrapped debris-gym env: ``observation_names()`` gives the indices of the
    chaser's state and of target slot 0; ``config`` the scales and tolerances.

    Attributes:
        dim: 2 or 3.
        goal_size: ``2 · dim + 1``.
        length_scale: L, m (half the world size).
        speed_scale: V, m/s.
        position_tolerance: ``chaser_radius + capture_radius``, m (the target radius is added per
            goal).
        speed_tolerance: ``capture_speed``, m/s.
    """

    def __init__(self, env: gym.Env[Any, Any]) -> None:
        base = env.unwrapped
        if not hasattr(base, "observation_names") or not hasattr(base, "config"):
            raise ValueError(f"env: a debris-gym env is needed, got {type(base).__name__}")
        config = base.config
        if config.n_targets != 1 or config.return_to_dock:
            raise ValueError(
                "env: one target and no return to the dock are needed (n_targets=1, "
                f"return_to_dock=False), got n_targets={config.n_targets}, "
                f"return_to_dock={config.return_to_dock}"
            )
        if config.observation != "kinematics":
            raise ValueError(f"env: observation='kinematics' is needed, got {config.observation!r}")
        names = list(base.observation_names())
        axes = "xyz"[: config.dim]

        def indices(prefix: str) -> np.ndarray:
            return np.array([names.index(f"{prefix}_{a}") for a in axes])

        self.dim: int = int(config.dim)
        self.goal_size: int = 2 * self.dim + 1
        self.chaser_pos = indices("chaser_pos")
        self.chaser_vel = indices("chaser_vel")
        self.target_pos = indices("target0_rel_pos")
        self.target_vel = indices("target0_rel_vel")
        self.target_radius = names.index("target0_radius")
        self.obs_size: int = len(names)
        self.length_scale: float = float(config.field_size) / 2.0
        self.speed_scale: float = float(np.sqrt(config.max_accel * self.length_scale))
        self.position_tolerance: float = float(config.chaser_radius + config.capture_radius)
        self.speed_tolerance: float = float(config.capture_speed)

    def goals(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(achieved_goal, desired_goal) of flat observations ``obs`` (shape (..., obs_size)).

        Both float32, shape (..., goal_size), scaled like the observation.
        """
        obs = np.asarray(obs, dtype=np.float32)
        if obs.shape[-1:] != (self.obs_size,):
            raise ValueError(f"obs: last axis of length {self.obs_size} needed, got {obs.shape}")
        achieved = np.zeros((*obs.shape[:-1], self.goal_size), dtype=np.float32)
        d = self.dim
        achieved[..., :d] = obs[..., self.chaser_pos]
        achieved[..., d : 2 * d] = obs[..., self.chaser_vel]
        desired = achieved.copy()
        # Target slot 0 holds target − chaser position / L and velocity / V.
        desired[..., :d] += obs[..., self.target_pos]
        desired[..., d : 2 * d] += obs[..., self.target_vel]
        desired[..., 2 * d] = obs[..., self.target_radius]
        return achieved, desired

    def goal_observation(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """The Dict observation (observation, achieved_goal, desired_goal) of flat
        observation(s) ``obs``."""
        achieved, desired = self.goals(obs)
        return {
            "observation": np.asarray(obs, dtype=np.float32),
            "achieved_goal": achieved,
            "desired_goal": desired,
        }


def failed(info: Mapping[str, Any]) -> bool:
    """Whether a step's info says the episode ended failed (any of :data:`FAILURE_KEYS`)."""
    return any(bool(info.get(key, False)) for key in FAILURE_KEYS)


def _crash_flags(info: Any, batch_shape: tuple[int, ...]) -> np.ndarray:
    """Boolean array of ``batch_shape``: the step ended failed (:func:`failed`)."""
    if info is None:
        return np.zeros(batch_shape, dtype=bool)
    if isinstance(info, Mapping):
        if batch_shape != ():
            raise ValueError(
                f"info: one dict goes with one goal pair, got goals of batch shape {batch_shape}"
            )
        return np.array(failed(info))
    if isinstance(info, (Sequence, np.ndarray)) and not isinstance(info, (str, bytes)):
        infos = np.asarray(info, dtype=object).reshape(-1)
        size = int(np.prod(batch_shape)) if batch_shape else 1
        if len(infos) != size or batch_shape == ():
            raise ValueError(
                f"info: {size} dicts needed (one per goal pair, batch shape {batch_shape}), "
                f"got {len(infos)}"
            )
        flags = np.empty(size, dtype=bool)
        for i, item in enumerate(infos):
            if not isinstance(item, Mapping):
                raise ValueError(f"info[{i}]: a dict needed, got {type(item).__name__}")
            flags[i] = failed(item)
        return flags.reshape(batch_shape)
    raise ValueError(f"info: a dict, a sequence of dicts or None needed, got {type(info).__name__}")


class GoalConditionedEnv(gym.Wrapper[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]):
    """The env with a goal ``Dict`` observation and a sparse goal reward (module docstring).

    Args:
        env: a debris-gym env with one target, no return, ``observation="kinematics"``.
        crash_penalty: a step ending failed (a collision, out of bounds, the Δv budget spent)
            is worth ``-crash_penalty`` (> 1, finite; default 100).
    """

    # gymnasium's Wrapper types the wrapped env with the wrapper's own observation type
    env: gym.Env[np.ndarray, np.ndarray]  # type: ignore[assignment]

    def __init__(
        self, env: gym.Env[np.ndarray, np.ndarray], crash_penalty: float = DEFAULT_CRASH_PENALTY
    ) -> None:
        super().__init__(env)  # type: ignore[arg-type]  # (gymnasium's slip, as above)
        penalty = float(crash_penalty)
        if not np.isfinite(penalty) or penalty <= 1.0:
            raise ValueError(f"crash_penalty: a finite value > 1 needed, got {crash_penalty!r}")
        self.crash_penalty = penalty
        self.layout = GoalLayout(env)
        goal_space = spaces.Box(-np.inf, np.inf, (self.layout.goal_size,), dtype=np.float32)
        # gymnasium types a Dict space's elements as spaces, not as their values
        self.observation_space = spaces.Dict(  # type: ignore[assignment]
            {
                "observation": env.observation_space,
                "achieved_goal": goal_space,
                "desired_goal": goal_space,
            }
        )

    def goal_observation(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """The Dict observation of a flat observation (or a batch of them)."""
        return self.layout.goal_observation(obs)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self.goal_observation(obs), info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], SupportsFloat, bool, bool, dict[str, Any]]:
        obs, _, terminated, truncated, info = self.env.step(action)
        goal_obs = self.goal_observation(obs)
        reward = float(
            self.compute_reward(goal_obs["achieved_goal"], goal_obs["desired_goal"], info)
        )
        return goal_obs, reward, terminated, truncated, info

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any
    ) -> np.ndarray:
        """Sparse goal reward, vectorised over leading axes.

        Args:
            achieved_goal: shape (..., goal_size), scaled as the observation (module docstring).
            desired_goal: the same shape.
            info: the step's info dict (goals of shape (goal_size,)), a sequence / array of info
                dicts, one per goal pair (SB3's HER passes them with ``copy_info_dict=True``),
                or None (no crash penalty). Only the :data:`FAILURE_KEYS` are read.

        Returns:
            float32 array of the goals' batch shape (0-d for one pair): 0 in the goal's capture
            zone, -1 outside it, ``-crash_penalty`` on a step that ended in a crash.
        """
        achieved = np.asarray(achieved_goal, dtype=np.float64)
        desired = np.asarray(desired_goal, dtype=np.float64)
        size = self.layout.goal_size
        for name, arr in (("achieved_goal", achieved), ("desired_goal", desired)):
            if arr.ndim == 0 or arr.shape[-1] != size:
                raise ValueError(f"{name}: last axis of length {size} needed, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name}: finite values needed")
        if achieved.shape != desired.shape:
            raise ValueError(
                f"desired_goal: shape {desired.shape} differs from achieved_goal's {achieved.shape}"
            )
        d = self.layout.dim
        length, speed = self.layout.length_scale, self.layout.speed_scale
        distance = np.linalg.norm(achieved[..., :d] - desired[..., :d], axis=-1) * length
        rel_speed = np.linalg.norm(achieved[..., d : 2 * d] - desired[..., d : 2 * d], axis=-1)
        rel_speed = rel_speed * speed
        reach = self.layout.position_tolerance + np.maximum(desired[..., 2 * d], 0.0) * length
        inside = (distance <= reach) & (rel_speed <= self.layout.speed_tolerance)
        reward = np.where(inside, 0.0, -1.0)
        reward = np.where(_crash_flags(info, achieved.shape[:-1]), -self.crash_penalty, reward)
        return reward.astype(np.float32)
