"""Shared fixtures: paths of the repo's example files."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DEMO_CELL = ROOT / "cells" / "demo_ur5e.yaml"
PICK_PLACE = ROOT / "tasks" / "pick_place.yaml"


@pytest.fixture
def in_repo(monkeypatch):
    """Run with the repository root as the working directory."""
    monkeypatch.chdir(ROOT)
    return ROOT
