"""A compiled CW guidance law toward the current goal: the base of ``action="residual"``.

The law steers the chaser to a *hold point* of its current goal (:func:`debris_gym.goal.
current_goal`) and brings it to rest there relative to the goal:

* a target: the point on the line from the chaser to the target's centre where the gap
  between the two surfaces is :attr:`BaseLaw.standoff` (half the capture radius, the middle of
  the capture zone), moving with the target;
* the dock (every target captured, a return required): the dock itself, at rest in LVLH;
* nothing left: no thrust.

Each step it asks for a velocity relative to the goal along the line of sight, of magnitude

    v(s) = min(v_max, √(2 a_b |s|), k |s|)        (at most c/2 when |s| ≤ standoff)

where s (m) is the distance still to go (negative: too close, the law backs off), v_max
(:data:`APPROACH_SPEED`) the approach speed limit, a_b = :data:`BRAKE_FRACTION` · max_accel a
braking profile, k = :data:`CLOSING_FRACTION` / dt the final closing rate (a linear law that
ends without overshoot under the step's zero-order hold) and c the capture speed. It then
solves for the thrust that gives exactly that relative velocity at the step's end under the
CWH model — a one-step deadbeat law on the velocity: with x⁺ = Φ x + Γ u over one step (the
exact zero-order hold of :func:`debris_gym.dynamics.discretize`, the env's own transition) and
the goal's end velocity g⁺ (Φ_v g for a target on its unforced CW motion, 0 for the dock or a
frozen field),

    u = Γ_v⁻¹ (g⁺ + w − Φ_v x)

with Φ_v, Γ_v the velocity rows of Φ and Γ and w the wanted relative velocity. The command is
u / max_accel brought inside the thrust model's set (the unit ball for "ball", the box for
"box"). Tangential relative velocity is cancelled every step: the approach is a straight line
of sight.

The law does not plan around debris (a residual policy learns that). It has one simple
avoidance term, so that it can leave a target it has just captured when the next goal lies
behind it: for every body but the goal whose surface is within :data:`REPEL_RANGE` of the
chaser's surface, with n the unit vector from the body's centre to the chaser and
η = 1 − gap / REPEL_RANGE (1 at contact, 0 at the range), the share η of the wanted velocity's
component toward the body is turned into the direction of its tangential part (left in the
orbit plane when it has none), and REPEL_SPEED · η is added along n. It sees no body's motion
but the goal's and looks no further ahead than that range.

One implementation serves every caller: the residual mode's compiled pre-step
(:func:`residual_rows`, called by :meth:`debris_gym.mission_batch.MissionBatch.step`) and
:func:`base_commands` (the ``base-law`` baseline) run the same inlined :func:`goal_command`
on a batch's arrays, so the same state gives the same bits. No gymnasium import. Keys in
square brackets refer to docs/references.md ([Silver18]: residual policy learning).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.dynamics import discretize
from debris_gym.goal import DOCK_GOAL, TARGET_GOAL_MIN, current_goal
from debris_gym.jit import inlined, kernel
from debris_gym.mission_data import Field, Missions

__all__ = [
    "APPROACH_SPEED",
    "BRAKE_FRACTION",
    "CLOSING_FRACTION",
    "REPEL_RANGE",
    "REPEL_SPEED",
    "BaseLaw",
    "base_commands",
    "make_base_law",
    "residual_rows",
]

APPROACH_SPEED = 1.0
"""v_max: the law's speed limit relative to its goal (m/s)."""

BRAKE_FRACTION = 0.25
"""a_b / max_accel: the braking deceleration the approach profile plans with (the rest of the
thrust is left for the goal's motion and the orbital dynamics)."""

CLOSING_FRACTION = 0.3
"""k · dt: the share of the remaining distance the wanted speed covers per step near the goal.
Under the one-step velocity law the distance then shrinks by real factors (0.6, 0.25) per step
in free space — no overshoot; above about 0.34 the factors turn complex and it oscillates."""

REPEL_RANGE = 30.0
"""Surface-to-surface gap (m) within which a body other than the goal bends the approach."""

