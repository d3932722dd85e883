"""The named structures the compiled step passes around (as gymnax passes EnvState / EnvParams).

Each is a module-level :class:`~typing.NamedTuple`, which numba compiles as a record of typed
fields (arrays and scalars alike) and which its on-disk cache can key on:

* :class:`Rules` — what stays fixed for a batch: the physics of a step, the mission's rules,
  the reward weights;
* :class:`Shaping` — the optional terms of the potential, or None when all are off (the
  kernels are then compiled without them);
* :class:`Missions` — the per-mission state arrays (row i = mission i);
* :class:`Field` — the per-field arrays: the bodies (the six geometry arrays of
  :class:`~debris_gym.batch_geometry.FieldBatch`), the dock, the bounds and the scales;
* :class:`StepOutputs` — what a step returns: rewards, flags and reward terms;
* :class:`StepScratch` — the row loop's working arrays, allocated by its caller.

No numba or gymnasium import: these are plain data.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from debris_gym.config import EnvConfig
from debris_gym.rewards import REWARD_TERMS


class Rules(NamedTuple):
    """The fixed rules of every mission of a batch (SI units)."""

    dt: float
    """Step length (s)."""
    max_accel: float
    """Thrust limit (m/s²)."""
    box_thrust: bool
    """Thrust model: True "box" (per-axis clip, Δv rate Σ|u_i|), False "ball"."""
    step_matrix_t: np.ndarray
    """(2·dim + dim, n_sub·dim + dim): [x₀, u] @ it gives every sub-step position, the last
    being the end position, then the end velocity (exact zero-order hold)."""
    delta_v_budget: float
    """Δv budget (m/s); inf when there is none."""
    chaser_radius: float
    """Chaser radius (m)."""
    capture_radius: float
    """Capture distance from a target's surface (m)."""
    capture_speed: float
    """Highest speed relative to the target at which a capture counts (m/s)."""
    hold_steps: int
    """Consecutive step ends a capture needs (:func:`hold_steps`)."""
    hold_capture: bool
    """``capture_rule == "hold"``: the hold must also stay within ``capture_drift`` of where it
    began and untouched, and a step that collides captures nothing."""
    capture_drift: float
    """Largest move (m) of the chaser's position relative to the target from where the hold
    began (``hold_capture`` only)."""
    moving: bool
    """The bodies move on unforced CWH motion (``debris_motion`` is not "frozen")."""
    solid_targets: bool
    """Touching a target at any speed is a collision (else only an impact faster than
    ``capture_speed`` that is not departing, the v0 rule)."""
    body_matrix_t: np.ndarray
    """(2·dim, 2·dim) transposed state-transition matrix Φ(dt)ᵀ of a free body."""
    reach_position: float
    """Largest 2-norm of the position block of Φ(t) − I over the sub-steps: with
    ``reach_velocity`` it bounds how far a free body moves in a step (broad phase)."""
    reach_velocity: float
    """Largest 2-norm of the position-from-velocity block of Φ(t) over the sub-steps (s)."""
    swept_turns: bool
    """``polygon_turns == "swept"``: contacts with turning polygons cover their surface's sweep
    (see :func:`~debris_gym.swept_contacts.moving_path_touches`)."""
    n_targets: int
    """Targets per field T (the first T bodies)."""
    queued: bool
    """``target_order == "queued"``: only the first uncaptured target counts."""
    return_to_dock: bool
    """Success needs the chaser back at the dock, slow."""
    max_steps: int
    """Truncation limit (steps); −1 for none."""
    n_chasers: int
    """Chasers per field K (rows f·K … f·K + K − 1 fly in field f; 1 for the single-agent
    envs, whose row i flies in field i)."""
    chaser_separation: float
    """Centre-to-centre distance (m) at or below which two chasers of a field collide."""
    field_loop: bool
    """Step field by field (:func:`~debris_gym.mission_step.step_fields`, the swarms' loop),
    not row by row (the single-agent loop, one chaser per field)."""
    arrived_stay: bool
    """A chaser that succeeded stays in its field as a body held where it ended: the chasers
    still flying are checked against it like against a teammate (the formation slots of a
    reconfiguration); otherwise an ended chaser leaves the field."""
    gamma: float
    """Discount of the potential-based shaping."""
    tour_potential: bool
    """``shaping_potential == "tour"``: Φ = −(shortest remaining mission) / L."""
    terminal_zero: bool
    """``shaping_terminal == "zero"``: Φ = 0 after termination."""
    # the reward weights, named like their config keys (penalties as positive magnitudes);
    # flat fields, not a nested structure: numba's threaded loops take no nested tuples
    reward_capture: float
    reward_success: float
    reward_progress: float
    reward_delta_v: float
    reward_collision: float
    reward_out_of_bounds: float
    reward_time: float
    reward_budget: float
    # the uncertain world (docs/environments.md, "An uncertain world")
    thrust_errors: bool
    """The thrusters err (any ``thrust_*`` option above 0): every burn is drawn through
    :func:`debris_gym.uncertainty.err_thrust`."""
    thrust_sigma_magnitude: float
    """1σ of the thrust's relative magnitude error."""
    thrust_sigma_pointing: float
    """1σ (rad) of the thrust direction's error per transverse axis."""
    thrust_miss_probability: float
    """Chance that the thrusters do not fire in a step."""
    truth_orbits: bool
    """``truth_model="j2_drag"``: the step's end states are those of absolute orbits with J2
    and drag (:func:`debris_gym.orbit_truth.truth_step`), not of the CW model."""
    truth_substeps: int
    """Runge-Kutta sub-steps of the truth model per step."""
    atmosphere: np.ndarray
    """(K, 3) the truth model's density table (:data:`debris_gym.orbit_truth.ATMOSPHERE`)."""
    chaser_inv_ballistic: float
    """C_D·A/m (m²/kg) of the chaser and of the reference orbit."""


