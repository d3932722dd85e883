"""Several chasers in one debris field: PettingZoo envs on the single-agent compiled step.

``debris_gym.swarm.make("DebrisGym/Swarm2D-v0", **options)`` gives a
:class:`~debris_gym.swarm.parallel.SwarmParallelEnv` (PettingZoo ``ParallelEnv``);
:func:`parallel_env` and :func:`env` (its AEC view) take the same options. Needs PettingZoo (the
``multiagent`` extra; the specs, :class:`SwarmCore` and the SB3 training env
:class:`~debris_gym.integrations.sb3_swarm.SwarmVecEnv` do not). docs/swarm.md has the rules,
spaces and IDs.

Importing this module also registers every swarm ID in PettingZoo's own registry when the
installed PettingZoo has one (1.27 and later: ``pettingzoo.make("parallel", ID, **options)`` and
``pettingzoo.make("aec", ID, **options)``; :func:`register_with_pettingzoo`).
"""

from __future__ import annotations

import importlib
from functools import partial
from typing import TYPE_CHECKING, Any

from debris_gym.config import EnvConfig
from debris_gym.registration import V2_WORLD
from debris_gym.swarm.config import SwarmConfig, dock_slots, mission_config, split_options
from debris_gym.swarm.core import TEAM_INFO_KEYS, SwarmCore

if TYPE_CHECKING:
    from debris_gym.swarm.parallel import SwarmParallelEnv

__all__ = [
    "DEFAULT_SWARM",
    "SWARM_SPECS",
    "TEAM_INFO_KEYS",
    "SwarmConfig",
    "SwarmCore",
    "SwarmParallelEnv",
    "aec_env",
    "checked_options",
    "dock_slots",
    "env",
    "make",
    "parallel_env",
    "register_with_pettingzoo",
]

DEFAULT_SWARM = "DebrisGym/Swarm2D-v0"

_CAPTURE_MISSION: dict[str, object] = {
    "n_chasers": 3,
    "n_targets": 6,
    "n_obstacles": 20,
    "shaping_potential": "goal",
}
"""The capture mission: six targets shared by three chasers among twenty other debris, every
surviving chaser back at its own dock slot. Each chaser's shaping potential is its gap to its
current goal (``shaping_potential="goal"``), not the v2 world's shortest tour through every
remaining target: in a team that tour is not one chaser's task, and its exact search over six
targets (720 orders) would cost about 20 times the rest of a chaser's step
(docs/benchmarks.md)."""

_RECONFIGURATION: dict[str, object] = {
    "mission": "reconfigure",
    "assignment": "given",
    "n_chasers": 6,
    "n_targets": 1,
    "n_obstacles": 20,
    "debris_motion": "frozen",
    "shaping_potential": "goal",
    "dock_spacing": 12.0,
}
"""The reconfiguration of [Bandyopadhyay17]: six chasers from their dock slots to six formation
slots around a body among twenty other debris, one slot each, the debris frozen as in the paper
(``debris_motion="bounded"`` moves them). The dock slots are as far apart as the formation's
(12 m in the v2 world): the paper's starts and goals are r_col + r_max apart (its eq. 1–2), and
a planner that treats its teammates as spheres of that radius needs room to leave."""

SWARM_SPECS: dict[str, dict[str, Any]] = {
    "DebrisGym/Swarm2D-v0": {"max_episode_steps": 1000,
                             "kwargs": {"dim": 2, **V2_WORLD, **_CAPTURE_MISSION}},
    "DebrisGym/Swarm3D-v0": {"max_episode_steps": 1000,
                             "kwargs": {"dim": 3, **V2_WORLD, **_CAPTURE_MISSION}},
    "DebrisGym/Swarm2D-Easy-v0": {
        "max_episode_steps": 1000,
        "kwargs": {"dim": 2, **V2_WORLD, "n_chasers": 2, "n_targets": 2, "n_obstacles": 5,
                   "return_to_dock": False, "assignment": "given"},
    },
    "DebrisGym/Reconfigure2D-v0": {"max_episode_steps": 1000,
                                   "kwargs": {"dim": 2, **V2_WORLD, **_RECONFIGURATION}},
    "DebrisGym/Reconfigure3D-v0": {"max_episode_steps": 1000,
                                   "kwargs": {"dim": 3, **V2_WORLD, **_RECONFIGURATION}},
}  # fmt: skip
"""Every swarm ID with its time limit (steps) and options: the v2 world of the single-agent
IDs with several chasers. The Easy rung, for learners, gives each chaser its own target (the
balanced rule of :func:`~debris_gym.swarm.assignment.balanced_assignment`): what is left to
learn is the flight and the teammate; choosing targets is the task of the full IDs. The
Reconfigure IDs fly every chaser to its own formation slot (:mod:`debris_gym.swarm.formation`)."""


