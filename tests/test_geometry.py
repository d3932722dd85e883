"""The library's geometry (:class:`FieldGeometry`, a one-field view of the compiled batch) held to
the independent oracle of ``tests/geometry_oracle.py`` (pymunk in 2D, closed forms for spheres),
on random fields, points (inside bodies and on their surfaces too), segments and rays."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from debris_gym.generators import FieldSpec, random_field
from debris_gym.geometry import FieldGeometry, lidar_directions
from debris_gym.scenario import Body, Scenario
from tests.geometry_oracle import OracleField

IMPLEMENTATIONS = [FieldGeometry, OracleField]
"""Hand-computed cases check the library and the oracle alike (an oracle can be wrong too)."""


def random_scenario(seed: int, dim: int = 2, n_obstacles: int = 20) -> Scenario:
    spec = FieldSpec(dim=dim, n_obstacles=n_obstacles, polygon_fraction=0.5)
    return random_field(
        np.random.default_rng(seed), spec, mean_motion=0.0, dt=10.0, max_accel=0.05,
        capture_radius=5.0,
    )  # fmt: skip


def probe_points(scen: Scenario, rng: np.random.Generator, n_free: int = 100) -> np.ndarray:
    """Points all over the field, and around, inside and on the surface of every body."""
    dim = scen.dim
    pts = [rng.uniform(scen.low, scen.high, size=(n_free, dim))]
    for body in scen.bodies:
        centre = np.asarray(body.position, dtype=float)
        pts.append(centre + rng.uniform(-1.3, 1.3, size=(6, dim)) * body.radius)
        if body.is_polygon:
            verts = np.asarray(body.vertices, dtype=float)
            weights = rng.dirichlet(np.ones(len(verts)), size=4)
            pts.append(centre + weights @ verts)  # inside: convex combinations of the corners
            k = rng.integers(len(verts), size=4)
            u = rng.uniform(size=(4, 1))
            pts.append(centre + verts[k] + u * (verts[(k + 1) % len(verts)] - verts[k]))
        else:
            direction = rng.normal(size=(8, dim))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            depth = np.concatenate([np.ones(4), rng.uniform(0.05, 1.0, size=4)])[:, None]
            pts.append(centre + body.radius * depth * direction)  # on the surface, inside
    return np.vstack(pts)


# --- clearance and nearest points ---------------------------------------------------------------


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), dim=st.sampled_from([2, 3]))
def test_signed_distance_matches_the_oracle(seed, dim):
    scen = random_scenario(seed, dim)
    geom, oracle = FieldGeometry(scen), OracleField(scen)
    pts = probe_points(scen, np.random.default_rng(seed))
    ours = geom.signed_distance(pts)
    np.testing.assert_allclose(ours, oracle.signed_distance(pts), rtol=1e-9, atol=1e-9)
    assert (ours < 0).any() and (np.abs(ours) < 1e-9).any()  # inside and on surfaces covered
    for p, row in zip(pts[::25], ours[::25]):
        np.testing.assert_array_equal(geom.point_gaps(p), row)
        np.testing.assert_array_equal(geom.signed_distance(p), row)
        assert geom.clearance(p) == row.min()


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), dim=st.sampled_from([2, 3]))
def test_nearest_points_and_normals_match_the_oracle(seed, dim):
    scen = random_scenario(seed, dim)
    geom, oracle = FieldGeometry(scen), OracleField(scen)
    pts = probe_points(scen, np.random.default_rng(seed), n_free=40)
    gaps, normals, surface = geom.nearest_points(pts)
    for k, p in enumerate(pts):
        ref_gaps, ref_normals, ref_surface = oracle.nearest(p)
        np.testing.assert_allclose(gaps[k], ref_gaps, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(normals[k], ref_normals, rtol=1e-9, atol=1e-9)
        # pymunk's surface point is NaN for a point exactly on a polygon's edge (0 · 1/0)
        on_edge = np.isnan(ref_surface)
        ref_surface[on_edge] = np.broadcast_to(p, ref_surface.shape)[on_edge]
        np.testing.assert_allclose(surface[k], ref_surface, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=2), 1.0)
    np.testing.assert_allclose(gaps, geom.signed_distance(pts), rtol=1e-9, atol=1e-9)
    # the one-point and one-body forms give the same numbers
    one_gaps, one_normals = geom.gaps_and_normals(pts[0])
    np.testing.assert_array_equal(one_gaps, gaps[0])
    np.testing.assert_array_equal(one_normals, normals[0])
    last = len(scen.bodies) - 1
    one_body = geom.nearest_points(pts[1:2], last, last + 1)
    np.testing.assert_array_equal(one_body[0][0, 0], gaps[1, last])
    np.testing.assert_array_equal(one_body[1][0, 0], normals[1, last])
    np.testing.assert_array_equal(one_body[2][0, 0], surface[1, last])


def test_normals_are_the_gradient_of_the_distance():
    """Away from surfaces and corners' medial lines the normal is ∇d (central differences)."""
    scen = random_scenario(4)
    geom = FieldGeometry(scen)
    rng = np.random.default_rng(4)
    pts = probe_points(scen, rng)
    gaps, normals, _ = geom.nearest_points(pts)
    h = 1e-6
    checked = 0
    for k, p in enumerate(pts):
        fd = np.stack(
            [
                (geom.point_gaps(p + h * e) - geom.point_gaps(p - h * e)) / (2 * h)
                for e in np.eye(2)
            ],
            axis=1,
        )
        smooth = np.abs(gaps[k]) > 0.5
        close = np.all(np.abs(fd - normals[k]) < 1e-4, axis=1)
        checked += int(smooth.sum())
        # a kink (two edges equally near) can only make a few bodies disagree
        assert close[smooth].mean() > 0.9
    assert checked > 1000


