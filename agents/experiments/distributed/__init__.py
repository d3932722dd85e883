"""debris-gym on Ray: evaluation sweeps fanned out to Ray actors, Tune sweeps over ``train.py``'s
recipes, and RLlib on the registered envs.

* :mod:`~agents.experiments.distributed.evaluation` — :class:`RayBackend`, the
  ``evaluate.py --backend ray`` engine (same records as the local run);
* :mod:`~agents.experiments.distributed.sweep` — :func:`run_sweep`, a Ray Tune sweep over a
  recipe's ``sweep:`` section (``sweep.py``), the best trial exported as ``OUT/best/``;
* :mod:`~agents.experiments.distributed.rllib` — the envs under RLlib's new API stack
  (``examples/rllib_ppo.py``), the swarms as IPPO or MAPPO (``examples/swarm_mappo.py``);
* :mod:`~agents.experiments.distributed.rllib_mappo` — MAPPO's network (imports Ray and torch).

Ray is an optional dependency (``pip install 'debris-gym[distributed]'``): nothing here imports
it at module level, and :func:`require_ray` names the extra when it is missing. docs/distributed.md
is the user's page.
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["INSTALL_HINT", "require_ray"]

INSTALL_HINT = "pip install 'debris-gym[distributed]'"
"""How to get Ray with the versions this project is tested with."""


def require_ray(what: str = "the Ray backend", module: str = "ray") -> ModuleType:
    """``import module`` (``"ray"``, ``"ray.tune"``, ``"ray.rllib"``), or an ImportError that
    says what needs it and how to install it.

    Raises:
        ImportError: Ray (or the part of it) is not installed.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(
            f"{what} needs {module} ({exc.name or module} is not installed): {INSTALL_HINT}"
        ) from exc
