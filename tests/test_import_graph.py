"""No import cycles among the modules of debris_gym/ and agents/.

Every import statement is read from the source (``ast``), module-level and inside functions
alike: an import placed in a function to dodge a cycle is still a cycle. ``from pkg import name``
counts as an edge to ``pkg.name`` when that is a module, else to ``pkg`` (its ``__init__``);
``import pkg`` is an edge to ``pkg``'s ``__init__``. Relative imports are resolved. The graph's
strongly connected components of two or more modules (or a module importing itself) are the
cycles.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("debris_gym", "agents")

ALLOWED: set[frozenset[str]] = {
    frozenset({"agents.experiments.training.finetune", "agents.experiments.training.models"}),
}
"""Cycles known today in code other work is rewriting. This set must shrink to empty: remove a
cycle here when its code no longer has it (a test below fails on a cycle listed here that is
gone), and never add one."""


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            out[_module_name(path)] = path
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES.get(name, Path()).name == "__init__.py"


def _resolve(module: str, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` names (relative levels resolved)."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    if not _is_package(module):
        base = base[:-1]  # a module's own package
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def _targets(module: str, node: ast.AST) -> list[str]:
    """Project modules an import statement makes ``module`` import."""
    found = []
    if isinstance(node, ast.Import):
        found = [alias.name for alias in node.names]
    elif isinstance(node, ast.ImportFrom):
        source = _resolve(module, node)
        for alias in node.names:
            sub = f"{source}.{alias.name}"
            found.append(sub if sub in MODULES else source)
    return [name for name in found if name in MODULES]


def import_graph() -> dict[str, set[str]]:
    """Module → the project modules it imports anywhere in its source."""
    graph: dict[str, set[str]] = {}
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        edges = set()
        for node in ast.walk(tree):
            edges.update(_targets(module, node))
        graph[module] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """Strongly connected components of two or more modules, or of one importing itself
    (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.add(member)
                        if member == node:
                            break
                    if len(component) > 1 or node in graph[node]:
                        out.append(frozenset(component))
    return out


def cycle_path(graph: dict[str, set[str]], component: frozenset[str]) -> list[str]:
    """The shortest closed import chain through the first module of ``component`` (breadth
    first, for the failure message)."""
    start = min(component)
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for child in sorted(graph[node] & component):
                if child == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(previous[path[-1]])
                    return [*reversed(path), start]
                if child not in previous:
                    previous[child] = node
                    following.append(child)
        frontier = following
    return [start]


def _area(module: str) -> str:
    """``package.subpackage`` for a module in a subpackage, else the top package (its core)."""
    parts = module.split(".")
    if len(parts) >= 2 and _is_package(".".join(parts[:2])):
        return ".".join(parts[:2])
    return parts[0]


AREAS = sorted({_area(m) for m in MODULES})
GRAPH = import_graph()
CYCLES = cycles(GRAPH)


@pytest.mark.parametrize("area", AREAS)
def test_an_area_has_no_import_cycle(area):
    found = [c for c in CYCLES if any(_area(m) == area for m in c) and c not in ALLOWED]
    assert not found, "import cycles:\n" + "\n".join(
        " -> ".join(cycle_path(GRAPH, c)) for c in found
    )


def test_every_allowed_cycle_still_exists():
    gone = [sorted(c) for c in ALLOWED if c not in CYCLES]
    assert not gone, f"remove these from ALLOWED, they are no longer cycles: {gone}"


def test_the_checker_finds_a_cycle_and_resolves_imports():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"d"}, "e": {"a"}}
    assert set(cycles(graph)) == {frozenset("abc"), frozenset("d")}
    assert cycle_path(graph, frozenset("abc")) == ["a", "b", "c", "a"]
    # the resolution of the real tree: a module-level and a relative import
    assert "debris_gym.scenario" in GRAPH["debris_gym"]
    assert "debris_gym.generators" in GRAPH["debris_gym.envs.common"]
