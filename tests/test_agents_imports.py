"""Imports inside agents/: no cycle between its modules (imports placed inside functions
included, so a cycle cannot hide behind a lazy import), and the experiments layer owns its
config helpers (policies keep only what running a policy needs)."""

from __future__ import annotations

import ast
from pathlib import Path

import agents.policies.model_files as model_files
from tests.helpers import ROOT

CONFIG_HELPERS = {"ConfigError", "load_config_file", "ALGOS", "ON_POLICY_ALGOS"}


def _modules() -> dict[str, Path]:
    """Dotted name → file of every module of the agents package."""
    found = {}
    for path in sorted((ROOT / "agents").rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _imported(path: Path, package: str) -> list[tuple[str, list[str]]]:
    """(absolute module, names) of every import in ``path``, at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([node.module] if node.module else [])])
            out.append((base, [alias.name for alias in node.names]))
    return out


def _graph() -> dict[str, set[str]]:
    """Module → the agents modules it imports (``from pkg import mod`` counts as ``pkg.mod``)."""
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for module, names in _imported(path, package):
            for target in [module, *(f"{module}.{n}" for n in names)]:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan, iteratively)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_cycle_finder_finds_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]


def test_no_import_cycle_between_the_modules_of_agents():
    """Regression: training/models and training/finetune imported each other, each from
    inside a function."""
    assert _cycles(_graph()) == []


def test_the_experiments_layer_owns_its_config_helpers():
    taken = []
    scripts = [ROOT / name for name in ("train.py", "evaluate.py", "sweep.py", "imitate.py")]
    for path in [*sorted((ROOT / "agents" / "experiments").rglob("*.py")), *scripts]:
        for module, names in _imported(path, "agents.experiments"):
            if module.startswith("agents.policies") and CONFIG_HELPERS & set(names):
                taken.append(f"{path.relative_to(ROOT)}: {module} {sorted(names)}")
    assert taken == []
    assert not CONFIG_HELPERS & set(vars(model_files))
