"""The modules of ``cellrunner`` import each other without a cycle.

The graph is read from the source with ``ast``: every ``import`` counts, the ones inside
functions too (a lazy import that closes a loop still ties the two modules together), except
those under ``if TYPE_CHECKING:``, which never run. A module importing its own parent package
is not an edge: Python imports the parent first in any case.
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


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imported(tree: ast.AST) -> list[tuple[str, list[str]]]:
    """(module, names) of every import in ``tree`` outside ``if TYPE_CHECKING:`` blocks."""
    found: list[tuple[str, list[str]]] = []
    todo: list[ast.AST] = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and _is_type_checking(node):
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.Import):
            found.extend((alias.name, []) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.module, [alias.name for alias in node.names]))
        todo.extend(ast.iter_child_nodes(node))
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


def test_cellrunner_has_no_import_cycle() -> None:
    graph = import_graph(PACKAGE)
    assert len(graph) > 50, "the package's modules were not found"
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


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
            None,
        ),
    ],
)
def test_the_cycle_finder_sees_lazy_imports_and_skips_type_checking(
    tmp_path: Path, sources: dict[str, str], cycle: list[str] | None
) -> None:
    root = tmp_path / "pkg"
    root.mkdir()
    (root / "__init__.py").write_text("")
    for name, text in sources.items():
        (root / f"{name}.py").write_text(text + "\n")
    found = find_cycle(import_graph(root))
    assert found == (None if cycle is None else [f"pkg.{n}" for n in cycle])
