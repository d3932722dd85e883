"""Contacts with turning polygons, held to an independent dense check (``tests/turning_truth.py``).

A polygon turns in LVLH at its spin − n. With ``polygon_turns="swept"`` every contact the dense
check finds must be flagged in the step it happens (no late contact) and nothing it clears by
more than the check's tolerance may be flagged (no false contact); the same flights show that
``polygon_turns="sampled"`` (the v0 / v1 check) has both. Flights are flown through the env with
a pinned scenario: a polygon at rest on the V-bar and the chaser set beside it or flying past it
or into it, at the default turn (−n) and at tumble rates up to the largest allowed (1 rad/s), at
the default step and at long steps.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pymunk
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from debris_gym.envs import DebrisFieldEnv
from debris_gym.scenario import Body, Scenario
from debris_gym.swept_contacts import TURN_TOLERANCE
from tests.helpers import LEO_MEAN_MOTION, MOVING_WORLD
from tests.turning_truth import (
    SAMPLING_ERROR,
    StepTruth,
    flight_truth,
    polygon_distance,
    relative_motion,
)

N = LEO_MEAN_MOTION
CHASER_RADIUS = 1.0
"""The env's default ``chaser_radius`` (m): bodies are inflated by it."""
MAX_ACCEL = 0.05
CENTRE = np.array([0.0, 0.0])
"""Where the polygon sits (m), at rest: a CW equilibrium, and nowhere the broad phase's bound on
a body's own motion adds anything (the dock is elsewhere)."""

pytestmark = pytest.mark.filterwarnings("ignore:.*flown anyway:UserWarning")


def square(radius: float, angle: float = 0.0) -> np.ndarray:
    """A square's counter-clockwise vertices (m, relative to its centre), circumradius
    ``radius``, its first corner at ``angle`` (rad)."""
    a = angle + np.arange(4) * math.pi / 2
    return radius * np.stack([np.cos(a), np.sin(a)], axis=-1)


def scenario(vertices: np.ndarray, spin: float, dt: float) -> Scenario:
    """A target far away and one polygon at :data:`CENTRE`, both at rest on the V-bar."""
    radius = float(np.sqrt((vertices**2).sum(-1)).max())
    return Scenario(
        dim=2, bounds=((-500.0, 500.0), (-500.0, 500.0)), dock=(0.0, -300.0),
        targets=(Body(position=(0.0, 400.0), radius=5.0, velocity=(0.0, 0.0)),),
        obstacles=(Body(tuple(CENTRE), radius, (0.0, 0.0), tuple(map(tuple, vertices)), spin),),
        mean_motion=N, dt=dt, max_accel=MAX_ACCEL, motion="cwh", motion_faults="warn",
    )  # fmt: skip


_ENVS: dict[tuple, DebrisFieldEnv] = {}


def env_for(mode: str, dt: float, substeps: int) -> DebrisFieldEnv:
    """One env per (mode, step, sub-steps), reused (pinned fields are loaded on reset)."""
    key = (mode, dt, substeps)
    if key not in _ENVS:
        options = {**MOVING_WORLD, "dt": dt, "collision_substeps": substeps}
        _ENVS[key] = DebrisFieldEnv(dim=2, polygon_turns=mode, **options)
    return _ENVS[key]


def flagged_step(env, vertices, spin: float, dt: float, rel0, actions) -> tuple[int | None, int]:
    """Fly the chaser from the relative state ``rel0`` (to the polygon) with ``actions`` in
    ``env`` (its step ``dt``): the step (0-based) the env flags a collision in (None if none),
    and the steps flown."""
    chaser = np.concatenate([CENTRE + np.asarray(rel0[:2]), np.asarray(rel0[2:])])
    env.reset(
        options={"scenario": scenario(np.asarray(vertices), spin, dt), "chaser_state": chaser}
    )
    for k, action in enumerate(actions):
        *_, terminated, _, info = env.step(np.asarray(action, dtype=float))
        if info["collision"]:
            return k, k + 1
        if terminated:
            return None, k + 1
    return None, len(actions)


