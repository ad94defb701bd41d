"""The cells written from the SPEC alone (tests/cells/spec_written/): where they are, and
one cellrunner command run on them as a user runs it."""

from __future__ import annotations

from pathlib import Path

from bench.agreement import cli as cli  # one command in this process, with --json

HERE = Path(__file__).parent / "spec_written"


def cell(name: str) -> str:
    return str(HERE / "cells" / f"{name}.yaml")


def task(name: str) -> str:
    return str(HERE / "tasks" / f"{name}.yaml")
