"""Moving (v1) random fields: bodies on relative orbits, checked from outside.

Independent truth used here: the textbook CW closed form typed into
``tests.helpers.cw_positions`` ([Curtis14] eq. 7.53, not the library's state-transition matrix or
the generator's element form) propagates every body on a fine time grid; the drift condition
x_c = 4x₀ + 2ẏ₀/n is typed in below; solvability is checked by an independent time-expanded grid
search (:func:`space_time_route`), not by the generator's argument.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from debris_gym.generators import FieldSpec, draw_size, random_field, random_fields, unplaceable
from debris_gym.orbit_fields import orbit_drawer, stream_uniform
from debris_gym.orbit_separation import SEARCH_TOLERANCE, apart
from tests.helpers import cw_positions

N = 1.1314e-3  # rad/s, the default LEO mean motion (~92.6 min orbit)
PERIOD = 2.0 * math.pi / N
CAPTURE = 5.0

# the env's default random-field spec (debris_gym.envs.common._field_spec with its defaults)
DEFAULT = dict(target_clearance=17.0, dock_clearance=50.0, min_target_distance=150.0)


def spec_of(dim: int = 2, motion: str = "bounded", **kw) -> FieldSpec:
    return FieldSpec(dim=dim, motion=motion, mean_motion=N, **{**DEFAULT, **kw})


def draw(spec: FieldSpec, seeds) -> object:
    return random_fields([np.random.default_rng(s) for s in seeds], spec, capture_radius=CAPTURE)


def states_of(fields, k: int) -> np.ndarray:
    return np.concatenate([fields.centers[k], fields.velocities[k]], axis=1)


def check_field_over_time(fields, k: int, spec: FieldSpec, t: np.ndarray) -> None:
    """Every placement rule of a moving field (docs/environments.md, "Moving fields") on a time
    grid, from the CW closed form (not the generator)."""
    n_t = spec.n_targets
    radii = fields.radii[k]
    pos = cw_positions(states_of(fields, k), spec.mean_motion, t)  # (S, B, dim)
    half = spec.field_size / 2.0
    # inside the bounds with min_gap to spare
    assert np.all(np.abs(pos) + radii[None, :, None] <= half - spec.min_gap + 1e-6)
    # the dock (origin) clear of every surface by dock_clearance
    dock = np.linalg.norm(pos, axis=2) - radii[None]
    assert dock.min() >= spec.dock_clearance - 1e-6
    # targets start min_target_distance (centre) from the dock
    start = np.linalg.norm(fields.centers[k, :n_t], axis=1)
    assert np.all(start >= max(spec.min_target_distance, spec.dock_clearance) + radii[:n_t] - 1e-6)
    # pairwise gaps at every sampled time
    spacing = np.full(len(radii), spec.min_gap)
    spacing[:n_t] += spec.target_clearance
    gap = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=3)
    need = radii[:, None] + radii[None] + np.maximum(spacing[:, None], spacing[None])
    off = ~np.eye(len(radii), dtype=bool)
    assert np.all(gap.min(axis=0)[off] >= need[off] - 1e-6)


# --- determinism and the v0 fields -------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("motion", ["bounded", "drifting"])
def test_same_seed_same_field_and_a_field_depends_only_on_its_generator(dim, motion):
    spec = spec_of(dim, motion, spin_max=0.02)
    a = draw(spec, [3, 4, 5])
    b = draw(spec, [5])
    c = draw(spec, [3, 4, 5])
    for name in ("centers", "velocities", "radii", "spins", "vertices", "n_vertices"):
        np.testing.assert_array_equal(getattr(a, name), getattr(c, name))
        np.testing.assert_array_equal(getattr(a, name)[2], getattr(b, name)[0])
    # a field takes exactly one 64-bit word of its generator (retries happen inside the draw)
    rng = np.random.default_rng(7)
    random_fields([rng], spec, capture_radius=CAPTURE)
    ref = np.random.default_rng(7)
    ref.bit_generator.random_raw()
    assert rng.bit_generator.random_raw() == ref.bit_generator.random_raw()


def splitmix64(seed: int, count: int) -> list[int]:
    """SplitMix64 typed in from its reference (Steele, Lea, Flood 2014; Vigna's splitmix64.c),
    in Python integers: the first ``count`` outputs of ``seed``."""
    mask, out, x = (1 << 64) - 1, [], seed
    for _ in range(count):
        x = (x + 0x9E3779B97F4A7C15) & mask
        z = x
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        out.append(z ^ (z >> 31))
    return out


def test_the_stream_is_splitmix64():
    # the reference's published first outputs for seed 1234567
    assert splitmix64(1234567, 3) == [6457827717110365317, 3203168211198807973, 9817491932198370423]
    for key in (0, 1234567, 2**64 - 1, 0xDEADBEEFCAFEF00D):
        outputs = splitmix64(key, 40)
        for i in (0, 1, 2, 17, 39):
            assert stream_uniform(key, i) == (outputs[i] >> 11) * 2.0**-53
    # a long stream looks uniform (mean 1/2 ± a few standard errors of 1/√(12·N))
    u = np.array([(z >> 11) * 2.0**-53 for z in splitmix64(99, 4000)])
    assert abs(u.mean() - 0.5) < 4.0 / math.sqrt(12 * 4000)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_field_is_its_word_and_a_big_batch_is_its_rows(dim):
    spec = spec_of(dim)
    drawer = orbit_drawer(spec, CAPTURE)
    seeds = range(70)  # more than any chunk the draw could split a batch into
    batch = draw(spec, seeds)
    words = np.array(
        [np.random.default_rng(s).bit_generator.random_raw() for s in seeds], dtype=np.uint64
    )
    again = drawer.from_words(words[::-1])
    for name in ("centers", "velocities", "radii", "spins", "vertices", "n_vertices"):
        np.testing.assert_array_equal(getattr(again, name)[::-1], getattr(batch, name))
        for k in (0, 33, 69):
            np.testing.assert_array_equal(
                getattr(draw(spec, [k]), name)[0], getattr(batch, name)[k]
            )


def test_the_orbit_drawer_refuses_bad_arguments_by_name():
    with pytest.raises(ValueError, match="max_tries"):
        orbit_drawer(spec_of(2), CAPTURE, max_tries=0)
    with pytest.raises(ValueError, match="max_tries"):
        orbit_drawer(spec_of(2), CAPTURE, max_tries=2.5)
    with pytest.raises(ValueError, match=r"FieldSpec\.motion"):
        orbit_drawer(FieldSpec(dim=2), CAPTURE)
    # a spec that places nothing says so after its tries, and the generator moved by one word
    crowded = spec_of(2, n_obstacles=400, field_size=800.0)
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match=r"could not place.*after 2 tries"):
        random_fields([rng], crowded, capture_radius=CAPTURE, max_tries=2)
    ref = np.random.default_rng(3)
    ref.bit_generator.random_raw()
    assert rng.bit_generator.random_raw() == ref.bit_generator.random_raw()


V0_DIGESTS = {
    # sha256 of centers, radii, vertices, n_vertices of seeds (0, 1, 2, 19, 12345), env default
    # spec, drawn by main at ce0a88e (before moving fields existed): v0 fields must not change
    2: "913ec06ffa45776413fcf1c229c82f4e0c228c04a978010b0ffc721c3b1650ec",
    3: "250ed7c395030004fbe063e30ab6948c75bd5997d151deb65689e1e642192632",
}


@pytest.mark.parametrize("dim", [2, 3])
def test_v0_fields_are_bit_identical_to_mains(dim):
    spec = FieldSpec(dim=dim, target_clearance=17.0, dock_clearance=50.0)
    assert spec.motion == "frozen"
    fields = draw(spec, (0, 1, 2, 19, 12345))
    assert fields.velocities is None and fields.spins is None
    digest = hashlib.sha256()
    for a in (fields.centers, fields.radii, fields.vertices, fields.n_vertices):
        digest.update(np.ascontiguousarray(a).tobytes())
    assert digest.hexdigest() == V0_DIGESTS[dim]
    scenario = fields.scenario(0, mean_motion=N, dt=10.0, max_accel=0.05)
    assert scenario.motion == "frozen"
    assert draw_size(spec) == draw_size(dataclasses.replace(spec, mean_motion=2e-3))


# --- the orbits ---------------------------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
def test_bounded_fields_are_drift_free_and_move(dim):
    spec = spec_of(dim)
    fields = draw(spec, range(20))
    x0, vy0 = fields.centers[..., 0], fields.velocities[..., 1]
    x_c = 4.0 * x0 + 2.0 * vy0 / N  # textbook drift condition
    assert np.all(np.abs(x_c) <= 1e-9 * spec.field_size)
    speed = np.linalg.norm(fields.velocities, axis=2)
    assert speed.max() > 0.1  # the bodies do move
    # ≤ ~0.6 m/s at any time: n·√(4ρ² + ρ_z²) with ρ, ρ_z <= rho_max
    t = np.linspace(0.0, PERIOD, 721)
    for k in range(3):
        pos = cw_positions(states_of(fields, k), N, t)
        v = np.diff(pos, axis=0) / np.diff(t)[:, None, None]
        bound = N * math.sqrt(4.0 + (dim == 3)) * spec.rho_max
        assert np.linalg.norm(v, axis=2).max() <= bound * 1.001


@pytest.mark.parametrize("dim", [2, 3])
def test_drifting_fields_keep_their_offset_in_range(dim):
    spec = spec_of(dim, "drifting", drift_offset=(5.0, 15.0), horizon=8000.0)
    fields = draw(spec, range(10))
    x_c = 4.0 * fields.centers[..., 0] + 2.0 * fields.velocities[..., 1] / N
    assert np.all(np.abs(x_c) >= 5.0 - 1e-9)
    assert np.all(np.abs(x_c) <= 15.0 + 1e-9)
    assert (x_c > 0).any() and (x_c < 0).any()
    for k in range(len(fields)):
        check_field_over_time(fields, k, spec, np.linspace(0.0, 8000.0, 4001))


@pytest.mark.parametrize("dim", [2, 3])
def test_every_rule_holds_at_every_time_over_several_orbits(dim):
    spec = spec_of(dim)
    fields = draw(spec, range(12))
    t = np.linspace(0.0, 3.0 * PERIOD, 6001)  # drift-free: valid for ever, so check past one orbit
    for k in range(len(fields)):
        check_field_over_time(fields, k, spec, t)


def test_the_outside_check_sees_a_broken_field():
    spec = spec_of(2)
    fields = draw(spec, [0])
    t = np.linspace(0.0, 3.0 * PERIOD, 6001)
    check_field_over_time(fields, 0, spec, t)
    # a body given 40 m of radial offset drifts 0.07 m/s along-track: out of bounds in time
    drifting = dataclasses.replace(fields, velocities=fields.velocities.copy())
    drifting.velocities[0, 5, 1] += 0.5 * N * 40.0  # x_c = 4x0 + 2ẏ0/n grows by 40 m
    with pytest.raises(AssertionError):
        check_field_over_time(drifting, 0, spec, t)
    # two bodies on the same orbit, a few metres apart in phase
    twin = dataclasses.replace(
        fields, centers=fields.centers.copy(), velocities=fields.velocities.copy()
    )
    twin.centers[0, 6] = twin.centers[0, 5] + 1.0
    twin.velocities[0, 6] = twin.velocities[0, 5]
    with pytest.raises(AssertionError):
        check_field_over_time(twin, 0, spec, t)


def test_polygons_tumble_within_spin_max_and_the_scenario_moves():
    spec = spec_of(2, spin_max=0.03)
    fields = draw(spec, range(8))
    t = spec.n_targets
    polygon = fields.n_vertices > 0
    spins = fields.spins[:, t:]
    assert np.all(np.abs(fields.spins) <= 0.03)
    assert np.all(fields.spins[:, :t] == 0.0) and np.all(spins[~polygon] == 0.0)
    assert np.all(spins[polygon] != 0.0)
    scenario = fields.scenario(1, mean_motion=N, dt=10.0, max_accel=0.05)
    assert scenario.motion == "cwh"
    scenario.check_layout()
    np.testing.assert_array_equal(scenario.initial_body_states()[:, 2:], fields.velocities[1])
    np.testing.assert_array_equal([b.spin for b in scenario.bodies], fields.spins[1])
    # the Scenario's motion agrees with the textbook formula
    for tt in (0.0, 1234.5, PERIOD):
        np.testing.assert_allclose(
            scenario.body_positions(tt),
            cw_positions(states_of(fields, 1), N, np.array([tt]))[0],
            atol=1e-6,
        )
    one = random_field(
        np.random.default_rng(1), spec, mean_motion=N, dt=10.0, max_accel=0.05,
        capture_radius=CAPTURE,
    )  # fmt: skip
    assert one.to_dict() == scenario.to_dict()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    dim=st.sampled_from([2, 3]),
    motion=st.sampled_from(["bounded", "drifting"]),
    n_targets=st.integers(1, 4),
    n_obstacles=st.integers(0, 24),
    field_size=st.floats(800.0, 1500.0),
    rho_max=st.floats(0.0, 300.0),
    spin_max=st.floats(0.0, 0.05),
    horizon=st.floats(0.0, 9000.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_generated_fields_keep_every_rule_over_the_horizon(
    dim, motion, n_targets, n_obstacles, field_size, rho_max, spin_max, horizon, seed
):
    spec = spec_of(
        dim, motion, n_targets=n_targets, n_obstacles=n_obstacles, field_size=field_size,
        rho_max=rho_max, spin_max=spin_max, horizon=horizon, drift_offset=(2.0, 10.0),
    )  # fmt: skip
    try:
        fields = draw(spec, [seed, seed + 1])
    except ValueError as exc:  # a crowded spec may be refused, by name
        assert "could not place" in str(exc)
        return
    span = max(horizon, PERIOD)
    t = np.linspace(0.0, span, int(span / 2.0) + 1)  # every 2 s
    for k in range(2):
        check_field_over_time(fields, k, spec, t)
        if motion == "bounded":
            x_c = 4.0 * fields.centers[k, :, 0] + 2.0 * fields.velocities[k, :, 1] / N
            assert np.all(np.abs(x_c) <= 1e-9 * field_size)


def elements_of(state: np.ndarray, n: float) -> np.ndarray:
    """(x_c, y_c, a, b, a_z, b_z) of a state [x, y, (z), vx, vy, (vz)]: x_c = 4x₀ + 2ẏ₀/n,
    x₀ = x_c + b, ẋ₀ = n a, y₀ = y_c + 2a, z₀ = b_z, ż₀ = n a_z (textbook, typed in)."""
    dim = len(state) // 2
    x0, y0, vx0, vy0 = state[0], state[1], state[dim], state[dim + 1]
    x_c = 4.0 * x0 + 2.0 * vy0 / n
    a = vx0 / n
    z = (state[5] / n, state[2]) if dim == 3 else (0.0, 0.0)
    return np.array([x_c, y0 - 2.0 * a, a, x0 - x_c, *z])


@settings(max_examples=150, deadline=None)
@given(
    dim=st.sampled_from([2, 3]),
    drifting=st.booleans(),
    values=st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12),
    ratio=st.floats(0.8, 1.2),
)
def test_the_pair_check_agrees_with_dense_sampling(dim, drifting, values, ratio):
    """apart (exact in 2D, branch and bound otherwise) never passes a pair that comes closer
    than ``need`` on a dense time grid, and never refuses one that stays clearly apart; ``need``
    is set near the pair's true closest approach, where a wrong bound would show."""

    v = np.array(values)
    horizon = 1.3 * PERIOD
    states = []
    for body in (v[:6], v[6:]):
        pos = body[:3] * 300.0
        vel = body[3:] * 0.3
        if drifting:
            vel[1] = -2.0 * N * pos[0] + vel[1] * 0.05  # |x_c| up to ~30 m
        else:
            vel[1] = -2.0 * N * pos[0]  # drift-free
        states.append(np.r_[pos[:dim], vel[:dim]])
    states = np.array(states)
    e = elements_of(states[0], N) - elements_of(states[1], N)
    if dim == 2:
        e[4:] = 0.0
    if not drifting:
        e[0] = 0.0  # both x_c are 0 up to rounding
    t = np.linspace(0.0, horizon if drifting else PERIOD, 40001)
    pos = cw_positions(states, N, t)
    dist = np.linalg.norm(pos[:, 0] - pos[:, 1], axis=1)
    slack = np.abs(np.diff(dist)).max()  # the true minimum may lie this far below the sampled
    need = max(1.0, ratio * dist.min())
    ok = apart(e[0], e[1], e[2], e[3], e[4], e[5], need, dim, N, horizon)
    if ok:
        assert dist.min() >= need - 1e-6 * (1.0 + need)
    if dim == 2 and not drifting:
        if dist.min() - slack > need + 1e-6:
            assert ok  # exact in the plane: no refusal of a pair that stays apart
    elif dist.min() - slack > need + SEARCH_TOLERANCE:
        assert ok


# --- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"motion": "spinning"}, "FieldSpec.motion"),
        ({"motion": "bounded", "mean_motion": 0.0}, "FieldSpec.mean_motion"),
        ({"mean_motion": float("nan")}, "FieldSpec.mean_motion"),
        ({"mean_motion": -1e-3}, "FieldSpec.mean_motion"),
        ({"horizon": -1.0}, "FieldSpec.horizon"),
        ({"horizon": float("inf")}, "FieldSpec.horizon"),
        ({"drift_offset": (10.0, 5.0)}, "FieldSpec.drift_offset[1]"),
        ({"drift_offset": (-1.0, 5.0)}, "FieldSpec.drift_offset[0]"),
        ({"drift_offset": (1.0,)}, "FieldSpec.drift_offset"),
        ({"drift_offset": "far"}, "FieldSpec.drift_offset"),
        ({"spin_max": -0.1}, "FieldSpec.spin_max"),
        ({"spin_max": 5.0}, "FieldSpec.spin_max"),
        ({"rho_max": -1.0}, "FieldSpec.rho_max"),
        ({"rho_max": True}, "FieldSpec.rho_max"),
    ],
)
def test_bad_field_spec_values_are_refused_by_name(change, key):
    with pytest.raises(ValueError, match=key.replace("[", r"\[").replace("]", r"\]")):
        FieldSpec(**change)