def verdict(truth: list[StepTruth], flagged: int | None, flown: int) -> str:
    """The env's answer (collision flagged in step ``flagged`` of ``flown``) against the dense
    check: "ok"; "late" (flagged after the first step with a contact, or never); "false"
    (flagged in a step the check clears, with no contact before). A step whose smallest gap is
    within the band of the chaser's radius counts either way (band: the turn tolerance, the
    chord error every swept check has, the check's sampling error)."""
    first_contact = None
    clear = []
    for k, step in enumerate(truth[:flown]):
        band = TURN_TOLERANCE + step.chord_error + SAMPLING_ERROR + 1e-6
        clear.append(step.gap > CHASER_RADIUS + band)
        if first_contact is None and step.gap <= CHASER_RADIUS - band:
            first_contact = k
    if flagged is None:
        return "ok" if first_contact is None else "late"
    if first_contact is not None and first_contact < flagged:
        return "late"
    return "false" if clear[flagged] else "ok"


def check_flight(
    mode: str, vertices, spin: float, dt: float, substeps: int, rel0, actions
) -> tuple[str, bool]:
    """:func:`verdict` of one flight, and whether the dense check finds a contact in it."""
    vertices = np.asarray(vertices, dtype=float)
    env = env_for(mode, dt, substeps)
    flagged, flown = flagged_step(env, vertices, spin, dt, rel0, actions)
    accels = MAX_ACCEL * np.asarray(actions, dtype=float)
    truth = flight_truth(
        np.asarray(rel0, dtype=float), accels[:flown], spin - N, vertices, N, dt, substeps
    )
    return verdict(truth, flagged, flown), any(step.gap <= CHASER_RADIUS for step in truth)


def aimed(radius: float, angle: float, miss: float, speed: float, start: float) -> list[float]:
    """A relative state ``start`` m beyond the polygon's circumradius in direction ``angle``
    (rad), moving at ``speed`` (m/s) toward the point ``miss`` m to the side of its centre."""
    p = (radius + start) * np.array([math.cos(angle), math.sin(angle)])
    side = np.array([-math.sin(angle), math.cos(angle)])
    heading = miss * side - p
    heading /= np.linalg.norm(heading)
    return [*p, *(speed * heading)]


def beside(corner: float, lead: float, distance: float) -> list[float]:
    """A relative state at rest ``distance`` m from the centre, ``lead`` rad clockwise of the
    corner at angle ``corner``: a polygon turning clockwise (at −n, or faster) sweeps into it."""
    angle = corner - lead
    return [distance * math.cos(angle), distance * math.sin(angle), 0.0, 0.0]


def clear_start(rel0, vertices) -> bool:
    """The chaser starts outside the inflated polygon (the env refuses any other start)."""
    return polygon_distance(np.array([rel0[:2]]), np.asarray(vertices))[0] > CHASER_RADIUS + 1e-3


def fixed_flights(spin: float, dt: float) -> list[tuple]:
    """Flights (vertices, rel0, actions) beside, past and into a turning 25 m square: chasers at
    rest where a corner sweeps into them or just misses, and coasting or thrusting passes aimed
    into the square or just beyond the reach of its inflated corners."""
    verts = square(25.0)
    out = []
    rng = np.random.default_rng(20)
    steps_beside = max(3, math.ceil(60.0 / dt))
    for distance in (25.3, 25.9, 26.3):
        for lead in (0.01, 0.025, 0.045):
            rel0 = beside(-math.pi / 2, lead, distance)
            if clear_start(rel0, verts):
                out.append((verts, rel0, np.zeros((steps_beside, 2))))
    while len(out) < 24:
        # aimed into the square, or just past its corners' reach (26 m with the chaser's radius)
        miss = rng.uniform(26.1, 29.0) if len(out) % 3 == 0 else rng.uniform(10.0, 26.0)
        angle, speed = rng.uniform(0.0, 2 * math.pi), rng.uniform(0.1, 1.0)
        rel0 = aimed(25.0, angle, miss, speed, rng.uniform(0.5, 8.0))
        steps = min(30, math.ceil(70.0 / speed / dt) + 1)
        # every other pass thrusts (|action| < 1: the ball thrust model applies it unclipped)
        actions = rng.uniform(-0.7, 0.7, (steps, 2)) * (len(out) % 2)
        if clear_start(rel0, verts):
            out.append((verts, rel0, actions))
    return out


