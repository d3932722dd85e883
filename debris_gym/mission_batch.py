"""N rendezvous missions as arrays, stepped by compiled loops: the core of both environments.

:class:`MissionBatch` holds everything that changes during an episode — chaser states, clocks,
captures, collision / bounds / success flags, the gaps to every body, the shaping potential —
for N missions, plus their fields (a :class:`~debris_gym.batch_geometry.FieldBatch`). Its
:meth:`~MissionBatch.step` runs one decision step of every live mission in one numba-compiled
loop: exact propagation with the cached CWH matrices of :mod:`debris_gym.dynamics`, the swept
collision check along the sampled path, captures, collision and bounds, success, the shaping
potential and the named reward terms; :meth:`~MissionBatch.observe` writes the observations.

The single env (:class:`~debris_gym.envs.DebrisFieldEnv`) is a batch of one and the native
vector env a batch of N, so both run this one implementation of the rules. The rules are those
of ``docs/environments.md``; ``tests/test_mission_batch.py`` holds them to an independent
reference (numpy and pymunk, one env at a time). No gymnasium import.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from debris_gym.batch_geometry import FieldBatch, field_gaps, path_touches, ray_ranges
from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize, substep_position_matrix
from debris_gym.generators import MAX_POLYGON_VERTICES
from debris_gym.geometry import lidar_directions
from debris_gym.jit import inlined, kernel, threaded
from debris_gym.rewards import REWARD_TERMS
from debris_gym.thrust import delta_v_rate_row, thrust_row

# --- packed parameters of the compiled loops ---------------------------------------------------

# float parameters (MissionBatch.params)
_DT, _CHASER_R, _CAPTURE_R, _CAPTURE_V, _BUDGET, _GAMMA = range(6)
_W_CAPTURE, _W_SUCCESS, _W_PROGRESS, _W_DV, _W_COLLISION, _W_OOB, _W_TIME = range(6, 13)
_LIDAR_RANGE, _MAX_ACCEL, _W_SPEED, _SPEED_SLOPE = 13, 14, 15, 16
_W_CLEARANCE, _CLEARANCE_DIST, _W_CLOSING, _CLOSING_DIST = 17, 18, 19, 20
_N_PARAMS = 21

# integer options (MissionBatch.options)
_QUEUED, _RETURN, _TERMINAL_ZERO, _LIDAR, _OBS_TARGETS, _OBS_OBSTACLES, _MAX_STEPS, _BOX = range(8)
_OBS_GOAL, _OBS_OTHER_TARGETS = 8, 9
_N_OPTIONS = 10

# reward term columns, in REWARD_TERMS order
_T_CAPTURE, _T_SUCCESS, _T_PROGRESS, _T_DV, _T_COLLISION, _T_OOB, _T_TIME = range(7)
assert REWARD_TERMS == (
    "capture", "success", "progress", "delta_v", "collision", "out_of_bounds", "time"
)  # fmt: skip

OBS_LIMIT = 10.0
"""Observation values are normalised to about [−1, 1] and clipped to ±OBS_LIMIT."""


def check_threads(threads: int) -> int:
    """``threads`` validated: a whole number from 1 to numba's thread count (the cores, or
    ``NUMBA_NUM_THREADS``)."""
    limit = numba.config.NUMBA_NUM_THREADS
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)):
        raise ValueError(f"num_threads must be a whole number in [1, {limit}], got {threads!r}")
    if not 1 <= threads <= limit:
        raise ValueError(
            f"num_threads={threads} is out of range; allowed: [1, {limit}] (numba's thread "
            "count: the CPU cores, or NUMBA_NUM_THREADS)"
        )
    return int(threads)


class MissionBatch:
    """N missions with the same rules, physics and number of bodies.

    Args:
        cfg: the env configuration (rules, weights, observation layout).
        num: number of missions N.
        n_targets: targets per field T (the first T bodies).
        n_bodies: bodies per field B (targets and obstacles).
        mean_motion: n (rad/s), ``dt`` (s), ``max_accel`` (m/s²): the fields' physics.
        polygon_start: first body index that may be a convex polygon (default: T).
        max_episode_steps: truncation limit per episode, or None (the single env leaves it to
            gymnasium's ``TimeLimit``).
        threads: threads that step and observe the missions (row ranges in parallel; 1 = the
            calling thread only). The results do not depend on it.

    Per-mission arrays (row i = mission i; SI units): ``state`` (N, 2·dim) LVLH position and
    velocity, ``time`` (N,) s, ``steps`` (N,), ``delta_v`` (N,) m/s spent, ``captured`` (N, T),
    ``collision`` / ``out_of_bounds`` / ``success`` (N,), ``gaps`` (N, B) signed distance from
    the chaser's centre to every body (m), ``nearest`` (N, O) the obstacles by gap, nearest
    first (kinematics observations only), ``min_clearance`` (N,) smallest obstacle gap so far
    (m, chaser radius not subtracted), ``potential`` (N,) Φ, ``accel`` (N, dim) last commanded
    acceleration (m/s²); per field: ``dock``, ``low``, ``high`` (N, dim) m, ``length_scale``
    (N,) m and ``speed_scale`` (N,) m/s (the observation's L and V).
    """

    def __init__(
        self,
        cfg: EnvConfig,
        num: int,
        n_targets: int,
        n_bodies: int,
        *,
        mean_motion: float,
        dt: float,
        max_accel: float,
        polygon_start: int | None = None,
        max_episode_steps: int | None = None,
        threads: int = 1,
    ) -> None:
        n, d, t = num, cfg.dim, n_targets
        self.threads = check_threads(threads)
        self.config = cfg
        self.num, self.dim, self.n_targets = n, d, t
        self.physics = (mean_motion, dt, max_accel)
        start = t if polygon_start is None else polygon_start
        self.field = FieldBatch(n, n_bodies, d, MAX_POLYGON_VERTICES, polygon_start=start)
        model = discretize(mean_motion, dt, d)
        sub = substep_position_matrix(mean_motion, dt, d, cfg.collision_substeps)
        # one matrix maps [x₀, u] to the sub-step positions (the last is the end position)
        # followed by the end velocity
        end_velocity = np.hstack([model.ad[d:], model.bd[d:]])
        self.step_matrix_t = np.ascontiguousarray(np.vstack([sub, end_velocity]).T)
        budget = math.inf if cfg.delta_v_budget is None else cfg.delta_v_budget
        params = np.zeros(_N_PARAMS)
        params[[_DT, _CHASER_R, _CAPTURE_R, _CAPTURE_V, _BUDGET, _GAMMA]] = (
            dt, cfg.chaser_radius, cfg.capture_radius, cfg.capture_speed, budget,
            cfg.shaping_gamma,
        )  # fmt: skip
        params[_W_CAPTURE : _W_TIME + 1] = [getattr(cfg, f"reward_{k}") for k in REWARD_TERMS]
        params[_LIDAR_RANGE] = cfg.lidar_range
        params[_MAX_ACCEL] = max_accel
        params[_W_SPEED] = cfg.shaping_speed
        params[_SPEED_SLOPE] = cfg.shaping_speed_slope
        params[_W_CLEARANCE] = cfg.shaping_clearance
        params[_CLEARANCE_DIST] = cfg.shaping_clearance_distance
        params[_W_CLOSING] = cfg.shaping_closing
        params[_CLOSING_DIST] = cfg.shaping_closing_distance
        self.params = params
        shaped = cfg.shaping_speed > 0 or cfg.shaping_clearance > 0 or cfg.shaping_closing > 0
        self.shaping = params if shaped else None
        """The parameters again if an optional shaping term is on, else None (the kernels are
        compiled without those terms then)."""
        options = np.zeros(_N_OPTIONS, dtype=np.int64)
        options[_QUEUED] = cfg.target_order == "queued"
        options[_RETURN] = cfg.return_to_dock
        options[_TERMINAL_ZERO] = cfg.shaping_terminal == "zero"
        options[_LIDAR] = cfg.observation == "lidar"
        options[_OBS_TARGETS] = cfg.obs_targets
        options[_OBS_OBSTACLES] = cfg.obs_obstacles
        options[_MAX_STEPS] = -1 if max_episode_steps is None else max_episode_steps
        options[_BOX] = cfg.thrust_model == "box"
        options[_OBS_GOAL] = cfg.obs_goal
        options[_OBS_OTHER_TARGETS] = cfg.obs_other_targets
        self.options = options
        lidar = cfg.observation == "lidar"
        self.lidar_dirs = lidar_directions(d, cfg.lidar_rays) if lidar else np.zeros((1, d))
        self.max_accel = max_accel
        self.dt = dt
        # per mission
        self.state = np.zeros((n, 2 * d))
        self.time = np.zeros(n)
        self.steps = np.zeros(n, dtype=np.int64)
        self.delta_v = np.zeros(n)
        self.captured = np.zeros((n, t), dtype=bool)
        self.collision = np.zeros(n, dtype=bool)
        self.out_of_bounds = np.zeros(n, dtype=bool)
        self.success = np.zeros(n, dtype=bool)
        self.gaps = np.zeros((n, n_bodies))
        # every obstacle, by gap (the observation shows the first obs_obstacles)
        ranked = cfg.observation == "kinematics" and cfg.obs_obstacles > 0
        self.nearest = np.zeros((n, n_bodies - t if ranked else 0), dtype=np.int64)
        self.min_clearance = np.full(n, math.inf)
        self.potential = np.zeros(n)
        self.accel = np.zeros((n, d))
        # per field
        self.dock = np.zeros((n, d))
        self.low = np.zeros((n, d))
        self.high = np.zeros((n, d))
        self.length_scale = np.ones(n)
        self.speed_scale = np.ones(n)
        # step outputs (overwritten by every step)
        self._reward = np.zeros(n)
        self._terminated = np.zeros(n, dtype=bool)
        self._truncated = np.zeros(n, dtype=bool)
        self._terms = np.zeros((n, len(REWARD_TERMS)))
        self._step_tail: tuple | None = None  # the step kernel's arguments after the actions
        self._tail_vertices = 0  # id() of the vertex array the tail holds

    def set_world(self, rows: np.ndarray, dock, low, high, length_scale: float) -> None:
        """Dock position, bounds (m) and length scale L of the fields in ``rows``."""
        self.dock[rows] = dock
        self.low[rows] = low
        self.high[rows] = high
        self.length_scale[rows] = length_scale
        self.speed_scale[rows] = math.sqrt(self.max_accel * length_scale)

    def begin(self, rows: np.ndarray, states: np.ndarray | None = None) -> None:
        """Start new episodes in ``rows`` (fields loaded): chaser at ``states`` (R, 2·dim) or at
        rest at the dock, clocks and flags cleared, gaps and potential computed."""
        rows = np.asarray(rows, dtype=np.int64)
        f = self.field
        _begin(
            rows, None if states is None else np.ascontiguousarray(states, dtype=float),
            self.params, self.options, self.n_targets, self.state, self.time, self.steps,
            self.delta_v, self.captured, self.collision, self.out_of_bounds, self.success,
            self.gaps, self.nearest, self.min_clearance, self.potential, self.accel, f.centers,
            f.radii, f.polygon_start, f.polygons, f.n_vertices, f.vertices, self.dock,
            self.length_scale, self.speed_scale, self.shaping,
        )  # fmt: skip

    def step(
        self, actions: np.ndarray, live: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One decision step of the missions in ``live`` (the others are left as they are).

        Args:
            actions: (N, dim) normalised thrust commands (validated: finite), held over the step;
                the thrust model turns them into accelerations, and a burn that would overspend
                the Δv budget is cut to spend it exactly.
            live: (N,) bool, the missions that step.

        Returns:
            ``(reward (N,), terminated (N,), truncated (N,), terms (N, 7))``, buffers that the
            next call overwrites; rows not in ``live`` are zero / False. ``terms`` columns follow
            :data:`debris_gym.rewards.REWARD_TERMS`.
        """
        tail = self._step_tail
        if tail is None or self._tail_vertices != id(self.field.vertices):  # vertices can grow
            f = self.field
            self._tail_vertices = id(f.vertices)  # (the tail keeps that array alive)
            tail = self._step_tail = (
                self.step_matrix_t, self.params, self.options, self.n_targets, self.state,
                self.time, self.steps, self.delta_v, self.captured, self.collision,
                self.out_of_bounds, self.success, self.gaps, self.nearest, self.min_clearance,
                self.potential, self.accel, f.centers, f.radii, f.polygon_start, f.polygons,
                f.n_vertices, f.vertices, self.dock, self.low, self.high, self.length_scale,
                self.speed_scale, self.shaping, self._terms,
                self._reward, self._terminated, self._truncated,
            )  # fmt: skip
        if live.dtype != np.bool_ or actions.dtype != np.float64:
            live, actions = live.astype(np.bool_), actions.astype(np.float64)
        if self.threads > 1:
            _step_threaded(self.threads, live, np.ascontiguousarray(actions), *tail)
        else:
            _step(live, np.ascontiguousarray(actions), *tail)
        return self._reward, self._terminated, self._truncated, self._terms

    def captured_counts(self) -> np.ndarray:
        """(N,) int64: targets captured so far in each mission (a new array)."""
        out = np.empty(self.num, dtype=np.int64)
        _count_rows(self.captured, out)
        return out

    def observe(self, out: np.ndarray, horizon: int) -> np.ndarray:
        """Write every mission's observation into ``out`` (N, obs size) float32 and return it.

        Args:
            out: the buffer.
            horizon: steps the ``time_remaining`` element counts down from.
        """
        f = self.field
        args = (
            self.state, self.steps, self.delta_v, self.captured, self.gaps, self.nearest,
            f.centers, f.radii, f.polygon_start, f.n_vertices, f.vertices, self.n_targets,
            self.dock, self.length_scale, self.speed_scale, self.params, self.options,
            self.lidar_dirs, float(horizon), out,
        )  # fmt: skip
        if self.threads > 1:
            _observe_threaded(self.threads, *args)
        else:
            _observe(*args)
        return out


# --- compiled loops ---------------------------------------------------------------------------


@inlined
def _goal(i, prm, opt, n_targets, state, captured, gaps):
    """Mission ``i``'s current goal: ``(index, gap (m), goals after it)``.

    The goal is the nearest uncaptured target (the queue head if queued), index ≥ 0, with the
    gap from the chaser's surface to the target's; then the dock, index −1, with the distance
    to it (if a return is required); index −2 when nothing is left.
    """
    goal = -2
    gap = math.inf
    left = 0
    for j in range(n_targets):
        if not captured[i, j]:
            if (opt[_QUEUED] == 0 or left == 0) and gaps[i, j] < gap:
                gap = gaps[i, j]
                goal = j
            left += 1
    if left:
        return goal, gap - prm[_CHASER_R], left - 1 + opt[_RETURN]
    return (-1 if opt[_RETURN] else -2), 0.0, 0


@inlined
def _potential(
    i, prm, opt, n_targets, state, captured, gaps, centers, dock, length_scale, speed_scale,
    shaping,
):  # fmt: skip
    """Φ = −(gap to the current goal / L + goals after it), minus the approach-speed term
    ``shaping_speed`` · max(0, speed − (capture_speed + slope · gap)) / V and the clearance
    term ``shaping_clearance`` · max(0, 1 − c / d)² (c: the chaser surface's gap to the nearest
    obstacle) and the closing term ``shaping_closing`` · max over bodies b other than the goal
    within ``shaping_closing_distance`` of max(0, v_b − capture_speed) / V · (1 − c_b / d) (v_b:
    the chaser's speed toward b's centre) when they are on.

    ``shaping`` is None when all three are off (:attr:`MissionBatch.shaping`): numba then
    compiles a kernel without the call, whose mere presence (never taken) cost 3-4 % of a step.
    """
    goal, gap, after = _goal(i, prm, opt, n_targets, state, captured, gaps)
    if goal == -1:  # the distance to the dock, written out for 2 or 3 axes (no loop)
        off = state[i, 0] - dock[i, 0]
        s = off * off
        off = state[i, 1] - dock[i, 1]
        s += off * off
        if dock.shape[1] == 3:
            off = state[i, 2] - dock[i, 2]
            s += off * off
        gap = math.sqrt(s)
    goal_gap = max(gap, 0.0)
    phi = -(goal_gap / length_scale[i] + after)
    if shaping is not None:
        phi = _shaping_terms(
            phi, goal, goal_gap, i, prm, n_targets, state, gaps, centers, speed_scale
        )
    return phi


@kernel  # not inlined: off by default (see _potential's ``shaping``)
def _shaping_terms(phi, goal, goal_gap, i, prm, n_targets, state, gaps, centers, speed_scale):
    """Φ less the optional approach-speed, clearance and closing terms of :func:`_potential`."""
    dim = centers.shape[2]
    if prm[_W_SPEED] > 0.0 and goal != -2:
        s = 0.0
        for a in range(dim):
            s += state[i, dim + a] * state[i, dim + a]
        allowed = prm[_CAPTURE_V] + prm[_SPEED_SLOPE] * goal_gap
        phi -= prm[_W_SPEED] * max(math.sqrt(s) - allowed, 0.0) / speed_scale[i]
    if prm[_W_CLEARANCE] > 0.0 and gaps.shape[1] > n_targets:
        nearest = math.inf
        for b in range(n_targets, gaps.shape[1]):
            nearest = min(nearest, gaps[i, b])
        clearance = max(nearest - prm[_CHASER_R], 0.0)
        closeness = max(1.0 - clearance / prm[_CLEARANCE_DIST], 0.0)
        phi -= prm[_W_CLEARANCE] * closeness * closeness
    if prm[_W_CLOSING] > 0.0:
        worst = 0.0
        reach = prm[_CLOSING_DIST]
        for b in range(gaps.shape[1]):
            c = gaps[i, b] - prm[_CHASER_R]
            if b == goal or not c < reach:
                continue
            toward = 0.0
            dist2 = 0.0
            for a in range(dim):
                rel = centers[i, b, a] - state[i, a]
                toward += rel * state[i, dim + a]
                dist2 += rel * rel
            closing = toward / math.sqrt(dist2) if dist2 > 0.0 else 0.0
            excess = max(closing - prm[_CAPTURE_V], 0.0) / speed_scale[i]
            worst = max(worst, excess * (1.0 - max(c, 0.0) / reach))
        phi -= prm[_W_CLOSING] * worst
    return phi


@inlined
def _mission_gaps(
    point, i, n_targets, centers, radii, polygon_start, polygons, n_vertices, vertices, gaps,
    nearest,
):  # fmt: skip
    """Gaps (m) from ``point`` to every body of field ``i``, into ``gaps`` (B,), and the
    obstacles ``nearest`` (O,) (a permutation of them) re-sorted by gap (:func:`_sort_by_gap`).

    The gaps are exact for every body: computing all of them in one tight loop costs less than
    culling polygons with bounds (measured: the bookkeeping of a culled selection outweighs the
    polygon edges it saves at the default 20 obstacles).
    """
    field_gaps(point, i, centers, radii, polygon_start, polygons, n_vertices, vertices, gaps)
    _sort_by_gap(gaps, nearest)


@inlined
def _sort_by_gap(gaps, order):
    """Sort the body indices ``order`` by ``gaps`` (B,), nearest first, equal gaps by index.

    An insertion sort, started from the order of the step before: the chaser moves little in a
    step, so the order is nearly sorted already and the sort costs about one comparison per
    body, with branches that predict well. (Selecting the nearest few afresh every step, by
    insertion into a short sorted list, cost 3x more: its branches mispredict.) The result is
    the same (gap, index) order whatever the starting permutation.
    """
    for j in range(1, order.shape[0]):
        x = order[j]
        g = gaps[x]
        k = j - 1
        while k >= 0:
            y = order[k]
            h = gaps[y]
            if h < g or (h == g and y < x):
                break
            order[k + 1] = y
            k -= 1
        order[k + 1] = x


@inlined
def _select_nearest(gaps, first, skip, nearest, best):
    """The bodies ``first …`` except ``skip`` with the smallest ``gaps`` (B,), nearest first (ties
    by index), into ``nearest``; ``best`` is scratch of its length (their gaps, kept beside the
    indices: comparing with them directly instead of through ``gaps[nearest[k]]`` halved the
    selection's cost)."""
    n = nearest.shape[0]
    count = 0
    for b in range(first, gaps.shape[0] if n else first):
        if b == skip:
            continue
        g = gaps[b]
        if count == n:
            if not g < best[n - 1]:
                continue
            pos = n - 1
        else:
            pos = count
            count += 1
        while pos > 0 and g < best[pos - 1]:  # strict: an equal gap stays behind (by index)
            best[pos] = best[pos - 1]
            nearest[pos] = nearest[pos - 1]
            pos -= 1
        best[pos] = g
        nearest[pos] = b


@kernel
def _begin(
    rows, states, prm, opt, n_targets, state, time, steps, delta_v, captured, collision,
    out_of_bounds, success, gaps, nearest, min_clearance, potential, accel, centers, radii,
    polygon_start, polygons, n_vertices, vertices, dock, length_scale, speed_scale, shaping,
):  # fmt: skip
    dim = dock.shape[1]
    n_bodies = centers.shape[1]
    for r in range(rows.shape[0]):
        i = rows[r]
        for k in range(nearest.shape[1]):  # a new field: sort from index order
            nearest[i, k] = n_targets + k
        for a in range(dim):
            if states is None:
                state[i, a] = dock[i, a]
                state[i, dim + a] = 0.0
            else:
                state[i, a] = states[r, a]
                state[i, dim + a] = states[r, dim + a]
            accel[i, a] = 0.0
        time[i] = 0.0
        steps[i] = 0
        delta_v[i] = 0.0
        for j in range(n_targets):
            captured[i, j] = False
        collision[i] = False
        out_of_bounds[i] = False
        success[i] = False
        _mission_gaps(
            state[i, :dim], i, n_targets, centers, radii, polygon_start, polygons, n_vertices,
            vertices, gaps[i], nearest[i],
        )  # fmt: skip
        clearance = math.inf
        for b in range(n_targets, n_bodies):
            clearance = min(clearance, gaps[i, b])
        min_clearance[i] = clearance
        potential[i] = _potential(
            i, prm, opt, n_targets, state, captured, gaps, centers, dock, length_scale, speed_scale,
            shaping,
        )  # fmt: skip


@kernel
def _step(
    live, actions, matrix_t, prm, opt, n_targets, state, time, steps, delta_v, captured,
    collision, out_of_bounds, success, gaps, nearest, min_clearance, potential, last_accel,
    centers, radii, polygon_start, polygons, n_vertices, vertices, dock, low, high,
    length_scale, speed_scale, shaping, terms, reward, terminated, truncated,
):  # fmt: skip
    _step_rows(
        0, live.shape[0], live, actions, matrix_t, prm, opt, n_targets, state, time, steps,
        delta_v, captured, collision, out_of_bounds, success, gaps, nearest, min_clearance,
        potential, last_accel, centers, radii, polygon_start, polygons, n_vertices, vertices, dock,
        low, high, length_scale, speed_scale, shaping, terms, reward, terminated, truncated,
    )  # fmt: skip


@threaded
def _step_threaded(
    n_chunks, live, actions, matrix_t, prm, opt, n_targets, state, time, steps, delta_v, captured,
    collision, out_of_bounds, success, gaps, nearest, min_clearance, potential, last_accel,
    centers, radii, polygon_start, polygons, n_vertices, vertices, dock, low, high,
    length_scale, speed_scale, shaping, terms, reward, terminated, truncated,
):  # fmt: skip
    """:func:`_step` with the missions split into ``n_chunks`` row ranges run in parallel."""
    num = live.shape[0]
    for c in numba.prange(n_chunks):
        _step_rows(
            c * num // n_chunks, (c + 1) * num // n_chunks, live, actions, matrix_t, prm, opt,
            n_targets, state, time, steps, delta_v, captured, collision, out_of_bounds, success,
            gaps, nearest, min_clearance, potential, last_accel, centers, radii, polygon_start,
            polygons, n_vertices, vertices, dock, low, high, length_scale, speed_scale, shaping,
            terms, reward, terminated, truncated,
        )  # fmt: skip


@kernel  # called once per row range: no need to inline it
def _step_rows(
    lo, hi, live, actions, matrix_t, prm, opt, n_targets, state, time, steps, delta_v, captured,
    collision, out_of_bounds, success, gaps, nearest, min_clearance, potential, last_accel,
    centers, radii, polygon_start, polygons, n_vertices, vertices, dock, low, high,
    length_scale, speed_scale, shaping, terms, reward, terminated, truncated,
):  # fmt: skip
    """One step of the missions ``lo … hi − 1`` (see :meth:`MissionBatch.step`)."""
    n_bodies = gaps.shape[1]
    dim = dock.shape[1]
    n_out = matrix_t.shape[1]
    n_sub = (n_out - dim) // dim
    path = np.empty((n_sub + 1, dim))
    start = np.empty(2 * dim)
    accel = np.empty(dim)
    touched = np.empty(n_bodies, dtype=np.bool_)
    chaser_r = prm[_CHASER_R]
    for i in range(lo, hi):
        if not live[i]:
            for k in range(terms.shape[1]):
                terms[i, k] = 0.0
            reward[i] = 0.0
            terminated[i] = False
            truncated[i] = False
            continue
        # thrust: the commanded acceleration, cut to what the Δv budget still allows
        thrust_row(actions[i], prm[_MAX_ACCEL], opt[_BOX], accel)
        dv = delta_v_rate_row(accel, opt[_BOX]) * prm[_DT]
        if dv > 0.0 and delta_v[i] + dv > prm[_BUDGET]:
            scale = max(prm[_BUDGET] - delta_v[i], 0.0) / dv
            for k in range(dim):
                accel[k] = accel[k] * scale
            dv = dv * scale
        # simulate: [x₀, u] @ matrix_t gives every sub-step position and the end velocity
        for k in range(2 * dim):
            start[k] = state[i, k]
        for a in range(dim):
            path[0, a] = start[a]
        for c in range(n_out):
            s = 0.0
            for k in range(2 * dim):
                s += start[k] * matrix_t[k, c]
            for k in range(dim):
                s += accel[k] * matrix_t[2 * dim + k, c]
            if c < n_sub * dim:
                path[1 + c // dim, c % dim] = s
            else:
                state[i, dim + c - n_sub * dim] = s
        for a in range(dim):
            state[i, a] = path[n_sub, a]
            last_accel[i, a] = accel[a]
        # swept contact along the sampled path, from the gaps at its start
        path_touches(
            path, gaps[i], chaser_r, i, centers, radii, polygon_start, n_vertices, vertices, touched
        )
        time[i] += prm[_DT]
        steps[i] += 1
        delta_v[i] += dv

        # mission: captures, collision, bounds, success
        _mission_gaps(
            state[i, :dim], i, n_targets, centers, radii, polygon_start, polygons, n_vertices,
            vertices, gaps[i], nearest[i],
        )  # fmt: skip
        if n_bodies > n_targets:  # clearance to debris other than targets
            clearance = min_clearance[i]
            for b in range(n_targets, n_bodies):
                clearance = min(clearance, gaps[i, b])
            min_clearance[i] = clearance
        s = 0.0
        for a in range(dim):
            s += state[i, dim + a] * state[i, dim + a]
        slow = math.sqrt(s) <= prm[_CAPTURE_V]  # targets are at rest in LVLH (frozen field)
        new = 0
        reach = prm[_CAPTURE_R] + chaser_r
        for j in range(n_targets):
            if captured[i, j]:
                continue
            if slow and gaps[i, j] <= reach:
                captured[i, j] = True
                new += 1
            if opt[_QUEUED]:
                break  # only the queue head can be captured
        hit = False
        for b in range(n_targets, n_bodies):
            if touched[b]:
                hit = True  # any contact with debris that is not a target
                break
        if not hit and not slow:
            # a target touched too fast is a collision unless the chaser is leaving it: moving
            # away from its centre at both ends of the step and over the step as a whole
            # (departing after a gentle contact is not an impact)
            for j in range(n_targets):
                if touched[j]:
                    closing0 = 0.0
                    closing1 = 0.0
                    closing_step = 0.0
                    for a in range(dim):
                        toward = centers[i, j, a] - start[a]
                        closing0 += toward * start[dim + a]
                        closing1 += (centers[i, j, a] - state[i, a]) * state[i, dim + a]
                        closing_step += toward * (state[i, a] - start[a])
                    if closing0 > 0.0 or closing1 > 0.0 or closing_step > 0.0:
                        hit = True
        collision[i] = collision[i] or hit
        oob = False
        for a in range(dim):
            if state[i, a] <= low[i, a] or state[i, a] >= high[i, a]:
                oob = True
        out_of_bounds[i] = oob
        done = not collision[i]
        for j in range(n_targets):
            done = done and captured[i, j]
        if done and opt[_RETURN]:
            s = 0.0
            for a in range(dim):
                off = state[i, a] - dock[i, a]
                s += off * off
            done = math.sqrt(s) <= prm[_CAPTURE_R] and slow
        success[i] = success[i] or done

        # reward terms
        phi = _potential(
            i, prm, opt, n_targets, state, captured, gaps, centers, dock, length_scale, speed_scale,
            shaping,
        )  # fmt: skip
        progress = prm[_GAMMA] * phi - potential[i]
        potential[i] = phi
        terms[i, _T_CAPTURE] = prm[_W_CAPTURE] * new
        terms[i, _T_SUCCESS] = prm[_W_SUCCESS] * success[i]
        terms[i, _T_PROGRESS] = prm[_W_PROGRESS] * progress
        terms[i, _T_DV] = -prm[_W_DV] * dv
        terms[i, _T_COLLISION] = -prm[_W_COLLISION] * collision[i]
        terms[i, _T_OOB] = -prm[_W_OOB] * out_of_bounds[i]
        terms[i, _T_TIME] = -prm[_W_TIME]
        spent = delta_v[i] >= prm[_BUDGET]
        ended = success[i] or collision[i] or out_of_bounds[i] or spent
        if ended and opt[_TERMINAL_ZERO]:
            terms[i, _T_PROGRESS] -= prm[_W_PROGRESS] * prm[_GAMMA] * phi  # Φ(terminal) = 0
        terminated[i] = ended
        truncated[i] = opt[_MAX_STEPS] > 0 and steps[i] >= opt[_MAX_STEPS]
        total = 0.0
        for k in range(terms.shape[1]):
            total += terms[i, k]
        reward[i] = total


@kernel
def _count_rows(flags, out):
    """out[i] = number of True in flags[i] (numpy's bool sum along a short axis is ~4x slower)."""
    for i in range(flags.shape[0]):
        count = 0
        for j in range(flags.shape[1]):
            count += flags[i, j]
        out[i] = count


@inlined
def _put(out, i, k, value):
    """out[i, k] = value clipped to ±OBS_LIMIT (in float64, then rounded once to float32)."""
    out[i, k] = min(max(value, -OBS_LIMIT), OBS_LIMIT)
    return k + 1


@kernel
def _observe(
    state, steps, delta_v, captured, gaps, nearest, centers, radii, polygon_start,
    n_vertices, vertices, n_targets, dock, length_scale, speed_scale, prm, opt, lidar_dirs,
    horizon, out,
):  # fmt: skip
    _observe_rows(
        0, state.shape[0], state, steps, delta_v, captured, gaps, nearest, centers, radii,
        polygon_start, n_vertices, vertices, n_targets, dock, length_scale, speed_scale, prm, opt,
        lidar_dirs, horizon, out,
    )  # fmt: skip


@threaded
def _observe_threaded(
    n_chunks, state, steps, delta_v, captured, gaps, nearest, centers, radii, polygon_start,
    n_vertices, vertices, n_targets, dock, length_scale, speed_scale, prm, opt, lidar_dirs,
    horizon, out,
):  # fmt: skip
    """:func:`_observe` with the missions split into ``n_chunks`` row ranges run in parallel."""
    num = state.shape[0]
    for c in numba.prange(n_chunks):
        _observe_rows(
            c * num // n_chunks, (c + 1) * num // n_chunks, state, steps, delta_v, captured, gaps,
            nearest, centers, radii, polygon_start, n_vertices, vertices, n_targets, dock,
            length_scale, speed_scale, prm, opt, lidar_dirs, horizon, out,
        )  # fmt: skip


@kernel  # called once per row range
def _observe_rows(
    lo, hi, state, steps, delta_v, captured, gaps, nearest, centers, radii, polygon_start,
    n_vertices, vertices, n_targets, dock, length_scale, speed_scale, prm, opt, lidar_dirs,
    horizon, out,
):  # fmt: skip
    """Observations of the missions ``lo … hi − 1`` into ``out`` (:meth:`MissionBatch.observe`)."""
    dim = dock.shape[1]
    n_slots = opt[_OBS_TARGETS]
    order = np.empty(n_targets, dtype=np.int64)
    n_near = min(opt[_OBS_OBSTACLES], nearest.shape[1])
    if opt[_OBS_OTHER_TARGETS] and not opt[_LIDAR]:  # every body but the goal is a candidate
        n_near = min(opt[_OBS_OBSTACLES], gaps.shape[1] - 1)
    near = np.empty(n_near, dtype=np.int64)  # the bodies in the obstacle slots
    near_gap = np.empty(n_near)
    ranges = np.empty(lidar_dirs.shape[0])
    queued = opt[_QUEUED]
    for i in range(lo, hi):
        goal, gap = -2, 0.0  # the current goal, for the options that show it
        if opt[_OBS_GOAL] or opt[_OBS_OTHER_TARGETS]:
            goal, gap, _ = _goal(i, prm, opt, n_targets, state, captured, gaps)
        # x / L as x · (1 / L): one division per scale instead of one per element (the
        # divisions were a third of the observation's cost; equal to rounding)
        L = length_scale[i]
        V = speed_scale[i]
        inv_l = 1.0 / L
        inv_v = 1.0 / V
        k = 0
        for a in range(dim):
            k = _put(out, i, k, state[i, a] * inv_l)
        for a in range(dim):
            k = _put(out, i, k, state[i, dim + a] * inv_v)
        # target slots: uncaptured first (nearest first, or queue order), then captured, each
        # group in index order among equals
        for j in range(n_targets):
            order[j] = j
        for j in range(1, n_targets):  # insertion sort on (captured, key, index)
            x = order[j]
            m = j - 1
            while m >= 0 and _target_before(x, order[m], i, captured, gaps, queued):
                order[m + 1] = order[m]
                m -= 1
            order[m + 1] = x
        m = min(n_slots, n_targets)
        for s in range(m):
            j = order[s]
            for a in range(dim):
                k = _put(out, i, k, (centers[i, j, a] - state[i, a]) * inv_l)
            for a in range(dim):
                k = _put(out, i, k, -state[i, dim + a] * inv_v)  # targets at rest: minus chaser's
            k = _put(out, i, k, radii[i, j] * inv_l)
            k = _put(out, i, k, 1.0 if captured[i, j] else 0.0)
        for _slot in range(m, n_slots):  # empty slots read as "captured"
            for _ in range(2 * dim + 1):
                k = _put(out, i, k, 0.0)
            k = _put(out, i, k, 1.0)
        for a in range(dim):
            k = _put(out, i, k, (dock[i, a] - state[i, a]) * inv_l)
        if opt[_LIDAR]:
            ray_ranges(
                state[i, :dim], lidar_dirs, prm[_LIDAR_RANGE], i, centers, radii,
                polygon_start, n_vertices, vertices, ranges,
            )  # fmt: skip
            for r in range(ranges.shape[0]):
                k = _put(out, i, k, ranges[r] / prm[_LIDAR_RANGE])
        else:
            # the nearest obstacles by surface gap, nearest first (see _sort_by_gap); with
            # obs_other_targets the nearest bodies other than the current goal
            if opt[_OBS_OTHER_TARGETS]:
                _select_nearest(gaps[i], 0, goal, near, near_gap)
            else:
                for s in range(n_near):
                    near[s] = nearest[i, s]
            for s in range(n_near):
                b = near[s]
                for a in range(dim):
                    k = _put(out, i, k, (centers[i, b, a] - state[i, a]) * inv_l)
                k = _put(out, i, k, radii[i, b] * inv_l)
                k = _put(out, i, k, gaps[i, b] * inv_l)
            for _slot in range(n_near, opt[_OBS_OBSTACLES]):
                for _ in range(dim + 1):
                    k = _put(out, i, k, 0.0)
                k = _put(out, i, k, 1.0)
        budget = prm[_BUDGET]
        k = _put(out, i, k, 1.0 if budget == math.inf else max(budget - delta_v[i], 0.0) / budget)
        k = _put(out, i, k, max(horizon - steps[i], 0.0) / horizon)
        if opt[_OBS_GOAL]:  # the current goal at a 10x finer scale
            fine_l = L / 10.0
            s = 0.0
            for a in range(dim):
                if goal >= 0:
                    rel = centers[i, goal, a] - state[i, a]
                elif goal == -1:
                    rel = dock[i, a] - state[i, a]
                else:
                    rel = 0.0
                s += rel * rel
                k = _put(out, i, k, rel / fine_l)
            for a in range(dim):
                k = _put(out, i, k, 0.0 if goal == -2 else -state[i, dim + a] / (V / 10.0))
            if goal == -1:
                gap = math.sqrt(s)
            k = _put(out, i, k, (gap if goal != -2 else 0.0) / fine_l)


@inlined
def _target_before(x, y, i, captured, gaps, queued):
    """Does target x come before target y in the observation's slot order?"""
    cx, cy = captured[i, x], captured[i, y]
    if cx != cy:
        return cy  # uncaptured first
    if not cx and not queued:
        if gaps[i, x] != gaps[i, y]:
            return gaps[i, x] < gaps[i, y]  # nearest first
    return x < y
