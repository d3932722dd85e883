"""The safety shield around an agent (:class:`ShieldedAgent`), a team (:class:`TeamShield`) or an
env (:class:`ShieldWrapper`), with per-episode intervention counters (:class:`ShieldStats`).

``ShieldedAgent`` filters a ``predict()`` agent's actions for evaluation (``evaluate.py
--shield``); ``TeamShield`` filters every chaser's action of a swarm team, each through a shield
on the chaser's view, which counts the teammates as bodies (``evaluate.py --shield`` on swarm
IDs); ``ShieldWrapper`` filters every action a learner sends to a single env, for training with
the shield on, and reports the counters in ``info``. The first two count through a
:class:`ShieldFilter`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from agents.policies.base import unwrap
from agents.policies.shield import SafetyShield, ShieldParams
from debris_gym.envs import DebrisFieldEnv

__all__ = ["ShieldFilter", "ShieldStats", "ShieldWrapper", "ShieldedAgent", "TeamShield"]

_FIRST_ROW = np.zeros(1, dtype=np.int64)


@dataclass
class ShieldStats:
    """Interventions of one episode.

    Attributes:
        decisions: commands filtered.
        interventions: commands replaced.
        size_sum, size_max: sum and largest intervention size (‖u_safe − u_cmd‖ / max_accel,
            a fraction of the thrust limit) over the replaced commands.
    """

    decisions: int = 0
    interventions: int = 0
    size_sum: float = 0.0
    size_max: float = 0.0

    @property
    def size_mean(self) -> float:
        """Mean intervention size over the replaced commands (0 without any)."""
        return self.size_sum / self.interventions if self.interventions else 0.0

    def add(self, intervened: bool, size: float) -> None:
        """Count one decision."""
        self.decisions += 1
        if intervened:
            self.interventions += 1
            self.size_sum += size
            self.size_max = max(self.size_max, size)

    def as_info(self) -> dict[str, float | int]:
        """The counters under the ``info`` keys :class:`ShieldWrapper` uses."""
        return {
            "shield_decisions": self.decisions,
            "shield_interventions": self.interventions,
            "shield_size_mean": self.size_mean,
            "shield_size_max": self.size_max,
        }


class ShieldFilter:
    """A :class:`SafetyShield` on one env (or a swarm chaser's view) with the counters of the
    episode it is in: :attr:`stats` starts afresh when the env was reset since the last call
    (another field, or its clock went back) or when told.

    Args:
        env: the env (or field view) the filtered commands fly in.
        params: the shield's tunables (None: defaults).
    """

    def __init__(self, env: Any, params: ShieldParams | None = None) -> None:
        self.shield = SafetyShield(env, params)
        self.stats = ShieldStats()
        self._clock: tuple[Any, float] | None = None  # (scenario, elapsed) of the last call
        try:
            inner: Any = unwrap(env)
        except TypeError:  # a field view (one chaser of a swarm): a team flies direct thrust
            inner = None
        residual = isinstance(inner, DebrisFieldEnv) and inner.config.action == "residual"
        self._residual_env = inner if residual else None
        """The env when its actions are corrections to its base law (``action="residual"``):
        the shield then judges the command flown, base + correction."""

    def filter(self, action: Any, new_episode: bool = False) -> Any:
        """``action`` itself when the shield lets it pass, else the shield's safe action; the
        decision is counted in :attr:`stats`.

        In a residual env the shield judges the command the env will fly, the base law's
        command plus ``action`` clipped to [−1, 1] per axis, and a replaced command is
        returned as the correction that flies it (safe − base)."""
        env = self.shield.env
        clock = (env.scenario, env.elapsed)
        fresh = self._clock is None or clock[0] is not self._clock[0] or clock[1] < self._clock[1]
        if fresh or new_episode:
            self.stats = ShieldStats()
        self._clock = clock
        base = None
        command = action
        if self._residual_env is not None:
            batch = self._residual_env.batch
            if batch is None:
                raise RuntimeError("reset the env before filtering its actions")
            base = batch.base_commands(_FIRST_ROW)[0]
            command = np.clip(base + np.asarray(action, dtype=float), -1.0, 1.0)
        decision = self.shield.decide(command)
        self.stats.add(decision.intervened, decision.size)
        if not decision.intervened:
            return action
        if base is None:
            return decision.action
        correction = np.asarray(decision.action, dtype=float) - base
        return correction.astype(np.asarray(action).dtype, copy=False)


class _FilterReadout:
    """The shield and this episode's counters of the :class:`ShieldFilter` a filtering class
    keeps in ``self.filter``."""

    filter: ShieldFilter

    @property
    def shield(self) -> SafetyShield:
        """The shield."""
        return self.filter.shield

    @property
    def stats(self) -> ShieldStats:
        """This episode's counters."""
        return self.filter.stats


class ShieldedAgent(_FilterReadout):
    """Any ``predict()`` agent with its actions filtered by a :class:`SafetyShield`.

    Counts per episode in :attr:`stats` (reset when ``episode_start`` says so, or when the env
    was reset since the last call). Single observations only (the shield reads the one env it
    was built with): a batch of one is answered as a batch, a larger batch is refused.

    Args:
        agent: anything with SB3's ``predict(obs, state, episode_start, deterministic)``.
        env: the env the agent flies (wrapped or not).
        params: the shield's tunables (None: defaults).
    """

    def __init__(self, agent: Any, env: Any, params: ShieldParams | None = None) -> None:
        if not callable(getattr(agent, "predict", None)):
            raise TypeError(f"agent must have a predict() method, got {type(agent).__name__}")
        self.agent = agent
        self.filter = ShieldFilter(env, params)

    @property
    def episode_independent(self) -> bool:
        """The wrapped agent's (the shield keeps nothing from one episode to the next)."""
        return bool(getattr(self.agent, "episode_independent", False))

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """The agent's action, filtered by the shield; same signature as SB3's ``predict``."""
        env = self.shield.env
        obs_shape = env.observation_space.shape
        shape = np.shape(observation)
        batch = shape != obs_shape
        if batch and (shape[1:] != obs_shape or shape[0] != 1):
            raise ValueError(
                f"a shielded agent takes one observation of shape {obs_shape} (or a batch of "
                f"one), got shape {shape}: the shield checks the one env it was built with"
            )
        action, state = self.agent.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )
        single = np.asarray(action)[0] if batch else action
        new_episode = episode_start is not None and bool(np.any(episode_start))
        safe = self.filter.filter(single, new_episode)
        if safe is single:
            return action, state
        if batch:
            safe = np.asarray([safe], dtype=np.asarray(action).dtype)
        return safe, state


