"""The kinematics / lidar observation: one table of slots, the names and the compiled writer.

:data:`OBSERVATION_BLOCKS` lists the observation's blocks in order, each with the names of the
elements of one slot and how many slots the config gives it. From that one table come both
:func:`observation_names` (what every element means) and :func:`observation_layout` (where each
block starts), and the compiled writer :func:`observe_rows` writes each block from the offset
the layout gives it, in the element order of its table row. No gymnasium import.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numba
import numpy as np

from debris_gym.batch_geometry import ray_ranges
from debris_gym.config import EnvConfig
from debris_gym.geometry import lidar_directions
from debris_gym.goal import DOCK_GOAL, NO_GOAL, current_goal
from debris_gym.jit import inlined, kernel, threaded

OBS_LIMIT = 10.0
"""Observation values are normalised to about [−1, 1] and clipped to ±OBS_LIMIT."""

NEAR_LIMIT = 4.0
"""The near-field goal elements (``obs_near``) saturate at ±NEAR_LIMIT: the gap at 4 capture
radii, the closing speed at 4 capture speeds."""


class ObservationBlock(NamedTuple):
    """One block of the observation: ``slots(cfg)`` slots of the elements ``elements``.

    An element name with ``{a}`` stands for one element per axis (x, y, z); ``{k}`` is the
    slot's number.
    """

    name: str
    elements: tuple[str, ...]
    slots: Callable[[EnvConfig], int]


def _kinematics(cfg: EnvConfig) -> bool:
    return cfg.observation == "kinematics"


def _moving(cfg: EnvConfig) -> bool:
    return cfg.debris_motion != "frozen"


OBSERVATION_BLOCKS: tuple[ObservationBlock, ...] = (
    ObservationBlock("chaser", ("chaser_pos_{a}", "chaser_vel_{a}"), lambda cfg: 1),
    ObservationBlock(
        "targets",
        (
            "target{k}_rel_pos_{a}",
            "target{k}_rel_vel_{a}",
            "target{k}_radius",
            "target{k}_captured",
        ),
        lambda cfg: cfg.obs_targets,
    ),
    ObservationBlock(
        "target_holds", ("target{k}_hold",), lambda cfg: cfg.obs_targets if cfg.obs_hold else 0
    ),
    ObservationBlock("dock", ("dock_rel_pos_{a}",), lambda cfg: 1),
    ObservationBlock(
        "obstacles",
        ("obstacle{k}_rel_pos_{a}", "obstacle{k}_radius", "obstacle{k}_gap"),
        lambda cfg: cfg.obs_obstacles if _kinematics(cfg) else 0,
    ),
    ObservationBlock(
        "obstacle_velocities",
        ("obstacle{k}_rel_vel_{a}",),
        lambda cfg: cfg.obs_obstacles if _kinematics(cfg) and _moving(cfg) else 0,
    ),
    ObservationBlock("lidar", ("lidar{k}",), lambda cfg: 0 if _kinematics(cfg) else cfg.lidar_rays),
    ObservationBlock("budgets", ("delta_v_remaining", "time_remaining"), lambda cfg: 1),
    ObservationBlock(
        "goal", ("goal_rel_pos_{a}", "goal_rel_vel_{a}", "goal_gap"), lambda cfg: int(cfg.obs_goal)
    ),
    ObservationBlock(
        "goal_near", ("goal_near_gap", "goal_near_closing"), lambda cfg: int(cfg.obs_near)
    ),
    ObservationBlock(
        "teammates",
        (
            "teammate{k}_rel_pos_{a}",
            "teammate{k}_rel_vel_{a}",
            "teammate{k}_heading_{a}",
            "teammate{k}_flying",
        ),
        lambda cfg: cfg.obs_teammates,
    ),
)
"""The observation's blocks in order (docs/environments.md has the table with units)."""


def _block_names(block: ObservationBlock, cfg: EnvConfig) -> list[str]:
    axes = "xyz"[: cfg.dim]
    names = []
    for k in range(block.slots(cfg)):
        for element in block.elements:
            if "{a}" in element:
                names += [element.format(k=k, a=a) for a in axes]
            else:
                names.append(element.format(k=k))
    return names