class Shaping(NamedTuple):
    """The optional terms of the potential (config keys ``shaping_*``; see
    :mod:`debris_gym.rewards`)."""

    speed: float
    speed_slope: float
    clearance: float
    clearance_distance: float
    closing: float
    closing_distance: float


class Missions(NamedTuple):
    """Per-mission state, row i = mission i (SI units; see :class:`MissionBatch`)."""

    state: np.ndarray
    """(N, 2·dim) LVLH position (m) and velocity (m/s)."""
    time: np.ndarray
    """(N,) time since the episode began (s)."""
    steps: np.ndarray
    """(N,) int64 steps since the episode began."""
    delta_v: np.ndarray
    """(N,) Δv spent (m/s)."""
    captured: np.ndarray
    """(N, T) bool capture flags."""
    collision: np.ndarray
    """(N,) bool."""
    out_of_bounds: np.ndarray
    """(N,) bool."""
    success: np.ndarray
    """(N,) bool."""
    gaps: np.ndarray
    """(N, B) signed distance from the chaser's centre to every body's surface (m)."""
    nearest: np.ndarray
    """(N, O) int64 the obstacles by gap, nearest first (empty unless the kinematics
    observation shows obstacles)."""
    min_clearance: np.ndarray
    """(N,) smallest obstacle gap so far (m, chaser radius not subtracted)."""
    potential: np.ndarray
    """(N,) the shaping potential Φ."""
    accel: np.ndarray
    """(N, dim) acceleration the last step applied (m/s², after the budget cut)."""
    hold: np.ndarray
    """(N, T) int64 consecutive step ends each target has been held in capture range."""
    score: np.ndarray
    """(N,) the unshaped task score so far: the sum of every reward term but the progress
    shaping, undiscounted (what tables rank by; the shaping only guides learning)."""
    hold_anchor: np.ndarray
    """(N, T, dim) the chaser's position relative to each target (m) at the first step end of
    its current hold (``capture_rule="hold"``)."""
    budget_spent: np.ndarray
    """(N,) bool: the mission ended failed because the Δv budget ran out."""
    teammate_collision: np.ndarray
    """(N,) bool: the chaser touched another chaser of its field (a collision)."""
    separation: np.ndarray
    """(N,) closest approach (m, centre to centre) to another chaser of the field so far (inf
    with one chaser per field)."""
    assigned: np.ndarray
    """(N, T) bool: the targets that are the chaser's to capture (all of them unless a swarm
    assigns them); a chaser's ``captured`` flags start True for the others, so its goal, its
    observation's target slots, its captures and its success count its own alone."""
    noise_key: np.ndarray
    """(N,) uint64: the key of the episode's random errors (the uncertain world): every error
    is a pure function of the key, the step and what it perturbs
    (:func:`debris_gym.uncertainty.standard_normal`)."""


