"""The multi-target rendezvous environment on CWH dynamics."""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import gymnasium as gym
import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.envs.common import (
    check_motion_matches,
    checked_chaser_states,
    checked_continuous_actions,
    checked_discrete_action,
    checked_mission,
    checked_reset_options,
    checked_seed,
    discrete_action_table,
    field_spec,
    observation_names,
    registered_horizon,
    single_spaces,
    warn_if_physics_differ,
)
from debris_gym.generators import FieldArrays, paper_field, random_fields
from debris_gym.geometry import FieldGeometry
from debris_gym.goal import DOCK_GOAL, Goal, current_goal
from debris_gym.mission_batch import MissionBatch
from debris_gym.orbit_fields import OrbitDrawer, orbit_drawer
from debris_gym.rewards import REWARD_TERMS
from debris_gym.scenario import Scenario, as_scenario
from debris_gym.scenario_checks import check_dock_clear

TRAIL_LENGTH = 4096
"""Chaser positions the env keeps for :attr:`DebrisFieldEnv.trail` and rendering: the last
ones, enough for a whole episode of every registered ID (at most 2000 steps); without a time
limit older positions are dropped, so the memory stays bounded."""


class DebrisFieldEnv(gym.Env):
    """Rendezvous with several pieces of debris in one trip through a debris field, and return.

    ## Description

    A chaser spacecraft starts at rest at the dock, at the origin of the LVLH (Hill) frame of a
    circular reference orbit, and must rendezvous with every target — come within
    ``capture_radius`` of its surface at a relative speed of at most ``capture_speed`` — without
    touching any other debris, then (if ``return_to_dock``) come back to the dock the same way.
    Motion follows the Clohessy-Wiltshire-Hill equations ([Clohessy60], [Hill1878]; keys of
    docs/references.md), propagated exactly (zero-order hold) over each step; collisions are
    checked continuously along the path, not only at step ends. Debris is frozen in LVLH (exact
    only for ``mean_motion = 0``; see ``docs/environments.md``).

    ## Action Space

    ``action="continuous"``: ``Box(-1, 1, (dim,), float32)``, the commanded acceleration as a
    fraction of ``max_accel`` (m/s²); ``thrust_model="box"`` clips each axis, ``"ball"`` scales
    vectors longer than 1 onto the unit ball. ``action="discrete"``: ``Discrete(2·dim + 1)``:
    0 coast, then +x, −x, +y, −y (, +z, −z) at full thrust. NaN or infinite actions, wrong
    shapes, and complex, string, boolean or masked-array actions raise ``ValueError`` naming
    ``action`` (docs/validation.md).

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
    ``options={"scenario": ...}`` pins one or ``scenario="paper"`` selects the [APF-MPC] world.

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
        self._made_config = self.config  # what a {"mission": {}} reset option returns to
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use one of "
                f"{self.metadata['render_modes']} or None"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.dim = d = cfg.dim
        self.observation_space, self.action_space = single_spaces(cfg)
        self._discrete_actions = discrete_action_table(d, cfg.fine_thrust)
        self._obs_names = observation_names(cfg)
        self._field_spec = field_spec(cfg)
        self._scenario: Scenario | None = None
        self._drawn: FieldArrays | None = None  # a random field, until it is asked for
        self._drawer: OrbitDrawer | None = None  # draws the moving fields (spec checked once)
        self._world_drawn = False  # the batch holds a random field's world (dock, bounds, L)
        self._row = np.zeros(1, dtype=np.int64)  # the rows of the batch of one
        self._missions: MissionBatch | None = None  # this env's mission, a batch of one
        self._field_geometry: FieldGeometry | None = None
        self._obs_buffer = np.zeros((1, len(self._obs_names)), dtype=np.float32)
        self._live = np.ones(1, dtype=bool)
        self._horizon: int | None = None
        self._renderer = None

    # --- state accessors --------------------------------------------------------------------

    @property
    def made_config(self) -> EnvConfig:
        """The config the env was made with: what ``reset(options={"mission": {...}})`` changes
        keys of (``self.config`` is the one in force)."""
        return self._made_config

    @property
    def scenario(self) -> Scenario | None:
        """The current field (None before the first reset). A random field is drawn as arrays
        and loaded as they are; its :class:`Scenario` is built when first asked for here (the
        same object a :func:`~debris_gym.generators.random_field` draw gives)."""
        if self._scenario is None and self._drawn is not None:
            cfg = self.config
            self._scenario = self._drawn.scenario(
                0, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel
            )
        return self._scenario

    @property
    def chaser_state(self) -> np.ndarray:
        """Current chaser LVLH state [position (m), velocity (m/s)] (a copy)."""
        return self._missions.state[0].copy()

    @property
    def captured(self) -> np.ndarray:
        """Per-target capture flags (a copy), in scenario target order."""
        return self._missions.captured[0].copy()

    @property
    def elapsed(self) -> float:
        """Simulated time since reset (s)."""
        return float(self._missions.time[0])

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
        return float(self._missions.potential[0])

    @property
    def geometry(self) -> FieldGeometry:
        """Geometry of the current field as it is now (bodies where they are at the env's
        time), inflated by the chaser radius (built on first use, again when the bodies have
        moved): the clearance and collision queries planners share with the env."""
        t = self.elapsed if self.scenario.moving else 0.0
        geometry = self._field_geometry
        if geometry is None or geometry.time != t:
            geometry = self._field_geometry = FieldGeometry(
                self.scenario, inflate=self.config.chaser_radius, time=t
            )
        return geometry

    @property
    def current_goal(self) -> Goal:
        """The goal the mission is heading for now (:func:`debris_gym.goal.current_goal`): a
        target (index ≥ 0, with the chaser-surface-to-target-surface gap in m), the dock (−1,
        with the distance from the chaser's centre to the dock in m) or nothing left (−2, gap
        0), and how many goals come after it. The rule the shaping potential and the goal
        observation use."""
        m, cfg = self._missions, self.config
        index, gap, after = current_goal(
            0, m.gaps, m.captured, cfg.target_order == "queued", cfg.return_to_dock,
            cfg.chaser_radius,
        )  # fmt: skip
        if index == DOCK_GOAL:
            offset = m.state[0, : self.dim] - m.dock[0]
            gap = math.sqrt(float(offset @ offset))
        return Goal(int(index), float(gap), int(after))

    def observation_names(self) -> list[str]:
        """Name of every observation element, in order."""
        return list(self._obs_names)

    # --- scenario -----------------------------------------------------------------------------

    def _draw(self) -> FieldArrays:
        cfg = self.config
        if self._field_spec.motion == "frozen":
            return random_fields(
                [self.np_random], self._field_spec, capture_radius=cfg.capture_radius
            )
        if self._drawer is None:  # checks the spec (raises ValueError naming what is wrong)
            self._drawer = orbit_drawer(self._field_spec, cfg.capture_radius)
        return self._drawer.draw((self.np_random,))

    def _check_dim(self, scenario: Scenario) -> None:
        if scenario.dim != self.dim:
            raise ValueError(f"scenario has dim={scenario.dim} but the env has dim={self.dim}")

    def _batch_for(self, physics: tuple[float, float, float], n_targets: int, n_bodies: int):
        """The batch of one mission for fields of this physics and size (made again when they
        change)."""
        m = self._missions
        if m is None or (m.physics, m.n_targets, m.field.n_bodies) != (
            physics,
            n_targets,
            n_bodies,
        ):
            mean_motion, dt, max_accel = physics
            m = self._missions = MissionBatch(
                self.config, 1, n_targets, n_bodies, mean_motion=mean_motion, dt=dt,
                max_accel=max_accel, polygon_start=0,
            )  # fmt: skip
            self._world_drawn = False
        return m

    def _set_drawn(self, fields: FieldArrays) -> None:
        """Load a random field drawn as arrays (its Scenario is built only when asked for)."""
        self._scenario, self._drawn, self._field_geometry = None, fields, None
        cfg = self.config
        t = fields.n_targets
        m = self._batch_for((cfg.n, cfg.dt, cfg.max_accel), t, fields.radii.shape[1])
        # the batch of the single env lets any body be a polygon (pinned fields may have
        # polygon targets): the drawn vertices are the obstacles', from body t on
        spins = None if fields.spins is None else fields.spins[:, m.field.polygon_start :]
        m.load_arrays(
            self._row, fields.centers, fields.radii, fields.vertices, fields.n_vertices,
            fields.velocities, spins, vertex_start=t,
        )  # fmt: skip
        if not self._world_drawn:  # every random field has the same world
            half = fields.half_size
            m.set_world(self._row, 0.0, -half, half, half)
            self._world_drawn = True

    def _set_scenario(self, scenario: Scenario) -> None:
        self._scenario, self._drawn, self._field_geometry = scenario, None, None
        n_targets, n_bodies = len(scenario.targets), len(scenario.bodies)
        physics = (scenario.mean_motion, scenario.dt, scenario.max_accel)
        m = self._batch_for(physics, n_targets, n_bodies)
        self._world_drawn = False
        m.load_scenario(np.zeros(1, dtype=np.int64), scenario)
        m.set_world(
            np.zeros(1, dtype=np.int64),
            scenario.dock,
            scenario.low,
            scenario.high,
            scenario.size / 2.0,
        )

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
                own again) — a curriculum's rung, with the spaces unchanged.

        Raises:
            ValueError: naming the bad option; the env is unchanged.
        """
        seed = checked_seed(seed)
        options = checked_reset_options(options)
        saved = self._np_random, self._np_random_seed
        saved_state = None if saved[0] is None else saved[0].bit_generator.state
        saved_mission = self.config, self._field_spec, self._drawer, self._missions
        try:
            if options.get("mission") is not None:
                config = checked_mission(self._made_config, options["mission"])
                if config != self.config:  # a new batch, ruled by the new mission
                    self.config, self._drawer, self._missions = config, None, None
                    self._field_spec = field_spec(config)
            super().reset(seed=seed)
            drawn = None
            if options.get("scenario") is not None:
                scenario = as_scenario(
                    options["scenario"], horizon_steps=registered_horizon(self.spec)
                )
                self._check_dim(scenario)
                warn_if_physics_differ(self.config, scenario)
                check_motion_matches(self.config, scenario)
            elif self.config.scenario == "paper":
                scenario = paper_field(dt=self.config.dt, max_accel=self.config.max_accel)
            else:
                drawn = self._draw()
                scenario = None
            if options.get("chaser_state") is not None:
                if scenario is None:  # the initial state is checked against the field itself
                    cfg = self.config
                    scenario = drawn.scenario(
                        0, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel
                    )
                state = checked_chaser_states(
                    options["chaser_state"], 1, scenario.low, scenario.high,
                    scenario.size / scenario.dt, FieldGeometry(scenario).signed_distance,
                    self.config.chaser_radius,
                )[0]  # fmt: skip
            else:  # the chaser starts at the dock (random fields keep it clear by construction)
                state = None
                if options.get("scenario") is not None:
                    check_dock_clear(scenario, self.config.chaser_radius)
        except BaseException:  # nothing of the env changed but its generator: put it back
            self.config, self._field_spec, self._drawer, self._missions = saved_mission
            self._np_random, self._np_random_seed = saved
            if saved_state is not None:
                saved[0].bit_generator.state = saved_state
            raise
        # commit: the field and state are valid, nothing below raises on them
        if drawn is not None:
            self._set_drawn(drawn)
            if scenario is not None:
                self._scenario = scenario
        else:
            self._set_scenario(scenario)
        d = self.dim
        if state is None:  # at rest at the dock
            state = np.concatenate([self._missions.dock[0], np.zeros(d)])
        self._missions.begin(np.zeros(1, dtype=np.int64), state[None])
        self._trail = deque([state[:d].copy()], maxlen=TRAIL_LENGTH)
        terms = dict.fromkeys(REWARD_TERMS, 0.0)
        if self.render_mode == "human":
            self.render()
        return self._observe(), self._info(terms)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply one thrust command for ``dt`` seconds.

        Returns:
            observation, reward, terminated, truncated (always False: the time limit belongs to
            the ``TimeLimit`` wrapper), info.
        """
        if self._missions is None:
            raise RuntimeError("call reset() before step()")
        m = self._missions
        reward, terminated, _, terms = m.step(self._action(action), self._live)
        self._trail.append(m.state[0, : self.dim].copy())
        if self.render_mode == "human":
            self.render()
        info = self._info(dict(zip(REWARD_TERMS, terms[0].tolist())))
        return self._observe(), float(reward[0]), bool(terminated[0]), False, info

    # --- step hooks ---------------------------------------------------------------------------

    def _action(self, action: Any) -> np.ndarray:
        """The validated action as a normalised thrust command, shape (1, dim)."""
        if self.config.action == "discrete":
            index = checked_discrete_action(action, len(self._discrete_actions))
            return self._discrete_actions[index : index + 1]
        return checked_continuous_actions(action, (self.dim,))[None]

    def _observe(self) -> np.ndarray:
        if self._horizon is None:
            self._horizon = registered_horizon(self.spec)
        return self._missions.observe(self._obs_buffer, self._horizon)[0].copy()

    def _info(self, terms: dict[str, float]) -> dict[str, Any]:
        m = self._missions
        captured = m.captured[0].copy()
        return {
            "chaser_state": m.state[0].copy(),
            "time": float(m.time[0]),
            "delta_v": float(m.delta_v[0]),
            "targets_captured": int(np.count_nonzero(captured)),
            "n_targets": m.n_targets,
            "captured": captured,
            "min_clearance": float(m.min_clearance[0]) - self.config.chaser_radius,
            "collision": bool(m.collision[0]),
            "out_of_bounds": bool(m.out_of_bounds[0]),
            "is_success": bool(m.success[0]),
            "applied_accel": m.accel[0].copy(),
            "task_score": float(m.score[0]),
            "reward_terms": terms,
        }

    # --- rendering ----------------------------------------------------------------------------

    def render(self) -> np.ndarray | None:
        """Draw the field: ``rgb_array`` returns an (H, W, 3) uint8 image, ``human`` shows it."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        if self._missions is None:
            raise RuntimeError("call reset() before render()")
        from debris_gym.envs.rendering import Renderer

        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, fps=self.metadata["render_fps"])
        frame = self._renderer.draw(
            scenario=self.scenario,
            chaser_state=self._missions.state[0],
            captured=self._missions.captured[0],
            trail=np.asarray(self._trail),
            accel=self._missions.accel[0],
            time=float(self._missions.time[0]),
            delta_v=float(self._missions.delta_v[0]),
        )
        return frame if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