def observation_names(cfg: EnvConfig) -> list[str]:
    """Name of every observation element, in order (see docs/environments.md)."""
    return [name for block in OBSERVATION_BLOCKS for name in _block_names(block, cfg)]


class ObservationLayout(NamedTuple):
    """Where the writer puts each block (offsets into the observation) and what it shows."""

    size: int
    chaser: int
    targets: int
    target_slots: int
    target_holds: int
    hold_slots: int
    dock: int
    obstacles: int
    obstacle_slots: int
    obstacle_velocities: int
    obstacle_velocity_slots: int
    lidar: int
    lidar_rays: int
    budgets: int
    goal: int
    goal_slots: int
    goal_near: int
    goal_near_slots: int
    teammates: int
    teammate_slots: int
    other_targets: bool
    """``obs_other_targets``: the obstacle slots show the nearest bodies other than the goal."""
    lidar_range: float
    """Longest lidar range (m)."""
    sensor_range: float
    """``sensor_range`` (m; inf when unlimited): obstacle slots and lidar rays show nothing
    beyond it."""
    lidar_directions: np.ndarray
    """(rays, dim) unit ray directions ((1, dim) zeros without lidar)."""


def observation_layout(cfg: EnvConfig) -> ObservationLayout:
    """The :class:`ObservationLayout` of ``cfg``, from :data:`OBSERVATION_BLOCKS`."""
    offsets, slots, k = {}, {}, 0
    for block in OBSERVATION_BLOCKS:
        offsets[block.name], slots[block.name] = k, block.slots(cfg)
        k += len(_block_names(block, cfg))
    lidar = not _kinematics(cfg)
    return ObservationLayout(
        size=k,
        chaser=offsets["chaser"],
        targets=offsets["targets"],
        target_slots=slots["targets"],
        target_holds=offsets["target_holds"],
        hold_slots=slots["target_holds"],
        dock=offsets["dock"],
        obstacles=offsets["obstacles"],
        obstacle_slots=slots["obstacles"],
        obstacle_velocities=offsets["obstacle_velocities"],
        obstacle_velocity_slots=slots["obstacle_velocities"],
        lidar=offsets["lidar"],
        lidar_rays=slots["lidar"],
        budgets=offsets["budgets"],
        goal=offsets["goal"],
        goal_slots=slots["goal"],
        goal_near=offsets["goal_near"],
        goal_near_slots=slots["goal_near"],
        teammates=offsets["teammates"],
        teammate_slots=slots["teammates"],
        other_targets=bool(cfg.obs_other_targets),
        lidar_range=float(cfg.lidar_range),
        sensor_range=math.inf if cfg.sensor_range is None else float(cfg.sensor_range),
        lidar_directions=lidar_directions(cfg.dim, cfg.lidar_rays)
        if lidar
        else np.zeros((1, cfg.dim)),
    )


# --- compiled writer --------------------------------------------------------------------------


@kernel
def observe_all(rules, layout, missions, field, horizon, out):
    """Every mission's observation into ``out`` (N, size) float32."""
    observe_rows(0, out.shape[0], rules, layout, missions, field, horizon, out)


@threaded
def observe_all_threaded(n_chunks, rules, layout, missions, field, horizon, out):
    """:func:`observe_all` with the missions split into ``n_chunks`` row ranges run in parallel."""
    num = out.shape[0]
    for c in numba.prange(n_chunks):
        lo, hi = c * num // n_chunks, (c + 1) * num // n_chunks
        observe_rows(lo, hi, rules, layout, missions, field, horizon, out)


@inlined
def _put(out, i, k, value):
    """out[i, k] = value clipped to ±OBS_LIMIT (in float64, then rounded once to float32).

    ``k`` (a block's offset in the layout plus a count) is never negative, but the compiler
    cannot prove it, and numba wraps a negative signed index around on every write; indexing
    with the same bits as unsigned leaves that out.
    """
    out[i, np.uint64(k)] = min(max(value, -OBS_LIMIT), OBS_LIMIT)
    return k + 1


