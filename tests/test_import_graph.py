"""No import cycles among the modules of debris_gym/ and agents/ (imports inside functions
included: tests/import_graph.py). The graph's strongly connected components of two or more
modules (or a module importing itself) are the cycles."""

from __future__ import annotations

import pytest

from tests.import_graph import MODULES, cycle_path, cycles, import_graph, is_package


def _area(module: str) -> str:
    """``package.subpackage`` for a module in a subpackage, else the top package (its core)."""
    parts = module.split(".")
    if len(parts) >= 2 and is_package(".".join(parts[:2])):
        return ".".join(parts[:2])
    return parts[0]


AREAS = sorted({_area(m) for m in MODULES})
GRAPH = import_graph()
CYCLES = cycles(GRAPH)


@pytest.mark.parametrize("area", AREAS)
def test_an_area_has_no_import_cycle(area):
    found = [c for c in CYCLES if any(_area(m) == area for m in c)]
    assert not found, "import cycles:\n" + "\n".join(
        " -> ".join(cycle_path(GRAPH, c)) for c in found
    )


def test_the_checker_finds_a_cycle_and_resolves_imports():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"d"}, "e": {"a"}}
    assert set(cycles(graph)) == {frozenset("abc"), frozenset("d")}
    assert cycle_path(graph, frozenset("abc")) == ["a", "b", "c", "a"]
    # the resolution of the real tree: a module-level and a relative import
    assert "debris_gym.scenario" in GRAPH["debris_gym"]
    assert "debris_gym.generators" in GRAPH["debris_gym.envs.common"]