# --- swept contacts -----------------------------------------------------------------------------


def _graze(oracle: OracleField, body: int, path: np.ndarray) -> float:
    """|closest approach of the path to ``body`` − inflate| (m), by dense sampling."""
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    pts = np.vstack([(1 - t) * a + t * b for a, b in zip(path[:-1], path[1:])])
    if oracle.dim == 2:
        shape = oracle.shapes[body]
        closest = min(shape.point_query(tuple(p)).distance for p in pts)
    else:
        closest = float(np.linalg.norm(pts - oracle.centers[body], axis=1).min())
        closest -= oracle.radii[body]
    step = max(float(np.linalg.norm(b - a)) for a, b in zip(path[:-1], path[1:])) / 4000
    return abs(closest - oracle.inflate) - step


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    dim=st.sampled_from([2, 3]),
    inflate=st.sampled_from([0.0, 0.5, 4.0]),
    n_segments=st.integers(1, 3),
)
def test_swept_contacts_match_the_oracle(seed, dim, inflate, n_segments):
    scen = random_scenario(seed % 50, dim, n_obstacles=30)
    geom, oracle = FieldGeometry(scen, inflate=inflate), OracleField(scen, inflate=inflate)
    rng = np.random.default_rng(seed)
    centres = scen.body_positions()
    contacts = 0
    for k in range(60):
        start = rng.uniform(scen.low, scen.high)
        if k % 3 == 0:  # start inside a body or at its surface
            start = centres[rng.integers(len(centres))] + rng.normal(0.0, 3.0, dim)
        aim = centres[rng.integers(len(centres))] + rng.normal(0.0, 10.0, dim)
        end = aim if k % 2 else start + rng.uniform(-150.0, 150.0, dim)
        t = np.linspace(0.0, 1.0, n_segments + 1)[:, None]
        bend = rng.normal(0.0, 20.0, dim) * np.sin(np.pi * t)
        path = start + t * (end - start) + bend
        ours, ref = geom.touched(path), oracle.touched(path)
        for body in set(ours) ^ set(ref):
            assert _graze(oracle, body, path) <= 1e-9, (body, ours, ref)
        contacts += bool(ref)
        first, ref_first = geom.first_hit(path), oracle.first_hit(path)
        assert (first >= 0) == bool(ours)
        if first != ref_first and set(ours) == set(ref):
            # only a tie (two bodies met at the same point) may order differently
            for a, b in zip(path[:-1], path[1:]):
                hits = oracle.segment_contacts(a, b)
                if hits:
                    assert hits[first] == pytest.approx(hits[ref_first], abs=1e-9)
                    break
    assert contacts >= 10


