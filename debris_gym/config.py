"""Typed, validated configuration of :class:`debris_gym.envs.DebrisFieldEnv`.

Every keyword a user can pass to ``gym.make("DebrisGym/…", **kwargs)`` is a field of
:class:`EnvConfig`, and every field's unit, allowed range and meaning is in :data:`OPTIONS` —
the one place input is checked (``docs/environments.md`` is generated from the same table).
Unknown keys and out-of-range values raise ``ValueError`` naming the key and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from debris_gym.dynamics import DEFAULT_ORBIT_RADIUS, R_EARTH, mean_motion


@dataclass(frozen=True)
class Option:
    """How one config key is checked and documented.

    Attributes:
        unit: physical unit ("" for none).
        low, high: inclusive numeric range (None = unbounded on that side).
        choices: allowed values for categorical keys.
        optional: whether None is allowed (meaning "off" / "derive").
        doc: one-line meaning.
    """

    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] | None = None
    optional: bool = False
    doc: str = ""

    def describe(self) -> str:
        """Human-readable allowed range, as used in error messages and docs."""
        if self.choices is not None:
            text = "one of " + ", ".join(repr(c) for c in self.choices)
        else:
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            text = f"[{lo}, {hi}]"
        return text + (" or None" if self.optional else "")

    def limits(self) -> tuple[float, float]:
        """``(low, high)`` of a key bounded on both sides.

        Raises:
            TypeError: the key is unbounded on a side (the caller took the wrong key).
        """
        if self.low is None or self.high is None:
            raise TypeError(f"this option is unbounded on a side: {self.describe()}")
        return self.low, self.high


MAX_FIELD_SIZE = 1e6
"""Largest ``field_size`` (m)."""

WORLD_FRACTION = 0.25
"""In random fields (``scenario="random"``) every body radius, ``min_gap``, ``capture_radius``
and ``chaser_radius`` is at most this share of ``field_size``: a body, gap or capture zone a
quarter of the world wide leaves no room for a field (the generator could never place it)."""

MAX_LENGTH = WORLD_FRACTION * MAX_FIELD_SIZE
"""Upper bound (m) of the lengths tied to the world (radii, gaps, capture zone, chaser)."""

MAX_RANGE = 10.0 * MAX_FIELD_SIZE
"""Upper bound (m) of sensing and shaping distances (lidar range, shaping distances)."""

MAX_SPEED = 1e4
"""Upper bound (m/s) of ``capture_speed`` (above any relative speed in low Earth orbit)."""

MAX_DELTA_V = 1e6
"""Upper bound (m/s) of ``delta_v_budget``."""

MAX_HOLD = 3600.0
"""Upper bound (s) of ``capture_hold``: an hour of station-keeping beside a target."""

MAX_SLOPE = 1e3
"""Upper bound (1/s) of ``shaping_speed_slope``."""

MIN_DRAG_ALTITUDE = 150e3
"""Lowest reference-orbit altitude (m) of ``truth_model="j2_drag"``: below it a field decays
within a mission."""

MAX_WEIGHT = 1e6
"""Upper bound of every reward weight and shaping weight: with every weight, length and speed
bounded, no reward term can overflow to inf or NaN."""


OPTIONS: dict[str, Option] = {
    "dim": Option(choices=(2, 3), doc="2 = in-plane (x, y) motion, 3 = full 3D"),
    "scenario": Option(
        choices=("random", "paper"),
        doc="field source on reset: a seeded random field, or the fixed world of [APF-MPC]",
    ),
    "n_targets": Option(low=1, high=20, doc="debris to rendezvous with"),
    "n_obstacles": Option(low=0, high=2000, doc="other debris to avoid"),
    "field_size": Option(
        "m", 20.0, MAX_FIELD_SIZE, doc="edge of the square / cubic world, dock at centre"
    ),
    "obstacle_radius_min": Option("m", 0.01, MAX_LENGTH, doc="smallest obstacle (bounding) radius"),
    "obstacle_radius_max": Option("m", 0.01, MAX_LENGTH, doc="largest obstacle (bounding) radius"),
    "target_radius_min": Option("m", 0.01, MAX_LENGTH, doc="smallest target radius"),
    "target_radius_max": Option("m", 0.01, MAX_LENGTH, doc="largest target radius"),
    "polygon_fraction": Option(
        "", 0.0, 1.0, doc="share of 2D obstacles that are convex polygons (3D: all spheres)"
    ),
    "min_gap": Option("m", 0.0, MAX_LENGTH, doc="smallest free gap between generated bodies"),
    "orbit_radius": Option(
        "m", R_EARTH, 1e9, doc="reference orbit radius; sets the mean motion n = sqrt(μ/r³)"
    ),
    "mean_motion": Option(
        "rad/s",
        0.0,
        1e-2,
        optional=True,
        doc="overrides orbit_radius when set; 0 = free space (double integrator)",
    ),
    "dt": Option("s", 1e-3, 600.0, doc="decision step length (thrust held constant over a step)"),
    "max_accel": Option("m/s²", 1e-6, 100.0, doc="thrust acceleration limit"),
    "observation": Option(choices=("kinematics", "lidar"), doc="observation mode"),
    "action": Option(
        choices=("continuous", "discrete", "residual"),
        doc="action mode: 'continuous' thrust in [-1, 1]^dim; 'discrete' coast or thrust "
        "along an axis; 'residual' a correction in [-1, 1]^dim added to the compiled base "
        "law's command toward the current goal (debris_gym.base_law), the sum clipped per axis",
    ),
    "fine_thrust": Option(
        "",
        0.0,
        1.0,
        doc="discrete actions: also thrust along each axis at this fraction of max_accel "
        "(0 = full thrust only)",
    ),
    "thrust_model": Option(
        choices=("ball", "box"),
        doc="'ball': one gimballed engine, |u| <= max_accel; 'box': per-axis thrusters",
    ),
    "capture_radius": Option(
        "m", 1e-6, MAX_LENGTH, doc="capture zone depth around a target's surface"
    ),
    "capture_speed": Option(
        "m/s", 0.0, MAX_SPEED, doc="largest speed relative to the target that still captures"
    ),
    "capture_hold": Option(
        "s",
        0.0,
        MAX_HOLD,
        doc="how long the chaser must stay in capture range and speed: every step end over at "
        "least this span (1 + ceil(capture_hold / dt) consecutive step ends; 0 = one)",
    ),
    "capture_rule": Option(
        choices=("dwell", "hold"),
        doc="'dwell': a capture is the step ends of capture_hold in capture range and speed "
        "(v0, v1); 'hold': also within capture_drift of where the hold began, the target not "
        "touched during the hold, and a step that collides captures nothing (v2)",
    ),
    "capture_drift": Option(
        "m",
        0.0,
        MAX_LENGTH,
        doc="capture_rule='hold': how far the chaser's position relative to the target may move "
        "from where the hold began, at any step end of the hold",
    ),
    "solid_targets": Option(
        choices=(False, True),
        doc="targets are solid: touching one at any speed, captured or not, is a collision "
        "(False: only an impact faster than capture_speed that is not departing)",
    ),
    "debris_motion": Option(
        choices=("frozen", "bounded", "drifting"),
        doc="how random fields' bodies move: 'frozen' (fixed in LVLH, the v0 world), "
        "'bounded' (drift-free relative orbits, the v1 world), 'drifting' (relative orbits "
        "whose centres drift along-track slowly, |x_c| in the drift_offset range)",
    ),
    "drift_offset_min": Option(
        "m", 0.0, MAX_LENGTH, doc="smallest radial offset |x_c| of a drifting body's orbit"
    ),
    "drift_offset_max": Option(
        "m", 0.0, MAX_LENGTH, doc="largest radial offset |x_c| of a drifting body's orbit"
    ),
    "spin_max": Option(
        "rad/s", 0.0, 1.0, doc="largest tumble rate of a random field's 2D polygons (inertial)"
    ),
    "target_order": Option(
        choices=("any", "queued"), doc="'any': agent chooses; 'queued': env fixes the order"
    ),
    "return_to_dock": Option(choices=(True, False), doc="after the last capture, return to dock"),
    "delta_v_budget": Option(
        "m/s", 1e-6, MAX_DELTA_V, optional=True, doc="Δv available; the episode ends when spent"
    ),
    "chaser_radius": Option("m", 0.0, MAX_LENGTH, doc="chaser radius (bodies are inflated by it)"),
    "collision_substeps": Option(
        "", 1, 256, doc="sub-samples per step swept for continuous collision checking"
    ),
    "polygon_turns": Option(
        choices=("sampled", "swept"),
        doc="how contacts with turning 2D polygons are checked: 'sampled' (the polygon turned "
        "to each sub-step only, chords between: v0/v1), 'swept' (its surface's sweep in the "
        "broad phase, chords cut to short turns: every contact in its step, within 1 cm)",
    ),
    "obs_targets": Option("", 1, 20, doc="target slots K in the observation"),
    "obs_obstacles": Option("", 0, 64, doc="nearest-obstacle slots in 'kinematics' observations"),
    "lidar_rays": Option("", 4, 1024, doc="rays in 'lidar' observations"),
    "lidar_range": Option("m", 1e-3, MAX_RANGE, doc="lidar range"),
    "reward_capture": Option("", 0.0, MAX_WEIGHT, doc="bonus per target captured"),
    "reward_success": Option("", 0.0, MAX_WEIGHT, doc="bonus for completing the mission"),
    "reward_progress": Option(
        "", 0.0, MAX_WEIGHT, doc="weight of potential-based progress shaping"
    ),
    "reward_delta_v": Option("1/(m/s)", 0.0, MAX_WEIGHT, doc="penalty per m/s of Δv spent"),
    "reward_collision": Option("", 0.0, MAX_WEIGHT, doc="penalty for a collision"),
    "reward_out_of_bounds": Option("", 0.0, MAX_WEIGHT, doc="penalty for leaving the world bounds"),
    "reward_time": Option("", 0.0, MAX_WEIGHT, doc="penalty per step"),
    "reward_budget": Option(
        "",
        0.0,
        MAX_WEIGHT,
        doc="penalty for running out of Δv (the mission ends failed, unless that step succeeds, "
        "collides or leaves the bounds)",
    ),
    "shaping_gamma": Option("", 0.0, 1.0, doc="γ of the shaping term F = γΦ(s′) − Φ(s)"),
    "shaping_potential": Option(
        choices=("goal", "tour"),
        doc="Φ: 'goal' = −(gap to the current goal / L + goals after it); 'tour' = −(the "
        "shortest remaining mission through every uncaptured target (and home) / L)",
    ),
    "shaping_terminal": Option(
        choices=("zero", "hold"),
        doc="Φ after termination: 'zero' (policy-invariant) or 'hold' (a failure forfeits the "
        "progress still to make)",
    ),
    "shaping_speed": Option(
        "",
        0.0,
        MAX_WEIGHT,
        doc="weight of Φ's approach-speed term: −w·max(0, speed − allowed) / V, allowed = "
        "capture_speed + shaping_speed_slope · gap to the goal (0 = off)",
    ),
    "shaping_speed_slope": Option(
        "1/s",
        0.0,
        MAX_SLOPE,
        doc="allowed approach speed per metre of gap to the goal (shaping_speed)",
    ),
    "shaping_clearance": Option(
        "",
        0.0,
        MAX_WEIGHT,
        doc="weight of Φ's clearance term: −w·max(0, 1 − c / shaping_clearance_distance)², c = "
        "gap from the chaser's surface to the nearest debris that is not a target (0 = off)",
    ),
    "shaping_clearance_distance": Option(
        "m",
        1e-3,
        MAX_RANGE,
        doc="clearance below which Φ's clearance term acts (shaping_clearance)",
    ),
    "shaping_closing": Option(
        "",
        0.0,
        MAX_WEIGHT,
        doc="weight of Φ's closing term: −w·max over bodies b other than the goal with clearance "
        "c_b < shaping_closing_distance of max(0, v_b − capture_speed) / V · (1 − c_b / d), v_b "
        "the speed toward b's centre (0 = off)",
    ),
    "shaping_closing_distance": Option(
        "m", 1e-3, MAX_RANGE, doc="clearance below which Φ's closing term acts (shaping_closing)"
    ),
    "obs_other_targets": Option(
        choices=(False, True),
        doc="the nearest-obstacle slots hold the nearest bodies other than the current goal, "
        "targets included (captured ones too: they are still bodies to avoid)",
    ),
    "obs_teammates": Option(
        low=0,
        high=255,
        doc="teammate slots of a swarm's observation (the nearest other chasers still flying: "
        "relative position / L, velocity / V, where each heads / L, flying flag); 0 outside "
        "swarms",
    ),
    "obs_hold": Option(
        choices=(False, True),
        doc="append each target slot's hold progress: step ends held / the step ends a capture "
        "needs, 0 to 1",
    ),
    "obs_goal": Option(
        choices=(False, True),
        doc="append the current goal at a 10× finer scale: relative position / (L/10), "
        "relative velocity / (V/10), gap / (L/10)",
    ),
    "obs_near": Option(
        choices=(False, True),
        doc="append the current goal's near field: gap / capture_radius and closing speed / "
        "capture_speed (positive when approaching), each saturated at ±4",
    ),
    "nav_sigma_position": Option(
        "m",
        0.0,
        MAX_LENGTH,
        doc="navigation error: 1σ per axis of the observed positions (the chaser's and every "
        "body's; 0 = exact)",
    ),
    "nav_sigma_velocity": Option(
        "m/s",
        0.0,
        MAX_SPEED,
        doc="navigation error: 1σ per axis of the observed velocities (0 = exact)",
    ),
    "nav_bias": Option(
        choices=(False, True),
        doc="the navigation error is drawn once per episode and held (a bias); False: drawn "
        "afresh at every observation (white)",
    ),
    "thrust_sigma_magnitude": Option(
        "",
        0.0,
        1.0,
        doc="actuation error: 1σ of the thrust's relative magnitude error, drawn every step",
    ),
    "thrust_sigma_pointing": Option(
        "rad",
        0.0,
        1.0,
        doc="actuation error: 1σ of the thrust direction's error per transverse axis, drawn "
        "every step",
    ),
    "thrust_miss_probability": Option(
        "",
        0.0,
        1.0,
        doc="actuation error: chance that the thrusters do not fire in a step (no Δv charged)",
    ),
    "truth_model": Option(
        choices=("cw", "j2_drag"),
        doc="how the world moves: 'cw' (the Clohessy-Wiltshire model, exact), 'j2_drag' (every "
        "body and the chaser as an absolute orbit with J2 and drag, seen in the LVLH frame of "
        "the reference orbit)",
    ),
    "ballistic_coefficient": Option(
        "kg/m²",
        1.0,
        1e5,
        doc="truth_model='j2_drag': m/(C_D·A) of the debris that are not targets",
    ),
    "target_ballistic_coefficient": Option(
        "kg/m²", 1.0, 1e5, doc="truth_model='j2_drag': m/(C_D·A) of the targets"
    ),
    "chaser_ballistic_coefficient": Option(
        "kg/m²",
        1.0,
        1e5,
        doc="truth_model='j2_drag': m/(C_D·A) of the chaser and of the reference orbit (so an "
        "idle chaser at the LVLH origin stays there)",
    ),
    "orbit_inclination": Option(
        "deg", 0.0, 180.0, doc="truth_model='j2_drag': inclination of the reference orbit"
    ),
    "sensor_range": Option(
        "m",
        1e-3,
        MAX_RANGE,
        optional=True,
        doc="limited sensing: obstacle slots and lidar rays show nothing beyond this gap "
        "(targets, the mission's own, are always shown); None = unlimited",
    ),
    "shield": Option(
        choices=(False, True),
        doc="filter every command through the compiled safety shield before it is flown "
        "(one chaser per field; info 'shield_intervened', 'shield_interventions')",
    ),
    "shield_penalty": Option(
        "",
        0.0,
        MAX_WEIGHT,
        doc="shield=True: reward subtracted per command the shield replaces (reward term 'shield')",
    ),
}

UNCERTAINTY_KEYS = (
    "nav_sigma_position",
    "nav_sigma_velocity",
    "nav_bias",
    "thrust_sigma_magnitude",
    "thrust_sigma_pointing",
    "thrust_miss_probability",
    "truth_model",
    "ballistic_coefficient",
    "target_ballistic_coefficient",
    "chaser_ballistic_coefficient",
    "orbit_inclination",
    "sensor_range",
)
"""The options of the uncertain world (off by default; docs/environments.md, "An uncertain
world")."""


@dataclass(frozen=True)
class EnvConfig:
    """Configuration of a :class:`~debris_gym.envs.DebrisFieldEnv`; see :data:`OPTIONS`."""

    dim: int = 2
    scenario: str = "random"
    n_targets: int = 3
    n_obstacles: int = 20
    field_size: float = 1000.0
    obstacle_radius_min: float = 2.0
    obstacle_radius_max: float = 25.0
    target_radius_min: float = 3.0
    target_radius_max: float = 10.0
    polygon_fraction: float = 0.5
    min_gap: float = 10.0
    orbit_radius: float = DEFAULT_ORBIT_RADIUS
    mean_motion: float | None = None
    dt: float = 10.0
    max_accel: float = 0.05
    observation: str = "kinematics"
    action: str = "continuous"
    thrust_model: str = "ball"
    fine_thrust: float = 0.0
    capture_radius: float = 5.0
    capture_speed: float = 0.5
    capture_hold: float = 0.0
    capture_rule: str = "dwell"
    capture_drift: float = 1.0
    solid_targets: bool = False
    debris_motion: str = "frozen"
    drift_offset_min: float = 2.0
    drift_offset_max: float = 10.0
    spin_max: float = 0.0
    target_order: str = "any"
    return_to_dock: bool = True
    delta_v_budget: float | None = 100.0
    chaser_radius: float = 1.0
    collision_substeps: int = 8
    polygon_turns: str = "sampled"
    obs_targets: int = 3
    obs_obstacles: int = 8
    lidar_rays: int = 32
    lidar_range: float = 250.0
    reward_capture: float = 10.0
    reward_success: float = 50.0
    reward_progress: float = 10.0
    reward_delta_v: float = 0.05
    reward_collision: float = 50.0
    reward_out_of_bounds: float = 50.0
    reward_time: float = 0.01
    reward_budget: float = 0.0
    shaping_gamma: float = 0.99
    shaping_potential: str = "goal"
    shaping_terminal: str = "zero"
    shaping_speed: float = 0.0
    shaping_speed_slope: float = 0.01
    shaping_clearance: float = 0.0
    shaping_clearance_distance: float = 50.0
    shaping_closing: float = 0.0
    shaping_closing_distance: float = 20.0
    obs_goal: bool = False
    obs_near: bool = False
    obs_hold: bool = False
    obs_other_targets: bool = False
    obs_teammates: int = 0
    nav_sigma_position: float = 0.0
    nav_sigma_velocity: float = 0.0
    nav_bias: bool = False
    thrust_sigma_magnitude: float = 0.0
    thrust_sigma_pointing: float = 0.0
    thrust_miss_probability: float = 0.0
    truth_model: str = "cw"
    ballistic_coefficient: float = 50.0
    target_ballistic_coefficient: float = 100.0
    chaser_ballistic_coefficient: float = 100.0
    orbit_inclination: float = 51.6
    sensor_range: float | None = None
    shield: bool = False
    shield_penalty: float = 0.0

    def __post_init__(self) -> None:
        # each key alone (stored normalised: whole numbers as int, reals as float, flags as
        # bool), then the rules that tie keys together
        for f in dataclasses.fields(self):
            value = _checked(f.name, getattr(self, f.name), _kind(f.type))
            object.__setattr__(self, f.name, value)
        _check_cross_keys(self)

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvConfig:
        """Build a config, rejecting unknown keys with the list of known ones."""
        unknown = sorted(set(kwargs) - set(OPTIONS))
        if unknown:
            raise ValueError(
                f"unknown config key(s) {unknown}; known keys: {', '.join(sorted(OPTIONS))}"
            )
        return cls(**kwargs)

    @property
    def navigation_errors(self) -> bool:
        """Whether observations carry a navigation error."""
        return self.nav_sigma_position > 0.0 or self.nav_sigma_velocity > 0.0

    @property
    def actuation_errors(self) -> bool:
        """Whether the thrusters err."""
        return (
            self.thrust_sigma_magnitude > 0.0
            or self.thrust_sigma_pointing > 0.0
            or self.thrust_miss_probability > 0.0
        )

    @property
    def uncertain(self) -> bool:
        """Whether any option of the uncertain world is on (:data:`UNCERTAINTY_KEYS`)."""
        return (
            self.navigation_errors
            or self.actuation_errors
            or self.truth_model != "cw"
            or self.sensor_range is not None
        )

    @property
    def n(self) -> float:
        """Mean motion (rad/s): ``mean_motion`` if set, else derived from ``orbit_radius``."""
        return self.mean_motion if self.mean_motion is not None else mean_motion(self.orbit_radius)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of every key (for saving next to results)."""
        return dataclasses.asdict(self)


_WORLD_TIED = (
    "obstacle_radius_max",
    "target_radius_max",
    "min_gap",
    "capture_radius",
    "chaser_radius",
)
"""Keys bounded by ``WORLD_FRACTION · field_size`` in random fields (the lower radius of each
pair is bounded by its upper one)."""


def _kind(annotation: Any) -> str:
    """'int', 'float', 'str' or 'bool' from a field's annotation (a string: the module uses
    postponed evaluation)."""
    text = str(annotation)
    for kind in ("bool", "int", "float", "str"):
        if text.startswith(kind):
            return kind
    raise TypeError(f"EnvConfig field annotated {text!r} has no validation rule")


def _show(value: Any) -> str:
    """``repr(value)`` cut to a readable length (a 400-digit integer is still named)."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _checked(key: str, value: Any, kind: str) -> Any:
    """``value`` validated against :data:`OPTIONS` ``[key]`` and normalised to ``kind``.

    Raises:
        ValueError: naming ``key``, the value and the allowed range; checks run in the order
            type, finite, whole number, range, so that every bad value gets this error (never
            a ``TypeError`` or ``OverflowError`` from a conversion).
    """
    opt = OPTIONS[key]
    allowed = opt.describe()
    unit = f" {opt.unit}" if opt.unit else ""
    if value is None:
        if opt.optional:
            return None
        raise ValueError(f"{key} must not be None; allowed: {allowed}")
    if kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{key}={_show(value)} is not allowed; allowed: {allowed}")
        return bool(value)
    if kind == "str":
        if not isinstance(value, str) or value not in (opt.choices or ()):
            raise ValueError(f"{key}={_show(value)} is not allowed; allowed: {allowed}")
        return str(value)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(
            f"{key} must be a number, got {_show(value)} ({type(value).__name__}); "
            f"allowed: {allowed}"
        )
    if isinstance(value, numbers.Integral):
        number: int | float = int(value)  # exact, however large: compared without rounding
    else:
        try:
            number = float(value)
        except OverflowError:  # e.g. a Fraction beyond float range
            number = -math.inf if value < 0 else math.inf
        if not math.isfinite(number):
            raise ValueError(f"{key} must be finite, got {_show(value)}; allowed: {allowed}{unit}")
        if kind == "int":
            if not number.is_integer():
                raise ValueError(
                    f"{key} must be a whole number, got {_show(value)}; allowed: {allowed}"
                )
            number = int(number)  # 3.0 from JSON / YAML is the integer 3
    if (opt.low is not None and number < opt.low) or (opt.high is not None and number > opt.high):
        raise ValueError(f"{key}={_show(value)}{unit} is out of range; allowed: {allowed}{unit}")
    if opt.choices is not None and number not in opt.choices:
        raise ValueError(f"{key}={_show(value)} is not allowed; allowed: {allowed}")
    return int(number) if kind == "int" else float(number)


