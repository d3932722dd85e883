"""Guidance baselines for the debris_gym environments, all behind one ``predict()`` interface.

``make_agent(name, env, **params)`` builds a baseline by name:

=============  ==================================================================
``zero``       never thrusts (floor)
``random``     uniform random thrust (floor)
``apf``        artificial potential field, gradient → thrust with damping
``apf-rrt``    APF with local-minimum detection and RRT escape (seed 003)
``apf-mpc``    APF reference path tracked by an OSQP MPC on the CWH model (seed 000)
``astar``      A* grid path tracked by the same MPC (seed 000's A* baseline)
=============  ==================================================================

``load_agent("ppo:runs/ppo/model.zip", env)`` loads a policy trained by ``train.py`` (``sac``,
``td3``, ``dqn`` likewise; ``load_agent("pretrained", env)`` the shipped one) behind the same
interface; see :mod:`agents.learned`.
"""

from __future__ import annotations

import importlib
from typing import Any

BASELINES: dict[str, str] = {
    "zero": "agents.simple:ZeroAgent",
    "random": "agents.simple:RandomAgent",
    "apf": "agents.apf:APFAgent",
    "apf-rrt": "agents.apf_rrt:APFRRTAgent",
    "apf-mpc": "agents.apf_mpc:APFMPCAgent",
    "astar": "agents.astar_agent:AStarAgent",
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
    ``"pretrained"``, for ``env``. See :func:`agents.learned.load_agent` (imported on first use,
    so ``import agents`` does not import torch)."""
    from agents.learned import load_agent as _load_agent

    return _load_agent(spec, env, **kwargs)


__all__ = ["BASELINES", "load_agent", "make_agent"]
