"""The errors of the uncertain world, compiled: navigation (what the chaser observes) and
actuation (what its thrusters do).

Every error is a pure function of the episode's key (:attr:`Missions.noise_key
<debris_gym.mission_data.Missions.noise_key>`, drawn by the env from its seeded generator),
the step and the element it perturbs: a counter-based generator (SplitMix64 [Steele14] hashed
over those three, then Box–Muller), not a stream. So the errors of one mission do not depend
on how many missions a batch holds or in which order its rows step, the single env and a row
of the vector env see the same errors from the same seed, and the world with every option at
zero draws nothing.

* **Navigation** (``nav_sigma_position`` m, ``nav_sigma_velocity`` m/s, per axis): the
  observation is written from an observed copy of the world — the chaser's state and every
  body's position and velocity plus independent Gaussian errors (drawn afresh at every
  observation, or once per episode with ``nav_bias``) — with the gaps and the obstacle ranking
  measured again on it (:func:`navigate_rows`). The step judges the truth, never this copy.
* **Actuation** (:func:`err_thrust`): per step, the thrusters miss with
  ``thrust_miss_probability`` (no thrust, no Δv); otherwise the commanded acceleration is
  scaled by 1 + ``thrust_sigma_magnitude``·N(0, 1) (not below 0) and turned by Gaussian angles
  of ``thrust_sigma_pointing`` rad per transverse axis (one angle in 2D). The Δv budget is
  charged for what the thrusters did.

No gymnasium import.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from debris_gym.batch_geometry import field_gaps
from debris_gym.body import Body
from debris_gym.config import EnvConfig
from debris_gym.gap_order import sort_by_gap
from debris_gym.jit import inlined, kernel
from debris_gym.scenario import Scenario

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2⁻⁵³

STREAM_NAVIGATION = 1
"""Stream of the navigation errors."""
STREAM_THRUST = 2
"""Stream of the actuation errors."""

BIAS_STEP = -1
"""The step index whose draws a held (``nav_bias``) navigation error uses."""


@inlined
def mix64(x):
    """SplitMix64's output function [Steele14]: a bijective avalanche of the uint64 ``x``."""
    z = x + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@inlined
def unit_uniform(key, stream, step, index):
    """A uniform number in (0, 1], a pure function of (``key``, ``stream``, ``step``,
    ``index``) (integers; ``step`` may be −1)."""
    h = mix64(key ^ mix64(np.uint64(stream)))
    h = mix64(h ^ mix64(np.uint64(step + 1)))
    h = mix64(h + np.uint64(index) * _GOLDEN)
    return (float(h >> _S11) + 1.0) * _TO_UNIT