def _check_cross_keys(cfg: EnvConfig) -> None:
    """The rules between keys (each key is already valid on its own)."""
    pairs = (
        ("obstacle_radius_min", "obstacle_radius_max"),
        ("target_radius_min", "target_radius_max"),
        ("drift_offset_min", "drift_offset_max"),
    )
    for lo_key, hi_key in pairs:
        lo, hi = getattr(cfg, lo_key), getattr(cfg, hi_key)
        if lo > hi:
            raise ValueError(f"{lo_key}={lo!r} m must be <= {hi_key}={hi!r} m")
    if cfg.scenario == "paper" and cfg.dim != 2:
        raise ValueError("scenario='paper' is a 2D world; use dim=2")
    if cfg.debris_motion != "frozen" and cfg.n == 0.0:
        raise ValueError(
            f"debris_motion={cfg.debris_motion!r} needs an orbit (mean_motion > 0): in free "
            "space (mean_motion=0) relative orbits do not exist; use debris_motion='frozen'"
        )
    if cfg.action == "residual" and cfg.navigation_errors:
        raise ValueError(
            "action='residual' adds a base law computed on the true state; with navigation "
            f"errors (nav_sigma_position={cfg.nav_sigma_position!r} m, nav_sigma_velocity="
            f"{cfg.nav_sigma_velocity!r} m/s) the policy would see through them: use "
            "action='continuous', or no navigation errors"
        )
    if cfg.truth_model == "j2_drag":
        if cfg.debris_motion == "frozen" or cfg.scenario == "paper":
            raise ValueError(
                "truth_model='j2_drag' moves every body as an orbit; a frozen field "
                f"(debris_motion={cfg.debris_motion!r}, scenario={cfg.scenario!r}) is not one: "
                "use debris_motion='bounded' or 'drifting' with scenario='random'"
            )
        if cfg.mean_motion is not None:
            raise ValueError(
                f"truth_model='j2_drag' orbits the Earth at orbit_radius; mean_motion="
                f"{cfg.mean_motion!r} would set another: leave mean_motion None"
            )
        if cfg.orbit_radius - R_EARTH < MIN_DRAG_ALTITUDE:
            raise ValueError(
                f"truth_model='j2_drag' needs orbit_radius >= {R_EARTH + MIN_DRAG_ALTITUDE:g} m "
                f"(an altitude of {MIN_DRAG_ALTITUDE / 1e3:g} km or more), got {cfg.orbit_radius!r}"
            )
    if cfg.shield_penalty > 0.0 and not cfg.shield:
        raise ValueError(
            f"shield_penalty={cfg.shield_penalty!r} penalises the shield's interventions; "
            "it needs shield=True"
        )
    if cfg.scenario == "random":
        limit = WORLD_FRACTION * cfg.field_size
        for key in _WORLD_TIED:
            value = getattr(cfg, key)
            if value > limit:
                raise ValueError(
                    f"{key}={value!r} m is too large for field_size={cfg.field_size!r} m; "
                    f"allowed: [{OPTIONS[key].low:g}, {limit:g}] m ({WORLD_FRACTION:g} · "
                    "field_size) in random fields"
                )
