"""What the benchmark measures: env IDs, action draws, and the sizes of a quick, full or tiny run.

The size tables (:data:`QUICK`, :data:`FULL`, :data:`TINY`) are plain dicts so a caller can
override any entry (``run(sizes={**TINY, "scaling_rows": ((10, 2),)})``). Seconds are wall-clock
targets per repeat, counts are steps (or resets, or sub-envs) and ``*_envs`` entries are the
number N of sub-envs of a vector env.
"""

from __future__ import annotations

import math
from typing import Any

import debris_gym

DEBRIS_IDS = tuple(debris_gym.ENV_SPECS)
CARTPOLE = "CartPole-v1"
ID_2D = "DebrisGym/Rendezvous2D-v2"
ID_3D = "DebrisGym/Rendezvous3D-v2"
ID_V1 = "DebrisGym/Rendezvous2D-v1"
"""The v1 2D default: the vector env's random-action goals are stated for it (and held against
:data:`ID_2D` too)."""
SCALING_COUNTS = (10, 50, 100, 200)
"""Debris counts of the single-env scaling rows (the vector rows take theirs from the sizes)."""
DEFAULT_OBSTACLES = 20
"""Debris of the default field: the reference of both scaling tables."""
THRUST = 0.05
"""Continuous actions are uniform in [-THRUST, THRUST], a fraction of ``max_accel``."""
DISCRETE_COAST = 0.9
"""Share of coast (0) actions for discrete DebrisGym envs; the rest fire one random thruster."""

QUICK: dict[str, Any] = {
    # single env
    "repeats": 3,
    "step_seconds": 0.12,
    "reset_seconds": 0.1,
    "min_steps": 50,
    # vector env: N values, warm-up steps from reset, seconds per repeat
    "vector_envs": (64, 1024),
    "vector_variant_envs": 256,  # Rendezvous3D and observation=lidar rows
    "sync_envs": 64,
    "subproc_envs": (2, 8),
    "cartpole_envs": 1024,
    "warmup_steps": 150,
    "vector_seconds": 0.25,
    "sync_max_steps": 20,
    # vector scaling: (n_obstacles, N); a 20-debris row is added for every N
    "scaling_rows": ((10, 256), (50, 256), (100, 128), (200, 64)),
    "scaling_seconds": 0.15,
    "early_steps": 45,
    # memory: (small N, large N)
    "memory_envs": (64, 1024),
    # training
    "train_envs": (64, 256),
    "dummy_envs": 8,
    "train_rollout": 8192,  # env-steps per rollout (n_steps = rollout / N)
    "train_rollouts": 1,  # timed rollouts+updates per repeat
    "train_repeats": 1,
    "train_batch": 4096,
    "train_epochs": 2,
    # decision times: missions per agent (seeds DECISION_SEED …), time limit (None: the env's)
    "decision_episodes": 1,
    "decision_max_steps": None,
    # swarm: chasers K per field, chasers in all fields (E = total // K), warm-up steps of the
    # swarm core and of VMAS (whose step takes seconds at K = 256), seconds per repeat
    "swarm_chasers": (1, 8, 48, 256),
    "swarm_chasers_total": 1024,
    "swarm_warmup_steps": 150,
    "vmas_warmup_steps": 1,
    "swarm_seconds": 0.25,
    # the compiled shield: N of the shield-off and shield-on rows (one thread)
    "shield_envs": 1024,
}
"""Sizes of ``--quick``: fewer and shorter repeats, smaller N."""

FULL: dict[str, Any] = {
    **QUICK,
    "repeats": 5,
    "step_seconds": 0.9,
    "reset_seconds": 0.6,
    "min_steps": 200,
    "vector_envs": (64, 256, 1024, 4096),
    "vector_variant_envs": 1024,
    "warmup_steps": 250,
    "vector_seconds": 0.8,
    "sync_max_steps": 60,
    "scaling_rows": ((10, 1024), (50, 1024), (100, 1024), (200, 1024)),
    "scaling_seconds": 0.5,
    "early_steps": 60,
    "memory_envs": (64, 4096),
    "train_rollout": 16384,
    "train_rollouts": 3,
    "train_repeats": 2,
    "decision_episodes": 3,
    "swarm_warmup_steps": 250,
    "vmas_warmup_steps": 2,
    "swarm_seconds": 0.8,
}
"""Sizes of the default run."""

TINY: dict[str, Any] = {
    "vector_envs": (4,),
    "vector_variant_envs": 4,
    "sync_envs": 4,
    "subproc_envs": (2,),
    "cartpole_envs": 4,
    "warmup_steps": 3,
    "scaling_rows": ((10, 4), (50, 4), (100, 2), (200, 2)),
    "early_steps": 30,
    "memory_envs": (2, 6),
    "train_envs": (4,),
    "dummy_envs": 2,
    "train_rollout": 256,
    "train_rollouts": 1,
    "train_repeats": 1,
    "train_batch": 64,
    "train_epochs": 1,
    "decision_episodes": 1,
    "decision_max_steps": 5,
    "swarm_chasers": (1, 3),
    "swarm_chasers_total": 6,
    "swarm_warmup_steps": 3,
    "vmas_warmup_steps": 1,
    "shield_envs": 4,
}
"""Sizes for smoke tests (``run(sizes=TINY)``): every code path, seconds not minutes."""

MAX_STEPS = 300_000
"""Most single-env steps per repeat, whatever the calibration asks for."""
MAX_RESETS = 20_000
"""Most resets per repeat."""
MAX_VECTOR_STEPS = 4000
"""Most vector steps per repeat."""
MIN_VECTOR_STEPS = 3
"""Fewest vector steps per repeat (unless the section allows fewer)."""


def field_size_for(n_obstacles: int) -> float:
    """Field edge (m) for ``n_obstacles`` debris at the default density (20 per 1000 m square)."""
    return 1000.0 * math.sqrt(max(1.0, n_obstacles / DEFAULT_OBSTACLES))