@kernel  # called once per row range
def observe_rows(lo, hi, rules, layout, missions, field, horizon, out):
    """Observations of the missions ``lo … hi − 1`` into ``out``, block by block."""
    state, gaps, captured = missions.state, missions.gaps, missions.captured
    nearest, delta_v, steps = missions.nearest, missions.delta_v, missions.steps
    hold = missions.hold
    centers, radii, dock = field.centers, field.radii, field.dock
    velocities, attitude = field.velocities, field.attitude
    moving = rules.moving
    length_scale, speed_scale = field.length_scale, field.speed_scale
    n_vertices, vertices = field.n_vertices, field.vertices
    lidar_directions = layout.lidar_directions
    dim = dock.shape[1]
    n_targets = rules.n_targets
    order = np.empty(n_targets, dtype=np.int64)
    n_near = min(layout.obstacle_slots, nearest.shape[1])
    if layout.other_targets:  # every body but the goal is a candidate
        n_near = min(layout.obstacle_slots, gaps.shape[1] - 1)
    near = np.empty(n_near, dtype=np.int64)  # the bodies in the obstacle slots
    near_gap = np.empty(n_near)
    ranges = np.empty(lidar_directions.shape[0])
    mates = np.empty(layout.teammate_slots, dtype=np.int64)
    mate_d2 = np.empty(layout.teammate_slots)
    for i in range(lo, hi):
        # the row's field (an integer division costs more than the test that spares it)
        f = i if rules.n_chasers == 1 else i // rules.n_chasers
        goal, gap = NO_GOAL, 0.0  # the current goal, for the options that show it
        if layout.goal_slots or layout.goal_near_slots or layout.other_targets:
            goal, gap, _ = current_goal(
                i, gaps, captured, rules.queued, rules.return_to_dock, rules.chaser_radius
            )
        # x / L as x · (1 / L): one division per scale instead of one per element
        L = length_scale[f]
        V = speed_scale[f]
        inv_l = 1.0 / L
        inv_v = 1.0 / V

        # chaser: position / L, velocity / V
        k = layout.chaser
        for a in range(dim):
            k = _put(out, i, k, state[i, a] * inv_l)
        for a in range(dim):
            k = _put(out, i, k, state[i, dim + a] * inv_v)

        # targets: uncaptured first (nearest first, or queue order), then captured, each group
        # in index order among equals; per slot relative position, velocity, radius, captured
        k = layout.targets
        for j in range(n_targets):
            order[j] = j
        for j in range(1, n_targets):  # insertion sort on (captured, key, index)
            x = order[j]
            m = j - 1
            while m >= 0 and _target_before(x, order[m], i, captured, gaps, rules.queued):
                order[m + 1] = order[m]
                m -= 1
            order[m + 1] = x
        m = min(layout.target_slots, n_targets)
        for s in range(m):
            j = order[s]
            for a in range(dim):
                k = _put(out, i, k, (centers[f, j, a] - state[i, a]) * inv_l)
            for a in range(dim):
                if moving:
                    k = _put(out, i, k, (velocities[f, j, a] - state[i, dim + a]) * inv_v)
                else:  # at rest: minus the chaser's
                    k = _put(out, i, k, -state[i, dim + a] * inv_v)
            k = _put(out, i, k, radii[f, j] * inv_l)
            k = _put(out, i, k, 1.0 if captured[i, j] else 0.0)
        for _slot in range(m, layout.target_slots):  # empty slots read as "captured"
            for _ in range(2 * dim + 1):
                k = _put(out, i, k, 0.0)
            k = _put(out, i, k, 1.0)

        # hold progress of the same target slots (empty slots: 0)
        if layout.hold_slots:
            k = layout.target_holds
            for s in range(m):
                k = _put(out, i, k, min(hold[i, order[s]] / rules.hold_steps, 1.0))
            for _slot in range(m, layout.hold_slots):
                k = _put(out, i, k, 0.0)

        # dock: relative position / L
        k = layout.dock
        for a in range(dim):
            k = _put(out, i, k, (dock[i, a] - state[i, a]) * inv_l)

        # obstacles: the nearest by surface gap, nearest first (the step keeps them ranked);
        # with obs_other_targets the nearest bodies other than the current goal
        if layout.obstacle_slots:
            k = layout.obstacles
            if layout.other_targets:
                _select_nearest(gaps[i], 0, goal, near, near_gap)
            else:
                for s in range(n_near):
                    near[s] = nearest[i, s]
            n_seen = n_near  # the slots within sensor range (nearest first: a prefix)
            if layout.sensor_range != math.inf:
                n_seen = 0
                while n_seen < n_near and gaps[i, near[n_seen]] <= layout.sensor_range:
                    n_seen += 1
            for s in range(n_seen):
                b = near[s]
                for a in range(dim):
                    k = _put(out, i, k, (centers[f, b, a] - state[i, a]) * inv_l)
                k = _put(out, i, k, radii[f, b] * inv_l)
                k = _put(out, i, k, gaps[i, b] * inv_l)
            for _slot in range(n_seen, layout.obstacle_slots):
                for _ in range(dim + 1):
                    k = _put(out, i, k, 0.0)
                k = _put(out, i, k, 1.0)
            # the same bodies' velocities relative to the chaser (moving fields)
            if layout.obstacle_velocity_slots:
                k = layout.obstacle_velocities
                for s in range(n_seen):
                    b = near[s]
                    for a in range(dim):
                        k = _put(out, i, k, (velocities[f, b, a] - state[i, dim + a]) * inv_v)
                for _slot in range(n_seen, layout.obstacle_velocity_slots):
                    for _ in range(dim):
                        k = _put(out, i, k, 0.0)

        # lidar: ray ranges / lidar_range
        if layout.lidar_rays:
            k = layout.lidar
            reach = min(layout.lidar_range, layout.sensor_range)
            ray_ranges(
                state[i, :dim], lidar_directions, reach, f, centers, radii,
                field.polygon_start, n_vertices, vertices, attitude, ranges,
            )  # fmt: skip
            for r in range(ranges.shape[0]):  # nothing within reach reads as the full range
                k = _put(out, i, k, 1.0 if ranges[r] >= reach else ranges[r] / layout.lidar_range)

        # budgets: Δv remaining, time remaining (fractions)
        k = layout.budgets
        budget = rules.delta_v_budget
        spent = delta_v[i]
        k = _put(out, i, k, 1.0 if budget == math.inf else max(budget - spent, 0.0) / budget)
        k = _put(out, i, k, max(horizon - steps[i], 0.0) / horizon)

        # goal: the current goal at a 10x finer scale
        if layout.goal_slots:
            k = layout.goal
            fine_l = L / 10.0
            s = 0.0
            for a in range(dim):
                if goal >= 0:
                    rel = centers[f, goal, a] - state[i, a]
                elif goal == DOCK_GOAL:
                    rel = dock[i, a] - state[i, a]
                else:
                    rel = 0.0
                s += rel * rel
                k = _put(out, i, k, rel / fine_l)
            for a in range(dim):
                rel_v = 0.0 if goal == NO_GOAL else -state[i, dim + a]
                if moving and goal >= 0:
                    rel_v = velocities[f, goal, a] - state[i, dim + a]
                k = _put(out, i, k, rel_v / (V / 10.0))
            if goal == DOCK_GOAL:
                gap = math.sqrt(s)
            k = _put(out, i, k, (gap if goal != NO_GOAL else 0.0) / fine_l)

        # goal near field: gap / capture radius and closing speed / capture speed, saturated
        if layout.goal_near_slots:
            k = layout.goal_near
            goal_near_gap, goal_closing = NEAR_LIMIT, 0.0  # no goal: far, not closing
            if goal != NO_GOAL:
                dist2, toward = 0.0, 0.0
                for a in range(dim):
                    rel = (
                        dock[i, a] - state[i, a]
                        if goal == DOCK_GOAL
                        else centers[f, goal, a] - state[i, a]
                    )
                    rel_v = state[i, dim + a]  # the chaser's velocity relative to the goal
                    if moving and goal >= 0:
                        rel_v -= velocities[f, goal, a]
                    dist2 += rel * rel
                    toward += rel * rel_v
                dist = math.sqrt(dist2)
                if goal == DOCK_GOAL:
                    gap = dist
                goal_near_gap = min(max(gap, 0.0) / rules.capture_radius, NEAR_LIMIT)
                if dist > 0.0:
                    goal_closing = min(
                        max(toward / dist / rules.capture_speed, -NEAR_LIMIT), NEAR_LIMIT
                    )
            k = _put(out, i, k, goal_near_gap)
            k = _put(out, i, k, goal_closing)

        # teammates: the other chasers of the field still flying, nearest first
        if layout.teammate_slots:
            _teammates(i, f, rules, layout, missions, field, inv_l, inv_v, mates, mate_d2, out)


