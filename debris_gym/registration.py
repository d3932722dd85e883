"""Registration of the DebrisGym environment IDs with gymnasium.

Variants are registrations with different keyword arguments, not subclasses.
"""

from __future__ import annotations

import re

import gymnasium as gym

MIN_GYMNASIUM = (1, 0)
"""The oldest gymnasium the envs run on (its reset and vector-env API; 0.29 lacks both)."""


def require_gymnasium(version: str) -> None:
    """Refuse a gymnasium older than :data:`MIN_GYMNASIUM` at import, with the fix, rather than
    an ``AttributeError`` deep inside the first ``reset``.

    Raises:
        ImportError: ``version`` is older than 1.0 (or not a version number).
    """
    found = re.match(r"(\d+)\.(\d+)", version)
    if found is None or (int(found[1]), int(found[2])) < MIN_GYMNASIUM:
        raise ImportError(
            f"debris-gym needs gymnasium >= {'.'.join(map(str, MIN_GYMNASIUM))}, found "
            f"gymnasium {version}; upgrade it: pip install 'gymnasium>=1.0'"
        )


require_gymnasium(gym.__version__)

ENTRY_POINT = "debris_gym.envs.debris_field:DebrisFieldEnv"
VECTOR_ENTRY_POINT = "debris_gym.envs.vector:DebrisFieldVectorEnv"

PHYSICAL_WORLD: dict[str, object] = {
    "debris_motion": "bounded",
    "solid_targets": True,
    "capture_speed": 0.2,
    "capture_hold": 30.0,
    "fine_thrust": 0.1,
    "shaping_gamma": 1.0,
    "shaping_terminal": "hold",
    "shaping_potential": "tour",
}
"""The options that make the v1 world (docs/environments.md, "What v1 changes"): bodies on
natural CWH relative orbits, solid targets, capture held for 30 s at ≤ 0.2 m/s relative to the
target, fine discrete thrust, and undiscounted shaping on the shortest remaining mission that
never refunds (so the return ranks a success above idling, crashing, fleeing and burning the
budget, whichever target a tour starts with)."""

HOLD_RULES: dict[str, object] = {
    "capture_rule": "hold",
    "capture_speed": 0.1,
    "capture_drift": 1.0,
    "reward_budget": 50.0,
    "obs_hold": True,
    "polygon_turns": "swept",
}
"""The rules v2 adds to the v1 world (docs/environments.md, "What v2 changes"): a capture is a
hold of 30 s within 1 m of where it began, at ≤ 0.1 m/s relative to the target, untouched; a
step that collides captures nothing; running out of Δv is a failure penalised like leaving the
world; the hold's progress is observed; the contact check follows a turning polygon's surface
through its turn. The figures are of the order of real proximity operations ([Fehse03]:
docking contact speeds, berthing capture boxes)."""

V2_WORLD: dict[str, object] = {**PHYSICAL_WORLD, **HOLD_RULES}
"""Every option of the v2 world: the v1 world with :data:`HOLD_RULES`."""

UNCERTAIN_WORLD: dict[str, object] = {
    **V2_WORLD,
    "nav_sigma_position": 1.0,
    "nav_sigma_velocity": 0.01,
    "thrust_sigma_magnitude": 0.05,
    "thrust_sigma_pointing": 0.02,
    "thrust_miss_probability": 0.01,
    "truth_model": "j2_drag",
    "sensor_range": 250.0,
}
"""The v2 world with every error of the uncertain world on at the order of a real proximity
operation (docs/environments.md, "An uncertain world"): relative navigation to 1 m and 1 cm/s,
thrust to 5 % and 0.02 rad with one step in a hundred missed, absolute orbits with J2 and drag
(the debris' ballistic coefficient half the chaser's and the targets'), sensing to 250 m."""

EASY_MISSION: dict[str, object] = {"n_targets": 1, "n_obstacles": 5, "return_to_dock": False}
"""The Easy rung of v1: one target among five other debris, no return (the mission ends at the
capture)."""

MEDIUM_MISSION: dict[str, object] = {"n_targets": 2, "n_obstacles": 10, "return_to_dock": True}
"""The Medium rung of v1: two targets among ten other debris, then back to the dock."""


def _rungs(version: str, world: dict[str, object]) -> dict[str, dict]:
    """The default ID of ``version`` in 2D and 3D and its Easy and Medium rungs, each flying
    ``world`` for 1 000 steps (the order of the docs' ID table)."""
    missions = {"": {}, "-Easy": EASY_MISSION, "-Medium": MEDIUM_MISSION}
    order = [(2, ""), (3, ""), (2, "-Easy"), (2, "-Medium"), (3, "-Easy"), (3, "-Medium")]
    return {
        f"DebrisGym/Rendezvous{dim}D{rung}-{version}": {
            "max_episode_steps": 1000,
            "kwargs": {"dim": dim, **world, **missions[rung]},
        }
        for dim, rung in order
    }


ENV_SPECS: dict[str, dict] = {
    **_rungs("v2", V2_WORLD),
    **{
        f"DebrisGym/Rendezvous{dim}D-Uncertain-v2": {
            "max_episode_steps": 1000,
            "kwargs": {"dim": dim, **UNCERTAIN_WORLD},
        }
        for dim in (2, 3)
    },
    **_rungs("v1", PHYSICAL_WORLD),
    "DebrisGym/Rendezvous2D-v0": {"max_episode_steps": 1000, "kwargs": {"dim": 2}},
    "DebrisGym/Rendezvous3D-v0": {"max_episode_steps": 1000, "kwargs": {"dim": 3}},
    "DebrisGym/PaperField2D-v0": {
        "max_episode_steps": 2000,
        "kwargs": {
            "dim": 2,
            "scenario": "paper",
            "field_size": 20.0,
            "mean_motion": 0.0,
            "dt": 0.1,
            "max_accel": 1.0,
            "capture_radius": 0.2,
            "capture_speed": 0.2,
            "chaser_radius": 0.1,
            "delta_v_budget": None,
            "lidar_range": 5.0,
            "obs_targets": 4,
        },
    },
}
"""Every registered ID with its time limit (steps) and keyword arguments. The Easy and Medium
IDs are difficulty rungs of the v2 (and of the v1) world (the same physics, rules and reward;
fewer targets and debris): the same missions as ``reset(options={"mission": EASY_MISSION})`` on
the default ID of their version, so a curriculum can climb them in one env."""


def register_envs() -> None:
    """Register every DebrisGym ID (idempotent)."""
    for env_id, spec in ENV_SPECS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=ENTRY_POINT,
            vector_entry_point=VECTOR_ENTRY_POINT,
            max_episode_steps=spec["max_episode_steps"],
            kwargs=dict(spec["kwargs"]),
        )
