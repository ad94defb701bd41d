"""The command line: exit codes, lazy imports, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.conftest import DEMO_CELL, ROOT

HEAVY = ("mujoco", "ompl", "asyncua", "toppra", "pinocchio")


def _run(*args, stdin=None):
    return subprocess.run(
        [sys.executable, "-m", "cellrunner.cli.main", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
        input=stdin,
    )


def _imported(argv, modules) -> tuple[int, list[str], str]:
    """Run the command in a fresh interpreter: (exit code, which of ``modules`` it loaded,
    stderr)."""
    code = (
        "import sys\nfrom cellrunner.cli.main import main\ntry:\n    rc = main(%r)\n"
        "except SystemExit as e:\n    rc = e.code\n"
        "print([m for m in %r if m in sys.modules])\nsys.exit(rc)"
    )
    r = subprocess.run(
        [sys.executable, "-c", code % (argv, modules)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    return r.returncode, json.loads(r.stdout.strip().splitlines()[-1].replace("'", '"')), r.stderr


def test_help_imports_nothing_heavy():
    rc, loaded, err = _imported(["--help"], (*HEAVY, "numpy"))
    assert rc == 0, err
    assert loaded == []


@pytest.mark.parametrize("cell", sorted(p.name for p in (ROOT / "cells").glob("*.yaml")))
def test_validate_imports_nothing_heavy_not_even_numpy(cell):
    """``validate`` reads files and checks them: no numpy (~50 ms of its ~0.2 s), no
    planning or simulation stack, on every reference cell and its tasks."""
    rc, loaded, err = _imported(["validate", str(ROOT / "cells" / cell)], (*HEAVY, "numpy"))
    assert rc == 0, err
    assert ": ok (cell " in err
    assert loaded == []


def test_warm_check_imports_only_what_reading_cached_plans_needs():
    """With every slot's plan cached, ``check --json`` loads the files and the plans: no
    planning stack, no solver, no plotting, no rich, no importlib.metadata."""
    argv = ["check", str(DEMO_CELL), str(ROOT / "tasks" / "pick_place.yaml"), "--json"]
    assert _run(*argv).returncode == 0  # fills the plan cache (cold or warm)
    unneeded = (*HEAVY, "scipy", "matplotlib", "coal", "rich", "importlib.metadata")
    rc, loaded, err = _imported(argv, unneeded)
    assert rc == 0, err
    assert loaded == []


def test_validate_ok():
    r = _run("validate", "cells/demo_ur5e.yaml")
    assert r.returncode == 0, r.stderr
    assert "cells/demo_ur5e.yaml: ok (cell demo-ur5e, ur5e" in r.stderr


def test_missing_file_is_input_error():
    r = _run("validate", "cells/nope.yaml")
    assert r.returncode == 2
    assert r.stderr.strip() == "cells/nope.yaml:1:1: error: no such file: cells/nope.yaml"


def test_bad_arguments_exit_2_without_traceback():
    r = _run("check", "cells/demo_ur5e.yaml")  # a cell without its task
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip() == "cellrunner check: error: give the TASK file after the CELL file"
    r = _run("dry-run", "--inject", "estop")
    assert r.returncode == 2 and "write FAULT@STEP" in r.stderr
    r = _run("frobnicate")
    assert r.returncode == 2 and "invalid choice" in r.stderr


def test_schema_command_prints_both():
    r = _run("schema")
    assert r.returncode == 0
    out = json.loads(r.stdout)
    assert set(out) == {"cell", "task"}
    assert out["cell"]["properties"]["robot"]
