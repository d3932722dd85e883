"""Every policy by name: the classical baselines (:data:`BASELINES`, :func:`make_agent`) and the
learned ones (:func:`load_agent`).

Agent modules are imported on first use, so looking a name up imports neither a planner nor
torch; a learned policy imports Stable-Baselines3 when it is loaded, never the trainer.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["BASELINES", "load_agent", "make_agent"]

BASELINES: dict[str, str] = {
    "zero": "agents.policies.simple:ZeroAgent",
    "random": "agents.policies.simple:RandomAgent",
    "apf": "agents.policies.apf:APFAgent",
    "apf-rrt": "agents.policies.apf_rrt:APFRRTAgent",
    "apf-mpc": "agents.policies.apf_mpc:APFMPCAgent",
    "astar": "agents.policies.astar:AStarAgent",
    "st-rrt": "agents.policies.st_rrt:STRRTAgent",
    "se-scp": "agents.policies.se_scp:SESCPAgent",
    "base-law": "agents.policies.base_law:BaseLawAgent",
}
"""Baseline name → ``module:Class`` (imported on first use)."""


def make_agent(name: str, env: Any, **params: Any) -> Any:
    """Build the baseline ``name`` for ``env``; ``params`` go to its constructor.

    Raises:
        ValueError: unknown name (the message lists the known ones).
    """
    if name not in BASELINES:
        raise ValueError(f"unknown agent {name!r}; known baselines: {', '.join(BASELINES)}")
    module_name, class_name = BASELINES[name].split(":")
    cls = getattr(importlib.import_module(module_name), class_name)
    return cls(env, **params)


def load_agent(spec: str, env: Any, **kwargs: Any) -> Any:
    """Load a learned policy: ``"ppo:PATH"`` (or ``ppo=PATH``; ``sac``, ``td3``, ``dqn``) or
    ``"pretrained"``, for ``env``. See :func:`agents.policies.learned.load_agent`."""
    from agents.policies.learned import load_agent as load_learned

    return load_learned(spec, env, **kwargs)
