"""Iterations until every agent's graph is connected, with and without node sharing: the
measurement of [Bandyopadhyay17] Fig. 4 and 7 on the library's 3D fields (planner only).

    PYTHONPATH=$PWD python docs/swarm_connectivity.py --agents 6 --seeds 10

Each seed draws a frozen field of ``DebrisGym/Rendezvous3D-v2`` (``debris_motion="frozen"``);
the N agents start on the swarm envs' dock lattice around its dock (pitch ``--pitch`` m) and
the N goals lie on a Fibonacci shell ``--shell`` m above the surface of target 0 (the "central
body"); a seed whose goals fall in a body is skipped. Both explorations
(:func:`agents.planners.swarm_exploration.compare_sharing`) draw from the seed's generator, with
r_col = 2 m, r_max = 10 m (one 10 s step at 1 m/s), the "se-scp" sphere margins, a cap of
``--cap`` iterations. Prints one line per seed and the means.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> None:
    import gymnasium as gym

    from agents.planners.spherical_expansion import node_radii
    from agents.planners.swarm_expansion import SwarmParams
    from agents.planners.swarm_exploration import compare_sharing
    from debris_gym.geometry import FieldGeometry
    from debris_gym.swarm.config import dock_slots

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, default=6)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--pitch", type=float, default=30.0, help="start lattice pitch (m)")
    parser.add_argument("--shell", type=float, default=40.0, help="goal shell height (m)")
    parser.add_argument("--cap", type=int, default=300, help="most iterations")
    args = parser.parse_args(argv)
    n = args.agents
    env = gym.make("DebrisGym/Rendezvous3D-v2", debris_motion="frozen")
    shared, alone = [], []
    for seed in range(args.seeds):
        env.reset(seed=seed)
        scen = env.unwrapped.scenario
        geo = FieldGeometry(scen)
        starts = np.array(scen.dock) + dock_slots(n, args.pitch, 3)
        body = scen.targets[0]
        k = np.arange(n) + 0.5
        phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
        unit = np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]
        goals = np.array(body.position) + (body.radius + args.shell) * unit
        margins = np.full(geo.n_bodies, env.unwrapped.config.chaser_radius + 0.002 * scen.size)
        if node_radii(geo, np.vstack([starts, goals]), margins, scen.low, scen.high).min() < 1:
            print(f"N={n} seed={seed}: a start or goal lies in a body, skipped")
            continue
        p = SwarmParams(r_col=2.0, r_max=10.0, max_iterations=args.cap)
        began = time.perf_counter()
        c = compare_sharing(geo, starts, goals, margins, seed, p, low=scen.low, high=scen.high)
        shared.append(c.shared)
        alone.append(c.alone)
        print(
            f"N={n} seed={seed}: with sharing {c.shared.iterations} (connected "
            f"{c.shared.connected}, nodes per agent {c.shared.nodes_per_agent.mean():.0f}), "
            f"without {c.alone.iterations} (connected {c.alone.connected}, nodes per agent "
            f"{c.alone.nodes_per_agent.mean():.0f}), {time.perf_counter() - began:.1f} s"
        )
    env.close()
    for name, runs in (("with sharing", shared), ("without", alone)):
        if runs:
            its = [r.iterations for r in runs]
            print(
                f"{name}: iterations mean {np.mean(its):.1f}, median {np.median(its):.0f} "
                f"(connected {sum(r.connected for r in runs)}/{len(runs)}; cap {args.cap})"
            )


if __name__ == "__main__":
    main()
