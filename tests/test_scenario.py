"""Scenario data, serialisation, generators (property-based) and the paper preset."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import re
import warnings

import gymnasium as gym
import numpy as np
import pymunk
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import debris_gym  # noqa: F401 - registers the IDs
from debris_gym import generators, solvability
from debris_gym.config import OPTIONS
from debris_gym.convex_polygons import POLYGON_DRAWS, convex_polygons
from debris_gym.envs.common import PHYSICS_DIFFER
from debris_gym.generators import (
    MAX_POLYGON_VERTICES,
    FieldSpec,
    draw_size,
    paper_field,
    random_field,
    random_fields,
    route_by_construction,
)
from debris_gym.scenario import Body, Scenario, as_scenario
from debris_gym.scenario_checks import check_dock_clear
from debris_gym.solvability import grid_route_exists, is_solvable
from tests.geometry_oracle import OracleField
from tests.helpers import flies_old_ids, simple_scenario

# pinned scenarios in the frozen-world envs (v0) too
pytestmark = flies_old_ids


def make(spec: FieldSpec, seed: int, capture_radius: float = 5.0) -> Scenario:
    return random_field(
        np.random.default_rng(seed),
        spec,
        mean_motion=1.1e-3,
        dt=10.0,
        max_accel=0.05,
        capture_radius=capture_radius,
    )


def pymunk_overlaps(scen: Scenario) -> list[tuple[int, int]]:
    """Independent overlap test with pymunk's own queries.

    Two convex bodies overlap iff an edge of one enters the other (segment query), a circle's
    centre is within its radius of the other (point query), or one holds the other's centre.
    """
    shapes = OracleField(scen).shapes
    pairs = []
    for i, a in enumerate(shapes):
        for j, b in enumerate(shapes):
            if j <= i:
                continue
            hit = False
            for first, second in ((a, b), (b, a)):
                if isinstance(second, pymunk.Circle):
                    centre = second.offset
                    hit |= first.point_query(centre).distance <= second.radius
                else:
                    verts = second.get_vertices()
                    for k in range(len(verts)):
                        v, w = verts[k], verts[(k + 1) % len(verts)]
                        hit |= first.segment_query(v, w, 0.0) is not None
                    centroid = sum(verts, pymunk.Vec2d(0, 0)) / len(verts)
                    hit |= first.point_query(centroid).distance <= 0
            if hit:
                pairs.append((i, j))
    return pairs


def spec_strategy(dim: int, sizes: tuple[float, float]):
    return st.builds(
        FieldSpec,
        dim=st.just(dim),
        n_targets=st.integers(1, 6),
        n_obstacles=st.integers(0, 40),
        field_size=st.floats(*sizes),
        polygon_fraction=st.floats(0.0, 1.0),
        min_gap=st.floats(4.0, 30.0),
        chaser_radius=st.floats(0.0, 2.0),
    )


def check_field(spec: FieldSpec, seed: int, capture_radius: float) -> None:
    scen = make(spec, seed, capture_radius)
    assert len(scen.targets) == spec.n_targets and len(scen.obstacles) == spec.n_obstacles
    assert OracleField(scen).point_gaps(scen.dock).min() > spec.chaser_radius
    # bounding circles / spheres at least min_gap apart (so the exact shapes are too)
    centres = scen.body_positions()
    radii = np.array([b.radius for b in scen.bodies])
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1) - radii[:, None] - radii[None]
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= spec.min_gap - 1e-9
    if scen.dim == 2:
        assert pymunk_overlaps(scen) == []
    assert np.all(centres - radii[:, None] > scen.low) and np.all(
        centres + radii[:, None] < scen.high
    )
    assert scen.check_layout() is scen  # every rule a pinned field must pass (min_gap 0 too)
    # solvable by the generator's own proof AND by an independent grid search, whose cell is
    # small enough (diagonal below the capture depth) that it cannot step over a capture zone
    assert is_solvable(scen, spec.chaser_radius, capture_radius)
    cell = 0.9 * capture_radius / math.sqrt(scen.dim)
    assert grid_route_exists(scen, spec.chaser_radius, capture_radius, cell=cell)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=spec_strategy(2, (600.0, 1500.0)), seed=st.integers(0, 2**32 - 1))
def test_generated_2d_fields_never_overlap_and_are_solvable(spec, seed):
    check_field(spec, seed, capture_radius=5.0)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=spec_strategy(3, (600.0, 900.0)), seed=st.integers(0, 2**32 - 1))
def test_generated_3d_fields_never_overlap_and_are_solvable(spec, seed):
    check_field(spec, seed, capture_radius=20.0)


def test_overlap_probe_detects_overlaps():
    """The independent probe itself must be able to fail."""
    square = ((-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0))
    scen = Scenario(
        dim=2,
        bounds=((-100, 100), (-100, 100)),
        dock=(0, 0),
        targets=(Body(position=(50.0, 0.0), radius=3.0),),
        obstacles=(
            Body(position=(20.0, 20.0), radius=math.sqrt(50), vertices=square),
            Body(position=(26.0, 20.0), radius=2.0),
            Body(position=(-40.0, 0.0), radius=2.0),
        ),
    )
    assert pymunk_overlaps(scen) == [(1, 2)]


def test_grid_search_detects_an_enclosed_target():
    """A target walled in by overlapping debris is reported unsolvable by both checks."""
    ring = tuple(
        Body(position=(200 + 30 * math.cos(a), 30 * math.sin(a)), radius=9.0)
        for a in np.linspace(0, 2 * math.pi, 16, endpoint=False)
    )
    scen = Scenario(
        dim=2,
        bounds=((-500, 500), (-500, 500)),
        dock=(0, 0),
        targets=(Body(position=(200.0, 0.0), radius=3.0),),
        obstacles=ring,
    )
    assert not grid_route_exists(scen, 1.0, 5.0)
    assert not is_solvable(scen, 1.0, 5.0)
    # opening the ring (drop two neighbouring stones) makes it solvable again
    opened = Scenario(
        dim=2, bounds=scen.bounds, dock=scen.dock, targets=scen.targets, obstacles=ring[2:]
    )
    assert is_solvable(opened, 1.0, 5.0)


def test_crowded_field_raises_a_clear_error():
    spec = FieldSpec(n_obstacles=2000, field_size=300.0)
    with pytest.raises(ValueError, match="n_obstacles"):
        make(spec, 0)


def test_generator_is_deterministic_per_seed():
    spec = FieldSpec()
    assert make(spec, 5) == make(spec, 5)
    assert make(spec, 5) != make(spec, 6)


def test_polygons_are_convex_ccw_with_circumradius():
    scen = make(FieldSpec(polygon_fraction=1.0), 3)
    for b in scen.obstacles:
        v = np.asarray(b.vertices)
        assert np.max(np.linalg.norm(v, axis=1)) == pytest.approx(b.radius)
        e = np.roll(v, -1, axis=0) - v
        cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        assert np.all(cross > 0)


# --- the batched generator ------------------------------------------------------------------


def tight_spec_strategy(dim: int):
    """Specs where the proof does not follow from the placement (small gaps, big chaser)."""
    return st.builds(
        FieldSpec,
        dim=st.just(dim),
        n_targets=st.integers(1, 4),
        n_obstacles=st.integers(0, 25),
        field_size=st.floats(600.0, 1000.0),
        polygon_fraction=st.floats(0.0, 1.0),
        min_gap=st.floats(0.0, 4.0),
        target_clearance=st.floats(0.0, 4.0),
        chaser_radius=st.floats(1.0, 3.0),
    )


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=tight_spec_strategy(2), seed=st.integers(0, 2**32 - 1))
def test_fields_are_solvable_when_the_proof_is_checked_per_field(spec, seed):
    check_field(spec, seed, capture_radius=5.0)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    spec=st.one_of(spec_strategy(2, (600.0, 1500.0)), spec_strategy(3, (600.0, 900.0))),
    seeds=st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=6),
)
def test_batch_equals_single_draws_and_every_field_is_valid(spec, seeds):
    """Row k of a batch is the field random_field draws from generator k alone."""
    kwargs = dict(mean_motion=1.1e-3, dt=10.0, max_accel=0.05)
    batch = random_fields([np.random.default_rng(s) for s in seeds], spec, capture_radius=5.0)
    for k, seed in enumerate(seeds):
        single = random_field(np.random.default_rng(seed), spec, capture_radius=5.0, **kwargs)
        scen = batch.scenario(k, **kwargs)
        assert scen == single
        assert Scenario.from_dict(scen.to_dict()) == scen  # passes every rule of a loaded field
        assert is_solvable(scen, spec.chaser_radius, 5.0)
        for body in scen.obstacles:
            if body.is_polygon:
                assert 3 <= len(body.vertices) <= MAX_POLYGON_VERTICES
    for k, seed in enumerate(seeds):  # the batch's order does not matter either
        again = random_fields([np.random.default_rng(seed)], spec, capture_radius=5.0)
        np.testing.assert_array_equal(again.centers[0], batch.centers[k])


def test_big_batches_and_many_bodies_equal_single_draws():
    """Batches over the chunk size, and fields too big for the simultaneous rounds."""
    kwargs = dict(mean_motion=0.0, dt=10.0, max_accel=0.05, capture_radius=5.0)
    for spec, n in (
        (FieldSpec(n_obstacles=5), 70),
        (FieldSpec(n_obstacles=80, field_size=2500), 3),
    ):
        batch = random_fields(
            [np.random.default_rng(i) for i in range(n)], spec, capture_radius=5.0
        )
        for k in (0, n // 2, n - 1):
            single = random_field(np.random.default_rng(k), spec, **kwargs)
            assert batch.scenario(k, mean_motion=0.0, dt=10.0, max_accel=0.05) == single


def sequential_placement(cand, valid, radii, spacing):
    """Reference: place bodies one after another, each at its first valid candidate."""
    num, n_bodies, n_cand, dim = cand.shape
    centers = np.zeros((num, n_bodies, dim))
    placed = np.ones(num, dtype=bool)
    for k in range(num):
        for b in range(n_bodies):
            for c in range(n_cand):
                need = radii[k, b] + radii[k, :b] + np.maximum(spacing[b], spacing[:b])
                dist = np.sqrt(((cand[k, b, c] - centers[k, :b]) ** 2).sum(axis=1))
                if valid[k, b, c] and np.all(dist >= need):
                    centers[k, b] = cand[k, b, c]
                    break
            else:
                placed[k] = False
                break
    return centers, placed


@pytest.mark.parametrize(
    "spec",
    [
        FieldSpec(),
        FieldSpec(dim=3, n_obstacles=30),
        FieldSpec(n_targets=6, n_obstacles=40, field_size=600.0, min_gap=30.0),  # crowded
        FieldSpec(n_targets=6, n_obstacles=40, field_size=500.0, min_gap=30.0),  # too crowded
        FieldSpec(n_obstacles=70, field_size=1500.0),  # one body after another only
    ],
)
def test_compiled_placement_equals_one_body_after_another(spec):
    """The compiled draw against the block layout decoded here in numpy and placed by
    :func:`sequential_placement`."""
    u = np.random.default_rng(0).random((24, draw_size(spec)))
    centers, radii, _, _, placed = generators._draw_fields(u, spec)
    t, b_all, dim = spec.n_targets, spec.n_targets + spec.n_obstacles, spec.dim
    is_target = np.arange(b_all) < t
    lo = np.where(is_target, spec.target_radius[0], spec.obstacle_radius[0])
    hi = np.where(is_target, spec.target_radius[1], spec.obstacle_radius[1])
    np.testing.assert_array_equal(radii, lo + (hi - lo) * u[:, :b_all])
    polygons = spec.n_obstacles * (1 + POLYGON_DRAWS) if dim == 2 else 0
    n_cand = generators.candidates(spec)
    coords = u[:, b_all + polygons :].reshape(len(u), b_all, n_cand, dim)
    lim = spec.field_size / 2.0 - radii - spec.min_gap
    cand = (coords * 2.0 - 1.0) * lim[:, :, None, None]
    dock = np.where(
        is_target, max(spec.min_target_distance, spec.dock_clearance), spec.dock_clearance
    )
    reach = dock + radii
    valid = ((cand**2).sum(axis=3) >= reach[:, :, None] ** 2) & (lim > 0.0)[:, :, None]
    spacing = spec.min_gap + np.where(is_target, spec.target_clearance, 0.0)
    ref_centers, ref_placed = sequential_placement(cand, valid, radii, spacing)
    np.testing.assert_array_equal(placed, ref_placed)
    np.testing.assert_array_equal(centers[placed], ref_centers[placed])


def test_a_draw_takes_one_fixed_block_from_its_generator():
    spec = FieldSpec()
    rng = np.random.default_rng(4)
    random_fields([rng], spec, capture_radius=5.0)  # this seed's field comes on the first draw
    ref = np.random.default_rng(4)
    ref.random(draw_size(spec))
    assert rng.random() == ref.random()


@settings(max_examples=30, deadline=None)
@given(
    shape=st.lists(
        st.floats(0.0, 1.0, exclude_max=True), min_size=3 + MAX_POLYGON_VERTICES,
        max_size=3 + MAX_POLYGON_VERTICES,
    ),
    radius=st.floats(0.5, 50.0),
)  # fmt: skip
def test_generated_polygons_are_convex_ccw_and_hold_their_centre(shape, radius):
    vertices, count = convex_polygons(np.array([shape]), np.array([radius]))
    m = int(count[0])
    assert 3 <= m <= MAX_POLYGON_VERTICES
    v = vertices[0, :m]
    np.testing.assert_array_equal(vertices[0, m:], np.broadcast_to(v[0], (len(shape) - 3 - m, 2)))
    assert np.max(np.linalg.norm(v, axis=1)) == pytest.approx(radius)
    e = np.roll(v, -1, axis=0) - v
    cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    assert np.all(cross > 0)  # strictly convex, counter-clockwise
    centre_side = e[:, 0] * (0.0 - v[:, 1]) - e[:, 1] * (0.0 - v[:, 0])
    assert np.all(centre_side > 0)  # the centre is strictly inside


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    spec=st.one_of(spec_strategy(2, (600.0, 1500.0)), spec_strategy(3, (600.0, 900.0))),
    capture_radius=st.floats(0.5, 20.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_proof_holds_by_construction_where_claimed(spec, capture_radius, seed):
    if not route_by_construction(spec, capture_radius):
        return
    u = np.random.default_rng(seed).random((16, draw_size(spec)))
    centers, radii, _, _, placed = generators._draw_fields(u, spec)
    half = spec.field_size / 2.0
    low, high = np.full(spec.dim, -half), np.full(spec.dim, half)
    proof = solvability.route_proof(
        centers, radii, spec.n_targets, low, high, np.zeros(spec.dim), spec.chaser_radius,
        capture_radius,
    )  # fmt: skip
    assert np.all(proof[placed])


def test_json_round_trip(tmp_path):
    scen = make(FieldSpec(), 1)
    again = Scenario.from_dict(json.loads(json.dumps(scen.to_dict())))
    assert again == scen
    path = tmp_path / "s.json"
    scen.save(path)
    assert Scenario.load(path) == scen
    assert as_scenario(str(path)) == scen
    assert [p.name for p in tmp_path.iterdir()] == ["s.json"]  # no temp files left behind


def test_save_is_atomic_on_failure(tmp_path, monkeypatch):
    path = tmp_path / "s.json"
    path.write_text("previous content")
    scen = make(FieldSpec(), 1)

    def boom(*_args, **_kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("os.replace", boom)
    with pytest.raises(OSError):
        scen.save(path)
    assert path.read_text() == "previous content"
    assert [p.name for p in tmp_path.iterdir()] == ["s.json"]


@pytest.mark.parametrize(
    "mutate, fragment",
    [
        (lambda d: d.update(dim=4), "dim"),
        (lambda d: d.update(targets=[]), "target"),
        (lambda d: d["targets"][0].update(radius=-1), "radius"),
        (lambda d: d.update(dt=0), "dt"),
        (lambda d: d.update(max_accel=float("nan")), "max_accel"),
        (lambda d: d.update(extra=1), "unknown scenario keys"),
        (
            lambda d: d["obstacles"].append(
                {"position": [0, 0], "vertices": [[0, 0], [1, 1], [2, 0]]}
            ),
            "convex",
        ),
        (lambda d: d["targets"][0].update(velocity=[1.0, 0.0]), "frozen"),
        (lambda d: d.update(motion="keplerian"), "motion"),
        (lambda d: d.update(dock=[0.0]), "dock"),
    ],
)
def test_invalid_scenarios_raise(mutate, fragment):
    data = make(FieldSpec(n_obstacles=2), 0).to_dict()
    mutate(data)
    with pytest.raises(ValueError, match=fragment):
        Scenario.from_dict(data)


def test_paper_field_matches_seed_000_world():
    scen = paper_field()
    assert scen.bounds == ((0.0, 20.0), (0.0, 20.0))
    assert scen.mean_motion == 0.0 and scen.dt == pytest.approx(0.1)
    assert all(not b.is_polygon for b in scen.obstacles)
    assert is_solvable(scen, 0.1, 0.2)
    assert grid_route_exists(scen, 0.1, 0.2, cell=0.05)


# --- every scenario is checked before it is flown ------------------------------------------------


def _flown(data) -> tuple[float, np.ndarray]:
    """Reward and observation of the first step of the default env with ``data`` pinned."""
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=PHYSICS_DIFFER)
        env.reset(seed=0, options={"scenario": data})
    obs, reward, *_ = env.step(np.array([0.0, 1.0], np.float32))
    return reward, obs


def _default_field() -> dict:
    """The default env's first field (seed 0) as a dict, with the env's physics."""
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    env.reset(seed=0)
    return copy.deepcopy(env.unwrapped.scenario.to_dict())


def _first_polygon(data: dict) -> int:
    return next(i for i, b in enumerate(data["obstacles"]) if "vertices" in b)


def _star(data: dict) -> None:
    """A pentagram: every turn is to the left, but the boundary winds twice."""
    i = _first_polygon(data)
    r = data["obstacles"][i]["radius"]
    data["obstacles"][i]["vertices"] = [
        [r * math.cos(0.8 * math.pi * k), r * math.sin(0.8 * math.pi * k)] for k in range(5)
    ]


def _move(kind: str, i: int, where):
    def mutate(data: dict) -> None:
        data[kind][i]["position"] = list(where(data))

    return mutate


REPRODUCERS = {
    # name: (mutation of the default field, what the error must name)
    "nan bounds": (lambda d: d["bounds"][0].__setitem__(0, math.nan), "bounds[0][0]"),
    "dock inside an obstacle": (
        lambda d: d.update(dock=d["obstacles"][0]["position"]),
        "dock=",
    ),
    "dock outside the bounds": (lambda d: d.update(dock=[600.0, 0.0]), "dock="),
    "target inside an obstacle": (
        _move("targets", 0, lambda d: d["obstacles"][0]["position"]),
        "targets[0] and obstacles[0] overlap",
    ),
    "target outside the bounds": (
        _move("targets", 1, lambda d: [0.0, 700.0]),
        "targets[1]",
    ),
    "overlapping obstacles": (
        _move("obstacles", 4, lambda d: np.add(d["obstacles"][3]["position"], 1.0)),
        "obstacles[3] and obstacles[4] overlap",
    ),
    "tiny bounds": (lambda d: d.update(bounds=[[-1.0, 1.0], [-1.0, 1.0]]), "bounds[0] spans"),
    "huge bounds": (lambda d: d.update(bounds=[[-1e7, 1e7], [-1e7, 1e7]]), "bounds[0] spans"),
    "world far from the LVLH origin": (
        lambda d: d.update(bounds=[[-500.0, 500.0], [-500.0, 2e6]]),
        "bounds[1]",
    ),
    "dt missing": (lambda d: d.pop("dt"), "['dt']"),
    "mean_motion missing": (lambda d: d.pop("mean_motion"), "['mean_motion']"),
    "max_accel missing": (lambda d: d.pop("max_accel"), "['max_accel']"),
    "dt out of range": (lambda d: d.update(dt=1e6), "dt=1000000.0 s is out of range"),
    "mean_motion out of range": (lambda d: d.update(mean_motion=1.0), "mean_motion=1.0"),
    "max_accel out of range": (lambda d: d.update(max_accel=1e3), "max_accel=1000.0"),
    "self-intersecting polygon": (_star, "winds 2 times"),
    "polygon radius disagrees": (
        lambda d: d["obstacles"][_first_polygon(d)].update(radius=100.0),
        "radius=100.0 m disagrees",
    ),
    "target radius missing": (lambda d: d["targets"][2].pop("radius"), "targets[2].radius"),
    "dock missing": (lambda d: d.pop("dock"), "['dock']"),
    "position missing": (lambda d: d["obstacles"][1].pop("position"), "obstacles[1].position"),
    "radius as a string": (lambda d: d["targets"][0].update(radius="5"), "targets[0].radius"),
    "bounds not pairs": (lambda d: d.update(bounds=[1.0, 2.0]), "bounds[0]"),
    "targets not a list": (lambda d: d.update(targets=3), "targets"),
    "body not a dict": (lambda d: d["obstacles"].__setitem__(2, [1.0, 2.0]), "obstacles[2]"),
    "dim as a float": (lambda d: d.update(dim=2.0), "dim"),
}


@pytest.mark.parametrize("name", sorted(REPRODUCERS))
def test_bad_scenarios_are_refused_naming_the_key(name):
    """Each was accepted (NaN or absurd rewards, a start in collision) or failed with a bare
    KeyError / TypeError before; now a ValueError names the key, also when pinned in an env."""
    mutate, fragment = REPRODUCERS[name]
    data = _default_field()
    mutate(data)
    with pytest.raises(ValueError) as refused:
        Scenario.from_dict(data)
    assert fragment in str(refused.value)
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    with pytest.raises(ValueError, match=re.escape(fragment)):
        env.reset(seed=0, options={"scenario": data})


def test_the_default_field_flies_unmutated():
    """The reproducers' base passes, so each refusal above is due to its mutation alone."""
    reward, obs = _flown(_default_field())
    assert math.isfinite(reward) and abs(reward) < 5.0 and np.all(np.isfinite(obs))