class Field(NamedTuple):
    """Per-field arrays: row f = field f (the field of missions f·K … f·K + K − 1, K =
    :attr:`Rules.n_chasers`), except ``dock``, one row per mission (each chaser's own dock
    slot)."""

    centers: np.ndarray
    """(N, B, dim) body centres (m)."""
    radii: np.ndarray
    """(N, B) bounding radii (m)."""
    polygon_start: int
    """First body index that may be a polygon."""
    polygons: np.ndarray
    """(N, P + 1) the polygon list of each field (see FieldBatch)."""
    n_vertices: np.ndarray
    """(N, P) vertex counts of the bodies from ``polygon_start`` on."""
    vertices: np.ndarray
    """(N, P, V, 4) polygon vertices and edges (m; see FieldBatch)."""
    velocities: np.ndarray
    """(N, B, dim) body velocities (m/s)."""
    attitude: np.ndarray
    """(N, P, 2) cos, sin of the angle each polygon has turned through (see FieldBatch)."""
    turns: np.ndarray
    """(N, P, 6) cos, sin of the angle a polygon turns through in one step, then in one
    collision sub-step, then those two angles (rad; signed, not reduced modulo 2π)."""
    dock: np.ndarray
    """(N, dim) each mission's dock position (m)."""
    low: np.ndarray
    """(N, dim) lower bounds (m)."""
    high: np.ndarray
    """(N, dim) upper bounds (m)."""
    length_scale: np.ndarray
    """(N,) the observation's length scale L (m)."""
    speed_scale: np.ndarray
    """(N,) the observation's speed scale V (m/s)."""
    reference: np.ndarray
    """(N, 6) the truth model's reference orbit, ECI position (m) and velocity (m/s) (unused
    by the CW model)."""
    inv_ballistic: np.ndarray
    """(N, B) each body's C_D·A/m (m²/kg) in the truth model."""


class StepOutputs(NamedTuple):
    """What a step writes: rows not stepped are zero / False."""

    reward: np.ndarray
    """(N,) sum of the terms."""
    terminated: np.ndarray
    """(N,) bool: success, collision, out of bounds or budget spent."""
    truncated: np.ndarray
    """(N,) bool: the step limit reached."""
    terms: np.ndarray
    """(N, 8) reward terms, columns in :data:`REWARD_TERMS` order."""


class StepScratch(NamedTuple):
    """Working arrays of one row loop of the step, reused from row to row (the loop itself is
    compiled without reference counting and may not allocate; see
    :func:`debris_gym.mission_step.step_rows`)."""

    path: np.ndarray
    """(C, S + 1, dim) each chaser's position at the step's start and at each of its S sub-steps
    (m), C = :attr:`Rules.n_chasers`."""
    start: np.ndarray
    """(C, 2·dim) each chaser's state before the step."""
    accel: np.ndarray
    """(dim,) the acceleration the step applies (m/s²)."""
    touched: np.ndarray
    """(C, B) bool: the bodies each chaser's path touched."""
    relative_path: np.ndarray
    """(S + 1, dim) a path relative to one moving body (m)."""
    order: np.ndarray
    """(T,) int64 scratch of the tour potential."""
    counters: np.ndarray
    """(T,) int64 scratch of the tour potential."""
    legs: np.ndarray
    """(T, T) scratch of the tour potential: the legs between targets (m)."""
    homes: np.ndarray
    """(T,) scratch of the tour potential: each target's distance to the dock (m)."""
    dvs: np.ndarray
    """(C,) each chaser's Δv of the step (m/s)."""
    mates: np.ndarray
    """(C,) bool: each chaser touched another in the step."""
    truth_states: np.ndarray
    """(1 + B, 6) the truth model's LVLH states of the chaser and the bodies (3D; empty
    without the truth model)."""
    truth_accels: np.ndarray
    """(1 + B, 3) their thrust (m/s², LVLH)."""
    truth_inv: np.ndarray
    """(1 + B,) their C_D·A/m (m²/kg)."""
    truth_work: np.ndarray
    """The truth model's scratch (:func:`debris_gym.orbit_truth.truth_work`)."""


def hold_steps(capture_hold: float, dt: float) -> int:
    """Consecutive step ends in capture range that span at least ``capture_hold`` seconds:
    1 + ⌈capture_hold / dt⌉ (one step end for no hold; 4 for 30 s at dt = 10 s)."""
    return 1 + max(0, math.ceil(capture_hold / dt - 1e-9))