def test_specs_that_cannot_move_safely_are_refused_by_name():
    # a drift too long for the box
    spec = spec_of(2, "drifting", drift_offset=(200.0, 300.0), horizon=20000.0)
    assert "drift_offset" in unplaceable(spec)
    with pytest.raises(ValueError, match="drift_offset"):
        draw(spec, [0])
    # gaps the chaser cannot pass at every instant
    with pytest.raises(ValueError, match="min_gap"):
        draw(spec_of(2, min_gap=1.0), [0])
    # a box too small for the dock distance along the V-bar
    assert "along-track" in unplaceable(spec_of(2, field_size=300.0, min_target_distance=140.0))
    with pytest.raises(ValueError, match="could not place"):
        draw(spec_of(2, n_obstacles=400), [0])


# --- solvability: an independent time-expanded search ---------------------------------------
#
# The chaser is a point of radius CHASER moving on a grid of cells (edge h) in steps of
# dt = h / SPEED: each step it stays or moves to a face neighbour, a straight segment at
# SPEED = 1 m/s (about twice the fastest body, a speed the 0.05 m/s² chaser reaches in 20 s).
# Every point of that segment lies within h/2 of one of the two cell centres, and during the
# step a body stays within v_b·dt/2 of its position at the step's middle (v_b: its top speed),
# so a cell is free for a step when its centre is at least r_b + CHASER + h/2 + v_b·dt/2 from
# every body's mid-step centre and its outer edge is CHASER inside the bounds: a route of free
# cells is collision-free in continuous time, conservatively. The search is the set of cells
# reachable at each step (breadth-first over time), from the dock cell at t = 0. A target is
# reached when a reachable cell's centre is within r_T + G of the target's centre, G = the
# free-cell inflation + h (the first free ring around it); the last G − CAPTURE metres are
# flown inside the target's collar, which the separation test shows no other body enters
# (G + 2·CHASER < min_gap + target_clearance, asserted). The way back is a second reachable
# set seeded at every reached cell and time; a target counts when it reaches the dock cell.
# This is a kinematic relaxation (speed-limited, not thrust-limited): it answers the geometric
# question "is there a collision-free corridor through space-time", independently of the
# generator's code and argument.