def test_start_gaps_of_inf_leave_bodies_out_of_the_swept_check():
    scen = random_scenario(2)
    geom = FieldGeometry(scen, inflate=1.0)
    centres = scen.body_positions()
    path = np.array([centres[3] + [-200.0, 0.0], centres[3] + [200.0, 0.0]])
    assert 3 in geom.touched(path)
    gaps = geom.point_gaps(path[0])
    gaps[3] = np.inf
    assert 3 not in geom.touched(path, gaps)
    assert geom.first_hit(path, gaps) != 3


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_first_hit_is_the_body_met_first_along_the_path(make):
    square = ((-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0))
    scen = Scenario(
        dim=2,
        bounds=((-100, 100), (-100, 100)),
        dock=(0, -80),
        targets=(Body(position=(40.0, 0.0), radius=5.0),),
        obstacles=(Body(position=(0.0, 0.0), radius=math.sqrt(50), vertices=square),),
    )
    geom = make(scen, inflate=1.0)
    path = np.array([[-50.0, 0.0], [80.0, 0.0]])
    assert geom.first_hit(path) == 1 and geom.touched(path) == [0, 1]
    assert geom.first_hit(path[::-1]) == 0
    # starting inside the square's margin touches it at once, even heading out
    assert geom.first_hit(np.array([[5.5, 0.0], [20.0, 0.0]])) == 1
    assert geom.touched(np.array([[0.0, 5.5], [0.0, 20.0]])) == [1]
    assert geom.touched(np.array([[0.0, 6.5], [0.0, 20.0]])) == []
    # passing 1.5 m from a corner misses the 1 m margin; 0.5 m does not
    corner = np.array([5.0, 5.0]) + 1.5 / math.sqrt(2)
    along = np.array([1.0, -1.0]) * 30
    assert geom.first_hit(np.array([corner - along, corner + along])) == -1
    corner = np.array([5.0, 5.0]) + 0.5 / math.sqrt(2)
    assert geom.first_hit(np.array([corner - along, corner + along])) == 1


# --- lidar ---------------------------------------------------------------------------------------


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), dim=st.sampled_from([2, 3]))
def test_lidar_matches_the_oracle(seed, dim):
    scen = random_scenario(seed, dim)
    geom, oracle = FieldGeometry(scen), OracleField(scen)
    dirs = lidar_directions(dim, 24)
    rng = np.random.default_rng(seed)
    origins = probe_points(scen, rng, n_free=10)[::7]
    # a sensor exactly on a surface is a tie between "inside" (range 0) and "outside"
    origins = origins[np.abs(geom.signed_distance(origins)).min(axis=1) > 1e-6]
    for origin in origins:
        np.testing.assert_allclose(
            geom.lidar(origin, dirs, 300.0), oracle.lidar(origin, dirs, 300.0), atol=1e-9
        )


