"""The one policy interface of debris-gym, and the base class of the classical baselines.

Every policy — classical or learned — answers SB3's protocol::

    action, state = policy.predict(observation, state=None, episode_start=None, deterministic=True)

for a single observation or a batch, in the same shape. Classical baselines are full-state
feedback on a known field (the source papers' assumption; in a moving field, the v1 world, they
know the bodies' motion too: :class:`agents.planners.motion.FieldMotion`): they are built with
the env (:func:`agents.make_agent`) and read the field from ``env.unwrapped.scenario`` and the
chaser's state and capture flags from the env's read-only properties. So they act for the env
they were built with; SB3's ``evaluate_policy`` works on a one-env ``DummyVecEnv`` around that env.

What they read is the small read-only protocol :class:`FieldView`: a
:class:`~debris_gym.envs.DebrisFieldEnv` is one, and so is one chaser of a swarm
(:class:`agents.policies.chaser_view.ChaserView`), which a single-agent baseline flies unchanged.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from gymnasium import spaces

from agents.planners.teammates import MovingSpheres
from debris_gym.config import EnvConfig
from debris_gym.dynamics import cw_transition
from debris_gym.envs import DebrisFieldEnv
from debris_gym.geometry import FieldGeometry, geometry_now
from debris_gym.scenario import Scenario
from debris_gym.thrust import action_for_accel
from debris_gym.uncertainty import field_with_states

FIELD_VIEW_MEMBERS = (
    "config", "dim", "observation_space", "scenario", "chaser_state", "captured", "elapsed",
    "geometry",
)  # fmt: skip
"""The members of :class:`FieldView`, what :func:`field_view` looks for."""


class FieldView(Protocol):
    """What a classical agent reads from the env it flies, all read-only: the field, one
    chaser's state and capture flags, the clock and the options."""

    @property
    def config(self) -> EnvConfig:
        """The env's options."""

    @property
    def dim(self) -> int:
        """2 or 3."""

    @property
    def observation_space(self) -> spaces.Space:
        """The space of the observations ``predict`` is given."""

    @property
    def scenario(self) -> Scenario | None:
        """The current field, its ``dock`` the chaser's own (None before the first reset)."""

    @property
    def chaser_state(self) -> np.ndarray:
        """The chaser's LVLH state [position (m), velocity (m/s)] (a copy)."""

    @property
    def captured(self) -> np.ndarray:
        """(T,) bool: the targets the chaser has nothing more to do with (a copy)."""

    @property
    def elapsed(self) -> float:
        """Time since the episode began (s)."""

    @property
    def geometry(self) -> FieldGeometry:
        """The field's geometry with the bodies where they are now, inflated by the chaser's
        radius."""


NAV_REFRESH_STEPS = 10
"""Steps between a :class:`NavigatedView`'s re-estimates of the field."""


def _inner(env: Any) -> Any:
    base = env
    if hasattr(base, "envs") and len(base.envs) == 1:  # SB3 DummyVecEnv
        base = base.envs[0]
    return getattr(base, "unwrapped", base)


def unwrap(env: Any) -> DebrisFieldEnv:
    """The :class:`DebrisFieldEnv` inside ``env`` (gymnasium wrappers, or a one-env VecEnv)."""
    base = _inner(env)
    if not isinstance(base, DebrisFieldEnv):
        raise TypeError(f"expected a DebrisGym env, got {type(base).__name__}")
    return base


class NavigatedView:
    """A :class:`DebrisFieldEnv` with navigation errors as a classical agent sees it: the
    chaser's state as the last observation saw it, and the field as its navigation estimates
    it, re-estimated every ``refresh_steps`` steps from the observation of that step (every
    body's observed state carried back to t = 0 by the CW model:
    :attr:`DebrisFieldEnv.estimated_body_states`), the bodies predicted from there by the CW
    model. Each re-estimate is a new field, so the agent re-plans on it. The bodies' shapes and
    sizes are known. The agent never reads the true states; the env still judges on them.

    Args:
        env: the env (unwrapped).
        refresh_steps: steps between re-estimates, >= 1.
    """

    def __init__(self, env: DebrisFieldEnv, refresh_steps: int = NAV_REFRESH_STEPS) -> None:
        if isinstance(refresh_steps, bool) or not (
            isinstance(refresh_steps, int) and refresh_steps >= 1
        ):
            raise ValueError(f"refresh_steps must be an integer >= 1, got {refresh_steps!r}")
        self._env = env
        self.refresh_steps = refresh_steps
        self._geometry: FieldGeometry | None = None
        self._estimate: Scenario | None = None
        self._estimated_at = -1  # the step of the estimate (-1: none yet)

    @property
    def config(self) -> EnvConfig:
        return self._env.config

    @property
    def dim(self) -> int:
        return self._env.dim

    @property
    def observation_space(self) -> spaces.Space:
        return self._env.observation_space

    @property
    def scenario(self) -> Scenario | None:
        env = self._env
        truth = env.scenario
        if truth is None:
            return None
        step = round(env.elapsed / truth.dt)
        fresh = step == 0 or step < self._estimated_at
        if fresh or self._estimate is None or step - self._estimated_at >= self.refresh_steps:
            if step == 0:  # the episode's first observation
                estimate = env.estimated_scenario
            else:
                now = env.estimated_body_states
                if truth.moving:
                    back = cw_transition(truth.mean_motion, -env.elapsed, truth.dim)
                    now = now @ back.T
                estimate = field_with_states(truth, now, "navigated")
            self._estimate, self._estimated_at = estimate, step
        return self._estimate

    @property
    def chaser_state(self) -> np.ndarray:
        return self._env.estimated_chaser_state

    @property
    def captured(self) -> np.ndarray:
        return self._env.captured

    @property
    def elapsed(self) -> float:
        return self._env.elapsed

    @property
    def geometry(self) -> FieldGeometry:
        scenario = self.scenario
        if scenario is None:
            raise RuntimeError("call reset() first")
        self._geometry = geometry_now(
            self._geometry, scenario, self.elapsed, self.config.chaser_radius
        )
        return self._geometry


