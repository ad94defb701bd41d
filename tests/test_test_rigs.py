"""Tests share helpers through rigs (tests/rig.py and the helper modules beside the
tests), never by importing a test module: a test module imported by another runs its
module-level code twice and hides what the other depends on. A hard dependency is never
skipped: a broken install must fail, not pass by skipping."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.conftest import ROOT

#: installed with cellrunner itself (pyproject's dependencies): never a reason to skip
HARD = {"mujoco", "pinocchio", "pin", "coal", "ompl", "toppra", "rtde_control", "rtde_receive"}


def _test_modules() -> list[Path]:
    return sorted((ROOT / "tests").rglob("*.py"))


def _imports_of_test_modules(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        found += [
            n for n in names if n.startswith("tests.") and n.split(".")[-1].startswith("test_")
        ]
    return found


def _hard_skips(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    return [
        node.args[0].value
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr == "importorskip"
        and node.args
        and isinstance(node.args[0], ast.Constant)
        and node.args[0].value in HARD
    ]


def test_no_test_module_is_imported_by_another() -> None:
    found = {
        str(p.relative_to(ROOT)): names
        for p in _test_modules()
        if (names := _imports_of_test_modules(p))
    }
    assert not found, found


def test_no_hard_dependency_is_skipped() -> None:
    found = {str(p.relative_to(ROOT)): s for p in _test_modules() if (s := _hard_skips(p))}
    assert not found, found


def test_the_checks_see_what_they_look_for(tmp_path: Path) -> None:
    bad = tmp_path / "test_bad.py"
    bad.write_text(
        "import pytest\nfrom tests.web.test_status_page_browser import READY\n"
        "def test_x():\n    pytest.importorskip('mujoco')\n"
    )
    assert _imports_of_test_modules(bad) == ["tests.web.test_status_page_browser"]
    assert _hard_skips(bad) == ["mujoco"]