def make_rules(
    cfg: EnvConfig,
    n_targets: int,
    step_matrix_t: np.ndarray,
    *,
    dt: float,
    max_accel: float,
    max_episode_steps: int | None,
    body_matrix_t: np.ndarray,
    reach: tuple[float, float],
    n_chasers: int = 1,
    chaser_separation: float | None = None,
    field_loop: bool = False,
    arrived_stay: bool = False,
    truth_substeps: int = 1,
    atmosphere: np.ndarray | None = None,
) -> Rules:
    """The :class:`Rules` of ``cfg`` for fields of ``n_targets`` targets and the given physics
    (``body_matrix_t`` and ``reach``: see :class:`Rules`), ``n_chasers`` chasers per field that
    collide within ``chaser_separation`` (m, centre to centre; default: touching, twice the
    chaser radius); with ``arrived_stay`` a chaser that succeeded stays a body in its field."""
    return Rules(
        dt=float(dt),
        max_accel=float(max_accel),
        box_thrust=cfg.thrust_model == "box",
        step_matrix_t=step_matrix_t,
        delta_v_budget=math.inf if cfg.delta_v_budget is None else float(cfg.delta_v_budget),
        chaser_radius=float(cfg.chaser_radius),
        capture_radius=float(cfg.capture_radius),
        capture_speed=float(cfg.capture_speed),
        hold_steps=hold_steps(cfg.capture_hold, dt),
        hold_capture=cfg.capture_rule == "hold",
        capture_drift=float(cfg.capture_drift),
        moving=cfg.debris_motion != "frozen",
        solid_targets=bool(cfg.solid_targets),
        body_matrix_t=body_matrix_t,
        reach_position=float(reach[0]),
        reach_velocity=float(reach[1]),
        swept_turns=cfg.polygon_turns == "swept",
        n_targets=int(n_targets),
        queued=cfg.target_order == "queued",
        return_to_dock=bool(cfg.return_to_dock),
        max_steps=-1 if max_episode_steps is None else int(max_episode_steps),
        n_chasers=int(n_chasers),
        field_loop=bool(field_loop or n_chasers > 1),
        arrived_stay=bool(arrived_stay),
        chaser_separation=(
            2.0 * float(cfg.chaser_radius)
            if chaser_separation is None
            else float(chaser_separation)
        ),
        gamma=float(cfg.shaping_gamma),
        tour_potential=cfg.shaping_potential == "tour",
        terminal_zero=cfg.shaping_terminal == "zero",
        **{f"reward_{k}": float(getattr(cfg, f"reward_{k}")) for k in REWARD_TERMS},
        thrust_errors=cfg.actuation_errors,
        thrust_sigma_magnitude=float(cfg.thrust_sigma_magnitude),
        thrust_sigma_pointing=float(cfg.thrust_sigma_pointing),
        thrust_miss_probability=float(cfg.thrust_miss_probability),
        truth_orbits=cfg.truth_model == "j2_drag",
        truth_substeps=int(truth_substeps),
        atmosphere=np.zeros((1, 3)) if atmosphere is None else atmosphere,
        chaser_inv_ballistic=1.0 / float(cfg.chaser_ballistic_coefficient),
    )


def make_shaping(cfg: EnvConfig) -> Shaping | None:
    """The optional potential terms of ``cfg``, or None when all three are off."""
    if not (cfg.shaping_speed > 0 or cfg.shaping_clearance > 0 or cfg.shaping_closing > 0):
        return None
    return Shaping(
        speed=float(cfg.shaping_speed),
        speed_slope=float(cfg.shaping_speed_slope),
        clearance=float(cfg.shaping_clearance),
        clearance_distance=float(cfg.shaping_clearance_distance),
        closing=float(cfg.shaping_closing),
        closing_distance=float(cfg.shaping_closing_distance),
    )


def new_missions(num: int, dim: int, n_targets: int, n_bodies: int, n_ranked: int) -> Missions:
    """Zeroed :class:`Missions` (``min_clearance`` inf) for ``num`` missions; ``n_ranked``
    obstacles kept sorted by gap."""
    return Missions(
        state=np.zeros((num, 2 * dim)),
        time=np.zeros(num),
        steps=np.zeros(num, dtype=np.int64),
        delta_v=np.zeros(num),
        captured=np.zeros((num, n_targets), dtype=bool),
        collision=np.zeros(num, dtype=bool),
        out_of_bounds=np.zeros(num, dtype=bool),
        success=np.zeros(num, dtype=bool),
        gaps=np.zeros((num, n_bodies)),
        nearest=np.zeros((num, n_ranked), dtype=np.int64),
        min_clearance=np.full(num, math.inf),
        potential=np.zeros(num),
        accel=np.zeros((num, dim)),
        hold=np.zeros((num, n_targets), dtype=np.int64),
        score=np.zeros(num),
        hold_anchor=np.zeros((num, n_targets, dim)),
        budget_spent=np.zeros(num, dtype=bool),
        teammate_collision=np.zeros(num, dtype=bool),
        separation=np.full(num, math.inf),
        assigned=np.ones((num, n_targets), dtype=bool),
        noise_key=np.zeros(num, dtype=np.uint64),
    )


def new_step_outputs(num: int) -> StepOutputs:
    """Zeroed :class:`StepOutputs` for ``num`` missions."""
    return StepOutputs(
        reward=np.zeros(num),
        terminated=np.zeros(num, dtype=bool),
        truncated=np.zeros(num, dtype=bool),
        terms=np.zeros((num, len(REWARD_TERMS))),
    )
