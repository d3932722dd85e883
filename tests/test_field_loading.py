"""The reset's load path: fields given as arrays go into a batch as they are.

Independent truth used here: the input arrays themselves, polygon edges recomputed in numpy
(next vertex − this), the world typed in from the config (±field_size/2, dock at the origin), and
``math.cos`` / ``math.sin`` of (spin − n)·dt typed in for the polygons' turns.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.batch_geometry import FieldBatch
from debris_gym.envs import DebrisFieldEnv
from debris_gym.generators import FieldSpec, random_fields

N = 1.1314e-3


def drawn(seeds, spin_max: float = 0.02):
    spec = FieldSpec(
        dim=2, motion="bounded", mean_motion=N, target_clearance=17.0, dock_clearance=50.0,
        min_target_distance=150.0, spin_max=spin_max,
    )  # fmt: skip
    return random_fields([np.random.default_rng(s) for s in seeds], spec, capture_radius=5.0)


def check_loaded(batch: FieldBatch, row: int, fields, k: int, first: int) -> None:
    """Row ``row`` of ``batch`` holds field ``k`` of ``fields``, its polygons from body
    ``first`` on."""
    np.testing.assert_array_equal(batch.centers[row], fields.centers[k])
    np.testing.assert_array_equal(batch.radii[row], fields.radii[k])
    np.testing.assert_array_equal(batch.velocities[row], fields.velocities[k])
    np.testing.assert_array_equal(
        batch.start_states[row], np.hstack([fields.centers[k], fields.velocities[k]])
    )
    np.testing.assert_array_equal(batch.attitude[row], [[1.0, 0.0]] * batch.spins.shape[1])
    start = batch.polygon_start
    np.testing.assert_array_equal(batch.spins[row], fields.spins[k, start:])
    counts = np.zeros(batch.n_bodies - start, dtype=int)
    counts[first - start :] = fields.n_vertices[k]
    np.testing.assert_array_equal(batch.n_vertices[row], counts)
    listed = np.flatnonzero(counts)
    assert batch.polygons[row, 0] == len(listed)
    np.testing.assert_array_equal(batch.polygons[row, 1 : 1 + len(listed)], listed)
    for j, m in enumerate(counts):
        slots = batch.vertices[row, j]
        if m == 0:
            assert not slots.any()
            continue
        rel = fields.vertices[k, j - (first - start), :m]
        np.testing.assert_array_equal(slots[:m, :2], rel)
        absolute = rel + batch.centers[row, start + j]
        np.testing.assert_allclose(slots[:m, 2:], np.roll(absolute, -1, axis=0) - absolute)
        assert not slots[m:].any()


@settings(max_examples=50, deadline=None)
@given(seeds=st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=4), every_body=st.booleans())
def test_loaded_arrays_are_the_fields(seeds, every_body):
    fields = drawn(seeds)
    t, b = fields.n_targets, fields.radii.shape[1]
    start = 0 if every_body else t  # the single env's batch lets any body be a polygon
    batch = FieldBatch(len(seeds) + 2, b, 2, polygon_start=start)
    rows = np.arange(len(seeds))[::-1] + 1
    # rows that held other polygons first: loading replaces everything
    other = drawn([s + 1 for s in seeds])
    batch.load_arrays(
        rows, other.centers, other.radii, other.vertices, other.n_vertices, other.velocities,
        other.spins[:, start:], vertex_start=t,
    )  # fmt: skip
    batch.load_arrays(
        rows, fields.centers, fields.radii, fields.vertices, fields.n_vertices,
        fields.velocities, fields.spins[:, start:], vertex_start=t,
    )  # fmt: skip
    for k, row in enumerate(rows):
        check_loaded(batch, row, fields, k, t)
    for row in (0, len(seeds) + 1):  # untouched
        assert not batch.centers[row].any() and not batch.n_vertices[row].any()


def test_a_field_at_rest_and_a_bigger_polygon_load_too():
    fields = drawn([4])
    t, b = fields.n_targets, fields.radii.shape[1]
    batch = FieldBatch(1, b, 2, max_vertices=3, polygon_start=t)  # grows for 7 vertices
    batch.load_arrays([0], fields.centers, fields.radii, fields.vertices, fields.n_vertices)
    assert batch.max_vertices >= fields.n_vertices.max()
    assert not batch.velocities.any() and not batch.spins.any()
    np.testing.assert_array_equal(batch.start_states[0, :, :2], fields.centers[0])
    np.testing.assert_array_equal(batch.n_vertices[0], fields.n_vertices[0])


def test_wrong_shapes_are_refused_by_name():
    fields = drawn([0])
    t, b = fields.n_targets, fields.radii.shape[1]
    batch = FieldBatch(2, b, 2, polygon_start=t)
    good = dict(
        rows=[0], centers=fields.centers, radii=fields.radii, vertices=fields.vertices,
        n_vertices=fields.n_vertices, velocities=fields.velocities, spins=fields.spins[:, t:],
    )  # fmt: skip
    bad = {
        "centers": fields.centers[:, :-1],
        "radii": fields.radii[:, :-1],
        "velocities": fields.velocities[:, :, :1],
        "spins": fields.spins,
        "n_vertices": fields.n_vertices[:, 1:],
        "vertices": fields.vertices[:, :, :, :1],
    }
    for name, value in bad.items():
        with pytest.raises(ValueError, match=name):
            batch.load_arrays(**{**good, name: value})
    with pytest.raises(ValueError, match="vertex_start"):
        batch.load_arrays(**good, vertex_start=t - 1)
    assert not batch.centers.any()  # nothing was written


def test_the_single_env_turns_its_polygons_at_spin_minus_n():
    env = DebrisFieldEnv(dim=2, debris_motion="bounded", spin_max=0.02)
    cfg = env.config
    for seed in (0, 1):
        env.reset(seed=seed)
        spins = env.scenario.bodies
        turns = env.batch.turns[0]  # the bodies from the batch's polygon_start on
        start = env.batch.field.polygon_start
        for j, body in enumerate(spins[start:]):
            rate = body.spin - cfg.n
            sub = cfg.dt / cfg.collision_substeps
            expected = [
                math.cos(rate * cfg.dt), math.sin(rate * cfg.dt),
                math.cos(rate * sub), math.sin(rate * sub), rate * cfg.dt, rate * sub,
            ]  # fmt: skip
            assert turns[j].tolist() == expected  # bit for bit: every env turns a field alike
        assert any(b.spin != 0.0 for b in spins)


def test_the_single_env_keeps_the_world_of_each_field():
    env = DebrisFieldEnv(dim=2, debris_motion="bounded", field_size=1200.0)
    half = 600.0
    cfg = env.config
    small = drawn([9]).scenario(0, mean_motion=cfg.n, dt=cfg.dt, max_accel=cfg.max_accel)
    for options in (None, {"scenario": small}, None, None):
        env.reset(seed=3, options=options)
        m = env.batch
        limit = small.high if options else np.full(2, half)
        np.testing.assert_array_equal(m.high[0], limit)
        np.testing.assert_array_equal(m.low[0], -limit)
        np.testing.assert_array_equal(m.dock[0], small.dock if options else np.zeros(2))
        assert m.length_scale[0] == (small.size / 2.0 if options else half)
        np.testing.assert_array_equal(env.chaser_state, np.zeros(4))
