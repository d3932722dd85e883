"""One reconfiguration flown by the "ma-se-scp" team, step by step: the wall time of every team
decision and how far the swarm still is from its formation.

    PYTHONPATH=$PWD python docs/swarm_flight.py --chasers 48 --seed 907000000 --every 10

Flies ``DebrisGym/Reconfigure3D-v0`` (``--env`` for another reconfiguration ID) with
``--chasers`` chasers from ``--seed`` (``start_episode``: the exploration, the slots by the
graphs' path costs, then the flight) with the team's defaults, for at most ``--steps`` steps.
Every ``--every`` steps prints: the step, the seconds of the last team decision (every chaser's
plan), the chasers still flying, the pool's nodes, the chasers with no chain in their graph
(stranded), the plans grown from a chaser (``own_expansions``) and holds so far, and the mean
and largest distance (m) from a chaser to its slot. Ends with the team outcome, Δv, the mean
decision time and the wall time. Nothing is written.
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
    from agents.policies.ma_se_scp import MASESCPTeam
    from agents.policies.team import start_episode
    from debris_gym import swarm

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="DebrisGym/Reconfigure3D-v0")
    parser.add_argument("--chasers", type=int, default=48)
    parser.add_argument("--seed", type=int, default=907_000_000)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--every", type=int, default=10)
    args = parser.parse_args(argv)
    if args.every < 1 or args.steps < 1:
        parser.error("--every and --steps must be >= 1")

    env = swarm.make(args.env, n_chasers=args.chasers, assignment="given")
    team = MASESCPTeam(env, measure_alone=False)
    began = time.perf_counter()
    observations, _, _ = start_episode(env, team, args.seed)
    slots = np.array([v.scenario.dock for v in team.views], dtype=float)
    print(f"exploration and assignment: {time.perf_counter() - began:.1f} s", flush=True)
    decisions: list[float] = []
    step = 0
    while env.agents and step < args.steps:
        t = time.perf_counter()
        actions = team.predict({a: observations[a] for a in env.agents})
        decisions.append(time.perf_counter() - t)
        observations, *_ = env.step(actions)
        step += 1
        if step % args.every == 0 or not env.agents:
            graphs = team.graphs
            left = np.linalg.norm(team.positions() - slots, axis=1)
            own = sum(m.stats.get("own_expansions", 0) for m in team.members)
            holds = sum(m.stats.get("holds", 0) for m in team.members)
            stranded = int(graphs.stranded.sum()) if graphs is not None else 0
            nodes = graphs.n_nodes if graphs is not None else 0
            print(
                f"step {step}: {decisions[-1]:.2f} s, flying {len(env.agents)}, nodes {nodes}, "
                f"stranded {stranded}, own expansions {own}, holds {holds}, "
                f"to slot mean {left.mean():.0f} m max {left.max():.0f} m",
                flush=True,
            )
    core = env.core
    missions = core.shell.batch_in_use.missions
    rows = slice(0, core.chasers)
    print(
        f"team success {bool(core.team_success()[0])}, reconfigured "
        f"{int(np.count_nonzero(missions.success[rows]))}/{core.chasers}, steps {step}, "
        f"min separation {float(core.min_separation()[0]):.2f} m, "
        f"Δv total {float(missions.delta_v[rows].sum()):.1f} m/s, "
        f"decision mean {np.mean(decisions):.2f} s, wall {time.perf_counter() - began:.0f} s"
    )
    env.close()


if __name__ == "__main__":
    main()
