"""Fly one episode of DebrisGym/Rendezvous2D-v0 with a simple braking-profile guidance law.

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


def guidance_action(env: gym.Env) -> np.ndarray:
    """Braking-profile guidance toward the nearest uncaptured target, then the dock.

    Commands the velocity v_des = min(v_max, sqrt(a · gap)) toward the goal point, so the chaser
    can always stop in time with half its thrust, and thrusts to match it. Ignores debris.
    """
    base = env.unwrapped
    scen, cfg, state, d = base.scenario, base.config, base._state, base.dim
    pos, vel = state[:d], state[d:]
    remaining = [i for i, c in enumerate(base._captured) if not c]
    if remaining:
        centres = np.array([scen.targets[i].position for i in remaining])
        target = scen.targets[remaining[int(np.argmin(np.linalg.norm(centres - pos, axis=1)))]]
        offset = np.asarray(target.position) - pos
        stand_off = target.radius + cfg.chaser_radius + 0.5 * cfg.capture_radius
        offset -= offset / max(np.linalg.norm(offset), 1e-9) * stand_off
    else:
        offset = np.asarray(scen.dock) - pos
    gap = float(np.linalg.norm(offset))
    speed = min(0.5 * cfg.capture_speed + np.sqrt(scen.max_accel * gap), 10.0)
    v_des = offset / max(gap, 1e-9) * min(speed, gap / scen.dt)
    accel = (v_des - vel) / scen.dt
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
        obs, reward, terminated, truncated, info = env.step(guidance_action(env))
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
