"""The layers import one way, and no module takes another module's private names.

- ``debris_gym``: the physics (dynamics, geometry, swept contacts) imports only physics; the
  core (everything but the envs, the gymnasium registration, the integrations and the
  suites) imports neither gymnasium nor the envs; nothing imports ``agents``.
- ``agents``: planners ← control ← policies ← experiments; inside experiments, evaluation
  runs below the distributed backends (a script passes a backend in); the experiments layer
  owns its config helpers (running a policy never needs them).

Imports inside functions count (tests/import_graph.py).
"""

from __future__ import annotations

import pytest

import agents.policies.model_files as model_files
from tests.import_graph import MODULES, imported_names

AGENT_LAYERS = {
    "planners": {"planners"},
    "control": {"planners", "control"},
    "policies": {"planners", "control", "policies"},
}
"""Layer of agents → the layers of ``agents`` its modules may import."""

PHYSICS = {
    "debris_gym.dynamics",
    "debris_gym.thrust",
    "debris_gym.relative_orbits",
    "debris_gym.swept_contacts",
    "debris_gym.geometry_kernels",
    "debris_gym.batch_geometry",
    "debris_gym.orbit_separation",
    "debris_gym.orbit_truth",
    "debris_gym.jit",
}
"""The physics of debris_gym: CW motion, thrust, contacts and gaps, compiled."""

SHELL_LAYER = (
    "debris_gym.envs",
    "debris_gym.integrations",
    "debris_gym.suites",
    "debris_gym.swarm",
)
"""The modules that build on gymnasium (with ``debris_gym.registration`` and the package's
``__init__``, which registers the IDs)."""

CONFIG_HELPERS = {"ConfigError", "load_config_file", "ALGOS", "ON_POLICY_ALGOS"}
"""Training-configuration helpers: the experiments layer's own."""


def _in(module: str, *prefixes: str) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def _core(module: str) -> bool:
    shell = _in(module, *SHELL_LAYER) or module in ("debris_gym", "debris_gym.registration")
    return module.startswith("debris_gym") and not shell


def _modules(prefix: str) -> list[str]:
    return sorted(m for m in MODULES if _in(m, prefix))


@pytest.mark.parametrize("layer", sorted(AGENT_LAYERS))
def test_an_agents_layer_imports_only_itself_and_the_layers_below(layer):
    modules = _modules(f"agents.{layer}")
    assert modules, f"agents/{layer} has no modules"
    for module in modules:
        for target, _ in imported_names(module):
            parts = target.split(".")
            if parts[0] != "agents":
                continue
            assert len(parts) > 1 and parts[1] in AGENT_LAYERS[layer], f"{module} imports {target}"


def test_evaluation_runs_below_the_distributed_backends():
    """Regression: the evaluation command imported the Ray backend (a layer up); the script
    passes the backend in."""
    for module in _modules("agents.experiments.evaluation"):
        for target, _ in imported_names(module):
            assert not _in(target, "agents.experiments.distributed"), f"{module} imports {target}"


def test_the_experiments_layer_owns_its_config_helpers():
    taken = [
        f"{module}: {target} {sorted(names)}"
        for module in _modules("agents.experiments")
        for target, names in imported_names(module)
        if _in(target, "agents.policies") and CONFIG_HELPERS & set(names)
    ]
    assert taken == []
    assert not CONFIG_HELPERS & set(vars(model_files))


def test_the_physics_imports_only_physics():
    for module in sorted(PHYSICS):
        assert module in MODULES, f"{module} is gone: update PHYSICS"
        for target, _ in imported_names(module):
            if target.startswith("debris_gym"):
                assert target in PHYSICS, f"{module} imports {target}"


def test_the_core_knows_nothing_of_gymnasium_the_envs_or_the_agents():
    core = [m for m in MODULES if _core(m)]
    assert "debris_gym.mission_batch" in core and "debris_gym.scenario" in core
    for module in core:
        for target, _ in imported_names(module):
            assert not _in(target, "gymnasium"), f"{module} imports {target}"
            assert not _in(target, *SHELL_LAYER, "debris_gym.registration"), (
                f"{module} imports {target}"
            )
    for module in _modules("debris_gym"):
        for target, _ in imported_names(module):
            assert not _in(target, "agents"), f"{module} imports {target}"


@pytest.mark.parametrize("package", ["debris_gym", "agents"])
def test_no_module_imports_another_modules_private_names(package):
    for module in _modules(package):
        for target, names in imported_names(module):
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{module} imports {private} from {target}"


def test_the_apf_mpc_policy_uses_no_other_baseline_policy():
    shared = {"base", "tracking"}  # the bases every tracker / classical agent builds on
    for target, _ in imported_names("agents.policies.apf_mpc"):
        parts = target.split(".")
        if parts[:2] == ["agents", "policies"]:
            assert parts[2] in shared, target