def test_a_hand_built_scenario_is_checked_when_pinned():
    """A Scenario object skips from_dict: its layout is checked on the way into the env."""
    scen = simple_scenario(dock=(200.0, 0.0))  # the obstacle's centre
    env = gym.make("DebrisGym/Rendezvous2D-v0")
    with pytest.raises(ValueError, match=r"dock=\[200.0, 0.0\] m is inside or on obstacles\[0\]"):
        env.reset(seed=0, options={"scenario": scen})
    with pytest.raises(ValueError, match=r"targets\[0\] and obstacles\[0\] overlap"):
        as_scenario(simple_scenario(targets=(Body(position=(190.0, 0.0), radius=5.0),)))


def test_scenario_physics_ranges_are_the_env_options():
    """The limits come from debris_gym.config.OPTIONS, not from a copy."""
    base = simple_scenario()
    for key in ("dt", "mean_motion", "max_accel"):
        opt = OPTIONS[key]
        assert dataclasses.replace(base, **{key: opt.high}).dt > 0  # the edges are allowed
        allowed = re.escape(f"allowed: [{opt.low:g}, {opt.high:g}] {opt.unit}")
        with pytest.raises(ValueError, match=f"{key}=.*{allowed}"):
            dataclasses.replace(base, **{key: opt.high * 1.5})
    with pytest.raises(ValueError, match="dt"):
        dataclasses.replace(base, dt=OPTIONS["dt"].low / 2)