REPEL_SPEED = 0.5
"""Speed away from a body (m/s) added at contact, falling linearly to 0 at :data:`REPEL_RANGE`."""

ZONE_SPEED_FRACTION = 0.5
"""Within ``standoff`` of the hold point the wanted speed is at most this share of
``capture_speed``."""


class BaseLaw(NamedTuple):
    """The fixed parameters of the law for one physics and config (SI units)."""

    velocity_map: np.ndarray
    """(dim, 2·dim) Φ_v: the velocity rows of the one-step state-transition matrix Φ(dt)."""
    input_inverse: np.ndarray
    """(dim, dim) Γ_v⁻¹: the inverse of the velocity rows of the one-step input matrix."""
    max_accel: float
    """Thrust limit (m/s²)."""
    box_thrust: bool
    """Thrust model "box" (clip per axis) rather than "ball" (scale onto the unit ball)."""
    speed_limit: float
    """v_max (m/s)."""
    brake: float
    """a_b (m/s²)."""
    gain: float
    """k (1/s)."""
    standoff: float
    """Gap (m) between the chaser's and the target's surfaces at the hold point."""
    zone_speed: float
    """Wanted speed limit (m/s) within ``standoff`` of the hold point."""
    repel_range: float
    """Gap (m, surface to surface) within which other bodies repel."""
    repel_speed: float
    """Repulsion speed at contact (m/s)."""
    moving: bool
    """Targets fly unforced CW motion (``debris_motion`` not "frozen")."""
    chaser_radius: float
    """Chaser radius (m) (the goal rule's gap is surface to surface)."""
    queued: bool
    """``target_order == "queued"`` (the goal rule)."""
    return_to_dock: bool
    """``return_to_dock`` (the goal rule)."""
    chasers: int = 1
    """Chasers per field K: row i flies in field i // K (a swarm's rows; each row's goal is
    its own, by its capture flags, which mark the targets assigned to others as taken)."""


def make_base_law(
    cfg: EnvConfig, mean_motion: float, dt: float, max_accel: float, chasers: int = 1
) -> BaseLaw:
    """The law for ``cfg``'s rules and a field's physics: mean motion n (rad/s), step ``dt``
    (s) and thrust limit ``max_accel`` (m/s²) — a scenario's, which may differ from the
    config's for a pinned field — with ``chasers`` per field."""
    d = cfg.dim
    model = discretize(float(mean_motion), float(dt), d)
    return BaseLaw(
        velocity_map=np.ascontiguousarray(model.ad[d:]),
        input_inverse=np.ascontiguousarray(np.linalg.inv(model.bd[d:])),
        max_accel=float(max_accel),
        box_thrust=cfg.thrust_model == "box",
        speed_limit=APPROACH_SPEED,
        brake=BRAKE_FRACTION * float(max_accel),
        gain=CLOSING_FRACTION / float(dt),
        standoff=0.5 * float(cfg.capture_radius),
        zone_speed=ZONE_SPEED_FRACTION * float(cfg.capture_speed),
        repel_range=REPEL_RANGE,
        repel_speed=REPEL_SPEED,
        moving=cfg.debris_motion != "frozen",
        chaser_radius=float(cfg.chaser_radius),
        queued=cfg.target_order == "queued",
        return_to_dock=bool(cfg.return_to_dock),
        chasers=int(chasers),
    )


