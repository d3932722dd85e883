"""Geometry: numpy clearance vs pymunk, swept collision checks, lidar."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.generators import FieldSpec, random_field
from debris_gym.geometry import FieldGeometry, lidar_directions
from debris_gym.scenario import Body, Scenario


def field_2d(seed: int, n_obstacles: int = 20) -> Scenario:
    spec = FieldSpec(dim=2, n_obstacles=n_obstacles, polygon_fraction=0.5)
    return random_field(
        np.random.default_rng(seed),
        spec,
        mean_motion=0.0,
        dt=10.0,
        max_accel=0.05,
        capture_radius=5.0,
    )


@pytest.mark.parametrize("seed", range(5))
def test_numpy_signed_distance_matches_pymunk(seed):
    scen = field_2d(seed)
    geom = FieldGeometry(scen)
    rng = np.random.default_rng(seed)
    # points all over the field, plus points near and inside every body
    pts = [rng.uniform(-500, 500, size=(300, 2))]
    for b in scen.bodies:
        pts.append(np.asarray(b.position) + rng.uniform(-1.3, 1.3, size=(20, 2)) * b.radius)
    pts = np.vstack(pts)
    ours = geom.signed_distance(pts)
    for j, shape in enumerate(geom.shapes):
        ref = np.array([shape.point_query(tuple(p)).distance for p in pts])
        np.testing.assert_allclose(ours[:, j], ref, atol=1e-9, rtol=1e-9)


def test_circle_clearance_hand_computed():
    scen = Scenario(
        dim=2,
        bounds=((-10, 10), (-10, 10)),
        dock=(0, 0),
        targets=(Body(position=(3.0, 4.0), radius=1.0),),
        obstacles=(Body(position=(-6.0, 0.0), radius=2.0),),
    )
    geom = FieldGeometry(scen)
    np.testing.assert_allclose(geom.signed_distance(np.zeros(2)), [4.0, 4.0])
    np.testing.assert_allclose(
        geom.signed_distance(np.array([-6.0, 1.0])), [math.hypot(9, 3) - 1, -1]
    )
    assert geom.clearance(np.array([3.0, 4.0])) == pytest.approx(-1.0)


def test_polygon_distance_hand_computed():
    square = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
    scen = Scenario(
        dim=2,
        bounds=((-10, 10), (-10, 10)),
        dock=(0, 0),
        targets=(Body(position=(8.0, 8.0), radius=1.0),),
        obstacles=(Body(position=(0.0, 0.0), radius=math.sqrt(2), vertices=square),),
    )
    geom = FieldGeometry(scen)
    pts = np.array([[3.0, 0.0], [0.5, 0.0], [4.0, 5.0], [0.0, 0.0]])
    np.testing.assert_allclose(geom.signed_distance(pts)[:, 1], [2.0, -0.5, 5.0, -1.0])


def test_3d_sphere_distance_and_swept_hit():
    scen = Scenario(
        dim=3,
        bounds=((-10, 10),) * 3,
        dock=(0, 0, 0),
        targets=(Body(position=(0.0, 5.0, 0.0), radius=1.0),),
        obstacles=(Body(position=(5.0, 0.0, 0.0), radius=2.0),),
    )
    geom = FieldGeometry(scen, inflate=0.5)
    assert geom.signed_distance(np.array([0.0, 0.0, 3.0])) == pytest.approx(
        [math.sqrt(34) - 1, math.sqrt(34) - 2]
    )
    # passes 1.4 m from the obstacle centre: inside 2 + 0.5 → hit, though both ends are clear
    assert geom.first_hit(np.array([[5.0, -4.0, 1.4], [5.0, 4.0, 1.4]])) == 1
    assert geom.first_hit(np.array([[5.0, -4.0, 2.6], [5.0, 4.0, 2.6]])) == -1
    # first along the path wins; touched() reports every body
    path = np.array([[0.0, 8.0, 0.0], [0.0, 2.0, 0.0], [8.0, 0.0, 0.0]])
    assert geom.first_hit(path) == 0
    assert geom.touched(path) == [0, 1]
    assert geom.touched(np.array([[5.0, -4.0, 2.6], [5.0, 4.0, 2.6]])) == []


def brute_force_hit(scen: Scenario, a, b, inflate: float, samples: int = 4001) -> bool:
    """Independent check: dense sampling of the segment against the exact signed distance."""
    geom = FieldGeometry(scen)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    pts = (1 - t) * np.asarray(a) + t * np.asarray(b)
    return bool((geom.signed_distance(pts) <= inflate).any())


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    ax=st.floats(-500, 500),
    ay=st.floats(-500, 500),
    bx=st.floats(-500, 500),
    by=st.floats(-500, 500),
)
def test_swept_check_agrees_with_dense_sampling(seed, ax, ay, bx, by):
    scen = field_2d(seed % 7, n_obstacles=30)
    geom = FieldGeometry(scen, inflate=1.0)
    got = geom.first_hit(np.array([[ax, ay], [bx, by]])) >= 0
    truth = brute_force_hit(scen, (ax, ay), (bx, by), inflate=1.0)
    if got != truth:
        # only a graze within the sampling resolution may disagree
        seg = math.hypot(bx - ax, by - ay) / 4000
        t = np.linspace(0, 1, 4001)[:, None]
        pts = (1 - t) * np.array([ax, ay]) + t * np.array([bx, by])
        margin = FieldGeometry(scen).signed_distance(pts).min() - 1.0
        assert abs(margin) <= seg + 1e-9


def test_lidar_2d_against_hand_computed_ranges():
    scen = Scenario(
        dim=2,
        bounds=((-100, 100), (-100, 100)),
        dock=(0, 0),
        targets=(Body(position=(0.0, 30.0), radius=5.0),),
        obstacles=(Body(position=(50.0, 0.0), radius=10.0),),
    )
    geom = FieldGeometry(scen)
    ranges = geom.lidar(np.zeros(2), lidar_directions(2, 4), 60.0)
    np.testing.assert_allclose(ranges, [40.0, 25.0, 60.0, 60.0], atol=1e-9)


def test_lidar_3d_against_hand_computed_ranges():
    scen = Scenario(
        dim=3,
        bounds=((-100, 100),) * 3,
        dock=(0, 0, 0),
        targets=(Body(position=(0.0, 0.0, 30.0), radius=5.0),),
        obstacles=(Body(position=(50.0, 0.0, 0.0), radius=10.0),),
    )
    geom = FieldGeometry(scen)
    dirs = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])
    np.testing.assert_allclose(geom.lidar(np.zeros(3), dirs, 60.0), [40.0, 25.0, 60.0, 60.0])
    # from inside a sphere the range is 0
    assert geom.lidar(np.array([50.0, 0, 0]), dirs[:1], 60.0)[0] == 0.0


def test_lidar_directions_are_unit_and_spread():
    for dim, n in ((2, 16), (3, 64)):
        d = lidar_directions(dim, n)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
        assert np.allclose(d.mean(axis=0), 0.0, atol=0.05)


def test_pymunk_space_holds_every_body_with_its_index():
    scen = field_2d(1)
    geom = FieldGeometry(scen)
    assert len(geom.space.shapes) == len(scen.bodies)
    assert [s.body_index for s in geom.shapes] == list(range(len(scen.bodies)))
    kinds = [isinstance(s, pymunk.Poly) for s in geom.shapes]
    assert kinds == [b.is_polygon for b in scen.bodies]


def test_negative_inflate_is_rejected():
    with pytest.raises(ValueError, match="inflate"):
        FieldGeometry(field_2d(0), inflate=-1.0)