def test_the_world_size_limits_are_the_field_size_range():
    lo, hi = OPTIONS["field_size"].low, OPTIONS["field_size"].high
    target = (Body(position=(0.0, 5.0), radius=1.0),)
    for half, ok in (
        (lo / 2, True),
        (lo / 2 * 0.999, False),
        (hi / 2, True),
        (hi / 2 * 1.001, False),
    ):
        scen = simple_scenario(bounds=((-half, half), (-half, half)), targets=target, obstacles=())
        if ok:
            assert scen.check_layout() is scen
        else:
            with pytest.raises(ValueError, match=r"bounds\[0\] spans"):
                scen.check_layout()


def test_a_malformed_json_file_names_the_file_and_line(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"dim": 2,\n "bounds": [[-500, 500],\n oops]}')
    with pytest.raises(ValueError, match=r"broken\.json.* is not valid JSON: .* line 3, column 2"):
        Scenario.load(path)
    with pytest.raises(ValueError, match=r"broken\.json"):
        as_scenario(str(path))


def test_a_file_with_a_bad_value_names_the_file_and_the_key(tmp_path):
    data = _default_field()
    data["targets"][1]["radius"] = -2.0
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"bad\.json.*targets\[1\]\.radius=-2.0 m"):
        Scenario.load(path)