@inlined
def wanted_velocity(state, goal, target, gap, law, w):
    """The velocity (m/s) relative to the goal the law wants at the step's end, into ``w``
    (dim,): v(s) along the line of sight (see the module docstring).

    Args:
        state: (2·dim,) the chaser's LVLH position (m) and velocity (m/s).
        goal: (2·dim,) the goal's state: a target's position and velocity, or the dock's
            position and zero velocity.
        target: the goal is a target (its hold point is ``law.standoff`` off its surface);
            else the dock (its hold point is the dock).
        gap: a target's surface-to-surface gap to the chaser (m; the goal rule's); unused for
            the dock.
        law: :class:`BaseLaw`.
        w: (dim,) out.
    """
    dim = w.shape[0]
    r2 = 0.0
    for a in range(dim):
        off = goal[a] - state[a]
        r2 += off * off
    r = math.sqrt(r2)
    togo = gap - law.standoff if target else r
    far = abs(togo)
    speed = min(law.speed_limit, math.sqrt(2.0 * law.brake * far), law.gain * far)
    if far <= law.standoff:
        speed = min(speed, law.zone_speed)
    scale = speed / r if r > 0.0 else 0.0
    if togo < 0.0:
        scale = -scale
    for a in range(dim):
        w[a] = scale * (goal[a] - state[a])


@inlined
def deflect(i, f, skip, law, state, gaps, centers, w):
    """Bend the wanted velocity ``w`` (dim,) of row ``i``'s chaser around every body of field
    ``f`` but ``skip`` within ``law.repel_range`` (see the module docstring)."""
    dim = w.shape[0]
    for b in range(gaps.shape[1]):
        gap = gaps[i, b] - law.chaser_radius
        if b == skip or gap >= law.repel_range:
            continue
        r2 = 0.0
        for a in range(dim):
            off = state[i, a] - centers[f, b, a]
            r2 += off * off
        if r2 == 0.0:
            continue
        r = math.sqrt(r2)
        near = 1.0 - max(gap, 0.0) / law.repel_range  # 1 at contact, 0 at the range
        inward = 0.0  # w · n, n the unit normal from the body's centre to the chaser
        for a in range(dim):
            inward += w[a] * (state[i, a] - centers[f, b, a]) / r
        blocked = near * inward if inward < 0.0 else 0.0
        # the tangential part of w sets the way around; if w points at the centre, turn left
        # in the orbit plane
        t0 = w[0] - inward * (state[i, 0] - centers[f, b, 0]) / r
        t1 = w[1] - inward * (state[i, 1] - centers[f, b, 1]) / r
        t2 = w[2] - inward * (state[i, 2] - centers[f, b, 2]) / r if dim > 2 else 0.0
        tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        if tn <= 1e-6 * (abs(inward) + 1e-12):
            t0 = -(state[i, 1] - centers[f, b, 1]) / r
            t1 = (state[i, 0] - centers[f, b, 0]) / r
            t2 = 0.0
            tn = math.sqrt(t0 * t0 + t1 * t1)
            if tn == 0.0:  # straight above or below the body (3D)
                t0, tn = 1.0, 1.0
        push = law.repel_speed * near - blocked  # outward
        for a in range(dim):
            n_a = (state[i, a] - centers[f, b, a]) / r
            t_a = t0 if a == 0 else (t1 if a == 1 else t2)
            w[a] += push * n_a - blocked * t_a / tn


@inlined
def thrust_for(state, goal, free, w, law, out):
    """The normalised command (dim,) into ``out`` that makes the chaser's velocity relative
    to the goal ``w`` (m/s) at the step's end under the CWH model: Γ_v⁻¹ (g⁺ + w − Φ_v x) /
    max_accel, brought inside the thrust model's set (``free``: the goal flies unforced CW
    motion, g⁺ = Φ_v g; else it is at rest, g⁺ = 0)."""
    dim = out.shape[0]
    vmap, inv = law.velocity_map, law.input_inverse
    for a in range(dim):  # the velocity change the thrust must make
        s = w[a]
        for k in range(2 * dim):
            s -= vmap[a, k] * state[k]
            if free:
                s += vmap[a, k] * goal[k]
        out[a] = s
    # out ← Γ_v⁻¹ out / max_accel (dim ≤ 3: the old out held in locals while it is rewritten)
    w0, w1 = out[0], out[1]
    w2 = out[2] if dim > 2 else 0.0
    norm2 = 0.0
    for a in range(dim):
        s = inv[a, 0] * w0 + inv[a, 1] * w1
        if dim > 2:
            s += inv[a, 2] * w2
        out[a] = s / law.max_accel
        norm2 += out[a] * out[a]
    if law.box_thrust:
        for a in range(dim):
            out[a] = min(max(out[a], -1.0), 1.0)
    elif norm2 > 1.0:
        norm = math.sqrt(norm2)
        for a in range(dim):
            out[a] = out[a] / norm