# --- hand-computed cases ------------------------------------------------------------------------


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_circle_clearance_hand_computed(make):
    scen = Scenario(
        dim=2,
        bounds=((-10, 10), (-10, 10)),
        dock=(0, 0),
        targets=(Body(position=(3.0, 4.0), radius=1.0),),
        obstacles=(Body(position=(-6.0, 0.0), radius=2.0),),
    )
    geom = make(scen)
    np.testing.assert_allclose(geom.signed_distance(np.zeros(2)).ravel(), [4.0, 4.0])
    np.testing.assert_allclose(
        geom.signed_distance(np.array([-6.0, 1.0])).ravel(), [math.hypot(9, 3) - 1, -1]
    )
    assert geom.signed_distance(np.array([3.0, 4.0])).min() == pytest.approx(-1.0)


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_polygon_distance_and_normals_hand_computed(make):
    square = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
    scen = Scenario(
        dim=2,
        bounds=((-10, 10), (-10, 10)),
        dock=(0, 0),
        targets=(Body(position=(8.0, 8.0), radius=1.0),),
        obstacles=(Body(position=(0.0, 0.0), radius=math.sqrt(2), vertices=square),),
    )
    geom = make(scen)
    pts = np.array([[3.0, 0.0], [0.5, 0.0], [4.0, 5.0], [0.0, 0.0]])
    np.testing.assert_allclose(geom.signed_distance(pts)[:, 1], [2.0, -0.5, 5.0, -1.0])
    nearest = geom.nearest if make is OracleField else lambda p: geom.nearest_points(p)
    for p, normal, surface in (
        ([3.0, 0.0], [1.0, 0.0], [1.0, 0.0]),
        ([0.5, 0.0], [1.0, 0.0], [1.0, 0.0]),  # inside: toward the nearest edge
        ([4.0, 5.0], [0.6, 0.8], [1.0, 1.0]),  # off a corner
    ):
        _, normals, points = nearest(np.array(p))
        np.testing.assert_allclose(np.reshape(normals, (-1, 2))[1], normal, atol=1e-12)
        np.testing.assert_allclose(np.reshape(points, (-1, 2))[1], surface, atol=1e-12)


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_3d_sphere_distance_and_swept_hit(make):
    scen = Scenario(
        dim=3,
        bounds=((-10, 10),) * 3,
        dock=(0, 0, 0),
        targets=(Body(position=(0.0, 5.0, 0.0), radius=1.0),),
        obstacles=(Body(position=(5.0, 0.0, 0.0), radius=2.0),),
    )
    geom = make(scen, inflate=0.5)
    assert geom.signed_distance(np.array([0.0, 0.0, 3.0])).ravel() == pytest.approx(
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


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_lidar_2d_against_hand_computed_ranges(make):
    scen = Scenario(
        dim=2,
        bounds=((-100, 100), (-100, 100)),
        dock=(0, 0),
        targets=(Body(position=(0.0, 30.0), radius=5.0),),
        obstacles=(Body(position=(50.0, 0.0), radius=10.0),),
    )
    ranges = make(scen).lidar(np.zeros(2), lidar_directions(2, 4), 60.0)
    np.testing.assert_allclose(ranges, [40.0, 25.0, 60.0, 60.0], atol=1e-9)


@pytest.mark.parametrize("make", IMPLEMENTATIONS)
def test_lidar_3d_against_hand_computed_ranges(make):
    scen = Scenario(
        dim=3,
        bounds=((-100, 100),) * 3,
        dock=(0, 0, 0),
        targets=(Body(position=(0.0, 0.0, 30.0), radius=5.0),),
        obstacles=(Body(position=(50.0, 0.0, 0.0), radius=10.0),),
    )
    geom = make(scen)
    dirs = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])
    np.testing.assert_allclose(geom.lidar(np.zeros(3), dirs, 60.0), [40.0, 25.0, 60.0, 60.0])
    # from inside a sphere the range is 0
    assert geom.lidar(np.array([50.0, 0, 0]), dirs[:1], 60.0)[0] == 0.0


# --- the API --------------------------------------------------------------------------------------


def test_lidar_directions_are_unit_and_spread():
    for dim, n in ((2, 16), (3, 64)):
        d = lidar_directions(dim, n)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
        assert np.allclose(d.mean(axis=0), 0.0, atol=0.05)
    with pytest.raises(ValueError, match="n_rays"):
        lidar_directions(2, 0)


def test_view_holds_every_body_in_order():
    scen = random_scenario(1)
    geom = FieldGeometry(scen)
    assert geom.n_bodies == len(scen.bodies)
    np.testing.assert_array_equal(geom.centers, scen.body_positions())
    np.testing.assert_array_equal(geom.radii, [b.radius for b in scen.bodies])
    assert list(geom.is_polygon) == [b.is_polygon for b in scen.bodies]


def test_bad_arguments_are_rejected():
    with pytest.raises(ValueError, match="inflate"):
        FieldGeometry(random_scenario(0), inflate=-1.0)
    with pytest.raises(ValueError, match="inflate"):
        FieldGeometry(random_scenario(0), inflate=math.nan)
    geom = FieldGeometry(random_scenario(0))
    with pytest.raises(ValueError, match="bodies"):
        geom.nearest_points(np.zeros((1, 2)), 3, geom.n_bodies + 1)