def test_a_polygon_radius_may_be_left_out_and_is_then_derived():
    data = _default_field()
    i = _first_polygon(data)
    radius = data["obstacles"][i].pop("radius")
    assert Scenario.from_dict(data).obstacles[i].radius == radius


@pytest.mark.parametrize(
    "vertices, fragment",
    [
        ([[1, 0], [0, 1]], "has 2 vertices; allowed: 3 to 64"),
        ([[1, 0], [-1, 0], [0, 1], [0, -1]], "turn at vertex 1"),  # a bow tie
        ([[0, -1], [-1, 0], [0, 1]], "not to the left"),  # clockwise
        ([[1, 0], [0, 1], [-1, 0], [-1, 0], [0, -1]], "not to the left"),  # a repeated vertex
        ([[1, 0], [0, 1], [-1, 0], [-0.5, -0.5], [0, -1]], "not to the left"),  # collinear
        ([[1, 0], [0, 1], [-1, 0], [0, -1], [1e300, 0]], "not to the left"),  # no overflow
    ],
)
def test_polygons_must_be_simple_convex_and_counter_clockwise(vertices, fragment):
    with pytest.raises(ValueError, match=rf"obstacles\[0\]\.vertices.*{fragment}"):
        Body.from_dict({"position": [0, 0], "vertices": vertices}, 2, "obstacles[0]")


