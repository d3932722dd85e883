"""Registration of the DebrisGym environment IDs with gymnasium.

Variants are registrations with different keyword arguments, not subclasses.
"""

from __future__ import annotations

import gymnasium as gym

ENTRY_POINT = "debris_gym.envs.debris_field:DebrisFieldEnv"
VECTOR_ENTRY_POINT = "debris_gym.envs.vector:DebrisFieldVectorEnv"

ENV_SPECS: dict[str, dict] = {
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
"""Every registered ID with its time limit (steps) and keyword arguments."""


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
