"""The cells written from the SPEC alone (tests/cells/spec_written/): where they are, and
one cellrunner command run on them as a user runs it."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from cellrunner.cli.main import main

HERE = Path(__file__).parent / "spec_written"


def cell(name: str) -> str:
    return str(HERE / "cells" / f"{name}.yaml")


def task(name: str) -> str:
    return str(HERE / "tasks" / f"{name}.yaml")


def cli(*argv: str) -> tuple[int, dict]:
    """One cellrunner command with --json, as a user runs it: its exit code and object
    (a command refused before it printed one: its error lines as the object's errors)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([*argv, "--json"])
        except SystemExit as leave:
            code = leave.code if isinstance(leave.code, int) else 2
    if not out.getvalue().strip():
        return code, {"ok": False, "errors": err.getvalue().splitlines()}
    return code, json.loads(out.getvalue())