@inlined
def _teammates(i, f, rules, layout, missions, field, inv_l, inv_v, mates, mate_d2, out):
    """The teammates block of row ``i`` (field ``f``): per slot, the nearest other chasers of
    the field still flying (and, with :attr:`~debris_gym.mission_data.Rules.arrived_stay`,
    those held at their slots; ties by row), relative position / L, relative velocity / V, the
    vector from it to the goal it heads for / L (:func:`~debris_gym.goal.current_goal`), and
    1 if it flies (0 if held); empty slots 0. ``mates`` (int64) and ``mate_d2`` are scratch of
    the slot count."""
    state, dock, centers = missions.state, field.dock, field.centers
    # the flags read once here, not through the record in the loop (each read of a record's
    # array inside the loop costs a reference-count update)
    success, collision = missions.success, missions.collision
    out_of_bounds, budget_spent = missions.out_of_bounds, missions.budget_spent
    gaps, captured = missions.gaps, missions.captured
    dim = dock.shape[1]
    n_slots = mates.shape[0]
    count = 0
    first = f * rules.n_chasers
    for j in range(first, first + rules.n_chasers):
        if j == i or collision[j] or out_of_bounds[j] or budget_spent[j]:
            continue
        if success[j] and not rules.arrived_stay:
            continue
        d2 = 0.0
        for a in range(dim):
            d = state[j, a] - state[i, a]
            d2 += d * d
        count = _keep_smallest(d2, j, count, mate_d2, mates)
    k = layout.teammates
    for s in range(n_slots):
        if s >= count:
            for _ in range(3 * dim + 1):
                k = _put(out, i, k, 0.0)
            continue
        j = mates[s]
        for a in range(dim):
            k = _put(out, i, k, (state[j, a] - state[i, a]) * inv_l)
        for a in range(dim):
            k = _put(out, i, k, (state[j, dim + a] - state[i, dim + a]) * inv_v)
        goal, _, _ = current_goal(
            j, gaps, captured, rules.queued, rules.return_to_dock, rules.chaser_radius
        )
        for a in range(dim):
            heading = 0.0
            if goal >= 0:
                heading = centers[f, goal, a] - state[j, a]
            elif goal == DOCK_GOAL:
                heading = dock[j, a] - state[j, a]
            k = _put(out, i, k, heading * inv_l)
        k = _put(out, i, k, 0.0 if success[j] else 1.0)


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


