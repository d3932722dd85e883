"""The layers of agents/ import one way (planners ← control ← policies ← experiments), and no
module of theirs imports another module's private names."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

AGENTS = Path(__file__).resolve().parents[1] / "agents"

ALLOWED = {
    "planners": {"planners"},
    "control": {"planners", "control"},
    "policies": {"planners", "control", "policies"},
}
"""Layer → the layers of ``agents`` its modules may import."""


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module, imported names) of every import statement in ``path``, lazy ones included."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.module, [alias.name for alias in node.names]))
    return out


def _modules(layer: str) -> list[Path]:
    return sorted((AGENTS / layer).glob("*.py"))


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_a_layer_imports_only_itself_and_the_layers_below(layer):
    assert _modules(layer), f"agents/{layer} has no modules"
    for path in _modules(layer):
        for module, _ in _imports(path):
            parts = module.split(".")
            if parts[0] != "agents":
                continue
            assert len(parts) > 1 and parts[1] in ALLOWED[layer], (
                f"agents/{layer}/{path.name} imports {module}"
            )


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_no_module_imports_private_names(layer):
    for path in _modules(layer):
        for module, names in _imports(path):
            private = [n for n in names if n.startswith("_")]
            assert not private, f"agents/{layer}/{path.name} imports {private} from {module}"


def test_the_apf_mpc_policy_uses_no_other_baseline_policy():
    policy_modules = {p.stem for p in _modules("policies")}
    shared = {"base", "tracking"}  # the bases every tracker / classical agent builds on
    for module, _ in _imports(AGENTS / "policies" / "apf_mpc.py"):
        parts = module.split(".")
        if parts[:2] == ["agents", "policies"]:
            assert parts[2] in shared and parts[2] in policy_modules, module