def field_view(env: Any) -> FieldView:
    """What a classical agent reads from ``env``: the :class:`DebrisFieldEnv` inside it
    (:func:`unwrap`; a :class:`NavigatedView` of it when its observations carry navigation
    errors), or ``env`` itself when it has every member of :class:`FieldView` (one chaser of a
    swarm, say). The members are looked up without being read (a view that has no field yet is
    still a view).

    Raises:
        TypeError: ``env`` is neither (the message names the members it lacks).
    """
    base = _inner(env)
    if isinstance(base, DebrisFieldEnv):
        return NavigatedView(base) if base.config.navigation_errors else base
    missing = [n for n in FIELD_VIEW_MEMBERS if inspect.getattr_static(base, n, None) is None]
    if missing:
        raise TypeError(
            f"expected a DebrisGym env or a field view, got {type(base).__name__} (it lacks "
            f"{', '.join(missing)})"
        )
    return base


def teammates_of(view: FieldView) -> Callable[..., MovingSpheres] | None:
    """What a view says of the other chasers in its field: its ``teammates(steps, ahead=False)``
    (one chaser of a swarm, :class:`agents.policies.chaser_view.ChaserView`: the others, or
    with ``ahead`` those ahead of it in the team's order and the held ones, as spheres on their
    predicted tracks over ``steps`` steps), or None (a single env has no teammates)."""
    source = getattr(view, "teammates", None)
    return source if callable(source) else None


class ClassicalAgent:
    """Base of the classical baselines: re-plans when the field changes, acts on the true state.

    Subclasses implement :meth:`plan` (called at the start of every episode with the current
    field; cache expensive work per scenario there) and :meth:`act` (one normalised action from
    the current state).

    Args:
        env: the DebrisGym env (wrapped or not) or :class:`FieldView` the agent flies; needs
            ``action="continuous"``.
    """

    name = "classical"

    action_dtype: type = np.float32
    """The dtype of :meth:`predict`'s actions (the action space's; a subclass whose command
    must reach the env unrounded says float64)."""

    episode_independent = True
    """Whether an episode's actions depend only on that episode (:meth:`plan` starts every
    episode afresh, random generators reseeded): episodes may then be flown in any order, by
    any copy of the agent (the Ray backend does; :mod:`agents.experiments.distributed`)."""

    def __init__(self, env: Any) -> None:
        self.env = field_view(env)
        if self.env.config.action != "continuous":
            raise ValueError(
                f"the {self.name!r} baseline needs action='continuous', got "
                f"action={self.env.config.action!r}"
            )
        self._scenario: Scenario | None = None
        self._episode_time: float | None = None

    # --- the shared interface -----------------------------------------------------------------

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3-style ``predict``: one action per observation, same batch shape."""
        obs = np.asarray(observation)
        single_shape = self.env.observation_space.shape
        batched = obs.shape != single_shape
        if batched and obs.shape[1:] != single_shape:
            raise ValueError(f"observation shape {obs.shape} does not match {single_shape}")
        if batched and obs.shape[0] != 1:
            raise ValueError(
                f"a classical agent flies the one env it was built with; got a batch of "
                f"{obs.shape[0]} observations"
            )
        scenario = self.scenario
        new_episode = self.env.elapsed == 0.0 and self._episode_time != 0.0
        if scenario is not self._scenario or new_episode:
            self._scenario = scenario
            self.plan(scenario)
        self._episode_time = self.env.elapsed
        action = np.asarray(self.act(), dtype=self.action_dtype)
        if not np.all(np.isfinite(action)):
            raise FloatingPointError(f"{self.name} produced a non-finite action {action}")
        return (action[None] if batched else action), state

    @property
    def scenario(self) -> Scenario:
        """The env's current field.

        Raises:
            RuntimeError: the env has not been reset yet (it has no field).
        """
        scenario = self.env.scenario
        if scenario is None:
            raise RuntimeError("reset the env before calling predict()")
        return scenario

    # --- hooks --------------------------------------------------------------------------------

    def plan(self, scenario: Scenario) -> None:
        """Prepare an episode on ``scenario`` (new field, or a new episode on the same one)."""

    def act(self) -> np.ndarray:
        """Normalised action in [-1, 1]^dim for the env's current state."""
        raise NotImplementedError

    # --- helpers for subclasses ---------------------------------------------------------------

    def accel_to_action(self, accel: np.ndarray) -> np.ndarray:
        """Acceleration (m/s²) → normalised action, by the env's own inverse thrust model
        (:func:`debris_gym.thrust.action_for_accel`)."""
        return action_for_accel(accel, self.scenario.max_accel, self.env.config.thrust_model)
