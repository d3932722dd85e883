"""What a mission shell checks and reads of its fields: the shape a batch must have to hold a
field, initial chaser states checked against the fields a reset installs, and a drawn field
as a :class:`~debris_gym.scenario.Scenario`."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from debris_gym.batch_geometry import FieldBatch
from debris_gym.config import EnvConfig
from debris_gym.envs.common import checked_chaser_states
from debris_gym.field_spec import MAX_POLYGON_VERTICES, FieldArrays, scenario_from_arrays
from debris_gym.geometry import FieldGeometry
from debris_gym.mission_batch import MissionBatch, Physics
from debris_gym.scenario import Scenario

__all__ = [
    "FieldShape",
    "batch_holds",
    "checked_initial_states",
    "drawn_scenario",
    "drawn_shape",
    "scenario_shape",
]


class FieldShape(NamedTuple):
    """What a batch must be made for to hold a field: its physics and sizes."""

    physics: Physics
    n_targets: int
    n_bodies: int
    polygon_targets: bool
    """Some target is a polygon (the batch must let every body be one)."""


def scenario_shape(scenario: Scenario) -> FieldShape:
    """The shape of a pinned field (or the paper world)."""
    return FieldShape(
        Physics(scenario.mean_motion, scenario.dt, scenario.max_accel),
        len(scenario.targets),
        len(scenario.bodies),
        any(t.vertices is not None for t in scenario.targets),
    )


def drawn_shape(config: EnvConfig, fields: FieldArrays) -> FieldShape:
    """The shape of fields drawn for ``config`` (their targets are circles / spheres)."""
    physics = Physics(config.n, config.dt, config.max_accel)
    return FieldShape(physics, fields.n_targets, fields.radii.shape[1], False)


def batch_holds(batch: MissionBatch, shape: FieldShape) -> bool:
    """Can ``batch`` hold fields of ``shape`` as it is?"""
    return (
        batch.physics == shape.physics
        and batch.n_targets == shape.n_targets
        and batch.field.n_bodies == shape.n_bodies
        and (not shape.polygon_targets or batch.field.polygon_start == 0)
    )


def checked_initial_states(
    value: Any,
    num: int,
    chasers: int,
    config: EnvConfig,
    field_size: float,
    scenario: Scenario | None,
    fields: FieldArrays | None,
) -> np.ndarray:
    """A reset's ``chaser_state`` option, (2·dim,) or (num, 2·dim), checked against the fields
    the reset installs (:func:`~debris_gym.envs.common.checked_chaser_states`): ``scenario``
    in every row (pinned or the paper world), or else the drawn ``fields`` (one per field,
    ``chasers`` rows each) with their gaps as the shell's batch would give them;
    ``field_size`` (m) the drawn fields' side.

    Raises:
        ValueError: naming the bad state.
    """
    if fields is None:
        assert scenario is not None
        geometry = FieldGeometry(scenario)
        return checked_chaser_states(
            value, num, scenario.low, scenario.high, scenario.size / scenario.dt,
            geometry.signed_distance, config.chaser_radius,
        )  # fmt: skip
    bodies = fields.radii.shape[1]
    check = FieldBatch(num, bodies, config.dim, MAX_POLYGON_VERTICES, fields.n_targets)
    check.load_arrays(
        np.arange(num, dtype=np.int64), *(np.repeat(a, chasers, axis=0) if chasers > 1 else a
        for a in (fields.centers, fields.radii, fields.vertices, fields.n_vertices))
    )  # fmt: skip
    low, high = np.array(fields.bounds).T
    return checked_chaser_states(
        value, num, low, high, field_size / config.dt, check.gaps, config.chaser_radius
    )


def drawn_scenario(batch: MissionBatch, i: int, config: EnvConfig, field_size: float) -> Scenario:
    """Field ``i`` of ``batch``, a drawn one of side ``field_size`` (m), as a
    :class:`~debris_gym.scenario.Scenario` as it was drawn at t = 0 (its bodies have moved
    since)."""
    field, d = batch.field, config.dim
    t = batch.n_targets
    vertices, counts = field.vertex_arrays(i)
    counts = counts[t - field.polygon_start :]
    vertices = vertices[t - field.polygon_start :]
    n_obstacles = field.n_bodies - t
    if counts.shape[0] != n_obstacles:  # 3D: spheres only, the batch keeps no polygon slots
        vertices, counts = np.zeros((n_obstacles, 0, 2)), np.zeros(n_obstacles, dtype=int)
    half = field_size / 2.0
    moving = config.debris_motion != "frozen"
    start = field.start_states[i]
    spins = np.zeros(field.n_bodies)
    spins[field.polygon_start :] = field.spins[i]
    return scenario_from_arrays(
        start[:, :d], field.radii[i], vertices, counts, t, ((-half, half),) * d,
        mean_motion=config.n, dt=config.dt, max_accel=config.max_accel,
        velocities=start[:, d:] if moving else None, spins=spins if moving else None,
    )  # fmt: skip