@inlined
def goal_command(i, f, law, state, gaps, captured, centers, velocities, dock, goal, w, out):
    """The law's command for mission (row) ``i`` flying in field ``f`` into ``out`` (dim,):
    its current goal by the goal rule; ``goal`` (2·dim,) and ``w`` (dim,) scratch."""
    dim = out.shape[0]
    index, gap, _ = current_goal(
        i, gaps, captured, law.queued, law.return_to_dock, law.chaser_radius
    )
    if index >= TARGET_GOAL_MIN:
        for a in range(dim):
            goal[a] = centers[f, index, a]
            goal[dim + a] = velocities[f, index, a]
    elif index == DOCK_GOAL:
        for a in range(dim):
            goal[a] = dock[i, a]
            goal[dim + a] = 0.0
    else:  # nothing left
        for a in range(dim):
            out[a] = 0.0
        return
    target = index >= TARGET_GOAL_MIN
    wanted_velocity(state[i], goal, target, gap, law, w)
    if law.repel_speed > 0.0:
        deflect(i, f, index, law, state, gaps, centers, w)
    thrust_for(state[i], goal, target and law.moving, w, law, out)


@kernel
def residual_rows(live, actions, law, missions, field, out):
    """The residual mode's commands of the rows in ``live``: ``out[i]`` = ``actions[i]`` plus
    the law's command of row ``i``, clipped to [−1, 1] per axis (row i flies in field
    i // ``law.chasers``). Rows not live are left as they are."""
    state, gaps, captured = missions.state, missions.gaps, missions.captured
    centers, velocities, dock = field.centers, field.velocities, field.dock
    dim = out.shape[1]
    goal = np.empty(2 * dim)
    w = np.empty(dim)
    base = np.empty(dim)
    for i in range(live.shape[0]):
        if not live[i]:
            continue
        f = i // law.chasers
        goal_command(i, f, law, state, gaps, captured, centers, velocities, dock, goal, w, base)
        for a in range(dim):
            out[i, a] = min(max(actions[i, a] + base[a], -1.0), 1.0)


@kernel
def _base_rows(rows, law, missions, field, out):
    state, gaps, captured = missions.state, missions.gaps, missions.captured
    centers, velocities, dock = field.centers, field.velocities, field.dock
    dim = out.shape[1]
    goal = np.empty(2 * dim)
    w = np.empty(dim)
    for r in range(rows.shape[0]):
        i = rows[r]
        f = i // law.chasers
        goal_command(i, f, law, state, gaps, captured, centers, velocities, dock, goal, w, out[r])


def base_commands(law: BaseLaw, missions: Missions, field: Field, rows: Any = None) -> np.ndarray:
    """The law's normalised commands for missions ``rows`` of a batch (default: all), from
    Python: the code the residual mode runs inside the step, on the same arrays.

    Args:
        law: :func:`make_base_law`.
        missions: the batch's :class:`~debris_gym.mission_data.Missions` (the chasers' states,
            gaps and capture flags).
        field: the batch's :class:`~debris_gym.mission_data.Field` (bodies and docks; row i
            flies in field i // ``law.chasers``).
        rows: mission indices (default: every row).

    Returns:
        (R, dim) float64 commands inside the thrust model's set (zeros where nothing is left).
    """
    n, dim = missions.state.shape[0], missions.state.shape[1] // 2
    picked = np.arange(n, dtype=np.int64) if rows is None else np.asarray(rows, dtype=np.int64)
    if picked.ndim != 1 or np.any((picked < 0) | (picked >= n)):
        raise ValueError(f"rows must be indices in [0, {n - 1}], got {rows!r}")
    out = np.zeros((picked.shape[0], dim))
    _base_rows(np.ascontiguousarray(picked), law, missions, field, out)
    return out