SPINS = (0.0, 0.01, 0.1, 1.0)
"""Tumble rates (rad/s) of the flights: none (the polygon turns at −n only), slow, fast, and
the largest allowed (:data:`debris_gym.scenario_values.MAX_SPIN`)."""
STEPS = ((10.0, 8), (60.0, 8))
"""(dt (s), collision_substeps) of the flights: the default step and a long one."""


def verdicts(mode: str, spin: float, dt: float, substeps: int) -> dict[str, int]:
    """How many of :func:`fixed_flights` get each verdict."""
    out: dict[str, int] = {}
    for verts, rel0, actions in fixed_flights(spin, dt):
        v, _ = check_flight(mode, verts, spin, dt, substeps, rel0, actions)
        out[v] = out.get(v, 0) + 1
    return out


# --- the dense check's own parts, held to independent references ------------------------------


def test_the_thrust_response_matches_an_ode_solver():
    rng = np.random.default_rng(0)
    for _ in range(5):
        state0 = rng.normal(0.0, [50.0, 50.0, 0.5, 0.5])
        accel = rng.uniform(-0.05, 0.05, 2)

        def rhs(_t, s, a=accel):
            x, _y, vx, vy = s
            return [vx, vy, 3 * N**2 * x + 2 * N * vy + a[0], -2 * N * vx + a[1]]

        times = np.linspace(0.0, 600.0, 7)
        sol = solve_ivp(rhs, (0.0, 600.0), state0, t_eval=times, rtol=1e-12, atol=1e-12)
        pos, vel = relative_motion(state0, accel, times, N)
        np.testing.assert_allclose(pos, sol.y[:2].T, atol=1e-6)
        np.testing.assert_allclose(vel, sol.y[2:].T, atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(
    sides=st.integers(3, 8),
    seed=st.integers(0, 2**32 - 1),
    point=st.tuples(st.floats(-40.0, 40.0), st.floats(-40.0, 40.0)),
)
def test_the_polygon_distance_matches_pymunk(sides, seed, point):
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0.0, 2 * math.pi, sides))
    verts = rng.uniform(2.0, 25.0) * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    space = pymunk.Space()
    poly = pymunk.Poly(space.static_body, [tuple(v) for v in verts])  # on a circle: convex
    space.add(poly)
    expected = poly.point_query(point).distance
    assert polygon_distance(np.array([point]), verts)[0] == pytest.approx(expected, abs=1e-9)


# --- the swept check against the dense check ---------------------------------------------------


def test_a_25_m_square_turning_beside_the_chaser_is_flagged_in_the_step_it_touches():
    """A 25 m square and the chaser both at rest on the V-bar (so neither centre moves), a corner
    turning at −n toward the chaser: the corner's sweep (≈ 0.28 m a step) is the only motion.
    Flown with the registered default env and the option."""
    verts = square(25.0, -math.pi / 2 + 0.06)  # a corner 0.06 rad (5 steps) short of the chaser
    rel0 = [0.0, -25.6, 0.0, 0.0]
    coast = np.zeros((12, 2))
    flags = {}
    for mode in ("swept", "sampled"):
        env = gym.make("DebrisGym/Rendezvous2D-v1", polygon_turns=mode, mean_motion=N)
        assert env.unwrapped.config.dt == 10.0
        flags[mode], _ = flagged_step(env, verts, 0.0, 10.0, rel0, coast)
    gaps = [step.gap for step in flight_truth(np.asarray(rel0), coast, -N, verts, N, 10.0, 8)]
    first = next(k for k, g in enumerate(gaps) if g <= CHASER_RADIUS)
    band = TURN_TOLERANCE + SAMPLING_ERROR
    assert first > 0
    assert gaps[first] < CHASER_RADIUS - band < CHASER_RADIUS + band < gaps[first - 1]
    assert flags["swept"] == first
    assert flags["sampled"] == first + 1  # the v1 check: a step late


