"""The same seed gives the same field, release after release: digests of fields drawn by the
registered IDs and by the generators, pinned in ``tests/data/pinned_fields.json``.

A change that alters any of them alters the registered IDs' results (every seeded episode, the
suites, the pretrained policies), which needs a new version, not an edit of the pinned data.
Rewrite the file (``python tests/test_pinned_fields.py``) only when a new version is made.
"""

from __future__ import annotations

import hashlib
import json
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import debris_gym  # noqa: F401  (registers the IDs)
from debris_gym.generators import FieldSpec, random_fields
from debris_gym.scenario import Scenario

PINNED = Path(__file__).resolve().parent / "data" / "pinned_fields.json"
ENV_IDS = (
    "DebrisGym/Rendezvous2D-v1",
    "DebrisGym/Rendezvous3D-v1",
    "DebrisGym/Rendezvous2D-v0",
    "DebrisGym/Rendezvous3D-v0",
)
SEEDS = range(5)
N = 1.1314e-3  # rad/s
_BASE = dict(target_clearance=17.0, dock_clearance=50.0, min_target_distance=150.0, mean_motion=N)
SPECS = {
    "drifting2d": dict(dim=2, motion="drifting", horizon=1000.0, spin_max=0.02),
    "drifting3d": dict(dim=3, motion="drifting", horizon=1000.0),
    "bounded2d_crowded": dict(dim=2, motion="bounded", n_obstacles=40),
    "frozen2d_crowded": dict(dim=2, n_obstacles=270),
    "frozen3d": dict(dim=3, n_obstacles=30),
}
"""Generator specs pinned besides the IDs' own: drifting orbits, crowded fields (several tries)."""


def _digest(arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def scenario_digest(scenario: Scenario) -> str:
    """Digest of a field's bodies: states at t = 0, radii, polygon vertices and spins."""
    bodies = scenario.bodies
    vertices = [np.asarray(b.vertices if b.vertices else [], dtype=float) for b in bodies]
    return _digest(
        [
            np.asarray(scenario.dock, dtype=float),
            np.asarray(scenario.bounds, dtype=float),
            np.asarray(scenario.initial_body_states()),
            np.array([b.radius for b in bodies]),
            np.array([b.spin for b in bodies]),
            *vertices,
        ]
    )


def env_digests(env_id: str) -> list[str]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the v0 IDs say they are old
        env = gym.make(env_id)
    out = []
    for seed in SEEDS:
        env.reset(seed=seed)
        out.append(scenario_digest(env.unwrapped.scenario))
    env.close()
    return out


def spec_digest(name: str) -> str:
    spec = FieldSpec(**{**_BASE, **SPECS[name]})
    f = random_fields([np.random.default_rng(s) for s in SEEDS], spec, capture_radius=5.0)
    arrays = [f.centers, f.radii, f.vertices, f.n_vertices]
    if f.velocities is not None:
        arrays += [f.velocities, f.spins]
    return _digest(arrays)


def _pinned() -> dict:
    return json.loads(PINNED.read_text())


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_an_id_draws_the_pinned_fields_for_seeds_0_to_4(env_id):
    assert env_digests(env_id) == _pinned()["env"][env_id]


@pytest.mark.parametrize("name", sorted(SPECS))
def test_a_generator_spec_draws_the_pinned_fields_for_seeds_0_to_4(name):
    assert spec_digest(name) == _pinned()["spec"][name]


if __name__ == "__main__":  # (re)write the pinned digests: only for a new version
    data = {
        "env": {env_id: env_digests(env_id) for env_id in ENV_IDS},
        "spec": {name: spec_digest(name) for name in sorted(SPECS)},
    }
    PINNED.write_text(json.dumps(data, indent=1) + "\n")
    sys.exit(0)
