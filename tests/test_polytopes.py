"""The polytopes inscribed in the unit ball (agents.planners.polytopes), both kinds, checked by
linear programmes solved here (the polytope's reach along a direction) and by sampling."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from agents.planners.polytopes import POLYTOPE_KINDS, inscribed_polytope

CASES = [(2, 16), (2, 5), (3, 26), (3, 48)]


def reach(normals: np.ndarray, offset: float, direction: np.ndarray) -> float:
    """max u·x over the polytope normals·x <= offset, by HiGHS."""
    dim = len(direction)
    res = linprog(-direction, A_ub=normals, b_ub=np.full(len(normals), offset),
                  bounds=[(None, None)] * dim, method="highs")  # fmt: skip
    assert res.status == 0
    return -res.fun


def unit_directions(dim: int, count: int, seed: int = 0) -> np.ndarray:
    u = np.random.default_rng(seed).normal(size=(count, dim))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


@pytest.mark.parametrize("kind", POLYTOPE_KINDS)
@pytest.mark.parametrize(("dim", "facets"), CASES)
def test_the_polytope_is_inside_the_unit_ball_and_holds_the_ball_of_its_offset(kind, dim, facets):
    poly = inscribed_polytope(dim, facets, kind)
    assert poly.kind == kind and poly.normals.shape[1] == dim
    np.testing.assert_allclose(np.linalg.norm(poly.normals, axis=1), 1.0, rtol=1e-12)
    reaches = [reach(poly.normals, poly.offset, u) for u in unit_directions(dim, 40)]
    assert max(reaches) <= 1.0 + 1e-9  # inside the ball, so inside ⇒ safe
    assert min(reaches) >= poly.offset - 1e-9  # and the ball of radius h is inside it
    # sampled: every point the half-spaces accept lies in the unit ball
    points = np.random.default_rng(1).uniform(-1.2, 1.2, size=(20000, dim))
    inside = np.all(points @ poly.normals.T <= poly.offset, axis=1)
    assert inside.any() and np.all(np.linalg.norm(points[inside], axis=1) <= 1.0 + 1e-9)


def vertices(normals: np.ndarray, offset: float) -> np.ndarray:
    """Every vertex of normals·x <= offset, by brute force: each set of ``dim`` facets whose
    planes meet in one point that every other facet accepts."""
    dim = normals.shape[1]
    sets = np.array(list(itertools.combinations(range(len(normals)), dim)))
    systems = normals[sets]
    regular = np.abs(np.linalg.det(systems)) > 1e-9
    points = np.linalg.solve(systems[regular], np.full((regular.sum(), dim, 1), offset))[..., 0]
    return points[np.all(points @ normals.T <= offset + 1e-9, axis=1)]


@pytest.mark.parametrize("kind", POLYTOPE_KINDS)
@pytest.mark.parametrize(("dim", "facets"), CASES)
def test_every_vertex_lies_on_the_unit_sphere(kind, dim, facets):
    """Inscribed, not just inside: the offset puts the farthest vertex on the sphere (and in
    these symmetric layouts every vertex of the 2D polygons and of the 3D lattice)."""
    poly = inscribed_polytope(dim, facets, kind)
    radii = np.linalg.norm(vertices(poly.normals, poly.offset), axis=1)
    assert len(radii) >= len(poly.normals)
    assert radii.max() == pytest.approx(1.0, abs=1e-9)
    if dim == 2 or kind == "lattice":
        np.testing.assert_allclose(radii, 1.0, atol=1e-9)


@pytest.mark.parametrize("facets", [3, 8, 16])
def test_the_two_2d_kinds_are_the_same_polygon_turned_by_half_a_facet(facets):
    lattice = inscribed_polytope(2, facets, "lattice")
    fibonacci = inscribed_polytope(2, facets, "fibonacci")
    assert lattice.offset == fibonacci.offset == pytest.approx(math.cos(math.pi / facets))
    x_axis = np.array([1.0, 0.0])
    assert reach(lattice.normals, lattice.offset, x_axis) == pytest.approx(lattice.offset)
    assert reach(fibonacci.normals, fibonacci.offset, x_axis) == pytest.approx(1.0)
    turn = np.pi / facets
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    np.testing.assert_allclose(lattice.normals @ rotation.T, fibonacci.normals, atol=1e-12)


def test_the_3d_facet_counts():
    assert len(inscribed_polytope(3, 16, "lattice").normals) == 26  # facets sets 2D only
    assert len(inscribed_polytope(3, 48, "fibonacci").normals) == 48
    lattice = inscribed_polytope(3, 16, "lattice")
    # the cube's face, edge and corner directions: 6 + 12 + 8
    counts = np.unique(np.count_nonzero(np.abs(lattice.normals) > 1e-12, axis=1), return_counts=1)
    assert dict(zip(*counts)) == {1: 6, 2: 12, 3: 8}


@settings(max_examples=40, deadline=None)
@given(facets=st.integers(3, 64), kind=st.sampled_from(POLYTOPE_KINDS))
def test_every_2d_polygon_has_the_regular_inner_radius(facets, kind):
    poly = inscribed_polytope(2, facets, kind)
    assert len(poly.normals) == facets
    assert poly.offset == pytest.approx(math.cos(math.pi / facets), rel=1e-15)
    np.testing.assert_array_equal(poly.offsets, np.full(facets, poly.offset))


def test_the_cached_polytope_cannot_be_changed():
    poly = inscribed_polytope(2, 16, "lattice")
    with pytest.raises(ValueError):
        poly.normals[0, 0] = 5.0
    assert inscribed_polytope(2, 16, "lattice") is poly


@pytest.mark.parametrize(
    ("args", "name"),
    [
        ((2, 16, "cube"), "kind"),
        ((4, 16, "lattice"), "dim"),
        ((2, 2, "lattice"), "facets"),
        ((3, 5, "fibonacci"), "facets"),
        ((2, 8.0, "fibonacci"), "facets"),
    ],
)
def test_bad_arguments_are_refused_by_name(args, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        inscribed_polytope(*args)
