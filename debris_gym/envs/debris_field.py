"""The multi-target rendezvous environment on CWH dynamics."""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    checked_continuous_actions,
    checked_discrete_action,
    checked_seed,
    discrete_action_table,
    observation_names,
    registered_horizon,
    single_spaces,
)
from debris_gym.envs.shell import MissionShell, ShellView
from debris_gym.geometry import FieldGeometry, geometry_now
from debris_gym.goal import DOCK_GOAL, Goal, current_goal
from debris_gym.mission_batch import MissionBatch
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Scenario

if TYPE_CHECKING:  # matplotlib is imported when an env first renders
    from debris_gym.envs.rendering import Renderer

TRAIL_LENGTH = 4096
"""Chaser positions the env keeps for :attr:`DebrisFieldEnv.trail` and rendering: the last
ones, enough for a whole episode of every registered ID (at most 2000 steps); without a time
limit older positions are dropped, so the memory stays bounded."""


class DebrisFieldEnv(ShellView, gym.Env):
    """Rendezvous with several pieces of debris in one trip through a debris field, and return.

    ## Description

    A chaser spacecraft starts at rest at the dock, at the origin of the LVLH (Hill) frame of a
    circular reference orbit (x radial, y along-track, z cross-track), and must rendezvous with
    every target — hold position beside it, matching its velocity — without touching any body,
    then (if ``return_to_dock``) come back to the dock and stop there. Motion follows the
    Clohessy-Wiltshire-Hill equations ([Clohessy60], [Hill1878]; keys of docs/references.md),
    propagated exactly (zero-order hold) over each step. In the v1 world every body — debris
    and targets — flies its own unforced relative orbit (bounded, drift-free), 2D polygons keep
    an inertially fixed attitude (turning at −n in LVLH), every body is solid, and contacts are
    found continuously along the path relative to each moving body. The registered default,
    ``DebrisGym/Rendezvous2D-v2``: a 1 km square at 400 km altitude (n ≈ 1.131e-3 rad/s), 3
    targets of 3–10 m and 20 other debris of 2–25 m (circles and convex polygons),
    ``dt`` = 10 s, ``max_accel`` = 0.05 m/s², a Δv budget of 100 m/s, 1000 steps.

    ## Action Space

    ``action="continuous"`` (default): ``Box(-1, 1, (dim,), float32)``, the commanded
    acceleration as a fraction of ``max_accel`` (m/s²); ``thrust_model="box"`` clips each axis,
    ``"ball"`` scales vectors longer than 1 onto the unit ball. ``action="discrete"``:
    ``Discrete(2·dim + 1)`` (0 coast, then +x, −x, +y, −y (, +z, −z) at full thrust), and with
    ``fine_thrust`` = f > 0 (v1: 0.1) ``Discrete(4·dim + 1)``, the same directions again at
    f·``max_accel``. ``action="residual"``: the continuous space, the action added to the
    command of a compiled CW guidance law toward the current goal (:mod:`debris_gym.base_law`;
    a zero action flies the law) and the sum clipped to [−1, 1] per axis before the thrust
    model. NaN or infinite actions, wrong shapes, and complex, string, boolean or masked-array
    actions raise ``ValueError`` naming ``action``.

    ## Observation Space

    ``Box(-10, 10, (77,), float32)`` for ``Rendezvous2D-v2`` (102 elements in 3D; 74 and 99 in
    v1, which does not observe the hold): positions
    divided by L = half the world size (500 m), velocities by V = sqrt(max_accel·L) (5 m/s),
    every element clipped to ±10. :meth:`observation_names` names each element;
    docs/environments.md lists them one by one.

    ======  =====================================================  ======  ========  ===  ===
    index   meaning                                                unit    scale     min  max
    ======  =====================================================  ======  ========  ===  ===
    0–1     chaser position x, y                                   m       L         −10  10
    2–3     chaser velocity x, y                                   m/s     V         −10  10
    4–21    3 target slots (uncaptured first, nearest first),      m, m/s  L, V, 1   −10  10
            6 each: target − chaser position (2), velocity (2),
            radius, captured flag (1 also for an empty slot)
    22–23   dock − chaser position                                 m       L         −10  10
    24–55   8 nearest obstacles by surface gap, 4 each: centre −   m       L         −10  10
            chaser position (2), bounding radius, gap from the
            chaser's centre to the surface (empty slot: 0, 0, 0, 1)
    56–71   the same 8 obstacles' velocity − chaser velocity (2)   m/s     V         −10  10
    72      Δv budget remaining (fraction)                         –       1         −10  10
    73      time remaining (fraction of the registered limit)      –       1         −10  10
    ======  =====================================================  ======  ========  ===  ===

    ``observation="lidar"`` replaces the obstacle blocks with ``lidar_rays`` ranges divided by
    ``lidar_range``; ``obs_goal`` adds the current goal's relative state.

    ## Rewards

    A sum of named terms, each reported in ``info["reward_terms"]`` and weighted by the config
    key ``reward_<term>``: ``capture`` (+10 per target captured), ``success`` (+50),
    ``progress`` (potential-based shaping on the shortest remaining mission / L, undiscounted
    in v1), ``delta_v`` (−0.05 per m/s), ``collision`` (−50), ``out_of_bounds`` (−50) and
    ``time`` (−0.01 per step). ``info["task_score"]`` sums every term but the shaping: what
    tables rank by. See :mod:`debris_gym.rewards` and docs/environments.md, "Rewards".

    ## Starting State

    The chaser at rest at the dock, unless ``reset(options={"chaser_state": ...})`` says
    otherwise. A new random field each reset (from the reset seed), unless
    ``options={"scenario": ...}`` pins one or ``scenario="paper"`` selects the [APF-MPC] world;
    ``options={"mission": ...}`` moves the env to another rung of the difficulty ladder.

    ## Episode End

    Terminated on success (every target captured, then back at the dock, within
    ``capture_radius`` at ≤ ``capture_speed``), a collision with any body, leaving the bounds,
    or spending the whole Δv budget. A target is captured when at each of
    1 + ⌈``capture_hold`` / ``dt``⌉ consecutive step ends (v1: 4, over 30 s) the chaser's
    surface is within ``capture_radius`` (5 m) of the target's and its velocity relative to the
    target is at most ``capture_speed`` (0.2 m/s). Truncated at the registration's
    ``max_episode_steps`` (1000 steps) by gymnasium's ``TimeLimit``; the env itself never
    truncates.

    ## Arguments

    Every key of :class:`debris_gym.config.EnvConfig` (units, defaults and ranges in
    docs/environments.md, "Options"; a bad key or value raises ``ValueError`` naming it), plus
    ``render_mode`` ("rgb_array" or "human").

    ## Version History

    * v2 (the default): the v1 world with the hold rules — a capture is a 30 s hold within 5 m
      of the target's surface at ≤ 0.1 m/s relative to it, drifting at most 1 m and untouched
      (a colliding step captures nothing); running out of Δv is a failure (−50); the hold's
      progress is observed; contacts follow a turning polygon's surface through its turn.
      ``Rendezvous2D-Uncertain-v2`` / ``3D``: v2 with navigation errors (1 m, 1 cm/s), thrust
      errors (5 %, 0.02 rad, 1 % misses), absolute orbits with J2 and drag as the truth, and
      a 250 m sensor range (docs/environments.md, "An uncertain world"; every error option is
      off in the other IDs).
    * v1: the physical world — every body on its natural CWH relative orbit, solid targets,
      capture as a 30 s hold at ≤ 0.2 m/s relative to the target, fine discrete thrust, a
      potential on the shortest remaining mission; the Easy and Medium rungs.
    * v0: the frozen world — debris fixed in LVLH (exact only for ``mean_motion`` = 0), capture
      at one step end at ≤ 0.5 m/s, targets touched gently are not a collision. Kept for
      reproducing earlier numbers.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 15}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        config = EnvConfig.from_kwargs(**kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.render_mode = render_mode
        self.dim = d = config.dim
        # one row; no autoreset and no step limit of its own (gymnasium's TimeLimit owns it)
        self._shell = MissionShell(config, 1)
        self.observation_space, self.action_space = single_spaces(config)
        self._discrete_actions = discrete_action_table(d, config.fine_thrust)
        self._obs_names = observation_names(config)
        self._obs_buffer = np.zeros((1, len(self._obs_names)), dtype=np.float32)
        self._field_geometry: FieldGeometry | None = None
        self._trail: deque[np.ndarray] = deque(maxlen=TRAIL_LENGTH)
        self._renderer: Renderer | None = None

    # --- state accessors --------------------------------------------------------------------

    @property
    def scenario(self) -> Scenario | None:
        """The current field (None before the first reset). A random field is drawn as arrays
        and loaded as they are; its :class:`Scenario` is built when asked for here (the same
        object a :func:`~debris_gym.generators.random_field` draw gives)."""
        return self._shell.scenario(0)

    @property
    def chaser_state(self) -> np.ndarray:
        """Current chaser LVLH state [position (m), velocity (m/s)] (a copy)."""
        return self._missions.missions.state[0].copy()

    @property
    def estimated_scenario(self) -> Scenario | None:
        """The field as the chaser's navigation saw it at the episode's start
        (``nav_sigma_*`` > 0: every body's initial state with the errors of the first
        observation; otherwise the field itself): what a planner flying on its observations
        knows (None before the first reset)."""
        return self._shell.estimated_scenario(0)

    @property
    def estimated_body_states(self) -> np.ndarray:
        """Every body's state as the last observation saw it, (B, 2·dim) [position (m),
        velocity (m/s)] (with ``nav_sigma_*`` > 0 the truth plus its navigation errors; a
        copy)."""
        centers, velocities = self._missions.observed_bodies()
        return np.concatenate([centers[0], velocities[0]], axis=1)

    @property
    def estimated_chaser_state(self) -> np.ndarray:
        """The chaser's state as the last observation saw it (with ``nav_sigma_*`` > 0 the
        true state plus its navigation error; a copy)."""
        return self._missions.observed_state()[0]

    @property
    def captured(self) -> np.ndarray:
        """Per-target capture flags (a copy), in scenario target order."""
        return self._missions.missions.captured[0].copy()

    @property
    def elapsed(self) -> float:
        """The mission clock (s): simulated time since reset, plus the steps a mission started
        part-way had already flown."""
        return float(self._missions.missions.time[0])

    @property
    def field_word(self) -> int | None:
        """The 64-bit word this episode's moving random field was drawn from: with
        ``reset(options={"start": {"field_word": w, ...}})`` any env of the same ID and
        options flies that field again (None: a pinned field, the paper world or a frozen v0
        field)."""
        return self._shell.field_word(0)

    @property
    def trail(self) -> np.ndarray:
        """Chaser positions (m) at the reset and every step end since, shape (k, dim): all of
        them for episodes up to :data:`TRAIL_LENGTH` − 1 steps, else the last
        :data:`TRAIL_LENGTH`."""
        return np.asarray(self._trail)

    @property
    def body_states(self) -> np.ndarray:
        """Every body's LVLH state now, (B, 2·dim) [position (m), velocity (m/s)], targets
        first (a copy; in a moving field equal to ``scenario.body_states(elapsed)``)."""
        f = self._missions.field
        return np.concatenate([f.centers[0], f.velocities[0]], axis=1)

    @property
    def potential(self) -> float:
        """The shaping potential Φ of the current state (dimensionless, docs/environments.md)."""
        return float(self._missions.missions.potential[0])

    @property
    def geometry(self) -> FieldGeometry:
        """Geometry of the current field as it is now (bodies where they are at the env's
        time), inflated by the chaser radius (built on first use, again when the bodies have
        moved): the clearance and collision queries planners share with the env."""
        scenario = self._shell.scenario(0)
        if scenario is None:
            raise RuntimeError("call reset() first")
        self._field_geometry = geometry_now(
            self._field_geometry, scenario, self.elapsed, self.config.chaser_radius
        )
        return self._field_geometry

    @property
    def current_goal(self) -> Goal:
        """The goal the mission is heading for now (:func:`debris_gym.goal.current_goal`): a
        target (index ≥ 0, with the chaser-surface-to-target-surface gap in m), the dock (−1,
        with the distance from the chaser's centre to the dock in m) or nothing left (−2, gap
        0), and how many goals come after it. The rule the shaping potential and the goal
        observation use."""
        batch, cfg = self._missions, self.config
        m = batch.missions
        index, gap, after = current_goal(
            0, m.gaps, m.captured, cfg.target_order == "queued", cfg.return_to_dock,
            cfg.chaser_radius,
        )  # fmt: skip
        if index == DOCK_GOAL:
            offset = m.state[0, : self.dim] - batch.dock[0]
            gap = math.sqrt(float(offset @ offset))
        return Goal(int(index), float(gap), int(after))

    @property
    def _missions(self) -> MissionBatch:
        return self._shell.batch_in_use

    # --- gymnasium API ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode.

        Transactional: the options, the field (drawn or pinned) and the initial state are all
        checked before anything of the env changes, so a reset that raises leaves the env as
        it was (same field, state, clock and generator; stepping goes on as before).

        Args:
            seed: seeds the env's generator (and so the random field).
            options: ``{"scenario": Scenario | dict | path}`` pins the field;
                ``{"chaser_state": array (2·dim,)}`` sets the initial LVLH state (m, m/s):
                strictly inside the bounds, clear of every body, speed at most the world size
                over ``dt`` (:func:`~debris_gym.envs.common.checked_chaser_states`);
                ``{"mission": {"n_targets": 1, "n_obstacles": 5, "return_to_dock": False}}``
                changes what the missions ask (:data:`~debris_gym.envs.common.MISSION_KEYS`)
                from this reset on, until a reset names another mission (``{}``: the env's
                own again) — a curriculum's rung, with the spaces unchanged;
                ``{"start": {"captured": [2, 0], "step": 140, "delta_v": 3.1, ...}}`` starts
                the mission part-way (:class:`~debris_gym.mission_starts.MissionStart`:
                targets already captured in that order, the bodies and the clock ``step``
                steps on, Δv already spent, the chaser holding beside the last capture unless
                ``chaser_state`` puts it elsewhere, ``field_word`` the field of a recorded
                episode).

        Raises:
            ValueError: naming the bad option; the env is unchanged.
        """
        seed = checked_seed(seed)
        saved = self._np_random, self._np_random_seed
        try:
            super().reset(seed=seed)
            self._shell.horizon = registered_horizon(self.spec)
            self._shell.reset([self.np_random], options)
        except BaseException:  # the shell put itself back; gymnasium's seeding goes back too
            self._np_random, self._np_random_seed = saved
            raise
        self._field_geometry = None
        state = self._missions.missions.state[0]
        self._trail.clear()
        self._trail.append(state[: self.dim].copy())
        terms = (0.0,) * len(REWARD_TERMS)
        if self.render_mode == "human":
            self.render()
        return self._observe(), self._shell.row_info(0, terms)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply one thrust command for ``dt`` seconds.

        Returns:
            observation, reward, terminated, truncated, info. The time limit belongs to the
            ``TimeLimit`` wrapper, which counts steps from the reset; a mission started
            part-way (``options={"start": {"step": k, ...}}``) is truncated here when its own
            clock reaches the limit, k steps before the wrapper would.
        """
        shell = self._shell
        result = shell.step(self._action(action), observe_into=self._obs_buffer)
        missions = shell.batch_in_use.missions
        self._trail.append(missions.state[0, : self.dim].copy())
        if self.render_mode == "human":
            self.render()
        info = shell.row_info(0, result.terms[0].tolist())
        truncated = shell.started_late.item(0) and missions.steps.item(0) >= shell.horizon
        observation = self._obs_buffer[0].copy()
        return observation, result.reward.item(0), result.terminated.item(0), truncated, info

    # --- step hooks ---------------------------------------------------------------------------

    def _action(self, action: Any) -> np.ndarray:
        """The validated action as a normalised thrust command, shape (1, dim)."""
        if self.config.action == "discrete":
            index = checked_discrete_action(action, len(self._discrete_actions))
            return self._discrete_actions[index : index + 1]
        return checked_continuous_actions(action, (self.dim,))[None]

    def _observe(self) -> np.ndarray:
        return self._shell.observe(self._obs_buffer)[0].copy()

    # --- rendering ----------------------------------------------------------------------------

    def render(self) -> np.ndarray | None:
        """Draw the field: ``rgb_array`` returns an (H, W, 3) uint8 image, ``human`` shows it."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        scenario = self.scenario
        if self._shell.batch is None or scenario is None:
            raise RuntimeError("call reset() before render()")
        from debris_gym.envs.rendering import Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        frame = self._renderer.draw(
            scenario=scenario,
            chaser_state=self._missions.missions.state[0],
            captured=self._missions.missions.captured[0],
            trail=np.asarray(self._trail),
            accel=self._missions.missions.accel[0],
            time=float(self._missions.missions.time[0]),
            delta_v=float(self._missions.missions.delta_v[0]),
        )
        return frame if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        self._shell.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
