"""Several chasers in one debris field as a PettingZoo ``ParallelEnv``.

:class:`SwarmParallelEnv` is the one-field view of a :class:`~debris_gym.swarm.core.SwarmCore`:
the same compiled step as the single-agent envs, the bodies flying once per field, chaser–chaser
contacts swept like chaser–body ones, and every rule of the single-agent world per chaser
(docs/swarm.md). Targets are shared: one chaser's capture counts for the team. A chaser that
collides (with debris or a teammate), leaves the world, spends its budget or succeeds (every
target captured, back at its own dock slot) leaves ``agents``; the episode ends when none is
left or at the time limit.
"""

from __future__ import annotations

import warnings
from collections import deque
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from debris_gym.envs.common import DEFAULT_HORIZON_STEPS, RESET_OPTIONS, checked_seed
from debris_gym.envs.debris_field import TRAIL_LENGTH
from debris_gym.rewards import REWARD_TERMS
from debris_gym.swarm.core import SwarmCore

if TYPE_CHECKING:  # matplotlib is imported when an env first renders
    from debris_gym.envs.rendering import Renderer

__all__ = ["SwarmParallelEnv"]


class SwarmParallelEnv(ParallelEnv):
    """K chasers, agents ``chaser_0 … chaser_{K−1}``, in one field of the single-agent world.

    Args:
        max_episode_steps: the time limit (steps) that truncates every chaser; None for none.
        render_mode: ``"rgb_array"`` (``render()`` returns a frame) or ``"human"`` (every
            reset and step also shows one), as the single-agent env draws them, with every
            chaser still in the field, its path and its goal slot; None: no rendering.
        **options: every single-agent option (:data:`debris_gym.config.OPTIONS`) plus the
            swarm's (:class:`~debris_gym.swarm.config.SwarmConfig`: ``n_chasers``, ``r_col``,
            ``dock_spacing``, ``reward_team``); ``obs_teammates`` defaults to the nearest
            min(K − 1, 4) teammates.

    Observation of each agent: the single-agent observation of its chaser (its own goal, dock
    slot and hold progress; the shared captures) followed by the ``teammates`` block. Action:
    the single-agent action space. ``state()``: every agent's observation, in agent order (a
    centralised critic's input).
    """

    metadata: dict[str, Any] = {
        "name": "debris_swarm_v0",
        "render_modes": ["human", "rgb_array"],
        "render_fps": 15,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        max_episode_steps: int | None = DEFAULT_HORIZON_STEPS,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.core = core = SwarmCore(1, max_episode_steps, **options)
        self.config, self.swarm = core.config, core.swarm
        self.render_mode = render_mode
        self._renderer: Renderer | None = None
        self._trails: list[deque[np.ndarray]] = [
            deque(maxlen=TRAIL_LENGTH) for _ in range(core.chasers)
        ]
        self.max_episode_steps = max_episode_steps
        self.possible_agents = [f"chaser_{j}" for j in range(core.chasers)]
        self.agents: list[str] = []
        self._index = {name: j for j, name in enumerate(self.possible_agents)}
        obs_space = core.observation_space
        self.state_space = spaces.Box(
            obs_space.low.min(), obs_space.high.max(), shape=(core.num * obs_space.shape[0],),
            dtype=np.float32,
        )  # fmt: skip
        self._np_random: np.random.Generator | None = None

    # --- spaces -------------------------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Box:
        """The observation space of ``agent`` (the same object for every agent)."""
        self._agent_index(agent)
        return self.core.observation_space

    def action_space(self, agent: str) -> spaces.Space:
        """The action space of ``agent`` (the same object for every agent)."""
        self._agent_index(agent)
        return self.core.action_space

    def observation_names(self) -> list[str]:
        """Name of every element of an agent's observation, in order."""
        return list(self.core.obs_names)

    def _agent_index(self, agent: str) -> int:
        index = self._index.get(agent)
        if index is None:
            raise ValueError(f"unknown agent {agent!r}; agents: {', '.join(self.possible_agents)}")
        return index

    # --- episode ------------------------------------------------------------------------------

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start an episode in a new field (seeded: the field the single-agent env draws for
        the same seed), every chaser at rest at its dock slot.

        Args:
            seed: seeds the field's generator.
            options: the single-agent reset options (``scenario``, ``chaser_state`` of shape
                (K, 2·dim), ``mission``) and ``assignment`` (with ``assignment="given"``: one
                list of target indices per chaser); other keys are warned about and ignored
                (PettingZoo's API test passes some of its own).
        """
        seed = checked_seed(seed)
        allowed = (*RESET_OPTIONS, "assignment")
        if isinstance(options, dict) and set(options) - set(allowed):
            unknown = sorted(set(options) - set(allowed), key=str)
            warnings.warn(
                f"reset options {unknown} are not swarm options (allowed: "
                f"{', '.join(allowed)}); ignored",
                stacklevel=2,
            )
            options = {k: v for k, v in options.items() if k in allowed}
        generator = None
        if seed is not None or self._np_random is None:
            generator, _ = seeding.np_random(seed)
        self.core.reset(None if generator is None else [generator], options)
        if generator is not None:
            self._np_random = generator
        self.agents = list(self.possible_agents)
        terms = np.zeros((self.core.num, len(REWARD_TERMS)))
        observations = self._observations(self.agents)
        positions = self._positions()
        for trail, position in zip(self._trails, positions):
            trail.clear()
            trail.append(position.copy())
        if self.render_mode == "human":
            self.render()
        return observations, self._infos(self.agents, terms, np.zeros(self.core.num))

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """One step of every chaser still flying (``actions``: one per agent in
        :attr:`agents`; other keys are refused).

        Returns:
            observations, rewards, terminations, truncations, infos: dicts over the agents that
            flew this step; those that ended leave :attr:`agents`.
        """
        if not self.agents:
            raise RuntimeError("no agent is flying: call reset()")
        flown = list(self.agents)
        result = self.core.step(self._commands(actions))
        observations = self._observations(flown)
        rows = [self._index[a] for a in flown]
        infos = self._infos(flown, result.terms, result.team)
        self.agents = [a for a in flown if self.core.flying[self._index[a]]]
        positions = self._positions()
        for j in rows:
            self._trails[j].append(positions[j].copy())
        if self.render_mode == "human":
            self.render()
        return (
            observations,
            {a: float(result.reward[j]) for a, j in zip(flown, rows)},
            {a: bool(result.terminated[j]) for a, j in zip(flown, rows)},
            {a: bool(result.truncated[j]) for a, j in zip(flown, rows)},
            infos,
        )

    def _commands(self, actions: dict[str, Any]) -> np.ndarray:
        """(K, dim) normalised thrust commands, zero for chasers not flying."""
        if not isinstance(actions, dict):
            raise ValueError(
                f"actions must be a dict agent -> action, got {type(actions).__name__}"
            )
        extra = sorted(set(actions) - set(self.agents))
        if extra:
            raise ValueError(
                f"actions for agents that are not flying: {extra}; flying: {self.agents}"
            )
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for {missing}: every agent in env.agents needs one")
        commands = np.zeros((self.core.num, self.config.dim))
        for agent, action in actions.items():
            commands[self._index[agent]] = self.core.command(action)
        return commands

    # --- reading ------------------------------------------------------------------------------

    def _infos(self, agents: list[str], terms: np.ndarray, team: np.ndarray) -> dict[str, dict]:
        rows = [self._index[a] for a in agents]
        return dict(zip(agents, self.core.row_infos(rows, terms, team)))

    def _observations(self, agents: list[str]) -> dict[str, np.ndarray]:
        obs = self.core.observe()
        return {a: obs[self._index[a]].copy() for a in agents}

    def team_success(self) -> bool:
        """Every target captured and every chaser that did not fail back at its dock slot
        (at least one such chaser)."""
        return bool(self.core.team_success()[0])

    def _positions(self) -> np.ndarray:
        return self.core.shell.batch_in_use.missions.state[:, : self.config.dim]

    @property
    def trails(self) -> list[np.ndarray]:
        """Each chaser's positions this episode (its last ``TRAIL_LENGTH``), (n, dim) m."""
        return [np.asarray(t) for t in self._trails]

    def render(self) -> np.ndarray | None:
        """Draw the field with every chaser still in it (flying, or held at its slot or dock),
        each one's path and goal slot: ``rgb_array`` returns an (H, W, 3) uint8 image,
        ``human`` shows it. The status line gives the time, the team's Δv, the fastest
        chaser's speed and the team's captures."""
        if self.render_mode is None:
            warnings.warn(
                "render() called without a render_mode; pass render_mode= to make()",
                stacklevel=2,
            )
            return None
        batch, scenario = self.core.shell.batch, self.core.shell.scenario(0)
        if batch is None or scenario is None:
            raise RuntimeError("call reset() before render()")
        from debris_gym.envs.rendering import Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        m = batch.missions
        present = self.core.flying | m.success
        frame = self._renderer.draw(
            scenario=scenario,
            chaser_state=m.state[present],
            captured=self.core.team_captured()[0],
            trail=self.trails,
            accel=m.accel[present],
            time=float(m.time.max()),
            delta_v=float(m.delta_v.sum()),
            goals=batch.dock,
        )
        return frame if self.render_mode == "rgb_array" else None

    def state(self) -> np.ndarray:
        """Every agent's observation, in agent order, as one vector (:attr:`state_space`)."""
        return self.core.observe().ravel().copy()

    def close(self) -> None:
        """Stop the field supply's worker thread and close the renderer."""
        self.core.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