def test_every_scenario_the_repo_ships_passes():
    """The paper world and the tests' shared field pass every rule; random fields are covered by
    the generator properties above."""
    for scen in (paper_field(), paper_field(dt=0.1, max_accel=1.0), simple_scenario()):
        assert Scenario.from_dict(scen.to_dict()) == scen
        assert scen.check_layout() is scen


@settings(max_examples=60, deadline=None)
@given(
    bodies=st.lists(
        st.tuples(
            st.floats(-80.0, 80.0), st.floats(-80.0, 80.0), st.floats(1.0, 20.0),
            st.integers(0, 6), st.floats(0.0, 2.0 * math.pi),
        ),
        min_size=2,
        max_size=8,
    )
)  # fmt: skip
def test_the_overlap_check_agrees_with_pymunk(bodies):
    """Circles and convex polygons at random: refused exactly when pymunk finds an overlap.

    Touching is allowed here and counts as contact in the probe, so the probe runs on every body
    shrunk and grown by 1e-6 of its size: shrunk ones that still meet overlap, grown ones that
    stay apart do not, and a layout between the two (touching to rounding) is left out."""

    def field(scale: float) -> Scenario:
        obstacles = []
        for x, y, r, n, turn in bodies:
            vertices = None
            if n >= 3:
                angles = turn + 2.0 * math.pi * np.arange(n) / n
                vertices = tuple((scale * r * math.cos(a), scale * r * math.sin(a)) for a in angles)
            obstacles.append(Body(position=(x, y), radius=scale * r, vertices=vertices))
        return Scenario(
            dim=2,
            bounds=((-200.0, 200.0), (-200.0, 200.0)),
            dock=(150.0, 150.0),
            targets=(Body(position=(150.0, -150.0), radius=2.0),),
            obstacles=tuple(obstacles),
        )

    overlap = bool(pymunk_overlaps(field(1.0 - 1e-6)))
    assume(overlap or not pymunk_overlaps(field(1.0 + 1e-6)))
    scen = field(1.0)
    if overlap:
        with pytest.raises(ValueError, match="overlap"):
            scen.check_layout()
    else:
        assert scen.check_layout() is scen