@inlined
def _keep_smallest(value, index, count, best, chosen):
    """Offer ``index`` with ``value`` to the ``count`` smallest values so far, kept sorted in
    ``best`` with their indices in ``chosen`` (at most ``best``'s length); returns the new
    count. Strict comparisons: an equal value stays behind the ones offered before it."""
    n = best.shape[0]
    if n == 0:
        return count
    if count == n:
        if not value < best[n - 1]:
            return count
        pos = n - 1
    else:
        pos = count
        count += 1
    while pos > 0 and value < best[pos - 1]:
        best[pos] = best[pos - 1]
        chosen[pos] = chosen[pos - 1]
        pos -= 1
    best[pos] = value
    chosen[pos] = index
    return count


@inlined
def _select_nearest(gaps, first, skip, nearest, best):
    """The bodies ``first …`` except ``skip`` with the smallest ``gaps`` (B,), nearest first (ties
    by index), into ``nearest``; ``best`` is scratch of its length (their gaps, kept beside the
    indices: comparing with them directly is cheaper than through ``gaps[nearest[k]]``)."""
    n = nearest.shape[0]
    count = 0
    for b in range(first, gaps.shape[0] if n else first):
        if b == skip:
            continue
        count = _keep_smallest(gaps[b], b, count, best, nearest)