CHASER = 1.0
SPEED = 1.0


@numba.njit(cache=True)
def _box(p, reach_r, shape, h, half, lo, hi):
    """Index box (``lo``, ``hi`` inclusive) of the cells within ``reach_r`` of point ``p``."""
    count = 1
    for a in range(len(shape)):
        lo[a] = max(0, int((p[a] - reach_r + half) // h))
        hi[a] = min(shape[a] - 1, int((p[a] + reach_r + half) // h))
        count *= max(hi[a] - lo[a] + 1, 0)
    return count


@numba.njit(cache=True)
def _box_cell(m, lo, hi, strides, p, h, half):
    """The ``m``-th cell of the index box (``lo``, ``hi`` inclusive), the last axis fastest: its
    flat index and the squared distance from its centre to point ``p``."""
    rem = m
    cell = 0
    d2 = 0.0
    for a in range(len(lo) - 1, -1, -1):
        span = hi[a] - lo[a] + 1
        ia = lo[a] + rem % span
        rem //= span
        cell += ia * strides[a]
        x = -half + (ia + 0.5) * h - p[a]
        d2 += x * x
    return cell, d2


@numba.njit(cache=True)
def _reach(mid, inflate, inside, targets, goal, dock_cell, shape, h, half):
    """Round trips dock → target → dock found, (T,) bool.

    ``mid``: (L, B, dim) body centres at the middle of each step; ``inflate``: (B,) free-cell
    distance; ``inside``: (cells,) cells inside the bounds; ``targets``: (L + 1, T, dim) target
    centres at the step times, target ``j`` being body ``j``."""
    n_layers, n_bodies, dim = mid.shape
    n_cells = inside.shape[0]
    n_t = targets.shape[1]
    strides = np.ones(dim, dtype=np.int64)
    for a in range(dim - 2, -1, -1):
        strides[a] = strides[a + 1] * shape[a + 1]
    done = np.zeros(n_t, dtype=np.bool_)
    reach = np.zeros((n_t + 1, n_cells), dtype=np.bool_)  # row 0: from the dock; 1 + j: back
    active = np.zeros(n_t + 1, dtype=np.bool_)
    reach[0, dock_cell] = True
    active[0] = True
    new = np.zeros(n_cells, dtype=np.bool_)
    free = np.zeros(n_cells, dtype=np.bool_)
    idx = np.zeros(dim, dtype=np.int64)
    lo = np.zeros(dim, dtype=np.int64)
    hi = np.zeros(dim, dtype=np.int64)
    for k in range(n_layers):
        free[:] = inside
        for b in range(n_bodies):  # stamp the cells a body may touch during step k
            count = _box(mid[k, b], inflate[b], shape, h, half, lo, hi)
            for m in range(count):
                cell, d2 = _box_cell(m, lo, hi, strides, mid[k, b], h, half)
                if d2 < inflate[b] * inflate[b]:
                    free[cell] = False
        for row in range(n_t + 1):
            if not active[row]:
                continue
            src = reach[row]
            for i in range(n_cells):
                ok = False
                if free[i]:
                    if src[i]:
                        ok = True
                    else:
                        rem = i
                        for a in range(dim):
                            idx[a] = rem // strides[a]
                            rem -= idx[a] * strides[a]
                        for a in range(dim):
                            s = strides[a]
                            if idx[a] > 0 and src[i - s] and free[i - s]:
                                ok = True
                                break
                            if idx[a] < shape[a] - 1 and src[i + s] and free[i + s]:
                                ok = True
                                break
                new[i] = ok
            src[:] = new
        # arrivals at t_{k+1}: seed the way back of every target reached
        for j in range(n_t):
            reach_r = goal[j]
            count = _box(targets[k + 1, j], reach_r, shape, h, half, lo, hi)
            for m in range(count):
                cell, d2 = _box_cell(m, lo, hi, strides, targets[k + 1, j], h, half)
                if d2 <= reach_r * reach_r and reach[0, cell]:
                    reach[1 + j, cell] = True
                    active[1 + j] = True
            if reach[1 + j, dock_cell]:
                done[j] = True
        if done.all():
            break
    return done


def space_time_route(
    states: np.ndarray, radii: np.ndarray, n_targets: int, field_size: float, n: float, h: float,
    horizon: float,
) -> tuple[np.ndarray, float]:  # fmt: skip
    """For each target, whether the time-expanded search finds dock → target → dock (T,), and
    the arrival distance G beyond a target's surface."""
    dim = states.shape[1] // 2
    cells = round(field_size / h)
    cells += 1 - cells % 2  # odd: the dock (origin) is a cell centre
    h = field_size / cells
    half = field_size / 2.0
    dt = h / SPEED
    layers = math.ceil(horizon / dt)
    t_fine = np.linspace(0.0, 2.0 * math.pi / n, 4097)
    pos_fine = cw_positions(states, n, t_fine)
    top = np.linalg.norm(np.diff(pos_fine, axis=0), axis=2).max(axis=0) / np.diff(t_fine)[0]
    top = top * 1.01 + 1e-3  # sampled chords under-read the top speed slightly
    inflate = radii + CHASER + h / 2.0 + top * dt / 2.0
    axis = -half + (np.arange(cells) + 0.5) * h
    grid = np.stack(np.meshgrid(*[axis] * dim, indexing="ij"), axis=-1).reshape(-1, dim)
    inside = np.all(np.abs(grid) + h / 2.0 + CHASER <= half, axis=1)
    mid = cw_positions(states, n, (np.arange(layers) + 0.5) * dt)  # (L, B, dim)
    gap = float((inflate[:n_targets] - radii[:n_targets]).max()) + h
    goal = radii[:n_targets] + gap
    targets = cw_positions(states[:n_targets], n, np.arange(layers + 1) * dt)
    dock_cell = (grid.shape[0] - 1) // 2
    assert np.allclose(grid[dock_cell], 0.0)
    ok = _reach(mid, inflate, inside, targets, goal, dock_cell, (cells,) * dim, h, half)
    return ok, gap


def test_the_search_finds_a_route_in_free_space_and_none_to_an_enclosed_target():
    # one target at rest on the V-bar (an equilibrium): reachable and back
    states = np.array([[0.0, 200.0, 0.0, 0.0]])
    ok, _ = space_time_route(states, np.array([5.0]), 1, 600.0, N, 5.0, 3000.0)
    assert ok.all()
    # the same target walled in by a ring of overlapping discs (n tiny: the ring stays put)
    angles = np.linspace(0.0, 2.0 * np.pi, 25)[:-1]
    ring = [[60.0 * math.cos(a), 200.0 + 60.0 * math.sin(a), 0.0, 0.0] for a in angles]
    radii = np.array([5.0] + [10.0] * len(ring))
    ok, _ = space_time_route(np.array(states.tolist() + ring), radii, 1, 600.0, 1e-9, 5.0, 3000.0)
    assert not ok.any()


def moving_wall(gap_x: float | None, speed: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A target at rest 250 m along-track behind a wall of overlapping discs (r 10 m, 15 m
    apart) at y = 165 m that slides radially at ``speed`` m/s, with a 3-disc gap centred at
    x = ``gap_x`` at t = 0 (None: no gap). Free space (n ~ 0): every body moves in a line."""
    bodies = [[0.0, 250.0, 0.0, 0.0]]
    for x in np.arange(-1800.0, 301.0, 15.0):
        if gap_x is None or abs(x - gap_x) > 20.0:
            bodies.append([x, 165.0, speed, 0.0])
    return np.array(bodies), np.array([5.0] + [10.0] * (len(bodies) - 1))


def test_the_search_follows_the_bodies_in_time():
    # the gap starts outside the box (x = -400 m): a snapshot at t = 0 shows a closed wall, but
    # the gap slides in after 200 s and the chaser can pass through it, both ways
    states, radii = moving_wall(-400.0)
    ok, _ = space_time_route(states, radii, 1, 600.0, 1e-9, 5.0, 3000.0)
    assert ok.all()
    frozen = states.copy()
    frozen[:, 2:] = 0.0
    ok, _ = space_time_route(frozen, radii, 1, 600.0, 1e-9, 5.0, 3000.0)
    assert not ok.any()
    # no gap at all, or a gap sliding away from the box: closed for good
    for gap in (None, 400.0):
        ok, _ = space_time_route(*moving_wall(gap), 1, 600.0, 1e-9, 5.0, 3000.0)
        assert not ok.any()


SEARCHES: dict[str, tuple[FieldSpec, float, float]] = {
    "2d": (spec_of(2), 5.0, 2.0 * PERIOD),
    "3d": (spec_of(3), 12.5, 2.0 * PERIOD),
    "2d-drifting": (spec_of(2, "drifting", drift_offset=(5.0, 20.0)), 5.0, PERIOD),
}
"""Kinds of field searched: the spec, the search's cell edge (m) and its horizon (s): two orbits,
or one for a drifting field (the horizon it is checked over)."""


def search_cases(kind: str, fast: int, slow: int) -> list:
    """Cases of the ``kind`` of :data:`SEARCHES`: seeds 0 … ``fast`` − 1 in the default run, and
    ``slow`` more from seed 100 marked ``slow``."""
    return [pytest.param(kind, seed, id=f"{kind}-seed{seed}") for seed in range(fast)] + [
        pytest.param(kind, 100 + seed, id=f"{kind}-seed{100 + seed}", marks=pytest.mark.slow)
        for seed in range(slow)
    ]


@pytest.mark.parametrize(
    ("kind", "seed"),
    [*search_cases("2d", 6, 30), *search_cases("3d", 2, 8), *search_cases("2d-drifting", 2, 10)],
)
def test_every_accepted_field_is_solvable_by_the_independent_search(kind, seed):
    """The search finds a route dock → every target → dock within the horizon in the field the
    generator accepts for ``seed``."""
    spec, cell, horizon = SEARCHES[kind]
    fields = draw(spec, [seed])
    ok, goal = space_time_route(
        states_of(fields, 0), fields.radii[0], spec.n_targets, spec.field_size, N, cell, horizon
    )
    assert goal + 2.0 * CHASER < spec.min_gap + spec.target_clearance
    assert ok.all(), f"seed {seed}: targets {np.flatnonzero(~ok)} not reachable and back"
