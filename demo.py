"""Fly one episode of DebrisGym/Rendezvous2D-v0 with a simple PD guidance law.

Prints a summary and saves a picture of the final frame. A placeholder main job until
``evaluate.py`` ships the baselines; the controller here ignores debris (it may collide).

    python demo.py [--env DebrisGym/Rendezvous2D-v0] [--seed 0] [--out runs/demo.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

import debris_gym  # noqa: F401  (registers the IDs)


def pd_action(env: gym.Env, k_p: float = 0.004, k_d: float = 0.12) -> np.ndarray:
    """Acceleration toward the nearest uncaptured target (then the dock), as a normalised action."""
    base = env.unwrapped
    scen, state, d = base.scenario, base._state, base.dim
    pos, vel = state[:d], state[d:]
    remaining = [i for i, c in enumerate(base._captured) if not c]
    if remaining:
        centres = np.array([scen.targets[i].position for i in remaining])
        k = int(np.argmin(np.linalg.norm(centres - pos, axis=1)))
        target = scen.targets[remaining[k]]
        offset = np.asarray(target.position) - pos
        dist = np.linalg.norm(offset)
        stand_off = target.radius + base.config.chaser_radius + 0.5 * base.config.capture_radius
        goal = pos + offset * (1.0 - stand_off / max(dist, 1e-9))
    else:
        goal = np.asarray(scen.dock)
    accel = k_p * (goal - pos) - k_d * vel
    return np.clip(accel / scen.max_accel, -1.0, 1.0).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="DebrisGym/Rendezvous2D-v0")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("runs/demo.png"))
    args = parser.parse_args()

    env = gym.make(args.env, render_mode="rgb_array")
    obs, info = env.reset(seed=args.seed)
    total, steps = 0.0, 0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(pd_action(env))
        total += reward
        steps += 1
    frame = env.render()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    import matplotlib.image

    matplotlib.image.imsave(args.out, frame)
    print(f"env        {args.env} (seed {args.seed})")
    print(f"steps      {steps} ({info['time']:.0f} s simulated)")
    print(f"captured   {info['targets_captured']}/{info['n_targets']} targets")
    print(f"success    {info['is_success']}   collision {info['collision']}")
    print(f"delta-v    {info['delta_v']:.2f} m/s")
    print(f"clearance  {info['min_clearance']:.1f} m (smallest)")
    print(f"return     {total:.2f}")
    print(f"picture    {args.out}")
    env.close()


if __name__ == "__main__":
    main()
