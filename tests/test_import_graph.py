"""The modules of ``cellrunner`` import each other without a cycle, and its packages
only along the layering (STYLE.md rule 1: dependencies point inward).

The graph is read from the source with ``ast``: every ``import`` counts, the ones inside
functions (a lazy import that closes a loop still ties the two modules together) and
under ``if TYPE_CHECKING:`` too (a circle closed through a type hint is a concept in the
wrong file). A module importing its own parent package is not an edge: Python imports the
parent first in any case.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "cellrunner"


def _modules(root: Path) -> dict[str, Path]:
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imported(tree: ast.AST) -> list[tuple[str, list[str]]]:
    """(module, names) of every import in ``tree``."""
    found: list[tuple[str, list[str]]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((alias.name, []) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.module, [alias.name for alias in node.names]))
    return found


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the modules of the same package it imports."""
    modules = _modules(root)
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for target, names in _imported(ast.parse(path.read_text(), str(path))):
            submodules = {f"{target}.{n}" for n in names} & modules.keys()
            # ``from pkg import sub`` imports the submodule; other names come from pkg itself
            edges = submodules if len(submodules) == len(names) and names else {target}
            edges |= submodules
            for edge in edges & modules.keys():
                if edge != name and not name.startswith(edge + "."):
                    graph[name].add(edge)
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as [a, b, ..., a], or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    for start in sorted(graph):
        if state.get(start):
            continue
        stack = [(start, iter(sorted(graph[start])))]
        state[start] = 1
        while stack:
            node, children = stack[-1]
            child = next(children, None)
            if child is None:
                state[node] = 2
                stack.pop()
            elif state.get(child) == 1:
                path = [n for n, _ in stack]
                return path[path.index(child) :] + [child]
            elif not state.get(child):
                state[child] = 1
                stack.append((child, iter(sorted(graph[child]))))
    return None


#: the packages each package may import (every package may import ``cellrunner.errors``,
#: ``cellrunner.thread_priority`` and itself); the CLI sits on top and may import any
LAYERS: dict[str, set[str]] = {
    "model": set(),
    "planning": {"model"},
    "vision": {"model", "planning"},
    "perception": {"model", "planning", "vision"},
    "sim": {"model", "planning", "vision", "perception"},
    "twin": {"model", "planning", "sim"},
    "backends": {"model", "sim"},
    "plc": {"model"},
    # perception: the watched zone's map; vision: align steps' eye; the twin (sim) only
    # through the backend Protocols (backends.base.RendersDepth renders its depth images)
    "execution": {"model", "planning", "backends", "perception", "vision"},
    "report": {"model", "planning", "sim"},
    # planning: the live 3D view poses the arm with its one kinematics (pinocchio)
    "web": {"model", "planning", "execution"},
    # recordings: the twin's model of the cell (sim), posed on the engine's observer points
    "record": {"model", "sim", "execution"},
    "commissioning": {"model", "planning", "execution", "backends", "vision"},
    # a step kind's module: its model, its planning and its run-time behaviour
    "steps": {"model", "planning", "execution"},
}
_ANYONE = {"errors", "thread_priority"}


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layering_breaks(graph: dict[str, set[str]]) -> list[str]:
    """``a -> b`` for every import of a module ``a`` into a package its layer may not use."""
    breaks = []
    for module, targets in sorted(graph.items()):
        allowed = LAYERS.get(_package(module))
        if allowed is None:  # the CLI and the package's own top-level modules
            continue
        for target in sorted(targets):
            package = _package(target)
            if package != _package(module) and package not in allowed | _ANYONE:
                breaks.append(f"{module} -> {target}")
    return breaks


def test_cellrunner_has_no_import_cycle() -> None:
    graph = import_graph(PACKAGE)
    assert len(graph) > 50, "the package's modules were not found"
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_packages_import_only_along_the_layering() -> None:
    graph = import_graph(PACKAGE)
    assert {_package(m) for m in graph} >= set(LAYERS), "a layered package was not found"
    assert layering_breaks(graph) == []


def test_the_layering_check_sees_sim_importing_backends() -> None:
    graph = {
        "cellrunner.sim.world": {"cellrunner.backends.base", "cellrunner.model.cell"},
        "cellrunner.backends.base": {"cellrunner.model.robot_state"},
        "cellrunner.cli.main": {"cellrunner.sim.world"},
    }
    assert layering_breaks(graph) == ["cellrunner.sim.world -> cellrunner.backends.base"]


@pytest.mark.parametrize(
    ("sources", "cycle"),
    [
        ({"a": "import pkg.b", "b": "from pkg import c", "c": ""}, None),
        ({"a": "import pkg.b", "b": "def f():\n    from pkg.a import x"}, ["a", "b", "a"]),
        (
            {"a": "from pkg import b", "b": "from pkg import c", "c": "import pkg.a"},
            ["a", "b", "c", "a"],
        ),
        (
            {
                "a": "import pkg.b",
                "b": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.a",
            },
            ["a", "b", "a"],
        ),
    ],
)
def test_the_cycle_finder_sees_lazy_imports_and_type_checking_ones(
    tmp_path: Path, sources: dict[str, str], cycle: list[str] | None
) -> None:
    root = tmp_path / "pkg"
    root.mkdir()
    (root / "__init__.py").write_text("")
    for name, text in sources.items():
        (root / f"{name}.py").write_text(text + "\n")
    found = find_cycle(import_graph(root))
    assert found == (None if cycle is None else [f"pkg.{n}" for n in cycle])
