"""Render one picture per registered env ID to ``docs/images/<name>.png``.

Each env is reset with seed 0 and flown by a simple controller that thrusts toward the first
target (velocity tracking that slides round debris), a few dozen steps (more for the small-``dt``
paper field) until the chaser brakes on its approach, so the trail and the thrust arrow show.
Run from the repository root::

    python docs/make_images.py
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

import debris_gym
from debris_gym.geometry import FieldGeometry

OUT = Path(__file__).resolve().parent / "images"
MAX_STEPS = 300


def toward_first_target(scenario: debris_gym.Scenario, state: np.ndarray) -> np.ndarray:
    """Thrust command (fraction of max_accel, norm <= 1) toward target 0, steering round debris.

    Tracks a desired velocity: toward the target at a capped speed, braking at 70 % thrust; near an
    obstacle (surface closer than ``reach``) the part heading into it is removed, so the chaser
    slides round it, and very close to it a push away is added.
    """
    d = scenario.dim
    pos, vel = state[:d], state[d:]
    offset = np.asarray(scenario.targets[0].position) - pos
    distance = np.linalg.norm(offset)
    v_max = 0.3 * np.sqrt(scenario.size * scenario.max_accel)
    # Brake at 70 % thrust to stop at the target's surface, allowing for the tracking lag.
    stopping = distance - scenario.targets[0].radius - 2.0 * scenario.dt * np.linalg.norm(vel)
    brake = np.sqrt(2.0 * 0.7 * scenario.max_accel * max(stopping, 0.0))
    desired = offset / distance * min(v_max, brake)
    n_targets = len(scenario.targets)
    gaps = FieldGeometry(scenario).signed_distance(pos)[n_targets:]
    centres = scenario.body_positions()[n_targets:]
    reach = 0.08 * scenario.size
    for gap, centre in zip(gaps, centres, strict=True):
        if gap < reach:
            away = (pos - centre) / np.linalg.norm(pos - centre)
            weight = min(1.0, (reach - gap) / (0.5 * reach))
            into = float(desired @ away)
            if into < 0.0:  # heading into it: slide along its surface instead
                desired -= weight * into * away
            desired += v_max * max(0.0, 1.0 - gap / (0.25 * reach)) * away
    accel = (desired - vel) / (2.0 * scenario.dt)
    cmd = accel / scenario.max_accel
    norm = np.linalg.norm(cmd)
    return (cmd / norm if norm > 1.0 else cmd).astype(np.float32)


def main() -> None:
    import matplotlib.image

    OUT.mkdir(parents=True, exist_ok=True)
    for env_id in debris_gym.ENV_SPECS:
        env = gym.make(env_id, render_mode="rgb_array")
        _, info = env.reset(seed=0)
        scenario = env.unwrapped.scenario
        goal = np.asarray(scenario.targets[0].position)
        start = np.linalg.norm(goal - info["chaser_state"][: scenario.dim])
        for _ in range(MAX_STEPS):
            action = toward_first_target(scenario, info["chaser_state"])
            _, _, terminated, truncated, info = env.step(action)
            # Stop once braking hard on the second half of the way, so the thrust arrow shows.
            left = np.linalg.norm(goal - info["chaser_state"][: scenario.dim])
            braking = left < 0.5 * start and np.linalg.norm(action) >= 0.6
            if terminated or truncated or braking:
                break
        frame = env.render()
        name = env_id.split("/")[1].split("-")[0].lower()
        path = OUT / f"{name}.png"
        matplotlib.image.imsave(path, frame)
        status = "collision" if info["collision"] else f"{info['targets_captured']} captured"
        steps = round(info["time"] / scenario.dt)
        print(f"{env_id}: {frame.shape[1]}x{frame.shape[0]} px, {steps} steps, {status} -> {path}")
        env.close()


if __name__ == "__main__":
    main()