@inlined
def standard_normal(key, stream, step, index):
    """A standard normal number, a pure function of its arguments (Box–Muller on the uniforms
    of elements 2·index and 2·index + 1)."""
    u1 = unit_uniform(key, stream, step, 2 * index)
    u2 = unit_uniform(key, stream, step, 2 * index + 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@inlined
def err_thrust(key, step, rules, accel):
    """The thrusters' errors of step ``step`` applied to the commanded acceleration ``accel``
    (dim,) in place (see the module docstring)."""
    if unit_uniform(key, STREAM_THRUST, step, 0) <= rules.thrust_miss_probability:
        for k in range(accel.shape[0]):
            accel[k] = 0.0
        return
    gain = max(
        1.0 + rules.thrust_sigma_magnitude * standard_normal(key, STREAM_THRUST, step, 1), 0.0
    )
    sigma = rules.thrust_sigma_pointing
    if accel.shape[0] == 2:
        angle = sigma * standard_normal(key, STREAM_THRUST, step, 2)
        c, s = math.cos(angle), math.sin(angle)
        x, y = accel[0], accel[1]
        accel[0] = gain * (c * x - s * y)
        accel[1] = gain * (s * x + c * y)
        return
    x, y, z = accel[0], accel[1], accel[2]
    norm = math.sqrt(x * x + y * y + z * z)
    if norm == 0.0 or sigma == 0.0:
        for k in range(3):
            accel[k] *= gain
        return
    # two unit vectors across the thrust: e1 ⟂ u (from the axis u is least along), e2 = u × e1
    ux, uy, uz = x / norm, y / norm, z / norm
    if abs(ux) <= abs(uy) and abs(ux) <= abs(uz):
        ax, ay, az = 0.0, uz, -uy
    elif abs(uy) <= abs(uz):
        ax, ay, az = -uz, 0.0, ux
    else:
        ax, ay, az = uy, -ux, 0.0
    an = math.sqrt(ax * ax + ay * ay + az * az)
    e1x, e1y, e1z = ax / an, ay / an, az / an
    e2x, e2y, e2z = uy * e1z - uz * e1y, uz * e1x - ux * e1z, ux * e1y - uy * e1x
    a1 = sigma * standard_normal(key, STREAM_THRUST, step, 2)
    a2 = sigma * standard_normal(key, STREAM_THRUST, step, 3)
    angle = math.sqrt(a1 * a1 + a2 * a2)
    if angle == 0.0:
        for k in range(3):
            accel[k] *= gain
        return
    # turn u by `angle` toward the transverse direction (a1 e1 + a2 e2) / angle
    tx = (a1 * e1x + a2 * e2x) / angle
    ty = (a1 * e1y + a2 * e2y) / angle
    tz = (a1 * e1z + a2 * e2z) / angle
    c, s = math.cos(angle), math.sin(angle)
    accel[0] = gain * norm * (c * ux + s * tx)
    accel[1] = gain * norm * (c * uy + s * ty)
    accel[2] = gain * norm * (c * uz + s * tz)


@kernel
def navigate_rows(
    sigma_position, sigma_velocity, bias, missions, field, state, centers, velocities, gaps,
    nearest,
):  # fmt: skip
    """The observed copy of every mission's world, one chaser per field (row i flies in field
    i): ``state`` (N, 2·dim) the chaser's state and ``centers`` / ``velocities`` (N, B, dim)
    the bodies, each plus the navigation errors of the row's key and step (a held bias: step
    :data:`BIAS_STEP`); then ``gaps`` (N, B) and ``nearest`` (N, O) measured on the copy.
    Element e of a row's draws: the chaser's 2·dim first, then body b's 2·dim from
    2·dim·(b + 1)."""
    truth, keys, steps = missions.state, missions.noise_key, missions.steps
    dim = truth.shape[1] // 2
    n_bodies = centers.shape[1]
    for i in range(truth.shape[0]):
        key = keys[i]
        step = BIAS_STEP if bias else steps[i]
        for a in range(dim):
            state[i, a] = truth[i, a] + sigma_position * standard_normal(
                key, STREAM_NAVIGATION, step, a
            )
            state[i, dim + a] = truth[i, dim + a] + sigma_velocity * standard_normal(
                key, STREAM_NAVIGATION, step, dim + a
            )
        for b in range(n_bodies):
            e = 2 * dim * (b + 1)
            for a in range(dim):
                centers[i, b, a] = field.centers[i, b, a] + sigma_position * standard_normal(
                    key, STREAM_NAVIGATION, step, e + a
                )
                velocities[i, b, a] = field.velocities[i, b, a] + sigma_velocity * (
                    standard_normal(key, STREAM_NAVIGATION, step, e + dim + a)
                )
        field_gaps(
            state[i, :dim], i, centers, field.radii, field.polygon_start, field.polygons,
            field.n_vertices, field.vertices, field.attitude, gaps[i],
        )  # fmt: skip
        for k in range(nearest.shape[1]):
            nearest[i, k] = missions.nearest[i, k]
        sort_by_gap(gaps[i], nearest[i])


@kernel
def navigation_errors(key, step, sigma_position, sigma_velocity, out):
    """The navigation errors of step ``step`` (:data:`BIAS_STEP` for a held bias) of the
    episode of key ``key`` into ``out`` (1 + B, 2·dim): row 0 the chaser's, row 1 + b body
    b's (position errors m, then velocity errors m/s): what :func:`navigate_rows` adds."""
    dim = out.shape[1] // 2
    for r in range(out.shape[0]):
        e = 2 * dim * r
        for a in range(dim):
            out[r, a] = sigma_position * standard_normal(key, STREAM_NAVIGATION, step, e + a)
            out[r, dim + a] = sigma_velocity * standard_normal(
                key, STREAM_NAVIGATION, step, e + dim + a
            )


def field_with_states(template: Scenario, states: np.ndarray, label: str) -> Scenario:
    """``template`` (its bounds, dock, bodies' shapes and sizes) with every body's initial
    state (B, 2·dim) replaced by ``states``; ``label`` is added to its name."""
    dim = template.dim

    def moved(body: Body, state: np.ndarray) -> Body:
        velocity = tuple(map(float, state[dim:])) if template.moving else body.velocity
        return dataclasses.replace(body, position=tuple(map(float, state[:dim])), velocity=velocity)

    n_t = len(template.targets)
    return dataclasses.replace(
        template,
        targets=tuple(moved(b, states[k]) for k, b in enumerate(template.targets)),
        obstacles=tuple(moved(b, states[n_t + k]) for k, b in enumerate(template.obstacles)),
        name=f"{template.name} ({label})".strip(),
    )


def estimated_field(truth: Scenario, key: int, config: EnvConfig) -> Scenario:
    """``truth`` with every body's initial state plus the navigation errors of the first
    observation of the episode of error key ``key`` (of the held bias with ``nav_bias``): the
    field as the chaser's navigation saw it at the episode's start."""
    dim = truth.dim
    errors = np.empty((1 + len(truth.bodies), 2 * dim))
    step = BIAS_STEP if config.nav_bias else 0
    navigation_errors(
        np.uint64(key), step, float(config.nav_sigma_position), float(config.nav_sigma_velocity),
        errors,
    )  # fmt: skip
    return field_with_states(truth, truth.initial_body_states() + errors[1:], "navigated")