def test_the_overlap_check_scales_to_the_largest_field():
    """2 000 obstacles: sweep and prune finds the one overlapping pair among ~2 million."""
    spec = FieldSpec(n_obstacles=2000, field_size=40_000.0)
    scen = make(spec, 0)
    assert scen.check_layout() is scen
    moved = list(scen.obstacles)
    moved[1500] = dataclasses.replace(moved[1500], position=moved[7].position)
    with pytest.raises(ValueError, match=r"obstacles\[7\] and obstacles\[1500\] overlap"):
        dataclasses.replace(scen, obstacles=tuple(moved)).check_layout()


def test_a_replaced_scenario_does_not_share_derived_data():
    """Regression: dataclasses.replace copied the cache of body positions (and of the layout
    check) into the new scenario, which then reported the old positions."""
    scen = simple_scenario()
    scen.body_positions()
    scen.check_layout()
    moved = dataclasses.replace(scen, obstacles=(Body(position=(0.0, 0.0), radius=20.0),))
    np.testing.assert_array_equal(moved.body_positions()[1], [0.0, 0.0])
    with pytest.raises(ValueError, match="dock="):
        moved.check_layout()


def test_an_env_can_ask_for_the_dock_to_clear_its_chaser():
    """A dock 0.5 m from an obstacle passes the scenario's own rule (no chaser in a scenario) but
    not the check an env with a 1 m chaser can make (it would start the episode in contact)."""
    scen = simple_scenario(obstacles=(Body(position=(20.5, 0.0), radius=20.0),))
    assert scen.check_layout() is scen
    check_dock_clear(scen, chaser_radius=0.4)
    with pytest.raises(ValueError, match=r"dock=\[0.0, 0.0\] m is within the chaser radius 1.0 m"):
        check_dock_clear(scen, chaser_radius=1.0)


def test_a_body_built_without_a_velocity_round_trips():
    """Regression: to_dict wrote "velocity": [], which from_dict refused."""
    scen = Scenario(
        dim=2, bounds=((-50.0, 50.0), (-50.0, 50.0)), dock=(0.0, 0.0),
        targets=(Body(position=(20.0, 0.0), radius=2.0),), mean_motion=0.0, dt=1.0, max_accel=1.0,
    )  # fmt: skip
    again = Scenario.from_dict(scen.to_dict())
    assert again.targets[0].velocity == (0.0, 0.0)
    assert again.body_states(5.0).tolist() == scen.body_states(5.0).tolist()
