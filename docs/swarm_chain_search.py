"""The cost of one chaser's chain search in flight, with the ellipsoid first and on the whole
graph alone, on the explored pool of a reconfiguration (planner only).

    PYTHONPATH=$PWD python docs/swarm_chain_search.py --chasers 48 --seed 907000000

Explores ``DebrisGym/Reconfigure3D-v0`` with ``--chasers`` chasers from ``--seed`` as the
"ma-se-scp" team does before its first step (the slots by the graphs' path costs), then times
:meth:`~agents.planners.swarm_expansion.SwarmGraphs.chain_to` for every chaser toward its slot,
from its start and from ``--advance`` of the way to its slot (its teammates likewise), once as
the team searches (the ellipsoid, then the whole graph when that finds none) and once on the
whole graph only (an unbounded ellipsoid). Prints the mean milliseconds per search of both,
in the same run, and whether both found chains of the same costs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> None:
    import agents.planners.swarm_expansion as expansion
    from agents.policies.ma_se_scp import MASESCPTeam
    from agents.policies.team import start_episode
    from debris_gym import swarm

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chasers", type=int, default=48)
    parser.add_argument("--seed", type=int, default=907_000_000)
    parser.add_argument("--advance", type=float, default=0.05)
    args = parser.parse_args(argv)

    env = swarm.make("DebrisGym/Reconfigure3D-v0", n_chasers=args.chasers, assignment="given")
    team = MASESCPTeam(env, measure_alone=False)
    start_episode(env, team, args.seed)
    team.predict({})  # the episode starts: the explored graphs are taken over
    graphs = team.graphs
    assert graphs is not None and graphs.assigned is not None
    starts = graphs.positions.copy()
    slots = graphs.centers[graphs.goal_nodes[graphs.assigned]]
    print(f"pool {graphs.n_nodes} nodes")
    stretch = expansion._ELLIPSOID_STRETCH
    for advance in (0.0, args.advance):
        graphs.move(starts + advance * (slots - starts))
        costs, ms = {}, {}
        for name, factor in (("ellipsoid first", stretch), ("whole graph", math.inf)):
            expansion._ELLIPSOID_STRETCH = factor
            began = time.perf_counter()
            found = [
                graphs.chain_to(k, int(graphs.assigned[k]))[0].cost for k in range(len(starts))
            ]
            ms[name] = 1000.0 * (time.perf_counter() - began) / len(starts)
            costs[name] = np.array(found)
        expansion._ELLIPSOID_STRETCH = stretch
        a, b = costs["ellipsoid first"], costs["whole graph"]
        same = bool(np.array_equal(np.isfinite(a), np.isfinite(b)))
        same = same and bool(np.allclose(a[np.isfinite(a)], b[np.isfinite(b)], rtol=1e-9))
        print(
            f"advance {advance:.2f}: {int(np.isfinite(a).sum())}/{len(a)} chains; "
            f"ellipsoid first {ms['ellipsoid first']:.1f} ms, whole graph "
            f"{ms['whole graph']:.1f} ms per search "
            f"({ms['whole graph'] / ms['ellipsoid first']:.1f}x); same costs: {same}"
        )
    env.close()


if __name__ == "__main__":
    main()
