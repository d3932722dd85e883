"""The multi-agent exploration ([Bandyopadhyay17] Algorithm 1, lines 6–38 before any agent
moves): every agent's graph (:class:`~agents.planners.swarm_expansion.SwarmGraphs`) grown one
iteration at a time until every start reaches every goal (Σ_ℓ F^ℓ_connected = N², line 29),
and the paper's measurement of it with and without node sharing (its Fig. 4 and 7).

Everything here is a pure function of the field and the generator passed in; nothing prints.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.planners.swarm_expansion import SwarmGraphs, SwarmParams

__all__ = ["Exploration", "SharingComparison", "compare_sharing", "explore"]


def _all_connected(graphs: SwarmGraphs, done: np.ndarray) -> bool:
    n = graphs.n_agents
    for i in np.flatnonzero(~done):
        reached = np.isfinite(graphs.path_costs(int(i)))
        graphs.reached[i] = reached
        done[i] = reached.sum() == n
    return bool(done.all())


@dataclass(frozen=True)
class Exploration:
    """What :func:`explore` found.

    Attributes:
        iterations: iterations run (the first at which Σ F_connected = N², or the cap).
        connected: whether every agent's start reaches every goal.
        nodes_per_agent: (N,) |V^i| at the end.
        costs: (N, N) graph path cost (m) from agent i's start to goal j (inf: no path).
        share_nodes: whether nodes were shared.
        graphs: the graphs, to go on with (execution phase).
    """

    iterations: int
    connected: bool
    nodes_per_agent: np.ndarray
    costs: np.ndarray
    share_nodes: bool
    graphs: SwarmGraphs = field(repr=False)


def explore(
    geometry: Any,
    starts: np.ndarray,
    goals: np.ndarray,
    margins: np.ndarray,
    rng: np.random.Generator,
    params: SwarmParams,
    *,
    low: np.ndarray,
    high: np.ndarray,
) -> Exploration:
    """Run the spherical expansion of every agent (the agents at their starts) until every
    graph connects its start to every goal, or ``params.max_iterations``.

    Arguments as :class:`SwarmGraphs`; ``rng`` draws every sample.
    """
    graphs = SwarmGraphs(geometry, starts, goals, margins, params, low=low, high=high)
    done = np.zeros(graphs.n_agents, dtype=bool)
    connected = False
    while graphs.iterations < params.max_iterations:
        graphs.iterate(rng)
        if _all_connected(graphs, done):
            connected = True
            break
    costs = np.array([graphs.path_costs(i) for i in range(graphs.n_agents)])
    return Exploration(
        iterations=graphs.iterations,
        connected=connected,
        nodes_per_agent=graphs.nodes_per_agent(),
        costs=costs,
        share_nodes=params.share_nodes,
        graphs=graphs,
    )


@dataclass(frozen=True)
class SharingComparison:
    """The same exploration with and without node sharing (one seed each, the same seed).

    Attributes:
        shared, alone: the two explorations.
    """

    shared: Exploration
    alone: Exploration


def compare_sharing(
    geometry: Any,
    starts: np.ndarray,
    goals: np.ndarray,
    margins: np.ndarray,
    seed: int,
    params: SwarmParams,
    *,
    low: np.ndarray,
    high: np.ndarray,
) -> SharingComparison:
    """Iterations until every graph is connected, with and without node sharing, both drawn
    from ``numpy.random.default_rng(seed)`` (the paper's measurement, Fig. 4 and 7)."""
    out = []
    for share in (True, False):
        p = dataclasses.replace(params, share_nodes=share)
        rng = np.random.default_rng(seed)
        out.append(explore(geometry, starts, goals, margins, rng, p, low=low, high=high))
    return SharingComparison(*out)