def __getattr__(name: str) -> Any:
    # the PettingZoo view is imported on first use: the specs and the core (which train.py
    # reads) need no PettingZoo
    if name == "SwarmParallelEnv":
        from debris_gym.swarm.parallel import SwarmParallelEnv

        return SwarmParallelEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def checked_options(env_id: str, options: dict[str, Any]) -> tuple[EnvConfig, SwarmConfig]:
    """The single-agent config and the swarm config of ``env_id`` with ``options`` over its
    own (``max_episode_steps`` left out), validated.

    Raises:
        ValueError: an unknown ID or a bad option (the message names it).
    """
    spec = SWARM_SPECS.get(env_id)
    if spec is None:
        raise ValueError(f"unknown swarm ID {env_id!r}; known: {', '.join(SWARM_SPECS)}")
    merged = {**spec["kwargs"], **options}
    merged.pop("max_episode_steps", None)
    env_options, swarm = split_options(merged)
    config = EnvConfig.from_kwargs(**env_options)
    swarm = swarm.checked(config)
    return mission_config(config, swarm), swarm


def make(env_id: str = DEFAULT_SWARM, **options: Any) -> SwarmParallelEnv:
    """The swarm env ``env_id`` (:data:`SWARM_SPECS`) with ``options`` over its own
    (``max_cycles``, PettingZoo's name, sets ``max_episode_steps``).

    Raises:
        ValueError: an unknown ID (the message lists the known ones) or option.
    """
    spec = SWARM_SPECS.get(env_id)
    if spec is None:
        raise ValueError(f"unknown swarm ID {env_id!r}; known: {', '.join(SWARM_SPECS)}")
    from debris_gym.swarm.parallel import SwarmParallelEnv

    options = dict(options)
    if "max_cycles" in options:  # PettingZoo's name for the time limit
        if "max_episode_steps" in options:
            raise ValueError("give max_cycles or max_episode_steps (the same limit), not both")
        options["max_episode_steps"] = options.pop("max_cycles")
    kwargs = {**spec["kwargs"], **options}
    kwargs.setdefault("max_episode_steps", spec["max_episode_steps"])
    return SwarmParallelEnv(**kwargs)


def parallel_env(**options: Any) -> SwarmParallelEnv:
    """The default swarm ID (:data:`DEFAULT_SWARM`) as a ``ParallelEnv``, with ``options``."""
    return make(DEFAULT_SWARM, **options)


def aec_env(env_id: str = DEFAULT_SWARM, **options: Any):
    """The swarm env ``env_id`` as a PettingZoo AEC env (``parallel_to_aec`` of :func:`make`).

    Raises:
        ValueError: an unknown ID or option.
    """
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(make(env_id, **options))


def env(**options: Any):
    """The default swarm ID as a PettingZoo AEC env (``parallel_to_aec`` of
    :func:`parallel_env`)."""
    return aec_env(DEFAULT_SWARM, **options)


def register_with_pettingzoo(pettingzoo: Any = None) -> list[str]:
    """Register every swarm ID (:data:`SWARM_SPECS`) in PettingZoo's registry, as a parallel
    env (:func:`make`) and as an AEC env (:func:`aec_env`), each ID's options and time limit
    its own; the time limit is PettingZoo's ``max_cycles`` option. IDs already registered are
    left as they are.

    Args:
        pettingzoo: the ``pettingzoo`` module (None: import it).

    Returns:
        the IDs registered now: none when PettingZoo is not installed or has no registry (its
        releases before 1.27 have none; their envs are modules with ``env()`` /
        ``parallel_env()``, as this one is).
    """
    if pettingzoo is None:
        try:
            pettingzoo = importlib.import_module("pettingzoo")
        except ImportError:
            return []
    register = getattr(pettingzoo, "register", None)
    registries: dict[str, Any] = {
        "parallel": getattr(pettingzoo, "parallel_registry", None),
        "aec": getattr(pettingzoo, "aec_registry", None),
    }
    if not callable(register) or any(r is None for r in registries.values()):
        return []
    creators = {"parallel": make, "aec": aec_env}
    registered = []
    for env_id in SWARM_SPECS:
        for kind, registry in registries.items():
            if env_id not in registry:
                # the ID's time limit is applied by the creator: a spec's max_cycles would be
                # passed beside a user's max_episode_steps, which make() refuses
                register(kind, env_id, entry_point=partial(creators[kind], env_id))
                registered.append(env_id)
    return sorted(set(registered))


register_with_pettingzoo()