class TeamShield:
    """One :class:`ShieldFilter` per chaser of a swarm team, each on the chaser's view
    (:class:`~agents.policies.chaser_view.ChaserView`), whose shield counts the teammates
    still in the field as bodies on their predicted tracks (:mod:`agents.policies.shield`).

    Args:
        views: the chasers' views, in chaser order.
        params: the shield's tunables (None: defaults).
    """

    def __init__(self, views: Sequence[Any], params: ShieldParams | None = None) -> None:
        self.filters = [ShieldFilter(view, params) for view in views]

    @property
    def stats(self) -> list[ShieldStats]:
        """Each chaser's counters this episode."""
        return [f.stats for f in self.filters]

    def filter(self, actions: dict[int, Any]) -> dict[int, Any]:
        """Each chaser's action (chaser index → action) through its chaser's shield."""
        return {k: self.filters[k].filter(a) for k, a in actions.items()}


class ShieldWrapper(_FilterReadout, gym.Wrapper):
    """A single DebrisGym env whose actions pass through a :class:`SafetyShield` first: train
    with the shield on. ``info`` gains ``shield_intervened`` (this step) and the episode's
    counters (:meth:`ShieldStats.as_info`).

    Args:
        env: a DebrisGym env (``gym.make(...)``), not a vector env.
        params: the shield's tunables (None: defaults).
    """

    def __init__(self, env: gym.Env, params: ShieldParams | None = None) -> None:
        unwrap(env)  # a DebrisGym env, or a clear TypeError
        super().__init__(env)
        self.filter = ShieldFilter(env, params)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the env and the episode's counters."""
        obs, info = self.env.reset(**kwargs)
        self.filter.stats = ShieldStats()
        return obs, {**info, "shield_intervened": False, **self.stats.as_info()}

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step with the shield's action in place of ``action`` (in a residual env, the
        correction that flies the shield's command: :meth:`ShieldFilter.filter`)."""
        before = self.stats.interventions
        safe = self.filter.filter(action)
        intervened = self.stats.interventions > before
        obs, reward, terminated, truncated, info = self.env.step(safe)
        info = {**info, "shield_intervened": intervened, **self.stats.as_info()}
        return obs, reward, terminated, truncated, info
