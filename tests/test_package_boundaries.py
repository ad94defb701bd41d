"""Packages meet through public names only: no module of ``cellrunner`` reads or writes a
private attribute (``obj._name``) that only another package defines, or imports a private
module or name from another package. Read from the source (AST), so it covers code that
no test runs.

A package is the first level under ``cellrunner`` (``sim``, ``twin``, ``backends``, ...).
``self._name`` and ``cls._name`` are always the module's own business; so is a name the
accessing module defines itself (``_stop`` of its own thread, say), which is why the rule
looks at the accessing module and not only at its package.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

from tests.conftest import ROOT

PACKAGE_ROOT = ROOT / "cellrunner"


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _package_of(path: Path) -> str:
    """``sim`` for cellrunner/sim/world.py; the module's own name for top-level modules."""
    return path.relative_to(PACKAGE_ROOT).parts[0].removesuffix(".py")


def _modules() -> dict[Path, ast.Module]:
    return {p: ast.parse(p.read_text(), str(p)) for p in sorted(PACKAGE_ROOT.rglob("*.py"))}


def _defined_private_names(tree: ast.Module) -> set[str]:
    """Private names a module defines: attributes it assigns on self or cls, methods and
    class attributes, module-level functions, classes and variables."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for sub in ast.walk(target):
                    if isinstance(sub, ast.Attribute) and _on_self(sub):
                        names.add(sub.attr)
                    elif isinstance(sub, ast.Name):
                        names.add(sub.id)
    return {n for n in names if _is_private(n)}


def _on_self(node: ast.Attribute) -> bool:
    return isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")


def _private_accesses(tree: ast.Module) -> list[tuple[int, str, str]]:
    """(line, attribute, expression) of every ``obj._name`` whose obj is not self or cls."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _is_private(node.attr) and not _on_self(node):
            found.append((node.lineno, node.attr, ast.unparse(node)))
    return found


def _imported_packages(tree: ast.Module) -> set[str]:
    """The cellrunner packages a module imports from (anywhere in it)."""
    packages = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules = [node.module]
        elif isinstance(node, ast.Import):
            modules = [a.name for a in node.names]
        else:
            continue
        for module in modules:
            parts = module.split(".")
            if parts[0] == "cellrunner" and len(parts) > 1:
                packages.add(parts[1])
    return packages


def _cross_package_imports(path: Path, tree: ast.Module) -> list[str]:
    """Imports of another package's private modules or names."""
    own = _package_of(path)
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules = [node.module]
            names = [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            modules, names = [a.name for a in node.names], []
        else:
            continue
        for module in modules:
            parts = module.split(".")
            if parts[0] != "cellrunner" or len(parts) < 2 or parts[1] == own:
                continue
            private = [p for p in parts[2:] if _is_private(p)] + [
                n for n in names if _is_private(n)
            ]
            if private:
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno}: imports {module}: {private}")
    return bad


def boundary_violations(modules: dict[Path, ast.Module]) -> list[str]:
    definers: dict[str, set[str]] = defaultdict(set)  # private name -> packages defining it
    own_names = {}
    for path, tree in modules.items():
        own_names[path] = _defined_private_names(tree)
        for name in own_names[path]:
            definers[name].add(_package_of(path))
    bad = []
    for path, tree in modules.items():
        package = _package_of(path)
        imported = _imported_packages(tree)
        for line, attr, expr in _private_accesses(tree):
            if attr in own_names[path]:
                continue
            defined_in = definers.get(attr, set())
            # a name its own package defines too is taken as its own unless the module
            # imports another package that defines it (then it may well be that one's)
            foreign = defined_in - {package}
            if package in defined_in:
                foreign &= imported
            if foreign:
                where = ", ".join(sorted(foreign))
                bad.append(f"{path.relative_to(ROOT)}:{line}: {expr} (private to {where})")
        bad += _cross_package_imports(path, tree)
    return sorted(bad, key=_file_and_line)


def _file_and_line(message: str) -> tuple[str, int]:
    file, line, _ = message.split(":", 2)
    return file, int(line)


def test_no_module_touches_another_packages_private_names() -> None:
    assert boundary_violations(_modules()) == []


def test_the_check_finds_a_private_reach_across_packages() -> None:
    """The rule on a made-up twin module that pokes the world as mujoco_physics once did."""
    modules = _modules()
    world_py = PACKAGE_ROOT / "sim" / "world.py"
    poke = PACKAGE_ROOT / "twin" / "poke.py"
    modules[poke] = ast.parse(
        "from cellrunner.sim.mujoco_loader import load_mujoco\n"
        "from cellrunner.sim.world import _ZERO6\n"
        "def reset(world, q):\n"
        "    world.data.qpos[world._ids.qpos] = q\n"
        "    world._q_prev_ref = q\n"
        "    return world._stop is None\n"
    )
    bad = boundary_violations(modules)
    assert bad == [
        "cellrunner/twin/poke.py:2: imports cellrunner.sim.world: ['_ZERO6']",
        "cellrunner/twin/poke.py:4: world._ids (private to plc, sim)",
        "cellrunner/twin/poke.py:5: world._q_prev_ref (private to sim)",
        # twin's server has a _stop of its own, but this module imports sim, which has one
        "cellrunner/twin/poke.py:6: world._stop (private to sim)",
    ]
    assert world_py in modules  # the names come from the real world module
