"""Every exception class cellrunner defines is drawn in the tree of cellrunner/errors.py,
so the tree a reader trusts is the whole tree (read from the source, as text); a broken
contract (InternalError) reaches the command line as the bug it is."""

from __future__ import annotations

import ast
import builtins
import os
import subprocess
import sys
from pathlib import Path

import pytest

import cellrunner.errors
from tests.conftest import DEMO_CELL, ROOT

#: every built-in exception (SystemExit and KeyboardInterrupt included)
_BASES = {
    name
    for name, value in vars(builtins).items()
    if isinstance(value, type) and issubclass(value, BaseException)
}


def exception_classes(root: Path) -> dict[str, str]:
    """Name -> module path of every class in ``root`` that derives, directly or through
    another class defined there, from a built-in exception."""
    bases: dict[str, tuple[list[str], str]] = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ClassDef):
                names = [ast.unparse(b).split(".")[-1] for b in node.bases]
                bases[node.name] = (names, str(path.relative_to(root.parent)))

    def is_exception(name: str, seen: frozenset[str] = frozenset()) -> bool:
        if name in _BASES:
            return True
        if name not in bases or name in seen:
            return False
        return any(is_exception(b, seen | {name}) for b in bases[name][0])

    return {name: where for name, (_, where) in bases.items() if is_exception(name)}


def test_every_exception_class_is_drawn_in_the_tree():
    found = exception_classes(ROOT / "cellrunner")
    assert len(found) > 25, "the exception classes were not found"
    tree = cellrunner.errors.__doc__ or ""
    assert {n: w for n, w in found.items() if n not in tree} == {}


def test_the_check_sees_a_class_outside_the_tree(tmp_path):
    pkg = tmp_path / "cellrunner"
    pkg.mkdir()
    (pkg / "a.py").write_text("class Odd(ValueError):\n    pass\nclass Child(Odd):\n    pass\n")
    (pkg / "b.py").write_text("class Plain:\n    pass\nclass Leave(SystemExit):\n    pass\n")
    assert exception_classes(pkg) == {
        "Odd": "cellrunner/a.py",
        "Child": "cellrunner/a.py",
        "Leave": "cellrunner/b.py",
    }


_BROKEN_CALL = """
import sys
import cellrunner.cli.cmd_validate as command
from cellrunner.cli.main import main
from cellrunner.errors import InternalError

def broken(args):
    raise InternalError("speed 2 is outside (0, 1]")

command.run = broken
sys.exit(main(["validate", sys.argv[1]]))
"""


@pytest.mark.parametrize("debug", [False, True])
def test_an_internal_error_is_reported_as_the_bug_it_is(debug):
    env = {**os.environ, "CELLRUNNER_DEBUG": "1" if debug else ""}
    r = subprocess.run(
        [sys.executable, "-c", _BROKEN_CALL, str(DEMO_CELL)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        timeout=60,
    )
    assert r.returncode == 1
    if debug:  # the traceback, for whoever fixes it
        assert "Traceback" in r.stderr and "InternalError: speed 2" in r.stderr
    else:
        assert r.stderr == (
            "cellrunner validate: internal error: InternalError: speed 2 is outside (0, 1] "
            "(set CELLRUNNER_DEBUG=1 for details)\n"
        )