def first_flag_and_truth(mode, verts, spin, dt, substeps, rel0, steps):
    """The step the env flags (0-based, or None) and the dense check of each step, for a chaser
    coasting ``steps`` steps from ``rel0``."""
    actions = np.zeros((steps, 2))
    flagged, _ = flagged_step(env_for(mode, dt, substeps), verts, spin, dt, rel0, actions)
    truth = flight_truth(np.asarray(rel0), actions, spin - N, verts, N, dt, substeps)
    return flagged, truth


def test_a_polygon_turning_a_whole_turn_per_step_is_still_checked():
    """At dt = 600 s a tumble of 2π/600 rad/s (plus n) turns the square exactly once a step: its
    attitude at every step end is its first, so only the stored angle (not its cos and sin) shows
    that a corner swept past the chaser in between."""
    dt = 600.0
    spin = 2 * math.pi / dt + N
    verts = square(25.0, -math.pi / 4)  # an edge's middle faces the chaser: 7.8 m clear
    rel0 = [0.0, -25.5, 0.0, 0.0]
    swept, truth = first_flag_and_truth("swept", verts, spin, dt, 8, rel0, 3)
    assert truth[0].gap < CHASER_RADIUS - 0.4  # the corners pass 0.5 m from the chaser's centre
    assert swept == 0
    sampled, _ = first_flag_and_truth("sampled", verts, spin, dt, 8, rel0, 3)
    assert sampled is None  # every step starts 7.8 m clear and no centre moves


@pytest.mark.parametrize(("dt", "substeps"), STEPS)
@pytest.mark.parametrize("spin", SPINS)
def test_swept_turns_flag_every_contact_in_its_step_and_nothing_else(spin, dt, substeps):
    assert verdicts("swept", spin, dt, substeps) == {"ok": 24}


def test_sampled_turns_flag_contacts_late_and_falsely_on_the_same_flights():
    """The same flights under the v0 / v1 check: late contacts already at the default turn, and
    false ones when the polygon turns far within a sub-step."""
    counts = {
        (spin, dt): verdicts("sampled", spin, dt, substeps)
        for spin in SPINS
        for dt, substeps in STEPS
    }  # fmt: skip
    assert counts[(0.0, 10.0)].get("late", 0) > 0
    assert counts[(1.0, 10.0)].get("false", 0) > 0
    assert sum(c.get("late", 0) for c in counts.values()) >= 10


@st.composite
def flights(draw):
    """A random convex polygon (3–7 corners on a circle of 2–25 m), a tumble rate across the
    allowed range, a step length (up to 10 min, with more sub-steps there so that the chords'
    own error stays small beside the turn's), and a chaser coasting or thrusting past or into
    it."""
    sides = draw(st.integers(3, 7))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    radius = draw(st.floats(2.0, 25.0))
    angles = np.sort(rng.uniform(0.0, 2 * math.pi, sides))
    verts = radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    spin = draw(st.one_of(st.sampled_from((0.0, 0.01, -0.1, 1.0, -1.0)), st.floats(-1.0, 1.0)))
    dt, substeps = draw(st.sampled_from((*STEPS, (600.0, 64))))
    speed = draw(st.floats(0.05, 1.5))
    rel0 = aimed(
        radius, draw(st.floats(0.0, 2 * math.pi)), draw(st.floats(0.0, radius + 3.0)), speed,
        draw(st.floats(CHASER_RADIUS + 0.1, 10.0)),
    )  # fmt: skip
    steps = min(30, math.ceil((2 * radius + 12.0) / speed / dt) + 1)
    thrust = draw(st.sampled_from((0.0, 0.7)))  # |action| < 1: applied unclipped
    actions = rng.uniform(-thrust, thrust, (steps, 2))
    return verts, spin, dt, substeps, rel0, actions


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(flight=flights())
def test_swept_turns_agree_with_the_dense_check_on_random_flights(flight):
    verts, spin, dt, substeps, rel0, actions = flight
    assume(clear_start(rel0, verts))
    result, contact = check_flight("swept", verts, spin, dt, substeps, rel0, actions)
    event("a contact" if contact else "no contact")
    assert result == "ok"
